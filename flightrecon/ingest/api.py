"""``load_flight``: read, map, merge and validate a recorder log into a :class:`Flight`.

Order of work (docs/ingest.md): metadata (sidecar, then command-line overrides) -> mapping ->
recorder log (read, map (a Garmin export through :mod:`.garmin`), time to seconds from the UTC
epoch, time order) -> separate GNSS / radar files merged at their own times -> derived channels
(TAS from IAS/CAS, magnetic -> true, ``n_long_g`` from airspeed and pitch) -> validation of
values and polarity.  Recoverable defects become warnings, both in
``Flight.warnings`` and through :func:`warnings.warn` with :class:`FlightReconWarning`.
"""

from __future__ import annotations

import dataclasses
import os
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.errors import FlightReconWarning, MetadataError, SchemaError
from flightrecon.ingest.derive import derive_n_long, derive_tas, true_from_magnetic
from flightrecon.ingest.garmin import (
    altimeter_settings_hpa,
    apply_garmin_columns,
    garmin_mapping,
    merge_with_user,
)
from flightrecon.ingest.gnss_quality import apply_gnss_quality
from flightrecon.ingest.gnss_use import GnssUse
from flightrecon.ingest.mapping import MappedTable, Mapping, load_mapping
from flightrecon.ingest.mapping_apply import apply_mapping
from flightrecon.ingest.merge import Rows, merge_rows
from flightrecon.ingest.readers import read_table
from flightrecon.ingest.door import DeclaredUnit, DoorCheck, DoorRefusal
from flightrecon.ingest.physics import door_checks
from flightrecon.ingest.timestamps import repair_time_order, unset_clock_rows
from flightrecon.ingest.sidecar import (
    apply_overrides,
    discover_sidecar,
    load_sidecar,
    normalise_epoch,
)
from flightrecon.ingest.validate import (
    Provenance,
    check_polarity,
    check_required,
    check_time,
    check_values,
)
from flightrecon.schema import BY_NAME, CHANNELS, GROUPS
from flightrecon.types import Flight, FlightMeta

__all__ = ["load_flight", "mapping_beside"]

PathLike = str | os.PathLike


def load_flight(log: PathLike, *, gnss: PathLike | None = None, radar: PathLike | None = None,
                mapping: PathLike | None = None, sidecar: PathLike | None = None,
                meta_overrides: dict[str, Any] | None = None,
                allow_unsorted: bool = False, gnss_use: GnssUse | None = None) -> Flight:
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
    use = gnss_use or GnssUse()
    if "withhold_gnss" in overrides:
        warnings.warn("load_flight: meta_overrides['withhold_gnss'] is deprecated; use "
                      "gnss_use=GnssUse(withhold=True)", DeprecationWarning, stacklevel=2)
        if bool(overrides.pop("withhold_gnss")):
            use = dataclasses.replace(use, withhold=True)
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
    src, meta = _read_log(log, mp, meta, allow_unsorted, warns, notes, withhold_gnss)
    for group, path in (("gnss", gnss), ("radar", radar)):
        if path is not None:
            _add_companion(src, group, Path(path), mp, meta, allow_unsorted, warns, notes)
    values = _derived_channels(src, meta, log, warns, notes)
    door: list[DoorCheck] = []
    gnss_rec: dict[str, Any] = {}
    data, repairs = _validated_frame(src, values, warns, notes, _declared_units(mp, src),
                                     door, use, gnss_rec)
    _check_priors(meta, data, warns)
    meta = dataclasses.replace(meta, extra={**meta.extra, "ingest_notes": notes,
                                            "ingest_repairs": [r.as_dict() for r in repairs],
                                            "door": [c.as_dict() for c in door],
                                            "mapping": None if mp is None else mp.file,
                                            "derived_channels": _derived(src),
                                            "ignored_columns": list(src.ignored),
                                            "gnss_use": gnss_rec or ({"options": use.as_dict()}
                                                                     if use.any else {}),
                                            "sidecar": None if sc is None else sc.path})
    for w in warns:
        warnings.warn(w, FlightReconWarning, stacklevel=2)
    return Flight(data=data, meta=meta, sources=tuple(src.files), warnings=tuple(warns))


def _derived(src: _Sources) -> dict[str, str]:
    """Channels computed at ingest (not recorded) -> how: the estimators widen their error
    model for them (the joint smoother: ``n_long_g``), the summary says which."""
    out = {ch: f"from {kind}_mps, sat_degc and baro_alt_m" for ch, kind in src.mt.derived.items()}
    if src.derive_long:
        out["n_long_g"] = "(dV/dt)/g0 + sin(pitch) from tas_mps and pitch_deg"
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


