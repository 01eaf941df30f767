"""A file's time cells read as time stamps: the rows written before the recorder's clock was
set; UTC stamps from a date, a time of day and a UTC offset in separate columns (Garmin
exports; docs/ingest.md), the date's order (ISO, day-first or month-first) settled by the
data; and times of day without a date placed on the flight's date.  Their order is
:mod:`.timestamps`' to repair or refuse."""

from __future__ import annotations

import dataclasses
import re
from pathlib import Path

import numpy as np
import pandas as pd

from flightrecon.errors import ValidationError
from flightrecon.ingest.mapping import MappedTable

__all__ = ["FIRST_FLIGHT_NS", "combine_date_time", "place_time_of_day", "unset_clock_rows"]

_DAY_NS = 86_400 * 10**9
#: 17 December 1903, the first powered flight: no recorder stamps an earlier time
FIRST_FLIGHT_NS = int(np.datetime64("1903-12-17", "ns").astype(np.int64))
#: the date a time of day gets when it is parsed without one (strptime's and pandas' default)
_NO_DATE_NS = int(np.datetime64("1900-01-01", "ns").astype(np.int64))
#: UTC offsets [h] of the Americas, where month-first dates are written (the guess of last resort)
_MONTH_FIRST_OFFSETS_H = (-10.0, -3.0)
#: a date: ``2021-06-23``, ``2021/06/23``, ``23/06/2021``, ``06/23/2021``, ``23.06.21``
_DATE_RE = (r"^\s*['\"]?(?P<a>\d{1,4})(?P<s>[-/.])(?P<b>\d{1,2})(?P=s)(?P<c>\d{1,4})"
            r"['\"]?\s*$")
#: a time of day: ``14:13``, ``14:13:58``, ``14:13:58.25``, ``2:13:58 PM``
_TOD_RE = (r"^\s*['\"]?(?P<h>\d{1,2}):(?P<m>\d{2})(?::(?P<s>\d{2})(?:[.,](?P<f>\d{1,9}))?)?"
           r"\s*(?P<ap>[AaPp][Mm])?['\"]?\s*$")
#: a date written in a file's name or its airframe line: ``20210623``, Garmin's ``log_110812_``
_HINT_RE = re.compile(r"(?<!\d)((?:19|20)\d{6})(?!\d)")
_GARMIN_NAME_RE = re.compile(r"log_(\d{6})_\d{6}")


def _empty_cells(col: np.ndarray) -> np.ndarray:
    """Mask of the empty cells of a raw column (NaN, NaT, None or blank text)."""
    if col.dtype == np.float64:
        return np.isnan(col)
    if np.issubdtype(col.dtype, np.datetime64):
        return np.isnat(col)
    s = pd.Series(col, dtype=object)
    return (s.isna() | s.astype(str).str.strip().eq("")).to_numpy()


def unset_clock_rows(columns: dict[str, np.ndarray], names: tuple[str, ...]) -> np.ndarray:
    """0-based indices of the rows at the start of a file whose time cells (any of ``names``:
    the time, and the date and UTC-offset columns if separate) are empty, up to the first row
    with a complete time: rows written before the recorder's clock was set.  Empty time
    cells after that stay an error (:func:`flightrecon.ingest.mapping_apply.apply_mapping`)."""
    n = len(columns[names[0]]) if names else 0
    k = 64
    while True:
        # a growing prefix: a file whose first row has its time costs one look at 64 rows
        k = min(k, n)
        empty = np.zeros(k, dtype=bool)
        for name in names:
            empty |= _empty_cells(columns[name][:k])
        if not k or not empty[0]:
            return np.zeros(0, dtype=np.int64)
        if not empty.all() or k == n:
            first_set = int(np.argmin(empty)) if not empty.all() else k
            return np.arange(first_set, dtype=np.int64)
        k *= 4


#: a UTC offset: ``+02:00``, ``-0500``, ``+2``, ``Z``
_OFFSET_RE = r"^\s*(?:(?P<z>[zZ])|(?P<sign>[+-])?(?P<h>\d{1,2})(?::?(?P<m>\d{2}))?)\s*$"


