"""Mapping files: foreign column names, units and signs -> the canonical schema.

A mapping file is TOML (read with :mod:`tomllib`, which never executes anything); its format
is documented with an example in ``docs/ingest.md``::

    [time]
    column = "TIME"        # source column
    unit = "s"             # "s" (seconds from the flight's epoch_utc) or "timestamp"
    format = "%H:%M:%S"    # optional strptime format for text timestamps (default ISO-8601)
    # or, for a recorder whose time is its frame count (no time column):
    # rate_hz = 10         # frames a second: row k at (k - 1) / rate_hz s; with column = a
    #                      # frame counter, at counter / rate_hz s

    [channels.n_norm_g]
    column = "VRTG"
    unit = "g"
    sign = 1               # or -1 (source positive the other way)
    scale = 1.0            # factor on the raw value, applied first
    offset = 1.0           # canonical units, added last (this recorder writes nz - 1)

    [channels.heading_deg]
    column = "HDG_MAG"
    unit = "deg"
    reference = "magnetic" # converted to true with the World Magnetic Model

    [channels.tas_mps]
    from = "cas"           # computed from cas_mps (or "ias": ias_mps) + sat_degc + baro_alt_m

    [gnss]                 # optional: the same tables for a separate GNSS file
    [gnss.time] ...
    [gnss.channels.gnss_lat_deg] ...
    [radar] ...            # and for a separate radar file

Columns of a file that already carry canonical names need no entry.  Everything wrong in the
mapping itself is a :class:`MappingError` (exit code 6) naming the mapping file, its line, the
table and the key, with the nearest valid name for a misspelt one ("did you mean ...").  So is a
combination the mapping asks for that cannot be made: a channel under ``[gnss.channels]`` or
``[radar.channels]`` that is not of that group, one source column as the time and a channel, a
derived channel whose source channels are neither mapped nor in the data file.
"""

from __future__ import annotations

import dataclasses
import difflib
import os
import re
import tomllib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from flightrecon.errors import InputFileError, MappingError
from flightrecon.ingest.units import (
    CANONICAL_DIMENSION,
    UNITS,
    Unit,
    lookup_unit,
)
from flightrecon.schema import BY_NAME, GROUPS

__all__ = [
    "DEFAULT_TIME_COLUMNS",
    "ChannelSpec",
    "MappedTable",
    "Mapping",
    "TimeSpec",
    "load_mapping",
    "with_frame_rate",
]

#: canonical time columns recognised without a mapping: seconds or UTC timestamps
DEFAULT_TIME_COLUMNS = (("t_s", "s"), ("time_utc", "timestamp"))
TIME_UNITS = ("s", "timestamp")
MAGNETIC_OK = ("heading_deg", "wind_from_deg")
DERIVED_OK = {"tas_mps": {"cas": "cas_mps", "ias": "ias_mps"}}


@dataclass(frozen=True)
class TimeSpec:
    """Where the time is: ``column`` in ``unit`` ``"s"`` or ``"timestamp"`` (``format`` optional).

    With ``rate_hz`` the time is the frame count at that rate (a recorder with no time column,
    :func:`flightrecon.ingest.mapping_apply.frame_seconds`): ``column`` empty (``""``, which
    names no column: a mapping's names are never empty), the data row ``k`` at
    ``(k - 1) / rate_hz`` s; ``column`` a frame counter, at ``counter / rate_hz`` s.
    """

    column: str
    unit: str
    format: str | None = None
    #: a separate date column (then ``column`` holds the time of day) and a column of UTC
    #: offsets (``+02:00``, local time = UTC + offset): :func:`.time_cells.combine_date_time`
    date_column: str | None = None
    utc_offset_column: str | None = None
    #: frames a second of a recorder whose time is its frame count
    rate_hz: float | None = None


