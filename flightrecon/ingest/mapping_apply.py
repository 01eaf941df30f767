"""Applying a column mapping (:mod:`flightrecon.ingest.mapping`) to a raw table: the channel
specs in force, the time column, each column converted to its canonical unit.
"""

from __future__ import annotations

import difflib
from pathlib import Path

import numpy as np
import pandas as pd

from flightrecon.errors import MappingError, ValidationError
from flightrecon.ingest.mapping import (
    DEFAULT_TIME_COLUMNS,
    DERIVED_OK,
    ChannelSpec,
    MappedTable,
    Mapping,
    TimeSpec,
    line_of,
)
from flightrecon.ingest.readers import RawTable
from flightrecon.ingest.units import lookup_unit, to_canonical
from flightrecon.schema import BY_NAME, GROUPS

__all__ = ["FRAME_RATE_HINT", "apply_mapping", "frame_seconds", "identity_specs",
           "mapping_location"]

#: how to read a recorder whose time is its frame count (the refusal of a file with no time)
FRAME_RATE_HINT = ("a recorder whose time is its frame count (one row per frame, no time "
                   "column or file): give its rate once, with --frame-rate HZ or rate_hz = HZ "
                   "in the mapping's [time] table (docs/ingest.md, 'Frame count as the time')")


def identity_specs(columns, exclude: set[str]) -> list[ChannelSpec]:
    """Specs for columns that already carry canonical channel names (canonical units)."""
    out = []
    for c in columns:
        if c in BY_NAME and BY_NAME[c].kind != "time" and c not in exclude:
            out.append(ChannelSpec(c, c, lookup_unit(BY_NAME[c].unit)))
    return out


def apply_mapping(raw: RawTable, mapping: Mapping | None, *, group: str | None = None,
                  mapping_file: str | None = None, warns: list[str] | None = None
                  ) -> MappedTable:
    """Map the raw columns of one file to canonical channels.

    Parameters
    ----------
    raw : the file's columns (:func:`flightrecon.ingest.readers.read_table`)
    mapping : its mapping, or ``None`` for a file with canonical column names
    group : ``"gnss"`` or ``"radar"`` for a separate measurement file: only that group's
        channels are taken from it
    mapping_file : for messages
    warns : list the time's warnings are added to (an ambiguous date's order guessed)

    Raises
    ------
    MappingError
        A mapped source column is not in the file.
    SchemaError
        No time column.
    ValidationError
        Non-numeric values in a used column, unparsable or missing timestamps.
    """
    file = raw.file
    mfile = mapping_file or (mapping.file if mapping else None)
    specs = _channel_specs(raw, mapping, group, mfile)
    tspec = _time_spec(raw, mapping, mfile, group)
    rows = np.arange(1, raw.n_rows + 1, dtype=np.int64)
    if raw.blank_rows.size:
        keep = np.ones(raw.n_rows, dtype=bool)
        keep[raw.blank_rows - 1] = False
        raw = RawTable(file=file, columns={k: v[keep] for k, v in raw.columns.items()},
                       n_rows=int(keep.sum()),
                       nan_text={k: m[keep] for k, m in raw.nan_text.items()}, fmt=raw.fmt,
                       bad_text={k: (m[keep], t) for k, (m, t) in raw.bad_text.items()},
                       nan_is_missing=raw.nan_is_missing)
        rows = rows[keep]
    notes: list[str] = []
    time = (frame_seconds(raw, tspec, rows) if tspec.rate_hz is not None
            else _convert_time(raw, tspec, rows, warns, notes))
    values: dict[str, np.ndarray] = {}
    nan_text: dict[str, np.ndarray] = {}
    source: dict[str, str] = {}
    derived: dict[str, str] = {}
    magnetic: list[str] = []
    for s in specs:
        if s.derived_from is not None:
            derived[s.channel] = s.derived_from
            continue
        col, v = _converted(raw, s, rows, mfile, f"{group}." if group else "")
        values[s.channel] = v
        source[s.channel] = col
        if col in raw.nan_text:
            nan_text[s.channel] = raw.nan_text[col]
        if s.reference == "magnetic":
            magnetic.append(s.channel)
        note = _mapping_note(s)
        if note:
            notes.append(note)
    return MappedTable(file=file, time_kind=tspec.unit, time=time, values=values,
                       nan_text=nan_text, source_column=source, magnetic=tuple(magnetic),
                       derived=derived, rows=rows, notes=tuple(notes))


