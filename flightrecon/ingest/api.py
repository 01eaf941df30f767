"""``load_flight``: read, map, merge and validate a recorder log into a :class:`Flight`.

Order of work (docs/ingest.md): metadata (sidecar, then command-line overrides) -> mapping ->
recorder log (read, map (a Garmin export through :mod:`.garmin`), time to seconds from the UTC
epoch, time order) -> separate GNSS / radar files merged at their own times -> derived channels
(TAS from IAS/CAS, magnetic -> true, ``n_long_g`` from airspeed and pitch) -> validation of
values and polarity.  Recoverable defects become warnings, both in
``Flight.warnings`` and through :func:`warnings.warn` with :class:`FlightReconWarning`.  The
reading is :mod:`.sources`', the derived channels and the validated table :mod:`.frame`'s.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.errors import FlightReconWarning, MetadataError
from flightrecon.geo.geoid import with_flight_geoid
from flightrecon.ingest.door import DoorCheck
from flightrecon.ingest.frame import declared_units, derived_channels, validated_frame
from flightrecon.ingest.gnss_use import GnssUse
from flightrecon.ingest.mapping import Mapping, load_mapping
from flightrecon.ingest.sidecar import apply_overrides, discover_sidecar, load_sidecar
from flightrecon.ingest.sources import Sources, add_companion, read_log
from flightrecon.types import Flight, FlightMeta

__all__ = ["load_flight"]

PathLike = str | os.PathLike


def load_flight(log: PathLike, *, gnss: PathLike | None = None, radar: PathLike | None = None,
                mapping: PathLike | None = None, sidecar: PathLike | None = None,
                meta_overrides: dict[str, Any] | None = None, allow_unsorted: bool = False,
                gnss_use: GnssUse | None = None, frame_rate_hz: float | None = None) -> Flight:
    """Load and validate a flight.

    Parameters
    ----------
    log : recorder log, CSV or Parquet (canonical columns, or foreign ones with ``mapping``)
    gnss, radar : separate GNSS / radar files, merged on UTC time (each fix one row at its own
        time); default: the sidecar's ``[files]``
    mapping : mapping file (TOML, docs/ingest.md); default: the sidecar's ``[files] mapping``
    sidecar : metadata file; default ``<log stem>.meta.toml`` beside the log if it exists
    meta_overrides : metadata from the command line (``FlightMeta`` field names; positions as
        :class:`Position` or ``"LAT,LON,ELEV_M"``); they win over the sidecar.  The former key
        ``withhold_gnss`` still works, with a :class:`DeprecationWarning`: use ``gnss_use``
    allow_unsorted : sort backward timestamps (and keep duplicates) with a warning instead of
        raising; the cleaning layer then decides what to do with duplicates
    gnss_use : how the GNSS fixes are used (:class:`flightrecon.ingest.gnss_use.GnssUse`:
        ``withhold`` drops every GNSS channel of the log and its companion files, as
        ``reconstruct --no-gnss``; ``withhold_s`` windows, ``interval_s`` thinning,
        ``h_sd_m`` / ``v_sd_m`` the receiver's sd); each option given wins over the
        sidecar's ``[gnss]`` table (docs/ingest.md, "Using the GNSS")
    frame_rate_hz : frames a second of a recorder timed by its frame count (``--frame-rate``)

    Returns
    -------
    Flight
        ``data``: ``t_s`` (seconds from ``meta.epoch_utc``, sorted), canonical channels in SI
        units (NaN where not sampled), ``row`` (1-based data row in its source file) and
        ``src_file`` (index into ``Flight.sources``).

    Raises
    ------
    InputFileError, SchemaError, ValidationError, MappingError, MetadataError
        See docs/ingest.md for each case; messages name the file, the column and the rows.
    """
    warns: list[str] = []
    notes: list[str] = []
    log = Path(log)
    overrides = dict(meta_overrides or {})
    use = _deprecated_withhold(overrides, gnss_use or GnssUse())
    sc, meta, companion = _metadata(log, sidecar, overrides or None, warns)
    use = use.over(sc.gnss if sc is not None else None)
    withhold_gnss = use.withhold
    gnss = gnss if gnss is not None else companion.get("gnss")
    if withhold_gnss:
        gnss = None
        notes.append("GNSS withheld: the log's GNSS channels and any GNSS file are not used")
    radar = radar if radar is not None else companion.get("radar")
    mapping = mapping if mapping is not None else companion.get("mapping")
    mp: Mapping | None = load_mapping(mapping) if mapping is not None else None
    src, meta = read_log(log, mp, meta, allow_unsorted, warns, notes, withhold_gnss,
                         frame_rate_hz)
    for group, path in (("gnss", gnss), ("radar", radar)):
        if path is not None:
            add_companion(src, group, Path(path), mp, meta, allow_unsorted, warns, notes)
    values = derived_channels(src, meta, log, warns, notes)
    door: list[DoorCheck] = []
    gnss_rec: dict[str, Any] = {}
    data, repairs = validated_frame(src, values, warns, notes, declared_units(mp, src),
                                    door, use, gnss_rec)
    _check_priors(meta, data, warns)
    meta = _geoid(meta, data, "geoid_undulation_m" in (sc.given if sc is not None else ())
                  or overrides.get("geoid_undulation_m") is not None, notes)
    record = dataclasses.replace(
        meta.ingest, notes=tuple(notes), repairs=tuple(r.as_dict() for r in repairs),
        door=tuple(c.as_dict() for c in door), mapping=None if mp is None else mp.file,
        derived_channels=_derived(src), ignored_columns=tuple(src.ignored),
        gnss_use=gnss_rec or ({"options": use.as_dict()} if use.any else {}),
        sidecar=None if sc is None else sc.path)
    meta = dataclasses.replace(meta, ingest=record)
    for w in warns:
        warnings.warn(w, FlightReconWarning, stacklevel=2)
    return Flight(data=data, meta=meta, sources=tuple(src.files), warnings=tuple(warns))


def _deprecated_withhold(overrides: dict[str, Any], use: GnssUse) -> GnssUse:
    """``use`` with the former ``meta_overrides['withhold_gnss']`` key taken out of
    ``overrides`` and honoured, with a :class:`DeprecationWarning`."""
    if "withhold_gnss" in overrides:
        warnings.warn("load_flight: meta_overrides['withhold_gnss'] is deprecated; use "
                      "gnss_use=GnssUse(withhold=True)", DeprecationWarning, stacklevel=3)
        if bool(overrides.pop("withhold_gnss")):
            use = dataclasses.replace(use, withhold=True)
    return use


def _geoid(meta: FlightMeta, data: pd.DataFrame, given: bool, notes: list[str]) -> FlightMeta:
    """The flight's geoid undulation: EGM96 at its fixes or departure unless the sidecar or the
    caller ``given`` one (:func:`flightrecon.geo.geoid.with_flight_geoid`)."""
    has_fixes = {"gnss_lat_deg", "gnss_lon_deg"} <= set(data.columns)
    lat, lon = (data[c].to_numpy(float) if has_fixes else np.array([])
                for c in ("gnss_lat_deg", "gnss_lon_deg"))
    return with_flight_geoid(meta, lat, lon, given, notes)


def _derived(src: Sources) -> dict[str, str]:
    """Channels computed at ingest (not recorded) -> how: the estimators widen their error
    model for them (the joint smoother: ``n_long_g``), the summary says which."""
    out = {ch: f"from {kind}_mps, sat_degc and baro_alt_m" for ch, kind in src.mt.derived.items()}
    if src.derive_long:
        out["n_long_g"] = "(dV/dt)/g0 + sin(pitch) from tas_mps and pitch_deg"
    if src.derive_lat:
        out["n_lat_g"] = "0 g: the lateral load of coordinated flight (no lateral accelerometer)"
    return out


def _metadata(log: Path, sidecar: PathLike | None, meta_overrides: dict[str, Any] | None,
              warns: list[str]) -> tuple[Any, FlightMeta, dict[str, Any]]:
    """The sidecar (given, or beside the log), the metadata with the command line's
    overrides, and the companion files the sidecar names."""
    if sidecar is not None and not Path(sidecar).is_file():
        raise MetadataError("sidecar file not found", file=str(sidecar))
    sc_path = Path(sidecar) if sidecar is not None else discover_sidecar(log)
    sc = load_sidecar(sc_path) if sc_path is not None else None
    meta = sc.meta if sc else FlightMeta()
    companion = dict(sc.files) if sc else {}
    if sc:
        warns += list(sc.warnings)
    return sc, apply_overrides(meta, meta_overrides), companion


def _check_priors(meta: FlightMeta, data: pd.DataFrame, warns: list[str]) -> None:
    """Known positions must fall inside the record; which estimators use the fixes and the
    winds aloft is said (docs/wind.md)."""
    if meta.fixes and len(data):
        from flightrecon.ingest.priors import check_fix_times

        check_fix_times(meta.fixes, float(data["t_s"].iloc[0]), float(data["t_s"].iloc[-1]))
    if meta.fixes or meta.wind_aloft:
        # used by the joint smoother (the default result) and Sabziev, not by the others
        # (docs/wind.md): said, so that nobody takes those methods' results for ones that used
        # them
        given = " and ".join(w for w, on in (("known positions (--fix)", meta.fixes),
                                             ("a winds-aloft prior (--wind)", meta.wind_aloft))
                             if on)
        warns.append(f"{given}: used by the joint smoother"
                     + (" and Sabziev (a fix only as the end point, at the end of the record)"
                        if meta.fixes else " and Sabziev")
                     + "; the sns, arms and azimuth methods do not use them")