@dataclass(frozen=True)
class ChannelSpec:
    """One canonical channel's source.

    Attributes
    ----------
    channel : canonical name
    column : source column (``None`` for a derived channel)
    unit : source unit
    sign : +1 or -1, applied after the unit conversion
    scale : factor on the raw value, applied first (a recorder counting in hundredths: 0.01)
    offset : added last, in the canonical unit (a normal load factor recorded as nz - 1: 1.0)
    reference : ``"true"`` or ``"magnetic"`` (heading-like channels only)
    derived_from : ``"cas"`` or ``"ias"`` for ``tas_mps`` computed from the air data
    unit_declared : the unit was written in the mapping (``unit = ...``): the user's word,
        which wins over a doubt of the door's physics checks (docs/door.md)
    unit_confirmed : ``unit_confirmed = true``: the unit is used as declared even where the
        door's physics contradicts it with certainty (recorded in the summary; docs/door.md)
    """

    channel: str
    column: str | None
    unit: Unit | None
    sign: float = 1.0
    reference: str = "true"
    derived_from: str | None = None
    scale: float = 1.0
    offset: float = 0.0
    unit_declared: bool = False
    unit_confirmed: bool = False


@dataclass(frozen=True)
class Mapping:
    """A parsed mapping for one file (and optional sub-mappings for GNSS and radar files)."""

    file: str
    time: TimeSpec | None
    channels: tuple[ChannelSpec, ...]
    gnss: Mapping | None = None
    radar: Mapping | None = None


@dataclass(frozen=True)
class MappedTable:
    """A file's columns mapped to canonical channels (SI units, signs applied).

    Attributes
    ----------
    file : source path
    time_kind : ``"s"`` (seconds from the epoch) or ``"timestamp"``
    time : float64 seconds, or int64 nanoseconds since 1970-01-01 UTC for timestamps
    values : channel -> float64 array (NaN where not sampled)
    nan_text : channel -> mask of cells the file wrote as NaN
    source_column : channel -> source column name (for messages)
    magnetic : channels given relative to magnetic north (still magnetic here)
    derived : channel -> ``"cas"`` / ``"ias"`` for channels to compute
    rows : 1-based data rows of the file for each kept row
    notes : conversions applied (for the metadata)
    """

    file: str
    time_kind: str
    time: np.ndarray
    values: dict[str, np.ndarray]
    nan_text: dict[str, np.ndarray]
    source_column: dict[str, str]
    magnetic: tuple[str, ...]
    derived: dict[str, str]
    rows: np.ndarray
    notes: tuple[str, ...] = ()


def load_mapping(path: str | os.PathLike) -> Mapping:
    """Parse a mapping file (TOML) into a :class:`Mapping`.

    Raises
    ------
    InputFileError
        The file is missing or unreadable.
    MappingError
        Not TOML, unknown keys, channels or units, bad sign, reference or derivation.
    """
    p = Path(path)
    file = str(p)
    if not p.is_file():
        raise InputFileError("mapping file not found", file=file)
    try:
        text = p.read_bytes().decode("utf-8")
        doc = tomllib.loads(text)
    except UnicodeDecodeError:
        raise MappingError("mapping file is not UTF-8 text", file=file) from None
    except tomllib.TOMLDecodeError as exc:
        raise MappingError(f"not a valid TOML file: {exc}", file=file) from None
    try:
        return _parse(doc, file, "", allow_sub=True)
    except MappingError as exc:
        _add_line(exc, text)
        raise


class _TableKeyError(MappingError):
    """A :class:`MappingError` about ``key`` of the TOML table ``table`` (``""``: the top
    level; ``key`` ``None``: the table itself), so that :func:`load_mapping` can name the line."""

    def __init__(self, message: str, *, file: str, table: str, key: str | None,
                 column: str | None = None) -> None:
        super().__init__(message, file=file, column=column)
        self.table = table
        self.key = key


def _error(message: str, file: str, table: str, key: str | None = None,
           column: str | None = None) -> MappingError:
    """The error of ``key`` in ``table`` (:class:`_TableKeyError`), to raise."""
    return _TableKeyError(message, file=file, table=table, key=key, column=column)


def _did_you_mean(name: str, choices) -> str:
    """`` (did you mean 'x'?)`` for the nearest of ``choices`` (:mod:`difflib`), else ``""``."""
    close = difflib.get_close_matches(name, sorted(choices), n=1, cutoff=0.6)
    return f" (did you mean '{close[0]}'?)" if close else ""


_HEADER_RE = re.compile(r"^\s*\[\s*([^\[\]]+?)\s*\]\s*(?:#.*)?$")
_KEY_RE = re.compile(r"""^\s*(?:"([^"]*)"|'([^']*)'|([A-Za-z0-9_.-]+))\s*=""")


