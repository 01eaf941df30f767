"""The recorder log and its companion files read into rows on one time base.

A log is read through its mapping (a Garmin export's built-in one under the user's), its rows
written before the recorder's clock was set dropped, its times turned into seconds from the
UTC epoch and put in order (:mod:`.timestamps`); a separate GNSS or radar file is merged in at
its own times (docs/ingest.md).  What was read, with its provenance, is a :class:`Sources` for
:func:`flightrecon.ingest.api.load_flight` to derive and validate.
"""

from __future__ import annotations

import dataclasses
import os
from pathlib import Path
from typing import Any

import numpy as np

from flightrecon.errors import MetadataError, SchemaError
from flightrecon.ingest.ed112 import dump_mapping
from flightrecon.ingest.garmin import (
    GarminReading,
    altimeter_settings_hpa,
    apply_garmin_columns,
    garmin_mapping,
    garmin_reading,
    merge_with_user,
)
from flightrecon.ingest.mapping import MappedTable, Mapping, with_frame_rate
from flightrecon.ingest.mapping_apply import apply_mapping
from flightrecon.ingest.merge import Rows, merge_rows
from flightrecon.ingest.readers import RawTable, read_table
from flightrecon.ingest.sidecar import normalise_epoch
from flightrecon.ingest.time_cells import place_time_of_day, unset_clock_rows
from flightrecon.ingest.timestamps import repair_time_order
from flightrecon.ingest.units_line import DUMP_DIALECT
from flightrecon.ingest.validate import check_required, check_time
from flightrecon.schema import GROUPS
from flightrecon.types import FlightMeta

PathLike = str | os.PathLike


@dataclasses.dataclass
class Sources:
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
    derive_lat: bool = False


def read_log(log: Path, user_mp: Mapping | None, meta: FlightMeta, allow_unsorted: bool,
             warns: list[str], notes: list[str], withhold_gnss: bool = False,
             frame_rate_hz: float | None = None) -> tuple[Sources, FlightMeta]:
    """The recorder log through its mapping (a Garmin export's built-in one under the user's):
    schema checks, time base, time order; ``frame_rate_hz`` (``--frame-rate``): a recorder
    whose time is its frame count (:func:`.mapping.with_frame_rate`)."""
    raw = read_table(log)
    warns += list(raw.warnings)
    reading, mp, garmin_used = _garmin_preset(raw, user_mp, log, warns, notes)
    raw, mp, dump_used = _dump_and_rate(raw, mp, user_mp, frame_rate_hz, log, warns, notes)
    if raw.blank_rows.size:
        warns.append(f"{log}: {raw.blank_rows.size} empty row(s) skipped (first: row "
                     f"{raw.blank_rows[0]})")
    raw = _drop_unset_clock(raw, mp, log, warns)
    try:
        mt = apply_mapping(raw, mp, warns=warns)
    except SchemaError as exc:          # no time column: point at a mapping beside the log
        hint = _mapping_hint(log) if mp is None else ""
        if not hint:
            raise
        raise SchemaError(f"{exc.message}; {hint}", file=exc.file, column=exc.column,
                          rows=exc.rows) from None
    mt = place_time_of_day(mt, meta.epoch_utc, _time_column(mt, mp, raw.columns), warns, notes)
    if raw.nan_is_missing:
        notes.append(f"{log}: NaN cells read as 'not sampled' (the file has no empty cells)")
    if reading is not None and mp is not None:
        mt = apply_garmin_columns(raw, mt, mp, withhold_gnss, reading, warns)
        meta = _qnh_from_setting(meta, altimeter_settings_hpa(raw, mt, reading), notes)
        meta = _garmin_meta(meta, reading, notes)
    withheld: set[str] = set()
    if withhold_gnss:
        kept = _without_gnss(mt)
        withheld = set(mt.source_column.values()) - set(kept.source_column.values())
        mt = kept
    used = (set(mt.source_column.values()) | set(_time_columns(mp, raw.columns))
            | set(garmin_used) | set(dump_used) | withheld)   # withheld GNSS: said, not "ignored"
    ignored = [c for c in raw.columns if c not in used]
    if ignored:
        shown = ", ".join(ignored[:8]) + (" ..." if len(ignored) > 8 else "")
        warns.append(f"{log}: {len(ignored)} column(s) not in the schema and not mapped, "
                     f"ignored: {shown}")
    mt, present, derive_long, derive_lat = _present_channels(mt, notes)
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
    return Sources(mt, rows, epoch_ns, [str(log)], [dict(mt.source_column)], magnetic,
                   derive_long, tuple(ignored), derive_lat), meta


def _garmin_preset(raw: RawTable, user_mp: Mapping | None, log: Path, warns: list[str],
                   notes: list[str]
                   ) -> tuple[GarminReading | None, Mapping | None, tuple[str, ...]]:
    """A Garmin export's reading (variant, columns' roles, conventions checked on the data),
    its built-in mapping under the user's, and the columns read through two-column conventions
    (:mod:`.garmin`); the user's mapping and nothing else for any other table."""
    if raw.dialect != "garmin":
        return None, user_mp, ()
    reading = garmin_reading(raw)
    mp = merge_with_user(garmin_mapping(raw, reading), user_mp)
    used = tuple(reading.roles[r] for r in ("magvar", "baro_set", "gs", "trk", "fix",
                                             "alt_msl", "vel_n", "vel_e") if r in reading.roles)
    notes.append(f"{log}: Garmin export: {reading.variant}; read with the built-in mapping"
                 + (" under the user's mapping" if user_mp else ""))
    warns += [f"{log}: {w}" for w in reading.warnings]
    return reading, mp, used