@dataclasses.dataclass
class _Sources:
    """The rows read so far (log first, then the companion files merged in), with the
    provenance the validation reports against."""

    mt: MappedTable
    rows: Rows
    epoch_ns: Any
    files: list[str]
    source_cols: list[dict[str, str]]
    magnetic: dict[str, tuple[str, str]]
    derive_long: bool = False
    ignored: tuple[str, ...] = ()


def _read_log(log: Path, user_mp: Mapping | None, meta: FlightMeta, allow_unsorted: bool,
              warns: list[str], notes: list[str], withhold_gnss: bool = False
              ) -> tuple[_Sources, FlightMeta]:
    """The recorder log through its mapping (a Garmin export's built-in one under the user's):
    schema checks, time base, time order."""
    raw = read_table(log)
    warns += list(raw.warnings)
    mp = user_mp
    garmin_used: tuple[str, ...] = ()
    if raw.dialect == "garmin":
        mp = merge_with_user(garmin_mapping(raw), user_mp)
        garmin_used = tuple(c for c in ("MagVar", "BaroA", "GndSpd", "TRK", "GPSfix")
                            if c in raw.columns)
        notes.append(f"{log}: Garmin export ({raw.preamble.get('airframe_name', 'airframe ?')}"
                     f", software {raw.preamble.get('system_software_part_number', '?')}) read "
                     "with the built-in mapping" + (" under the user's mapping" if user_mp
                                                    else ""))
    if raw.blank_rows.size:
        warns.append(f"{log}: {raw.blank_rows.size} empty row(s) skipped (first: row "
                     f"{raw.blank_rows[0]})")
    raw = _drop_unset_clock(raw, mp, log, warns)
    try:
        mt = apply_mapping(raw, mp)
    except SchemaError as exc:          # no time column: point at a mapping beside the log
        hint = _mapping_hint(log) if mp is None else ""
        if not hint:
            raise
        raise SchemaError(f"{exc.message}; {hint}", file=exc.file, column=exc.column,
                          rows=exc.rows) from None
    if raw.nan_is_missing:
        notes.append(f"{log}: NaN cells read as 'not sampled' (the file has no empty cells)")
    if raw.dialect == "garmin" and mp is not None:
        mt = apply_garmin_columns(raw, mt, mp, withhold_gnss)
        meta = _qnh_from_setting(meta, altimeter_settings_hpa(raw, mt), notes)
    withheld: set[str] = set()
    if withhold_gnss:
        kept = _without_gnss(mt)
        withheld = set(mt.source_column.values()) - set(kept.source_column.values())
        mt = kept
    used = (set(mt.source_column.values()) | set(_time_columns(mp, raw.columns))
            | set(garmin_used) | withheld)   # withheld GNSS columns are said so, not "ignored"
    ignored = [c for c in raw.columns if c not in used]
    if ignored:
        shown = ", ".join(ignored[:8]) + (" ..." if len(ignored) > 8 else "")
        warns.append(f"{log}: {len(ignored)} column(s) not in the schema and not mapped, "
                     f"ignored: {shown}")
    present = set(mt.values) | set(mt.derived)
    if "tas_mps" not in present and ("cas_mps" in present or "ias_mps" in present):
        present.add("tas_mps")
        mt = dataclasses.replace(mt, derived={**mt.derived, "tas_mps": "cas" if "cas_mps"
                                              in present else "ias"})
    derive_long = "n_long_g" not in present and {"tas_mps", "pitch_deg"} <= present
    if derive_long:
        present.add("n_long_g")
    if "heading_deg" not in present and {"q_dps", "r_dps"} <= present:
        present.add("heading_deg")
        notes.append("no heading channel: the heading is propagated from the body rates at "
                     "cleaning (docs/signals.md, 'Heading from the body rates')")
    check_required(present, str(log), ignored,
                   mapping_hint="" if mp is not None else _mapping_hint(log))
    notes += list(mt.notes)
    t, meta, epoch_ns, epoch_note = _log_seconds(mt, meta)
    if epoch_note:
        notes.append(epoch_note)
    t, tvalues, order, w = _time_order(t, mt.rows, mt.values, str(log),
                                       _time_column(mt, mp, raw.columns), allow_unsorted)
    warns += w
    sel = order if order is not None else slice(None)
    rows = Rows(t=t[sel], values={k: v[sel] for k, v in tvalues.items()},
                src_file=np.zeros(t.size, dtype=np.int64)[sel], row=mt.rows[sel],
                nan_text={k: v[sel] for k, v in mt.nan_text.items()})
    magnetic = {c: (str(log), mt.source_column[c]) for c in mt.magnetic}
    return _Sources(mt, rows, epoch_ns, [str(log)], [dict(mt.source_column)], magnetic,
                    derive_long, tuple(ignored)), meta


