"""Dates as recorded: ISO, day-first and month-first, the order settled by the data (issue 49,
item 2; ``flightrecon.ingest.time_cells``).

The real export re-saved through a spreadsheet (``../shared/realdata/g1000_sr22_TEST1_...``:
``23/06/2021``) was refused on all 4683 rows; its first rows are read here as recorded.  The
other cases are generated: a date's order is certain when a number is above 12, settled by the
time running on from row to row across a change of date, or by a date in the file name or the
airframe line; otherwise it is a guess, said in a warning.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flightrecon.errors import ValidationError
from flightrecon.ingest.readers import RawTable
from flightrecon.ingest.time_cells import combine_date_time, time_of_day_ns

ROOT = Path(__file__).resolve().parents[1]
TEST1 = ROOT.parent / "shared" / "realdata" / "g1000_sr22_TEST1_20210623.csv"


def _raw(dates, times, offsets=None, file="x.csv", preamble=None) -> RawTable:
    cols = {"D": np.array(dates, dtype=object), "T": np.array(times, dtype=object)}
    if offsets is not None:
        cols["O"] = np.array(offsets, dtype=object)
    return RawTable(file=file, columns=cols, n_rows=len(dates), preamble=preamble or {})


def _utc(raw: RawTable, offsets: bool = False):
    warns: list[str] = []
    notes: list[str] = []
    rows = np.arange(1, raw.n_rows + 1)
    ns = combine_date_time(raw, "T", "D", "O" if offsets else None, None, rows, warns, notes)
    return ns.astype("datetime64[ns]"), warns, notes


def _at(text: str) -> np.datetime64:
    return np.datetime64(text, "ns")


def test_iso_dates_unchanged():
    ns, warns, notes = _utc(_raw(["2021-06-23", "2021/06/23"], ["14:13:58", "14:13:59.5"]))
    assert list(ns) == [_at("2021-06-23T14:13:58"), _at("2021-06-23T14:13:59.5")]
    assert not warns and not notes


@pytest.mark.parametrize("dates, first", [
    (["23/06/2021"] * 2, "2021-06-23"),      # a first number above 12: a day
    (["06/23/2021"] * 2, "2021-06-23"),      # a second number above 12: month-first
    (["23.06.21"] * 2, "2021-06-23"),        # dots, two-digit year
])
def test_order_certain_from_a_number_above_12(dates, first):
    ns, warns, notes = _utc(_raw(dates, ["10:00:00", "10:00:01"]))
    assert ns[0] == _at(f"{first}T10:00:00")
    assert not warns and len(notes) == 1 and "is no date" in notes[0]


@pytest.mark.parametrize("dates, want", [
    # 5 June -> 6 June at midnight: month-first would leap from 6 May to 6 June
    (["05/06/2021", "05/06/2021", "06/06/2021"], "dmy"),
    # 5 June -> 6 June written month-first: day-first would leap from 6 May to 6 June
    (["06/05/2021", "06/05/2021", "06/06/2021"], "mdy"),
])
def test_order_settled_by_time_running_on(dates, want):
    ns, warns, notes = _utc(_raw(dates, ["23:59:58", "23:59:59", "00:00:00"]))
    assert list(np.diff(ns).astype(np.int64)) == [10**9, 10**9]
    assert ns[0] == _at("2021-06-05T23:59:58")
    assert not warns and "leap by more than a day" in notes[0]
    assert ("day-first" if want == "dmy" else "month-first") in notes[0].split(":")[1]


def test_order_settled_by_the_airframe_line():
    """A Garmin airframe line's flightstream_header carries the date (20210605)."""
    raw = _raw(["05/06/2021"] * 2, ["10:00:00", "10:00:01"],
               preamble={"flightstream_header": "25B289D04_20210605_100000"})
    ns, warns, notes = _utc(raw)
    assert ns[0] == _at("2021-06-05T10:00:00")
    assert not warns and "flightstream_header" in notes[0]