def _present_channels(mt: MappedTable, notes: list[str]
                      ) -> tuple[MappedTable, set[str], bool, bool]:
    """The channels the log has or that can be made from it: the true airspeed from CAS or
    IAS (at cleaning), ``n_long_g`` derived from airspeed and pitch, ``n_lat_g`` assumed 0
    (coordinated flight) where only ``n_norm_g`` is recorded, the heading from the body rates;
    returns the table (its ``derived`` updated), the set and the two derivation flags."""
    present = set(mt.values) | set(mt.derived)
    if "tas_mps" not in present and ("cas_mps" in present or "ias_mps" in present):
        present.add("tas_mps")
        mt = dataclasses.replace(mt, derived={**mt.derived, "tas_mps": "cas" if "cas_mps"
                                              in present else "ias"})
    derive_long = "n_long_g" not in present and {"tas_mps", "pitch_deg"} <= present
    if derive_long:
        present.add("n_long_g")
    derive_lat = "n_lat_g" not in present and "n_norm_g" in present
    if derive_lat:
        present.add("n_lat_g")
    if "heading_deg" not in present and {"q_dps", "r_dps"} <= present:
        present.add("heading_deg")
        notes.append("no heading channel: the heading is propagated from the body rates at "
                     "cleaning (docs/signals.md, 'Heading from the body rates')")
    return mt, present, derive_long, derive_lat


def _dump_and_rate(raw: RawTable, mp: Mapping | None, user_mp: Mapping | None,
                   frame_rate_hz: float | None, log: Path, warns: list[str], notes: list[str]
                   ) -> tuple[RawTable, Mapping | None, tuple[str, ...]]:
    """A parameter dump's built-in mapping under the user's (:func:`.ed112.dump_mapping`),
    then the command line's frame rate (:func:`.mapping.with_frame_rate`): the table, the
    mapping and the dump's time columns."""
    dump_used: tuple[str, ...] = ()
    if raw.dialect == DUMP_DIALECT:      # a parameter dump: header, units line (.ed112)
        raw, mp, dump_used, n, w = dump_mapping(raw, user_mp)
        notes += n
        warns += w
    if frame_rate_hz is not None:
        mp, note = with_frame_rate(mp, frame_rate_hz, raw.columns)
        (warns if "not used" in note else notes).append(f"{log}: {note}")
    return raw, mp, dump_used


def add_companion(src: Sources, group: str, path: Path, mp: Mapping | None, meta: FlightMeta,
                  allow_unsorted: bool, warns: list[str], notes: list[str]) -> None:
    """Merge a separate GNSS or radar file into ``src`` on UTC time (each fix its own row)."""
    sub = getattr(mp, group) if mp is not None else None
    craw = read_table(path)
    warns += list(craw.warnings)
    cm = apply_mapping(craw, sub, group=group, mapping_file=mp.file if mp else None,
                       warns=warns)
    cm = place_time_of_day(cm, meta.epoch_utc, "time", warns, notes)
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
    the start of the file, :func:`.time_cells.unset_clock_rows`) marked to be skipped, and a
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


def _garmin_meta(meta: FlightMeta, rd: GarminReading, notes: list[str]) -> FlightMeta:
    """The aircraft a Garmin export names (where the sidecar gives none: it wins), the GPS
    height's datum its data show, and the variant and conventions read, for ``info``
    (``ingest.recorder``)."""
    out: dict[str, Any] = {}
    ident = rd.identity
    if meta.aircraft_id is None and ident.get("aircraft_id"):
        out["aircraft_id"] = ident["aircraft_id"]
        notes.append(f"aircraft_id = {ident['aircraft_id']}: the {ident['id_from']} of the "
                     "export's information line (a sidecar's [flight] aircraft_id wins)")
    if rd.gnss_datum == "msl" and meta.gnss_alt_datum == "ellipsoid":
        out["gnss_alt_datum"] = "msl"
    recorder: dict[str, Any] = {"variant": rd.variant,
                                **{k: v for k, v in ident.items() if k != "id_from"},
                                "conventions": {c.quantity: c.text() for c in rd.conventions}}
    if rd.undulation_m is not None:
        recorder["recorded_undulation_m"] = float(np.round(rd.undulation_m, 1))
    return dataclasses.replace(meta, **out,
                               ingest=dataclasses.replace(meta.ingest, recorder=recorder))


def _without_gnss(mt: MappedTable) -> MappedTable:
    """``mt`` without its GNSS channels (``GnssUse.withhold``)."""
    gn = set(GROUPS["gnss"])
    return dataclasses.replace(mt, values={k: v for k, v in mt.values.items() if k not in gn},
                               nan_text={k: v for k, v in mt.nan_text.items() if k not in gn},
                               source_column={k: v for k, v in mt.source_column.items()
                                              if k not in gn})


def _time_column(mt: MappedTable, mp: Mapping | None, columns) -> str:
    if mp is not None and mp.time is not None:
        return mp.time.column or "(frame count)"
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