def _add_companion(src: _Sources, group: str, path: Path, mp: Mapping | None, meta: FlightMeta,
                   allow_unsorted: bool, warns: list[str], notes: list[str]) -> None:
    """Merge a separate GNSS or radar file into ``src`` on UTC time (each fix its own row)."""
    sub = getattr(mp, group) if mp is not None else None
    craw = read_table(path)
    warns += list(craw.warnings)
    cm = apply_mapping(craw, sub, group=group, mapping_file=mp.file if mp else None)
    if not cm.values:
        raise SchemaError(f"no {group} columns ({', '.join(GROUPS[group])}) in the "
                          f"{group} file", file=str(path))
    clash = [c for c in cm.values if c in src.rows.values
             and (~np.isnan(src.rows.values[c])).any()]
    if clash:
        raise SchemaError(f"the log already has {group} data in {', '.join(clash)} and a "
                          f"separate {group} file was given", file=str(path), column=clash[0])
    ct = _companion_seconds(cm, meta, src.epoch_ns)
    ct, cvalues, corder, w = _time_order(ct, cm.rows, cm.values, str(path), "time",
                                         allow_unsorted)
    warns += w
    csel = corder if corder is not None else slice(None)
    k = len(src.files)
    src.files.append(str(path))
    src.source_cols.append(dict(cm.source_column))
    for c in cm.magnetic:
        src.magnetic[c] = (str(path), cm.source_column[c])
    notes += list(cm.notes)
    add = Rows(t=ct[csel], values={c: v[csel] for c, v in cvalues.items()},
               src_file=np.full(ct.size, k, dtype=np.int64), row=cm.rows[csel],
               nan_text={c: v[csel] for c, v in cm.nan_text.items()})
    src.rows = merge_rows(src.rows, add)


def _derived_channels(src: _Sources, meta: FlightMeta, log: Path, warns: list[str],
                      notes: list[str]) -> dict[str, np.ndarray]:
    """The channels on the merged rows, with TAS from CAS/IAS and true from magnetic angles."""
    rows = src.rows
    values = dict(rows.values)
    for ch, kind in src.mt.derived.items():
        values[ch], w = derive_tas(rows.t, values, kind, str(log))
        warns += w
        notes.append(f"{ch} computed from {kind}_mps, sat_degc and baro_alt_m (ISA, "
                     "compressible)")
    for ch, (f, col) in src.magnetic.items():
        values[ch], n = true_from_magnetic(rows.t, values[ch], values, meta, f, col)
        notes += n
    if src.derive_long:
        values["n_long_g"], note = derive_n_long(rows.t, values, str(log))
        notes.append(note)
        warns.append(note)
    return values


def _declared_units(mp: Mapping | None, src: _Sources) -> dict[str, DeclaredUnit]:
    """The unit each mapped channel's column is read in, and whether the mapping wrote it
    (the user's word: it wins over the door's physics; docs/ingest.md, "The door").  A true
    airspeed computed from CAS or IAS is judged in its source's unit."""
    out: dict[str, DeclaredUnit] = {}
    for m, table in ((mp, "channels"), (getattr(mp, "gnss", None), "gnss.channels"),
                     (getattr(mp, "radar", None), "radar.channels")):
        if m is None:
            continue
        for spec in m.channels:
            if spec.unit is not None:
                out[spec.channel] = DeclaredUnit(spec.unit.name, spec.unit_declared,
                                                 f"{m.file} [{table}.{spec.channel}]")
    kind = src.mt.derived.get("tas_mps")
    if kind is not None and f"{kind}_mps" in out:
        out["tas_mps"] = out[f"{kind}_mps"]
    return out