def line_of(text: str, table: str, key: str | None) -> int | None:
    """Where a key of a mapping file is written, for messages.

    Parameters
    ----------
    text : the mapping file's TOML text
    table : dotted name of the table (``"channels.n_norm_g"``; ``""``: the top level)
    key : the key in that table; ``None`` for the table's header

    Returns
    -------
    int or None
        The 1-based line of the key (else of a header that names it as a table, else of the
        table's own header); ``None`` when it cannot be told (an inline table).
    """
    current = ""
    want = table.replace('"', "").replace("'", "")
    for i, line in enumerate(text.splitlines(), start=1):
        h = _HEADER_RE.match(line)
        if h:
            current = ".".join(part.strip().strip('"').strip("'")
                               for part in h.group(1).split("."))
            if key is None and (current == want or current.startswith(want + ".")):
                return i
            continue
        if key is None:
            continue
        k = _KEY_RE.match(line)
        if not k:
            continue
        name = next(g for g in k.groups() if g is not None).strip()
        full = ".".join(x for x in (current, name) if x)
        if full == ".".join(x for x in (want, key) if x):
            return i
    if key is not None:   # a table named by its header ([a.b.key], [key.x]), else its own
        return line_of(text, ".".join(x for x in (table, key) if x), None) or (
            line_of(text, table, None) if table else None)
    return None


def _add_line(exc: MappingError, text: str) -> None:
    """Prefix the message of ``exc`` with the line of the mapping file it is about."""
    if not isinstance(exc, _TableKeyError):
        return
    line = line_of(text, exc.table, exc.key)
    if line is not None:
        exc.message = f"line {line}: {exc.message}"
        exc.args = (str(exc),)


def _parse(doc: dict, file: str, prefix: str, allow_sub: bool) -> Mapping:
    allowed = {"time", "channels"} | ({"gnss", "radar"} if allow_sub else set())
    for k in doc:
        if k not in allowed:
            raise _error(f"unknown table or key '{prefix}{k}'{_did_you_mean(k, allowed)} "
                         f"(allowed here: {', '.join(sorted(allowed))})", file,
                         prefix.rstrip("."), k)
    time = None
    if "time" in doc:
        t = _table(doc["time"], file, f"{prefix}time")
        _only(t, {"column", "unit", "format", "date_column", "utc_offset_column", "rate_hz"},
              file, f"{prefix}time")
        frame = _frame_time(t, file, f"{prefix}time") if "rate_hz" in t else None
        if frame is None and "column" not in t:
            raise _error(f"[{prefix}time]: missing key 'column' (the time column), or rate_hz "
                         "for a recorder whose time is its frame count", file, f"{prefix}time")
        col = _str(t, "column", file, f"{prefix}time", required=frame is None)
        date_col = _str(t, "date_column", file, f"{prefix}time", required=False)
        ofs_col = _str(t, "utc_offset_column", file, f"{prefix}time", required=False)
        unit = _str(t, "unit", file, f"{prefix}time", required=False) or (
            "timestamp" if date_col or ofs_col else "s")
        if unit not in TIME_UNITS:
            raise _error(f"[{prefix}time] unit '{unit}' is not one of {TIME_UNITS}"
                         f"{_did_you_mean(unit, TIME_UNITS)}", file, f"{prefix}time", "unit",
                         column=col)
        if (date_col or ofs_col) and unit != "timestamp":
            raise _error(f"[{prefix}time] date_column / utc_offset_column need unit = "
                         "\"timestamp\"", file, f"{prefix}time", "unit", column=col)
        fmt = _str(t, "format", file, f"{prefix}time", required=False)
        time = frame or TimeSpec(str(col), unit, fmt, date_col, ofs_col)   # col never None
    chans: list[ChannelSpec] = []
    targets = _table(doc.get("channels", {}), file, f"{prefix}channels")
    group = prefix.rstrip(".") or None
    for name, spec in targets.items():
        where = f"{prefix}channels.{name}"
        chans.append(_parse_channel(name, spec, file, where))
        if group is not None and name not in GROUPS[group]:
            raise _error(f"[{where}]: {name} is not a {group} channel: only the {group} "
                         f"channels ({', '.join(GROUPS[group])}) are read from a separate "
                         f"{group} file; map it under [channels] for the recorder log",
                         file, where)
    cols = [c.column for c in chans if c.column is not None]
    dup = sorted({c for c in cols if cols.count(c) > 1})
    if dup:
        both = [c.channel for c in chans if c.column == dup[0]]
        raise _error(f"source column mapped to several channels: {', '.join(dup)} "
                     f"({' and '.join(f'[{prefix}channels.{b}]' for b in both)})", file,
                     f"{prefix}channels.{both[-1]}", "column", column=dup[0])
    if time is not None and time.column in cols:
        clash = next(c.channel for c in chans if c.column == time.column)
        raise _error(f"[{prefix}channels.{clash}]: column '{time.column}' is also the time "
                     f"column of [{prefix}time]: one source column cannot be both", file,
                     f"{prefix}channels.{clash}", "column", column=time.column)
    sub = {}
    for g in ("gnss", "radar"):
        if allow_sub and g in doc:
            sub[g] = _parse(_table(doc[g], file, g), file, f"{g}.", allow_sub=False)
    return Mapping(file=file, time=time, channels=tuple(chans), **sub)


