"""Writing a simulation: log, truth, metadata sidecar and sensor truth (docs/simulator.md).

``write_simulation(result, "x.parquet")`` writes

* ``x.parquet`` (or ``x.csv``): the recorded log, canonical columns;
* ``x.truth.parquet``: the truth on its uniform grid;
* ``x.meta.toml``: the metadata sidecar (format shared with :mod:`flightrecon.ingest`);
* ``x.sensors.json``: persistent sensor errors, weather, events and injected faults.

``write_export(result, "x.parquet", "ed112")`` adds the ED-112 minimum-rate export of the same
log (:mod:`flightrecon.sim.ed112`): ``x.ed112.csv``, the mapping that reads it,
``x.ed112.mapping.toml``, and its sidecar ``x.ed112.meta.toml`` (the same metadata, so that
``flightrecon reconstruct x.ed112.csv --mapping x.ed112.mapping.toml`` finds its end points).

``write_export(result, "x.parquet", "garmin")`` adds the log as a Garmin glass-cockpit CSV
export at 1 Hz (:mod:`flightrecon.sim.glass_cockpit`): ``x.garmin.csv``, read as recorded with
no mapping, and its sidecar ``x.garmin.meta.toml`` (airfields with their runways, QNH, geoid).

Every file is written atomically (:func:`flightrecon.export.atomic.atomic_path`); the same
result gives byte-identical files.
"""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd

from flightrecon.errors import OutputError
from flightrecon.export.atomic import atomic_path, write_text_atomic
from flightrecon.sim.sidecar import meta_toml, sibling

__all__ = ["EXPORT_FORMATS", "meta_toml", "sibling", "write_export", "write_frame",
           "write_simulation"]

EXPORT_FORMATS = ("ed112", "garmin")
"""Recorder export formats that :func:`write_export` writes beside a simulated log."""

CSV_FLOAT_FORMAT = "%.10g"
"""CSV number format: 10 significant digits (1e-6 deg of latitude is 0.1 m; finer than
every simulated noise)."""


PARQUET_ZSTD_LEVEL = (12, 3)
"""Parquet compression: zstd with byte-stream-split floats (about half the plain size); the
higher level below :data:`BIG_ROWS` rows, the faster one above (the 576 000-row long haul)."""
BIG_ROWS = 100_000


def write_frame(frame: pd.DataFrame, path: str | Path) -> Path:
    """Write ``frame`` as Parquet or CSV (by suffix), atomically and deterministically."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in (".parquet", ".csv"):
        raise OutputError("the log must end in .parquet or .csv", file=str(path))
    with atomic_path(path) as tmp:
        if suffix == ".parquet":
            import pyarrow as pa
            import pyarrow.parquet as pq

            floats = [c for c in frame.columns if frame[c].dtype.kind == "f"]
            pq.write_table(pa.Table.from_pandas(frame, preserve_index=False), tmp,
                           compression="zstd", compression_level=PARQUET_ZSTD_LEVEL[len(frame) > BIG_ROWS],
                           use_byte_stream_split=floats or False, use_dictionary=False)
        else:
            frame.to_csv(tmp, index=False, float_format=CSV_FLOAT_FORMAT, lineterminator="\n")
    return path


def write_simulation(result, path: str | Path) -> dict[str, Path]:
    """Write a :class:`~flightrecon.sim.scenarios.SimResult` beside ``path`` (module docstring).

    Returns the written paths by role (``log``, ``truth``, ``meta``, ``sensors``).
    """
    path = Path(path)
    out = {"log": write_frame(result.log, path)}
    out["truth"] = write_frame(result.truth, sibling(path, ".truth.parquet"))
    out["meta"] = write_text_atomic(sibling(path, ".meta.toml"), meta_toml(result.meta))
    out["sensors"] = write_text_atomic(
        sibling(path, ".sensors.json"),
        json.dumps(result.sensor_truth, indent=1, sort_keys=True, allow_nan=False) + "\n")
    return out


def write_export(result, path: str | Path, fmt: str) -> dict[str, Path]:
    """Write the recorder export ``fmt`` of ``result``'s log beside ``path`` (module
    docstring).

    Parameters
    ----------
    result : :class:`~flightrecon.sim.scenarios.SimResult`
    path : the simulated log's path (the export's names derive from it)
    fmt : one of :data:`EXPORT_FORMATS`

    Returns
    -------
    dict
        The written paths by role (``export``, ``mapping`` (ED-112 only), ``export_meta``).

    Raises
    ------
    OutputError
        An unknown format, or an ED-112 export of a result without a departure (the magnetic
        declination of the recorded heading needs a place).
    ValidationError
        A Garmin export of a log without a recorder channel it needs, or without
        ``epoch_utc`` (:func:`flightrecon.sim.glass_cockpit.glass_cockpit_export`).
    """
    if fmt not in EXPORT_FORMATS:
        raise OutputError(f"unknown export format {fmt!r}; choose one of {list(EXPORT_FORMATS)}")
    if fmt == "garmin":
        from flightrecon.sim.glass_cockpit import write_glass_cockpit

        g = write_glass_cockpit(result, sibling(path, f".{fmt}.csv"))
        return {"export": g["export"], "export_meta": g["meta"]}
    from flightrecon.sim.ed112 import ed112_export, ed112_mapping

    dep = result.meta.departure
    if dep is None:
        raise OutputError("the ED-112 export needs the flight's departure (magnetic heading)")
    ex = ed112_export(result.log, lat_deg=dep.lat_deg, lon_deg=dep.lon_deg,
                      epoch_utc=result.meta.epoch_utc)
    out = {"export": write_frame(ex, sibling(path, f".{fmt}.csv"))}
    out["mapping"] = write_text_atomic(sibling(path, f".{fmt}.mapping.toml"), ed112_mapping(ex))
    out["export_meta"] = write_text_atomic(sibling(path, f".{fmt}.meta.toml"),
                                           meta_toml(result.meta))
    return out
