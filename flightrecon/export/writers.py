"""Writers for reconstructed trajectories: CSV, Parquet, GeoJSON, KML, and the summary JSON.

Every writer goes through :func:`flightrecon.export.atomic.atomic_path`: a hidden temporary file
beside the target, renamed on success, removed on failure or Ctrl-C.

Formats
-------
* CSV: one header line, units in the column names, ``.`` decimal point; with the summary
  known, ``time_utc`` (ISO-8601, milliseconds, ``Z``) after ``t_s`` and ``alt_msl_m``
  (ellipsoidal height minus the flight's geoid undulation) after ``alt_m``.
* Parquet: the same columns (without ``time_utc`` / ``alt_msl_m``: the epoch and undulation
  are in its metadata); the file's key-value metadata holds ``flightrecon`` (JSON: flight
  metadata, settings, software version, SHA-256 of every input file, column datums).
* GeoJSON (RFC 7946): a ``FeatureCollection`` with one ``LineString`` of
  ``[lon, lat, ellipsoidal height]`` and one ``Point`` feature per output sample (thinned to at
  most ``max_points``) whose properties carry ``t_s``, ``time_utc``, ``alt_msl_m`` and the
  standard deviations.
* KML 2.2 with the Google extensions: a styled ``LineString`` and a ``gx:Track`` (one
  ``when`` in UTC, one ``gx:coord`` and one ``gx:angles`` heading/tilt/roll per sample) that
  Google Earth's time slider replays, altitudes ``absolute`` (above mean sea level:
  ellipsoidal height minus the flight's geoid undulation, refused when unknown), and one
  labelled placemark per event (lift-off, touchdown, exceedances, outages...).
* CZML (Cesium): a document packet and one aircraft packet with sampled positions
  (cartographic degrees, ellipsoidal height) and the track as a path.
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from flightrecon.errors import OutputError
from flightrecon.export.atomic import atomic_path
from flightrecon.export.encode import (
    clean_json,
    flight_of,
    geo_rows,
    sd_columns,
    thin_index,
    to_json,
    utc_strings,
)
from flightrecon.export.replay import write_czml, write_kml


FORMATS = ("csv", "parquet", "geojson", "kml", "czml")
_SUFFIX = {".csv": "csv", ".parquet": "parquet", ".pq": "parquet", ".geojson": "geojson",
           ".json": "geojson", ".kml": "kml", ".czml": "czml"}
#: the suffix a format is written with
SUFFIX_OF = {"csv": ".csv", "parquet": ".parquet", "geojson": ".geojson", "kml": ".kml",
             "czml": ".czml"}
METADATA_KEY = b"flightrecon"


def format_from_path(path: str | Path, fmt: str | None = None) -> str:
    """The output format: ``fmt`` if given, else from the suffix of ``path``.

    Raises
    ------
    OutputError
        If ``fmt`` is unknown, if the suffix tells no format and ``fmt`` is not given, or if
        the suffix names another format than ``fmt`` (``out.parquet`` with ``kml``).
    """
    suffix = Path(path).suffix.lower()
    if fmt:
        fmt = fmt.lower()
        if fmt not in FORMATS:
            raise OutputError(f"unknown output format '{fmt}' (choose from {', '.join(FORMATS)})")
        if suffix in _SUFFIX and _SUFFIX[suffix] != fmt:
            raise OutputError(f"the suffix '{suffix}' says {_SUFFIX[suffix]} but the format "
                              f"asked for is {fmt}: use {SUFFIX_OF[fmt]} or drop --format",
                              file=str(path))
        return fmt
    if suffix not in _SUFFIX:
        raise OutputError(f"cannot tell the output format from the suffix '{suffix}' "
                          "(use .csv, .parquet, .geojson, .kml or .czml, or --format)",
                          file=str(path))
    return _SUFFIX[suffix]



def write_summary(path: str | Path, summary: Mapping[str, Any]) -> Path:
    """Write the summary JSON atomically."""
    text = to_json(summary) + "\n"
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_csv(path: str | Path, track: pd.DataFrame,
              metadata: Mapping[str, Any] | None = None) -> Path:
    """Write ``track`` as CSV; with ``metadata`` (the summary) add ``time_utc`` and
    ``alt_msl_m`` (:func:`with_utc_and_msl`)."""
    if metadata:
        track = with_utc_and_msl(track, metadata)
    with atomic_path(path) as tmp:
        track.to_csv(tmp, index=False, float_format="%.10g")
    return Path(path)


def with_utc_and_msl(track: pd.DataFrame, metadata: Mapping[str, Any]) -> pd.DataFrame:
    """``track`` with ``time_utc`` after ``t_s`` (when the epoch is known) and ``alt_msl_m``
    after ``alt_m`` (ellipsoidal height minus the flight's geoid undulation, when known)."""
    fl = flight_of(metadata)
    out = track.copy()
    if "t_s" in out.columns and "time_utc" not in out.columns:
        utc = utc_strings(out["t_s"].to_numpy(float), fl.get("epoch_utc"))
        if utc is not None:
            out.insert(out.columns.get_loc("t_s") + 1, "time_utc", utc)
    n = fl.get("geoid_undulation_m")
    if "alt_m" in out.columns and "alt_msl_m" not in out.columns and isinstance(n, (int, float)):
        if fl.get("geoid_model") and {"lat_deg", "lon_deg"} <= set(out.columns):
            from flightrecon.geo.geoid import undulation_m   # the model's N at each sample

            n = undulation_m(out["lat_deg"].to_numpy(float), out["lon_deg"].to_numpy(float))
        out.insert(out.columns.get_loc("alt_m") + 1, "alt_msl_m",
                   out["alt_m"].to_numpy(float) - n)
    return out


def write_parquet(path: str | Path, track: pd.DataFrame, metadata: Mapping[str, Any]) -> Path:
    """Write ``track`` as Parquet with the ``flightrecon`` metadata block (module docstring).

    Snappy-compressed (the Parquet default).  Dictionary encoding is used only for the
    non-floating columns (``source``, ``up_source``, ``provenance``: a handful of distinct
    texts); measured floating-point columns have almost no repeated values, so a dictionary
    there costs time (it is built, then abandoned page by page) and saves nothing: on a
    576 000-row result the write takes 0.4 s instead of 0.9 s and the file is 6 % smaller.
    The pandas metadata is kept, so :func:`pandas.read_parquet` restores the same columns and
    dtypes.
    """
    table = pa.Table.from_pandas(track, preserve_index=False)
    md = dict(table.schema.metadata or {})
    md[METADATA_KEY] = to_json(metadata).encode("utf-8")
    table = table.replace_schema_metadata(md)
    dictionary = [f.name for f in table.schema if not pa.types.is_floating(f.type)]
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, use_dictionary=dictionary)
    return Path(path)