def _frame_time(t: dict, file: str, where: str) -> TimeSpec:
    """``[time] rate_hz = R`` (with an optional frame-counter ``column``): the time of a
    recorder that writes its frame count, not a time (:class:`TimeSpec`)."""
    rate = _number(t, "rate_hz", 0.0, file, where, None)
    if rate <= 0.0:
        raise _error(f"[{where}]: rate_hz must be a positive number of frames a second, got "
                     f"{t['rate_hz']!r}", file, where, "rate_hz")
    other = sorted(set(t) - {"rate_hz", "column", "unit"})
    if other:
        raise _error(f"[{where}]: with rate_hz the time is the frame count: {other[0]} does "
                     "not apply (a frame-counter column is named by 'column')", file, where,
                     other[0])
    if t.get("unit", "s") != "s":
        raise _error(f"[{where}]: with rate_hz the time is in seconds (unit = \"s\"), got "
                     f"unit = {t['unit']!r}", file, where, "unit")
    col = _str(t, "column", file, where, required=False)
    return TimeSpec(col or "", "s", rate_hz=rate)


def with_frame_rate(mapping: Mapping | None, rate_hz: float, columns
                    ) -> tuple[Mapping | None, str]:
    """The mapping with its time taken as the frame count at ``rate_hz`` (the command line's
    ``--frame-rate``), and a note saying what was done.

    The command line wins over the mapping's own ``rate_hz`` (the note gives both); a file
    with a time of its own (the mapping's time column in seconds or timestamps, else a
    ``t_s`` / ``time_utc`` column) keeps it: the rate is not used, and the note says so.

    Raises
    ------
    MappingError
        ``rate_hz`` is not a positive finite number.
    """
    if not (np.isfinite(rate_hz) and rate_hz > 0.0):
        raise MappingError(f"--frame-rate must be a positive number of frames a second, got "
                           f"{rate_hz!r}")
    own = mapping.time if mapping is not None else None
    if own is not None and own.rate_hz is None:
        return mapping, (f"--frame-rate {rate_hz:g} Hz not used: the mapping's [time] reads "
                         f"the time from column '{own.column}'")
    found = next((c for c, _ in DEFAULT_TIME_COLUMNS if c in columns), None)
    if own is None and found is not None:
        return mapping, (f"--frame-rate {rate_hz:g} Hz not used: the file has its own time "
                         f"column '{found}'")
    note = f"time: the frame count at {rate_hz:g} Hz (--frame-rate)"
    if own is not None and own.rate_hz != rate_hz:
        note += f", in place of the mapping's rate_hz = {own.rate_hz:g}"
    spec = TimeSpec(own.column if own is not None else "", "s", rate_hz=float(rate_hz))
    if mapping is None:
        return Mapping(file="--frame-rate", time=spec, channels=()), note
    return dataclasses.replace(mapping, time=spec), note