def _validated_frame(src: _Sources, values: dict[str, np.ndarray], warns: list[str],
                     notes: list[str], declared: dict[str, DeclaredUnit] | None = None,
                     door: list[DoorCheck] | None = None, use: GnssUse | None = None,
                     gnss_rec: dict[str, Any] | None = None) -> tuple[pd.DataFrame, list[Any]]:
    """The flight's table: values checked (ranges, polarity, GNSS quality and the analyst's
    GNSS options ``use``, physics), angles wrapped, empty channels dropped, provenance columns
    ``row`` and ``src_file``; with the repairs made.  The door's checks are appended to
    ``door``, what the GNSS options did and the rounding added to ``gnss_rec``."""
    rows = src.rows
    cols = _own_columns({"t_s": rows.t, **{c.name: values[c.name] for c in CHANNELS
                                           if c.name in values}})
    # one block per column (copy=False): no 100 MB consolidation copy for a 10-hour log
    data = pd.DataFrame(cols, copy=False)
    prov = Provenance(files=tuple(src.files), src_file=rows.src_file, row=rows.row,
                      source_column=tuple(src.source_cols))
    door = door if door is not None else []
    w, repairs = check_values(data, prov, rows.nan_text)
    warns += w
    door.append(_summary_check("values in range", w, f"{len(repairs)} value(s) repaired"))
    for r in {r.channel for r in repairs}:
        cols[r] = data[r].to_numpy()
    w = check_polarity(data, prov)
    warns += w
    door.append(_summary_check("load-factor polarity", w, "n_norm_g, n_long_g and the turns' "
                               "n_lat_g have the schema's signs"))
    w, rq, nq, rec = apply_gnss_quality(cols, rows.t, prov, use)
    if gnss_rec is not None:
        gnss_rec.update(rec)
    warns += w
    repairs += rq
    notes += nq
    try:                                 # units and time base against physics
        w, checks = door_checks(data, prov, declared)
    except DoorRefusal as exc:
        door += exc.checks
        raise
    warns += w
    door += checks
    for name in list(cols):
        ch = BY_NAME.get(name)
        if ch is not None and ch.angle:
            # wrapped on the sampled rows only: numpy's floating modulo is about 100 times
            # slower on NaN (the unsampled rows of a multi-rate log) than on numbers
            v = cols[name].copy()
            ok = ~np.isnan(v)
            v[ok] = np.mod(v[ok], 360.0)
            cols[name] = v
        if name != "t_s" and np.isnan(cols[name]).all():
            del cols[name]
    cols["row"] = np.array(rows.row, copy=True)
    cols["src_file"] = rows.src_file.astype(np.int8)
    return pd.DataFrame(cols, copy=False), repairs


def _summary_check(check: str, warns: list[str], ok_text: str) -> DoorCheck:
    """A door record for a validation step that raises on certainty and warns otherwise."""
    if warns:
        return DoorCheck(check, "-", "warned", float(len(warns)), "; ".join(warns))
    return DoorCheck(check, "-", "passed", None, ok_text)


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


def mapping_beside(log: PathLike) -> list[Path]:
    """Mapping files beside ``log``: ``<stem>.mapping.toml`` first, then any other
    ``*.mapping.toml`` / ``*mapping*.toml`` in its folder (sorted)."""
    log = Path(log)
    stem = log.name.split(".")[0]
    own = log.with_name(f"{stem}.mapping.toml")
    found = [own] if own.is_file() else []
    try:
        others = sorted(p for p in log.parent.glob("*mapping*.toml") if p.is_file())
    except OSError:
        others = []
    return found + [p for p in others if p != own]


def _mapping_hint(log: Path) -> str:
    found = mapping_beside(log)
    if not found:
        return ""
    names = ", ".join(str(p) for p in found[:3])
    return (f"a mapping file lies beside the log ({names}): give it with --mapping "
            f"{found[0]} (or mapping = \"{found[0].name}\" in the sidecar's [files])")


def _time_order(t, rows, values, file: str, column: str, allow_unsorted: bool):
    """Rows in time order: ``(t, values, selection, warnings)``, repaired and reported, or
    refused (:mod:`.timestamps`); with ``allow_unsorted`` the old rule (sort everything, keep
    duplicates, with a warning)."""
    if allow_unsorted:
        order, w = check_time(t, rows, file, column, allow_unsorted=True)
        return t, values, order, w
    rep = repair_time_order(t, rows, values, file, column)
    return rep.t, rep.values, rep.selection, rep.warnings


def _time_columns(mp: Mapping | None, columns) -> tuple[str, ...]:
    """Every source column the time is read from (time, and a separate date and offset)."""
    if mp is not None and mp.time is not None:
        return tuple(c for c in (mp.time.column, mp.time.date_column,
                                 mp.time.utc_offset_column) if c is not None)
    return ("t_s",) if "t_s" in columns else ("time_utc",)