def _channel_specs(raw: RawTable, mapping: Mapping | None, group: str | None,
                   mfile: str | None) -> list[ChannelSpec]:
    """The mapping's channel specs (each source column checked to be in the file), the
    canonical columns not mapped taken as they are, restricted to ``group``'s channels; a
    derived channel whose sources are neither mapped nor in the file is refused here, naming
    the mapping line that asks for it."""
    specs: list[ChannelSpec] = list(mapping.channels) if mapping else []
    prefix = f"{group}." if group else ""
    for s in specs:
        if s.column is not None and s.column not in raw.columns:
            close = difflib.get_close_matches(s.column, list(raw.columns), n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            where = mapping_location(mfile, f"{prefix}channels.{s.channel}", "column")
            raise MappingError(f"{where} maps channel {s.channel} to column '{s.column}', which "
                               f"is not in the file{hint}", file=raw.file, column=s.column)
    mapped_cols = {s.column for s in specs if s.column}
    mapped_chans = {s.channel for s in specs}
    specs += identity_specs([c for c in raw.columns if c not in mapped_cols], mapped_chans)
    if group is not None:
        allowed = set(GROUPS[group])
        specs = [s for s in specs if s.channel in allowed]
    else:
        _check_derivable(specs, raw.file, mfile)
    return specs


def _check_derivable(specs: list[ChannelSpec], file: str, mfile: str | None) -> None:
    """Refuse a channel the mapping derives (``from = ...``) whose source channels are neither
    mapped nor canonical columns of ``file``: a mapping error (exit code 6) naming the mapping
    file, its line, the table and the key, and a source the mapping does provide."""
    present = {s.channel for s in specs if s.derived_from is None}
    for s in specs:
        if s.derived_from is None:
            continue
        source = DERIVED_OK[s.channel][s.derived_from]
        missing = [c for c in (source, "baro_alt_m") if c not in present]
        if not missing:
            continue
        other = [k for k, c in DERIVED_OK[s.channel].items()
                 if k != s.derived_from and c in present]
        hint = f" (did you mean from = '{other[0]}'?)" if other and source in missing else ""
        where = mapping_location(mfile, f"channels.{s.channel}", "from", with_file=False)
        raise MappingError(f"{where} = '{s.derived_from}': {s.channel} from "
                           f"{s.derived_from.upper()} needs channel"
                           f"{'s' if len(missing) > 1 else ''} {' and '.join(missing)}, which "
                           f"the mapping does not map and the data file {file} does not have"
                           f"{hint}; map {missing[0]} in a [channels.{missing[0]}] table",
                           file=mfile or file)


def mapping_location(mfile: str | None, table: str, key: str | None = None, *,
                     with_file: bool = True) -> str:
    """Where in a mapping file a setting is, for the errors found while the mapping is applied
    to a data file: ``mapping file M line N, [table] key``.

    Parameters
    ----------
    mfile : the mapping file (``None``: no file, the table and key only)
    table, key : as for :func:`line_of`
    with_file : ``False`` leaves out ``mapping file M`` (for an error whose file it is)

    Returns
    -------
    str
        The location; the line is left out when the file cannot be read or the key found.
    """
    if mfile is None:
        return f"[{table}]" + (f" {key}" if key else "")
    line = None
    try:
        line = line_of(Path(mfile).read_text(encoding="utf-8"), table, key)
    except (OSError, UnicodeDecodeError):
        pass
    at = f"line {line}, " if line is not None else ""
    head = f"mapping file {mfile} " if with_file else ""
    return f"{head}{at}[{table}]" + (f" {key}" if key else "")


def _time_spec(raw: RawTable, mapping: Mapping | None, mfile: str | None,
               group: str | None = None) -> TimeSpec:
    """The time column: the mapping's ``[time]``, else the first default time column found."""
    from flightrecon.errors import SchemaError

    tspec = mapping.time if mapping and mapping.time else None
    if tspec is None:
        for col, unit in DEFAULT_TIME_COLUMNS:
            if col in raw.columns:
                tspec = TimeSpec(col, unit)
                break
    if tspec is None:
        raise SchemaError("no time column: expected 't_s' (seconds from epoch_utc) or "
                          "'time_utc' (UTC timestamps), or a [time] table in a mapping file; "
                          + FRAME_RATE_HINT, file=raw.file)
    for key, c in (("column", tspec.column), ("date_column", tspec.date_column),
                   ("utc_offset_column", tspec.utc_offset_column)):
        if c and c not in raw.columns:
            table = f"{group}.time" if group else "time"
            close = difflib.get_close_matches(c, list(raw.columns), n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise MappingError(f"{mapping_location(mfile, table, key)}: time column "
                               f"'{c}' is not in the file{hint}", file=raw.file, column=c)
    return tspec


def _converted(raw: RawTable, s: ChannelSpec, rows: np.ndarray, mfile: str | None = None,
               prefix: str = "") -> tuple[str, np.ndarray]:
    """One source column (its name, its values) as numbers in the canonical unit: scale, unit,
    sign, offset (an angle declared in radians checked to be one, :func:`_check_radians`)."""
    if s.column is None or s.unit is None:
        raise MappingError(f"channel {s.channel} has neither a source column and unit nor a "
                           "derivation", file=raw.file)
    arr = _numeric(raw.columns[s.column], raw.file, s.column, rows, raw.bad_text.get(s.column))
    arr = arr * s.scale if s.scale != 1.0 else arr
    _check_radians(arr, s, raw.file, mfile, prefix)
    v = to_canonical(arr, s.unit)
    if s.sign < 0:
        v = -v
    if s.offset != 0.0:
        v = v + s.offset
    return s.column, v


#: an angle in radians lies within +-2 pi (a heading 0..2 pi, an attitude +-pi): a column
#: declared in radians with more than this share of its values beyond is in degrees
RADIAN_OUTSIDE_SHARE = 0.05


def _check_radians(arr: np.ndarray, s: ChannelSpec, file: str, mfile: str | None,
                   prefix: str) -> None:
    """Refuse an angle declared in radians whose values cannot be radians (issue #50: a
    magnetic heading in degrees declared ``rad`` was read 57 times too large, wrapped, and
    gave a track 7 km off with exit 0): certain, whatever the flight, naming the mapping's
    line (exit 5)."""
    if s.unit is None or s.unit.name != "rad" or s.column is None:
        return
    f = arr[np.isfinite(arr)]
    if f.size < 8:
        return
    out = np.abs(f) > 2 * np.pi + 0.01
    if out.mean() <= RADIAN_OUTSIDE_SHARE:
        return
    where = mapping_location(mfile, f"{prefix}channels.{s.channel}", "unit")
    raise ValidationError(
        f"{s.channel} is declared in rad ({where} = \"rad\"), but "
        f"{100 * out.mean():.0f} % of its values lie beyond +-2 pi (up to {np.abs(f).max():.4g}), "
        f"which no angle in radians does: likely unit deg (factor 57.3). Declare unit = "
        "\"deg\" there", file=file, column=s.column)


def _mapping_note(s: ChannelSpec) -> str | None:
    """``channel <- column x scale [unit] x -1 +offset`` where the mapping changes anything."""
    unit = s.unit.name if s.unit is not None else None
    if (s.column != s.channel or unit != BY_NAME[s.channel].unit or s.sign < 0
            or s.scale != 1.0 or s.offset != 0.0):
        return (f"{s.channel} <- {s.column}"
                + (f" x {s.scale:g}" if s.scale != 1.0 else "")
                + f" [{unit}]" + (" x -1" if s.sign < 0 else "")
                + (f" {s.offset:+g} {BY_NAME[s.channel].unit}" if s.offset else ""))
    return None


def _numeric(col: np.ndarray, file: str, name: str, rows: np.ndarray,
             bad_text: tuple[np.ndarray, str] | None = None) -> np.ndarray:
    """Float64 values of a source column; non-numeric text is a ValidationError naming rows."""
    if bad_text is not None:
        bad = np.flatnonzero(bad_text[0])
        raise ValidationError(f"{bad.size} non-numeric value(s), first: '{bad_text[1][:40]}'",
                              file=file, column=name, rows=rows[bad])
    if col.dtype == np.float64:
        return col
    if np.issubdtype(col.dtype, np.datetime64):
        raise ValidationError("timestamps where numbers are expected", file=file, column=name)
    s = pd.Series(col, dtype=object)
    num = pd.to_numeric(s, errors="coerce").to_numpy(dtype=np.float64)
    present = s.notna().to_numpy()
    bad = np.flatnonzero(present & np.isnan(num)
                         & ~s.astype(str).str.strip().str.lower().isin(["nan", "+nan", "-nan"])
                         .to_numpy())
    if bad.size:
        first = str(s.iloc[bad[0]])[:40]
        raise ValidationError(f"non-numeric value(s), first: '{first}'", file=file, column=name,
                              rows=rows[bad])
    return num


def frame_seconds(raw: RawTable, tspec: TimeSpec, rows: np.ndarray) -> np.ndarray:
    """Seconds of every row of a recorder whose time is its frame count at ``tspec.rate_hz``:
    ``(k - 1) / rate_hz`` for data row ``k`` (the first frame at 0 s; an empty line skipped
    keeps its frame), or ``counter / rate_hz`` with a frame-counter column ``tspec.column``.

    Raises
    ------
    ValidationError
        A frame counter that is missing, not a whole number, or not a number.
    """
    rate = float(tspec.rate_hz or 0.0)
    if not tspec.column:
        return (rows.astype(np.float64) - 1.0) / rate
    col = raw.columns[tspec.column]
    n = _numeric(col, raw.file, tspec.column, rows, raw.bad_text.get(tspec.column))
    bad = np.flatnonzero(~np.isfinite(n) | (np.abs(n - np.round(n)) > 1e-6))
    if bad.size:
        raise ValidationError("frame counter missing or not a whole number", file=raw.file,
                              column=tspec.column, rows=rows[bad])
    return n / rate


def _convert_time(raw: RawTable, tspec: TimeSpec, rows: np.ndarray,
                  warns: list[str] | None = None, notes: list[str] | None = None
                  ) -> np.ndarray:
    """Seconds (float64) or UTC nanoseconds (int64) of every row; missing/bad times raise."""
    col = raw.columns[tspec.column]
    file = raw.file
    if tspec.date_column is not None or tspec.utc_offset_column is not None:
        from flightrecon.ingest.time_cells import combine_date_time

        return combine_date_time(raw, tspec.column, tspec.date_column,
                                 tspec.utc_offset_column, tspec.format, rows, warns,
                                 notes)
    if tspec.unit == "s":
        if np.issubdtype(col.dtype, np.datetime64):
            raise ValidationError("time column holds timestamps: set unit = \"timestamp\" in the "
                                  "mapping's [time] table or name it 'time_utc'", file=file,
                                  column=tspec.column)
        t = _numeric(col, file, tspec.column, rows, raw.bad_text.get(tspec.column))
        bad = np.flatnonzero(~np.isfinite(t))
        if bad.size:
            raise ValidationError("missing or non-finite time", file=file, column=tspec.column,
                                  rows=rows[bad])
        return t
    if np.issubdtype(col.dtype, np.datetime64):
        ts = col.astype("datetime64[ns]")
        bad = np.flatnonzero(np.isnat(ts))
    elif col.dtype == np.float64:
        raise ValidationError("time column holds numbers, not timestamps: set unit = \"s\"",
                              file=file, column=tspec.column)
    else:
        s = pd.Series(col, dtype=object)
        try:
            if tspec.format:
                parsed = pd.to_datetime(s, format=tspec.format, utc=True, errors="coerce")
            else:
                parsed = pd.to_datetime(s, format="ISO8601", utc=True, errors="coerce")
        except (ValueError, TypeError) as exc:
            raise ValidationError(f"cannot parse timestamps: {exc}", file=file,
                                  column=tspec.column) from None
        ts = parsed.dt.tz_localize(None).to_numpy("datetime64[ns]")
        bad = np.flatnonzero(np.isnat(ts))
    if bad.size:
        raise ValidationError("missing or unparsable timestamp(s)", file=file,
                              column=tspec.column, rows=rows[bad])
    return ts.astype(np.int64)