def _parse_channel(name: str, spec, file: str, where: str) -> ChannelSpec:
    if name not in BY_NAME or BY_NAME[name].kind == "time":
        hint = _did_you_mean(name, [c for c in BY_NAME if BY_NAME[c].kind != "time"])
        raise _error(f"[{where}]: unknown channel '{name}'{hint}", file, where)
    spec = _table(spec, file, where)
    _only(spec, {"column", "unit", "sign", "reference", "from", "scale", "offset",
                 "unit_confirmed"}, file, where)
    ch = BY_NAME[name]
    if "from" in spec:
        src = spec["from"]
        if not isinstance(src, str) or name not in DERIVED_OK or src not in DERIVED_OK[name]:
            ok = ", ".join(f"{k} from {sorted(v)}" for k, v in DERIVED_OK.items())
            raise _error(f"[{where}]: cannot derive {name} from '{src}' (possible: {ok})",
                         file, where, "from")
        extra = set(spec) - {"from"}
        if extra:
            raise _error(f"[{where}]: a derived channel takes only 'from' (got "
                         f"{', '.join(sorted(extra))}): it has no source column of its own",
                         file, where, sorted(extra)[0])
        return ChannelSpec(name, None, None, derived_from=src)
    col = _str(spec, "column", file, where, required=True)
    unit_txt = _str(spec, "unit", file, where, required=False) or ch.unit
    unit = lookup_unit(unit_txt)
    if unit is None:
        raise _error(f"[{where}]: unknown unit '{unit_txt}'{_did_you_mean(unit_txt, UNITS)} "
                     f"(known: {', '.join(UNITS)})", file, where, "unit", column=col)
    need = CANONICAL_DIMENSION[ch.unit]
    if unit.dimension != need:
        raise _error(f"[{where}]: unit '{unit_txt}' is a {unit.dimension}, channel {name} "
                     f"needs a {need} unit", file, where, "unit", column=col)
    sign = spec.get("sign", 1)
    if isinstance(sign, bool) or sign not in (1, -1):
        raise _error(f"[{where}]: sign must be 1 or -1, got {sign!r}", file, where, "sign",
                     column=col)
    ref = spec.get("reference", "true")
    if ref not in ("true", "magnetic"):
        raise _error(f"[{where}]: reference must be 'true' or 'magnetic', got {ref!r}",
                     file, where, "reference", column=col)
    if ref == "magnetic" and name not in MAGNETIC_OK:
        raise _error(f"[{where}]: reference = 'magnetic' only applies to "
                     f"{', '.join(MAGNETIC_OK)}", file, where, "reference", column=col)
    scale = _number(spec, "scale", 1.0, file, where, col)
    if scale == 0.0:
        raise _error(f"[{where}]: scale must not be zero", file, where, "scale", column=col)
    offset = _number(spec, "offset", 0.0, file, where, col)
    confirmed = spec.get("unit_confirmed", False)
    if not isinstance(confirmed, bool) or (confirmed and "unit" not in spec):
        raise _error(f"[{where}]: unit_confirmed must be true or false, beside a unit = ... "
                     f"(got {confirmed!r})", file, where, "unit_confirmed", column=col)
    return ChannelSpec(name, col, unit, float(sign), ref, scale=scale, offset=offset,
                       unit_declared="unit" in spec, unit_confirmed=confirmed)


def _number(t: dict, key: str, default: float, file: str, where: str, col: str | None
            ) -> float:
    v = t.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v):
        raise _error(f"[{where}]: {key} must be a finite number, got {v!r}", file, where, key,
                     column=col)
    return float(v)


def _table(v, file: str, where: str) -> dict:
    if not isinstance(v, dict):
        table, _, key = where.rpartition(".")
        raise _error(f"'{where}' must be a table", file, table, key)
    return v


def _only(t: dict, keys: set[str], file: str, where: str) -> None:
    for k in t:
        if k not in keys:
            raise _error(f"[{where}]: unknown key '{k}'{_did_you_mean(k, keys)} (allowed: "
                         f"{', '.join(sorted(keys))})", file, where, k)


def _str(t: dict, key: str, file: str, where: str, *, required: bool) -> str | None:
    v = t.get(key)
    if v is None:
        if required:
            raise _error(f"[{where}]: missing key '{key}'", file, where)
        return None
    if not isinstance(v, str) or not v:
        raise _error(f"[{where}]: '{key}' must be a non-empty string", file, where, key)
    return v