def _drop_unset_clock(raw, mp: Mapping | None, log: Path, warns: list[str]):
    """``raw`` with the rows written before the recorder's clock was set (empty time cells at
    the start of the file, :func:`.timestamps.unset_clock_rows`) marked to be skipped, and a
    warning naming them."""
    names = tuple(c for c in _time_columns(mp, raw.columns) if c in raw.columns)
    if not names:
        return raw
    idx = unset_clock_rows(raw.columns, names)
    if not idx.size:
        return raw
    blank = np.union1d(raw.blank_rows, idx + 1).astype(np.int64)
    if blank.size >= raw.n_rows:
        return raw                        # no time at all: apply_mapping names the rows
    warns.append(f"{log}: {idx.size} row(s) at the start have no time ({', '.join(names)} "
                 f"empty: written before the recorder's clock was set): dropped (rows "
                 f"{idx[0] + 1}..{idx[-1] + 1})")
    return dataclasses.replace(raw, blank_rows=blank)


def _qnh_from_setting(meta: FlightMeta, settings: tuple[float, float] | None,
                      notes: list[str]) -> FlightMeta:
    """The recorded altimeter setting at the take-off / landing
    (:func:`.garmin.altimeter_settings_hpa`) as the departure's / arrival's QNH where the
    sidecar and the command line give none (theirs wins; a note gives both)."""
    if settings is None:
        return meta
    out: dict[str, Any] = {}
    for key, val, where in (("qnh_departure_hpa", settings[0], "take-off"),
                            ("qnh_arrival_hpa", settings[1], "landing")):
        given = getattr(meta, key)
        if given is None:
            out[key] = round(val, 2)
            notes.append(f"{key} = {val:.1f} hPa: the altimeter setting BaroA in use at the "
                         f"{where} (the sidecar and the command line give none)")
        elif abs(given - val) >= 0.5:
            notes.append(f"{key} = {given:.1f} hPa as given (sidecar or command line); the "
                         f"altimeter setting BaroA in use at the {where} is {val:.1f} hPa")
    return dataclasses.replace(meta, **out) if out else meta


def _without_gnss(mt: MappedTable) -> MappedTable:
    """``mt`` without its GNSS channels (``GnssUse.withhold``)."""
    gn = set(GROUPS["gnss"])
    return dataclasses.replace(mt, values={k: v for k, v in mt.values.items() if k not in gn},
                               nan_text={k: v for k, v in mt.nan_text.items() if k not in gn},
                               source_column={k: v for k, v in mt.source_column.items()
                                              if k not in gn})


def _own_columns(cols: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The columns as writeable arrays that share memory with no other column (a copy
    only where needed: a read-only Arrow buffer, a column mapped twice), so the table can be
    built without a copy and still be modified column by column by its users."""
    out: dict[str, np.ndarray] = {}
    for k, v in cols.items():
        v = np.asarray(v)
        if not v.flags.writeable or any(np.may_share_memory(v, o) for o in out.values()):
            v = v.copy()
        out[k] = v
    return out


def _time_column(mt: MappedTable, mp: Mapping | None, columns) -> str:
    if mp is not None and mp.time is not None:
        return mp.time.column
    return "t_s" if "t_s" in columns else "time_utc"


def _epoch_ns(epoch_utc: str) -> int:
    return int(np.datetime64(epoch_utc.rstrip("Z"), "ns").astype(np.int64))


def _log_seconds(mt: MappedTable, meta: FlightMeta) -> tuple[np.ndarray, FlightMeta, int | None,
                                                             str | None]:
    """Recorder times in seconds from the epoch; the epoch from timestamps when not given."""
    if mt.time_kind == "s":
        ep = None if meta.epoch_utc is None else _epoch_ns(meta.epoch_utc)
        return mt.time.astype(np.float64), meta, ep, None
    note = None
    if meta.epoch_utc is None:
        ep = int(mt.time.min())
        meta = dataclasses.replace(meta, epoch_utc=normalise_epoch(
            str(np.datetime64(ep, "ns"))))
        note = f"epoch_utc taken from the log's first timestamp: {meta.epoch_utc}"
    else:
        ep = _epoch_ns(meta.epoch_utc)
    return (mt.time - ep).astype(np.float64) / 1e9, meta, ep, note


def _companion_seconds(cm: MappedTable, meta: FlightMeta, epoch_ns: int | None) -> np.ndarray:
    if cm.time_kind == "s":
        return cm.time.astype(np.float64)
    if epoch_ns is None:
        raise MetadataError("this file has UTC timestamps but the log's times are seconds with "
                            "no epoch_utc: give epoch_utc in the sidecar", file=cm.file)
    return (cm.time - epoch_ns).astype(np.float64) / 1e9