def test_order_settled_by_a_garmin_file_name():
    raw = _raw(["06/05/2021"] * 2, ["10:00:00", "10:00:01"], file="log_210605_095915_KCKN.csv")
    ns, warns, notes = _utc(raw)
    assert ns[0] == _at("2021-06-05T10:00:00")
    assert not warns and "file name" in notes[0]


@pytest.mark.parametrize("offset, day", [("+01:00", "2021-06-05"), ("-05:00", "2021-05-06")])
def test_ambiguous_order_is_a_guess_with_a_warning(offset, day):
    """Nothing settles 05/06/2021: read day-first, or month-first where every offset is one of
    the Americas; the warning says which reading, the other date and how to choose it."""
    raw = _raw(["05/06/2021"] * 2, ["10:00:00", "10:00:01"], [offset] * 2)
    ns, warns, notes = _utc(raw, offsets=True)
    local = ns[0] + np.timedelta64(int(offset[:3]), "h")
    assert str(local.astype("datetime64[D]")) == day
    assert len(warns) == 1 and "ambiguous" in warns[0] and "format" in warns[0]
    other = "2021-05-06" if day == "2021-06-05" else "2021-06-05"
    assert f"= {day}, not {other}" in warns[0]


def test_same_day_and_month_needs_no_warning():
    ns, warns, notes = _utc(_raw(["05/05/2021"] * 2, ["10:00:00", "10:00:01"]))
    assert ns[0] == _at("2021-05-05T10:00:00") and not warns and not notes


def test_quoted_cells_and_twelve_hour_clock():
    ns, _, _ = _utc(_raw(['"23/06/2021"', "23/06/2021"], ['"2:13:58 PM"', "12:00:01 AM"]))
    assert list(ns) == [_at("2021-06-23T14:13:58"), _at("2021-06-23T00:00:01")]


def test_time_of_day_cells_out_of_range():
    import pandas as pd

    v = time_of_day_ns(pd.Series(["24:00:00", "10:60:00", "13:00:00 PM", "9:05", "x"]))
    assert np.isnan(v[[0, 1, 2, 4]]).all() and v[3] == (9 * 60 + 5) * 60e9


def test_no_date_in_either_order_refused_naming_rows():
    raw = _raw(["23/06/2021", "23/13/2021", "23/06/2021"], ["10:00:00"] * 3)
    with pytest.raises(ValidationError) as exc:
        _utc(raw)
    assert exc.value.column == "D" and list(exc.value.rows) == [2]


def test_utc_offset_applied():
    ns, _, _ = _utc(_raw(["23/06/2021"], ["14:13:58"], ["+02:00"]), offsets=True)
    assert ns[0] == _at("2021-06-23T12:13:58")


@pytest.mark.skipif(not TEST1.is_file(), reason="the real exports of ../shared/realdata")
def test_real_export_resaved_day_first(tmp_path):
    """The first 60 rows of the real SR22T export re-saved through a spreadsheet (day-first
    dates, quoted airframe line): read as recorded, one row a second from 14:13:51 UTC (one
    second missing)."""
    from flightrecon.ingest.garmin import garmin_mapping
    from flightrecon.ingest.mapping_apply import apply_mapping
    from flightrecon.ingest.readers import read_table

    lines = TEST1.read_bytes().splitlines(keepends=True)
    cut = tmp_path / TEST1.name
    cut.write_bytes(b"".join(lines[:63]))
    raw = read_table(cut)
    warns: list[str] = []
    mt = apply_mapping(raw, garmin_mapping(raw), warns=warns)
    t = mt.time.astype("datetime64[ns]")
    assert t[0] == _at("2021-06-23T14:13:51")
    step = np.diff(t).astype(np.int64) / 1e9
    assert np.all((step >= 1.0) & (step <= 2.0))        # one second apart (one missing)
    assert t[-1] == _at("2021-06-23T14:14:51")
    assert not warns and any("day-first" in n for n in mt.notes)