def read_parquet_metadata(path: str | Path) -> dict[str, Any]:
    """The ``flightrecon`` metadata block of a Parquet file this tool wrote: a JSON object
    (UTF-8, standard JSON; docs/output.md, "Formats"); ``{}`` when the file has none.

    Raises
    ------
    InputFileError
        If the block is not a JSON object (a file written by something else under our key).
    """
    from flightrecon.errors import InputFileError

    md = pq.read_schema(path).metadata or {}
    if METADATA_KEY not in md:
        return {}
    try:
        doc = json.loads(md[METADATA_KEY].decode("utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise InputFileError(f"its '{METADATA_KEY.decode()}' metadata is not JSON ({exc})",
                             file=str(path)) from exc
    if not isinstance(doc, dict):
        raise InputFileError(f"its '{METADATA_KEY.decode()}' metadata is not a JSON object",
                             file=str(path))
    return doc


def write_geojson(path: str | Path, track: pd.DataFrame, properties: Mapping[str, Any],
                  max_points: int = 2000, metadata: Mapping[str, Any] | None = None) -> Path:
    """RFC 7946 FeatureCollection: the track as a LineString plus thinned Point features
    carrying ``t_s``, ``time_utc`` and ``alt_msl_m`` (when the summary gives the epoch and the
    geoid undulation) and the standard deviations."""
    rows = geo_rows(track)
    if metadata:
        rows = with_utc_and_msl(rows, metadata)
    coords = np.round(rows[["lon_deg", "lat_deg", "alt_m"]].to_numpy(), 8).tolist()
    sd_cols = sd_columns(rows)
    features = [{
        "type": "Feature",
        "geometry": {"type": "LineString", "coordinates": coords},
        "properties": {**clean_json(dict(properties)), "height_datum": "WGS-84 ellipsoid"},
    }]
    extra = [c for c in ("time_utc", "alt_msl_m", "source") if c in rows.columns]
    for i in thin_index(len(rows), max_points):
        r = rows.iloc[i]
        props: dict[str, Any] = {"t_s": float(r["t_s"])}
        for c in extra:
            props[c] = str(r[c]) if c != "alt_msl_m" else float(r[c])
        for c in sd_cols:
            props[c] = float(r[c])
        features.append({"type": "Feature",
                         "geometry": {"type": "Point",
                                      "coordinates": [round(float(r["lon_deg"]), 8),
                                                      round(float(r["lat_deg"]), 8),
                                                      round(float(r["alt_m"]), 3)]},
                         "properties": clean_json(props)})
    doc = {"type": "FeatureCollection", "features": features}
    text = json.dumps(doc, allow_nan=False)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)



def write_track(path: str | Path, track: pd.DataFrame, metadata: Mapping[str, Any],
                fmt: str | None = None, *, attitude: pd.DataFrame | None = None,
                geoid_undulation_m: float | None = None) -> Path:
    """Write ``track`` in the format chosen by ``fmt`` or the suffix of ``path``.

    ``metadata`` is the summary (may be empty for a bare CSV result: then no UTC time and no
    MSL altitude are added, and KML is refused unless ``geoid_undulation_m`` is given);
    ``attitude`` the recorder's attitude for the KML replay.
    """
    fmt = format_from_path(path, fmt)
    if fmt == "csv":
        return write_csv(path, track, metadata)
    if fmt == "parquet":
        return write_parquet(path, track, metadata)
    flight = flight_of(metadata)
    name = str(flight.get("flight_id") or Path(path).stem)
    if geoid_undulation_m is not None:
        metadata = {**metadata, "flight": {**flight, "geoid_undulation_m": geoid_undulation_m}}
    if fmt == "geojson":
        return write_geojson(path, track, {"name": name, "flight": flight}, metadata=metadata)
    if fmt == "czml":
        return write_czml(path, track, name, metadata)
    return write_kml(path, track, name, geoid_undulation_m, metadata=metadata,
                     attitude=attitude)


def read_track(path: str | Path) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Read a result written by :func:`write_track` (CSV or Parquet) with its metadata."""
    from flightrecon.errors import InputFileError

    p = Path(path)
    if not p.is_file():
        raise InputFileError("no such result file", file=str(p))
    try:
        if p.suffix.lower() in (".parquet", ".pq"):
            return pd.read_parquet(p), read_parquet_metadata(p)
        if p.suffix.lower() == ".csv":
            return pd.read_csv(p), {}
    except (OSError, ValueError, pa.ArrowException) as exc:
        raise InputFileError(f"cannot read result: {exc}", file=str(p)) from exc
    raise InputFileError("a result to convert must be .csv or .parquet", file=str(p))
