"""A file's time cells read as time stamps: the rows written before the recorder's clock was
set, and UTC stamps from a date, a time of day and a UTC offset in separate columns (Garmin
exports; docs/ingest.md).  Their order is :mod:`.timestamps`' to repair or refuse."""

from __future__ import annotations

import numpy as np
import pandas as pd

from flightrecon.errors import ValidationError


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


def combine_date_time(raw, time_column: str, date_column: str | None,
                      offset_column: str | None, fmt: str | None, rows: np.ndarray
                      ) -> np.ndarray:
    """UTC time stamps [int64 ns since 1970] of rows whose date, time of day and UTC offset are
    separate columns (Garmin exports: ``Lcl Date``, ``Lcl Time``, ``UTCOfst``).

    ``UTC = local - offset``: a local time ``10:00`` at offset ``+02:00`` is ``08:00`` UTC.
    The offset is ``[+-]HH:MM``, ``[+-]HHMM``, ``[+-]H`` or ``Z``, or a number of hours (a
    whole number of 100 or more read as ``HHMM``: a CSV reader takes ``+0530`` for 530).

    Parameters
    ----------
    raw : the file's :class:`~flightrecon.ingest.readers.RawTable`
    time_column : time of day (``HH:MM:SS[.fff]``), or the whole local time without a date
    date_column : date (``YYYY-MM-DD``, or as ``fmt`` says), or ``None``
    offset_column : UTC offset, or ``None`` (the time is UTC)
    fmt : strptime format of the date and time joined by one space (default ISO-8601)
    rows : (N,) 1-based data rows (for the messages)

    Raises
    ------
    ValidationError
        An empty or unparsable date, time or offset, naming the column and the rows.
    """
    file = raw.file
    text = _text(raw.columns[time_column], "%H:%M:%S")
    if date_column is not None:
        text = _text(raw.columns[date_column], "%Y-%m-%d") + " " + text
    parsed = pd.to_datetime(text, format=fmt or "ISO8601", errors="coerce")
    ts = parsed.to_numpy("datetime64[ns]").astype(np.int64)
    bad = np.isnat(parsed.to_numpy("datetime64[ns]"))
    if bad.any():
        col = time_column if date_column is None else f"{date_column}' + '{time_column}"
        raise ValidationError(f"missing or unparsable date/time ({int(bad.sum())} row(s), "
                              f"first: '{text.iloc[int(np.argmax(bad))][:40]}')", file=file,
                              column=col, rows=rows[bad])
    if offset_column is None:
        return ts
    oc = raw.columns[offset_column]
    if oc.dtype == np.float64:
        # hours (-5, 5.5), or [+-]HHMM read as a number (+0530 -> 530)
        hhmm = np.isfinite(oc) & (np.abs(oc) >= 100) & (np.mod(np.abs(oc), 1.0) == 0)
        a = np.abs(oc)
        hours = np.where(hhmm, np.sign(oc) * (a // 100 + np.mod(a, 100) / 60.0), oc)
        bad = ~np.isfinite(hours) | (np.abs(hours) > 14.0) | (hhmm & (np.mod(a, 100) >= 60))
        first = "" if not bad.any() else str(oc[int(np.argmax(bad))])
    else:
        otext = _text(oc, "%H:%M")
        m = otext.str.extract(_OFFSET_RE)
        sign = np.where(m["sign"].fillna("+").to_numpy() == "-", -1.0, 1.0)
        hh = pd.to_numeric(m["h"], errors="coerce").to_numpy(dtype=float)
        mm = pd.to_numeric(m["m"], errors="coerce").fillna(0.0).to_numpy(dtype=float)
        hours = np.where(m["z"].notna().to_numpy(), 0.0, sign * (hh + mm / 60.0))
        bad = ~np.isfinite(hours) | (np.abs(hours) > 14.0) | (mm >= 60.0)
        first = "" if not bad.any() else str(otext.iloc[int(np.argmax(bad))])
    if bad.any():
        raise ValidationError(f"missing or unparsable UTC offset ({int(bad.sum())} row(s), "
                              f"first: '{first[:20]}'; expected +HH:MM)", file=file,
                              column=offset_column, rows=rows[bad])
    return ts - np.round(hours * 3600e9).astype(np.int64)