def _text(col: np.ndarray, fmt: str) -> pd.Series:
    """A raw column as stripped text (dates of a date-typed column as ``fmt``)."""
    if np.issubdtype(col.dtype, np.datetime64):
        return pd.Series(pd.to_datetime(col).strftime(fmt), dtype=object)
    return pd.Series(col, dtype=object).astype(str).str.strip()


def _bad(what: str, text: pd.Series, bad: np.ndarray, file: str, column: str,
         rows: np.ndarray, expected: str = "") -> ValidationError:
    """The refusal of a time column's unparsable cells, quoting the first."""
    first = str(text.iloc[int(np.argmax(bad))])[:40]
    return ValidationError(f"missing or unparsable {what} ({int(bad.sum())} row(s), first: "
                           f"'{first}'{expected})", file=file, column=column, rows=rows[bad])


def utc_offset_hours(raw, offset_column: str, rows: np.ndarray) -> np.ndarray:
    """The UTC offset of every row [h]: ``[+-]HH:MM``, ``[+-]HHMM``, ``[+-]H`` or ``Z``, or a
    number of hours (a whole number of 100 or more read as ``HHMM``: a CSV reader takes
    ``+0530`` for 530).

    Raises
    ------
    ValidationError
        An empty or unparsable offset, or one beyond 14 h, naming the rows.
    """
    oc = raw.columns[offset_column]
    if oc.dtype == np.float64:
        hhmm = np.isfinite(oc) & (np.abs(oc) >= 100) & (np.mod(np.abs(oc), 1.0) == 0)
        a = np.abs(oc)
        hours = np.where(hhmm, np.sign(oc) * (a // 100 + np.mod(a, 100) / 60.0), oc)
        bad = ~np.isfinite(hours) | (np.abs(hours) > 14.0) | (hhmm & (np.mod(a, 100) >= 60))
        otext = pd.Series(oc, dtype=object)
    else:
        otext = _text(oc, "%H:%M").str.strip("'\"")
        m = otext.str.extract(_OFFSET_RE)
        sign = np.where(m["sign"].fillna("+").to_numpy() == "-", -1.0, 1.0)
        hh = pd.to_numeric(m["h"], errors="coerce").to_numpy(dtype=float)
        mm = pd.to_numeric(m["m"], errors="coerce").fillna(0.0).to_numpy(dtype=float)
        hours = np.where(m["z"].notna().to_numpy(), 0.0, sign * (hh + mm / 60.0))
        bad = ~np.isfinite(hours) | (np.abs(hours) > 14.0) | (mm >= 60.0)
    if bad.any():
        raise _bad("UTC offset", otext, bad, raw.file, offset_column, rows,
                   "; expected +HH:MM")
    return hours


def time_of_day_ns(text: pd.Series) -> np.ndarray:
    """Nanoseconds since midnight of times of day written ``H:MM``, ``HH:MM:SS``,
    ``HH:MM:SS.fff`` (or ``,fff``), with an optional ``AM``/``PM`` (a spreadsheet's 12-hour
    clock); NaN where a cell is none of these or out of range (hour 24, minute 60)."""
    m = text.str.extract(_TOD_RE)
    h = pd.to_numeric(m["h"], errors="coerce").to_numpy(dtype=float)
    mi = pd.to_numeric(m["m"], errors="coerce").to_numpy(dtype=float)
    s = pd.to_numeric(m["s"], errors="coerce").fillna(0.0).to_numpy(dtype=float)
    frac = m["f"].fillna("0").str.pad(9, side="right", fillchar="0")
    ns = pd.to_numeric(frac, errors="coerce").to_numpy(dtype=float)
    ap = m["ap"].fillna("").str.upper().to_numpy(dtype=str)
    twelve = ap != ""
    bad = (h > 23) | (mi > 59) | (s > 60) | (twelve & ((h < 1) | (h > 12)))
    h = np.where(twelve, np.mod(h, 12.0) + np.where(ap == "PM", 12.0, 0.0), h)
    out = ((h * 60.0 + mi) * 60.0 + s) * 1e9 + ns
    out[bad] = np.nan
    return out


@dataclasses.dataclass(frozen=True)
class _DateFields:
    """A date column's distinct texts split into their three numbers: ``a``, ``b``, ``c`` in
    writing order (NaN where a text is not a date), ``year_first`` where ``a`` has four
    digits; ``inv`` maps every row to its text."""

    texts: np.ndarray
    inv: np.ndarray
    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    year_first: np.ndarray


def _date_fields(text: pd.Series) -> _DateFields:
    texts, inv = np.unique(text.to_numpy(dtype=str), return_inverse=True)
    # the year's place and a two-digit year (year last: 21 -> 2021, 98 -> 1998) per text
    m = pd.Series(texts, dtype=object).str.extract(_DATE_RE)
    num = {k: pd.to_numeric(m[k], errors="coerce").to_numpy(dtype=float) for k in "abc"}
    year_first = m["a"].fillna("").str.len().to_numpy() == 4
    c = num["c"]
    two = ~year_first & (m["c"].fillna("").str.len().to_numpy() == 2)
    c = np.where(two, np.where(c < 70, 2000.0 + c, 1900.0 + c), c)   # 21 -> 2021, 98 -> 1998
    return _DateFields(texts, inv, num["a"], num["b"], c, year_first)


def _days_ns(year: np.ndarray, month: np.ndarray, day: np.ndarray) -> np.ndarray:
    """Midnight of each (year, month, day) [int64 ns]; NaT (as int64 min) where no such date."""
    ok = np.isfinite(year) & np.isfinite(month) & np.isfinite(day)
    frame = pd.DataFrame({"year": np.where(ok, year, 2000), "month": np.where(ok, month, 1),
                          "day": np.where(ok, day, 1)}).astype(np.int64)
    out = pd.to_datetime(frame, errors="coerce").to_numpy("datetime64[ns]").astype(np.int64)
    out[~ok] = np.iinfo(np.int64).min
    return out


_NAT = np.iinfo(np.int64).min
_ORDER_NAME = {"dmy": "day-first (DD/MM/YYYY)", "mdy": "month-first (MM/DD/YYYY)",
               "ymd": "year-first (YYYY-MM-DD)"}


def _readings(f: _DateFields) -> dict[str, np.ndarray]:
    """Each order the column's dates can be read in -> midnight of every distinct text (NaT
    where that order reads no date): year-first texts are read only as year-month-day,
    year-last texts day-first and month-first."""
    parsed = np.isfinite(f.a)
    if not parsed.any() or f.year_first[parsed].mean() >= 0.5:
        return {"ymd": np.where(f.year_first, _days_ns(f.a, f.b, f.c), _NAT)}
    last = ~f.year_first
    return {"dmy": np.where(last, _days_ns(f.c, f.b, f.a), _NAT),
            "mdy": np.where(last, _days_ns(f.c, f.a, f.b), _NAT)}


def _date_hints(raw) -> list[tuple[np.datetime64, str]]:
    """Dates written in the file's name and its airframe line (``20210623`` in a Garmin
    ``flightstream_header``, Garmin's file name ``log_YYMMDD_HHMMSS_...``), with where."""
    out: list[tuple[np.datetime64, str]] = []
    places = [("the file name", Path(raw.file).name)]
    places += [(f"the airframe line ({k})", str(v)) for k, v in raw.preamble.items()]
    for where, text in places:
        found = _HINT_RE.findall(text) + ["20" + d for d in _GARMIN_NAME_RE.findall(text)]
        for d in found:
            try:
                out.append((np.datetime64(f"{d[:4]}-{d[4:6]}-{d[6:]}", "D"), where))
            except ValueError:
                continue
    return out


def _jumps(days: np.ndarray, f: _DateFields, rest_ns: np.ndarray) -> np.ndarray:
    """Rows (0-based) where the time read with these dates leaps by more than a day from the
    row before, either way: consecutive rows of a recorder are one sample apart."""
    t = days[f.inv].astype(np.float64) + rest_ns
    return np.flatnonzero(np.abs(np.diff(t)) > _DAY_NS) + 1


def _settle_order(f: _DateFields, readings: dict[str, np.ndarray], rest_ns: np.ndarray,
                  offsets_h: np.ndarray | None, hints: list[tuple[np.datetime64, str]],
                  where: str, rows: np.ndarray) -> tuple[str, str, bool]:
    """Which order the dates are read in, why, and whether that is a guess.

    Settled, in turn, by: the only order that reads every date (a first number above 12 is
    a day); the order under which the time runs on from row to row (under the other, a
    change of date between two consecutive rows leaps by weeks or goes back); a date
    written in the file's name or airframe line that only one order gives.  Otherwise a
    guess: month-first where every UTC offset is one of the Americas (-10 h to -3 h),
    day-first elsewhere (or with no offset).
    """
    count = {k: int((v != _NAT).sum()) for k, v in readings.items()}
    full = [k for k, n in count.items() if n == max(count.values())]
    if len(full) == 1:
        k = full[0]
        if k == "ymd":
            return k, "", False
        other = "mdy" if k == "dmy" else "dmy"
        i = int(np.argmax((readings[k] != _NAT) & (readings[other] == _NAT)))
        return k, (f"{where} read {_ORDER_NAME[k]}: '{f.texts[i]}' is no date "
                   f"{_ORDER_NAME[other].split(' ')[0]}"), False
    dmy, mdy = readings["dmy"], readings["mdy"]
    if np.array_equal(dmy, mdy):
        return "dmy", "", False       # day and month equal in every date: the same either way
    jumps = {k: _jumps(readings[k], f, rest_ns) for k in ("dmy", "mdy")}
    if jumps["dmy"].size != jumps["mdy"].size:
        k = "dmy" if jumps["dmy"].size < jumps["mdy"].size else "mdy"
        other = "mdy" if k == "dmy" else "dmy"
        first = int(rows[jumps[other][0]])
        return k, (f"{where} read {_ORDER_NAME[k]}: read {_ORDER_NAME[other].split(' ')[0]}, "
                   f"the time would leap by more than a day between consecutive rows "
                   f"{jumps[other].size} time(s) (first at row {first}), against "
                   f"{jumps[k].size} read {_ORDER_NAME[k].split(' ')[0]}"), False
    as_day = {k: set(v[v != _NAT].astype("datetime64[ns]").astype("datetime64[D]"))
              for k, v in readings.items()}
    for d, place in hints:
        near = {k: any(abs(int((d - x).astype(int))) <= 1 for x in s) for k, s in as_day.items()}
        if near["dmy"] != near["mdy"]:
            k = "dmy" if near["dmy"] else "mdy"
            return k, (f"{where} read {_ORDER_NAME[k]}: {place} gives the date {d} (within a "
                       f"day of the dates read so; read the other way they fall elsewhere)"), \
                False
    americas = (offsets_h is not None and offsets_h.size > 0
                and bool(np.all((offsets_h >= _MONTH_FIRST_OFFSETS_H[0])
                                & (offsets_h <= _MONTH_FIRST_OFFSETS_H[1]))))
    k = "mdy" if americas else "dmy"
    other = "mdy" if k == "dmy" else "dmy"
    i = int(np.argmax(dmy != mdy))
    on = {o: str(readings[o][i].astype("datetime64[ns]").astype("datetime64[D]"))
          for o in ("dmy", "mdy")}
    why = ("every UTC offset is one of the Americas, where dates are written month-first"
           if americas else "day-first is the usage outside the Americas" +
           ("" if offsets_h is None else " (the UTC offsets recorded are not of the Americas)"))
    fmt = "%m/%d/%Y" if other == "mdy" else "%d/%m/%Y"
    return k, (f"{where}: the dates are ambiguous ('{f.texts[i]}': every day and month "
               f"number is 12 or less, the time runs on row to row either way, and neither "
               f"the file name nor the airframe line gives the date): read "
               f"{_ORDER_NAME[k]}, '{f.texts[i]}' = {on[k]}, not {on[other]}, because {why}; "
               f"if the flight was on {on[other]}, give the [time] format = "
               f"\"{fmt} %H:%M:%S\" in a mapping"), True


def _dates_ns(raw, date_column: str, rest_ns: np.ndarray, offsets_h: np.ndarray | None,
              rows: np.ndarray, warns: list[str] | None, notes: list[str] | None
              ) -> np.ndarray:
    """Midnight of every row's date [int64 ns], the order settled by :func:`_settle_order`
    (a note says how, a warning when it is a guess).

    Raises
    ------
    ValidationError
        A cell that is no date in the order read, naming the rows.
    """
    text = _text(raw.columns[date_column], "%Y-%m-%d")
    f = _date_fields(text)
    readings = _readings(f)
    where = f"{raw.file}: column '{date_column}'"
    order, why, guess = _settle_order(f, readings, rest_ns, offsets_h, _date_hints(raw),
                                      where, rows)
    days = readings[order][f.inv]
    bad = days == _NAT
    if bad.any():
        raise _bad("date", text, bad, raw.file, date_column, rows,
                   f"; read {_ORDER_NAME[order]}")
    target = warns if guess else notes
    if why and target is not None:
        target.append(why)
    return days


def combine_date_time(raw, time_column: str, date_column: str | None,
                      offset_column: str | None, fmt: str | None, rows: np.ndarray,
                      warns: list[str] | None = None, notes: list[str] | None = None
                      ) -> np.ndarray:
    """UTC time stamps [int64 ns since 1970] of rows whose date, time of day and UTC offset are
    separate columns (Garmin exports: ``Lcl Date``, ``Lcl Time``, ``UTCOfst``).

    ``UTC = local - offset``: a local time ``10:00`` at offset ``+02:00`` is ``08:00`` UTC
    (offsets as :func:`utc_offset_hours` reads them).  Without ``fmt`` the date is read as
    written: ``YYYY-MM-DD`` (or with ``/`` or ``.``), or day-first / month-first with the
    year last (a file re-saved through a spreadsheet: ``23/06/2021``), the order settled by
    the data (:func:`_settle_order`: a note says how, a warning when nothing in the file
    settles it); the time of day as :func:`time_of_day_ns` reads it.  A time column with no
    date column that holds times of day only gives stamps on 1900-01-01, which
    :func:`place_time_of_day` puts on the flight's date.

    Parameters
    ----------
    raw : the file's :class:`~flightrecon.ingest.readers.RawTable`
    time_column : time of day (``HH:MM:SS[.fff]``), or the whole local time without a date
    date_column : date, or ``None``
    offset_column : UTC offset, or ``None`` (the time is UTC)
    fmt : strptime format of the date and time joined by one space (default: as above)
    rows : (N,) 1-based data rows (for the messages)
    warns, notes : lists the date order's guess (a warning) or evidence (a note) is added to

    Raises
    ------
    ValidationError
        An empty or unparsable date, time or offset, naming the column and the rows.
    """
    file = raw.file
    hours = None if offset_column is None else utc_offset_hours(raw, offset_column, rows)
    off_ns = np.zeros(rows.size) if hours is None else np.round(hours * 3600e9)
    text = _text(raw.columns[time_column], "%H:%M:%S.%f")
    if date_column is not None and fmt is None:
        tod = time_of_day_ns(text)
        bad = ~np.isfinite(tod)
        if bad.any():
            raise _bad("time of day", text, bad, file, time_column, rows,
                       "; expected HH:MM:SS")
        days = _dates_ns(raw, date_column, tod - off_ns, hours, rows, warns, notes)
        return days + tod.astype(np.int64) - off_ns.astype(np.int64)
    if date_column is not None:
        text = _text(raw.columns[date_column], "%Y-%m-%d") + " " + text
    parsed = pd.to_datetime(text, format=fmt or "ISO8601", errors="coerce")
    ts = parsed.to_numpy("datetime64[ns]").astype(np.int64)
    bad = np.isnat(parsed.to_numpy("datetime64[ns]"))
    if bad.any() and date_column is None and fmt is None:
        tod = time_of_day_ns(text)           # a local time of day without a date
        if np.isfinite(tod).all():
            ts, bad = _NO_DATE_NS + tod.astype(np.int64), np.zeros(rows.size, dtype=bool)
    if bad.any():
        col = time_column if date_column is None else f"{date_column}' + '{time_column}"
        raise _bad("date/time", text, bad, file, col, rows)
    return ts - off_ns.astype(np.int64)


def place_time_of_day(mt: MappedTable, epoch_utc: str | None, column: str,
                      warns: list[str], notes: list[str]) -> MappedTable:
    """``mt`` with times of day that carry no date put on the flight's date.

    A time column parsed without a date (a strptime ``format`` of the time of day only, or
    times of day with a UTC offset) gives stamps on 1900-01-01, the parsers' default date;
    taken as they are they would lie 120 years before the flight.  No recorder stamps a time
    before the first powered flight (:data:`FIRST_FLIGHT_NS`), so such stamps are times of
    day: with ``epoch_utc`` they are put on the epoch's date (the day before or after where
    the first stamp is nearer the epoch so), rolling over midnight forward (a step back of
    more than 12 hours is the next day); without it they become seconds from midnight of a
    date unknown (``time_kind`` ``"s"``, a warning says so).

    Raises
    ------
    ValidationError
        Stamps before 1903-12-17 that are not all times of day on 1900-01-01 (mixed with
        dated stamps, or a corrupt date): they cannot be placed, the rows are named.
    """
    if mt.time_kind == "s" or not mt.time.size:
        return mt
    t = np.asarray(mt.time, dtype=np.int64)
    early = t < FIRST_FLIGHT_NS
    if not early.any():
        return mt
    near = (t > _NO_DATE_NS - _DAY_NS) & (t < _NO_DATE_NS + 2 * _DAY_NS)
    if not early.all() or not near.all():
        bad = early if not early.all() else ~near
        first = str(np.datetime64(int(t[np.argmax(bad)]), "ns"))[:19]
        mixed = " among stamps with a later date" if not early.all() else ""
        raise ValidationError(
            f"{int(bad.sum())} time stamp(s) dated before 1903-12-17, the first powered flight "
            f"(first {first}){mixed}: neither a date a recorder writes nor a time of day "
            "alone, so they cannot be placed in time (check the time column and its format)",
            file=mt.file, column=column, rows=mt.rows[bad])
    x = t - _NO_DATE_NS
    back = np.flatnonzero(np.diff(x) < -_DAY_NS // 2) + 1
    passed = np.zeros(x.size, dtype=np.int64)
    passed[back] = 1                       # midnight passed: the rest is the next day
    x = x + np.cumsum(passed) * _DAY_NS
    roll = f", {back.size} midnight(s) passed" if back.size else ""
    if epoch_utc is None:
        warns.append(f"{mt.file}: column '{column}' holds times of day without a date and no "
                     "epoch_utc is given: the times are seconds from midnight of an unknown "
                     f"date{roll}; UTC times and what needs the date (the magnetic variation) "
                     "cannot be had: give epoch_utc = \"YYYY-MM-DDT00:00:00Z\" (the flight's "
                     "date) in the sidecar")
        return dataclasses.replace(mt, time=x.astype(np.float64) / 1e9, time_kind="s")
    ep = int(np.datetime64(epoch_utc.strip().rstrip("Zz"), "ns").astype(np.int64))
    base = ep - ep % _DAY_NS
    base += int(np.round((ep - (base + x[0])) / _DAY_NS)) * _DAY_NS
    placed = base + x
    day = str(np.datetime64(int(placed[0]), "ns").astype("datetime64[D]"))
    notes.append(f"{mt.file}: column '{column}': times of day without a date placed on "
                 f"{day} (the date of epoch_utc {epoch_utc}){roll}")
    return dataclasses.replace(mt, time=placed)
