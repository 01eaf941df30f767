"""Time-base repair of one file's rows, with a report: what is repaired, what is refused.

A recorder's time column goes wrong in a few recognisable ways.  Two of them have one obvious
repair, which is applied and reported with the rows it touched; the others have none and are
refused, naming the rows (docs/ingest.md, "Repaired, warned, refused"):

* **exact duplicate rows** (the same time stamp and the same value in every channel, a
  recorder word written twice): the repeats are dropped;
* **local swaps** (a row whose time stamp is earlier than the row before it by at most
  :data:`LOCAL_SWAP_PERIODS` nominal sample periods, e.g. two adjacent rows exchanged): the rows
  are sorted back into time order; the order is unambiguous because every displaced row
  belongs within a few rows of where it was written;
* rows sharing a time stamp whose channels **complement** each other (one row has the loads,
  the other the GNSS fix) are kept, and merged by the cleaning layer (``docs/signals.md``);
* **conflicting duplicates** (one time stamp, rows sharing a channel without being exact
  repeats, two different values of one channel or a row half repeated): refused, which row is
  right is not ours to guess;
* **clock resets** (time stamps going back by more than a few sample periods: a recorder
  restart, two files appended): refused;
* **clock jumps** (time stamps leaping forward while the aircraft, by its GNSS positions in the
  same file, hardly moved): refused; without GNSS positions a forward jump cannot be told from
  a recording gap and is left to the gap handling of the cleaning layer.

Everything is vectorised over the rows; a file whose time stamps already increase costs one
``np.diff``.
"""

from __future__ import annotations

import numpy as np

from flightrecon.errors import ValidationError

__all__ = [
    "CLOCK_JUMP_MIN_S",
    "LOCAL_SWAP_PERIODS",
    "nominal_interval_s",
    "repair_time_order",
]

#: a backward step of at most this many nominal sample periods is a local swap (re-sorted);
#: a deeper one is a clock reset (refused)
LOCAL_SWAP_PERIODS = 8.0
#: a forward step shorter than this is never called a clock jump [s]
CLOCK_JUMP_MIN_S = 60.0
#: ... and neither is one where the aircraft covered at least this fraction of the distance its
#: speed implies over the step (GNSS positions either side)
CLOCK_JUMP_DISTANCE_FRACTION = 0.1

_EARTH_R_M = 6_371_000.0


def nominal_interval_s(t: np.ndarray) -> float:
    """Median of the positive intervals between consecutive time stamps [s] (NaN if none)."""
    dt = np.diff(np.asarray(t, dtype=float))
    dt = dt[dt > 0]
    return float(np.median(dt)) if dt.size else float("nan")


def _same_values(values: dict[str, np.ndarray], a: np.ndarray, b: np.ndarray
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, str | None]:
    """For row pairs (a[k], b[k]): identical in every channel; complementary (no channel
    sampled in both); conflicting (a channel sampled in both with different values); and the
    first channel sampled in both rows of a pair that is neither identical nor complementary."""
    same = np.ones(a.size, dtype=bool)
    overlap = np.zeros(a.size, dtype=bool)
    conflict = np.zeros(a.size, dtype=bool)
    first = None
    for name, v in values.items():
        va, vb = v[a], v[b]
        na, nb = np.isnan(va), np.isnan(vb)
        same &= (va == vb) | (na & nb)
        both = ~na & ~nb
        overlap |= both
        conflict |= both & (va != vb)
    complementary = ~overlap
    for name, v in values.items():
        both = ~np.isnan(v[a]) & ~np.isnan(v[b]) & ~same
        if both.any():
            first = name
            break
    return same, complementary, conflict, first


def _haversine_m(lat1, lon1, lat2, lon2):
    p1, p2 = np.radians(lat1), np.radians(lat2)
    dl = np.radians(lon2 - lon1)
    a = np.sin((p2 - p1) / 2) ** 2 + np.cos(p1) * np.cos(p2) * np.sin(dl / 2) ** 2
    return 2 * _EARTH_R_M * np.arcsin(np.sqrt(np.clip(a, 0.0, 1.0)))


def _clock_jumps(t: np.ndarray, values: dict[str, np.ndarray], period: float) -> np.ndarray:
    """Indices i (into the sorted rows) where t[i] - t[i-1] is a clock jump (module docstring)."""
    dt = np.diff(t)
    cand = np.flatnonzero(dt > max(CLOCK_JUMP_MIN_S, 1000.0 * period)) + 1
    if cand.size == 0 or "gnss_lat_deg" not in values or "gnss_lon_deg" not in values:
        return np.array([], dtype=np.int64)
    lat, lon = values["gnss_lat_deg"], values["gnss_lon_deg"]
    fix = np.flatnonzero(~np.isnan(lat) & ~np.isnan(lon))
    if fix.size < 4:
        return np.array([], dtype=np.int64)
    speed = None
    if "gnss_vn_mps" in values and "gnss_ve_mps" in values:
        speed = np.hypot(values["gnss_vn_mps"], values["gnss_ve_mps"])
    elif "tas_mps" in values:
        speed = values["tas_mps"]
    if speed is None:
        return np.array([], dtype=np.int64)
    out = []
    for i in cand:
        k = np.searchsorted(fix, i)          # first fix at or after row i
        if k == 0 or k >= fix.size:
            continue
        before, after = fix[k - 1], fix[k]
        # speed either side of the step (median over up to 16 samples)
        s_b = speed[max(0, i - 16):i]
        s_a = speed[i:i + 16]
        s = np.concatenate([s_b[~np.isnan(s_b)], s_a[~np.isnan(s_a)]])
        if s.size == 0:
            continue
        v = float(np.median(s))
        if v < 30.0:                          # on the ground: a parked recorder may pause
            continue
        gap = t[after] - t[before]
        d = float(_haversine_m(lat[before], lon[before], lat[after], lon[after]))
        if d < CLOCK_JUMP_DISTANCE_FRACTION * v * gap:
            out.append(i)
    return np.asarray(out, dtype=np.int64)


def repair_time_order(t: np.ndarray, rows: np.ndarray, values: dict[str, np.ndarray],
                      file: str, column: str) -> tuple[np.ndarray | None, list[str]]:
    """Bring one file's rows into time order by the rules of the module docstring.

    Parameters
    ----------
    t : (N,) time stamps [s], in file order
    rows : (N,) 1-based data rows of the file (for the messages)
    values : channel -> (N,) values in file order (NaN where not sampled)
    file, column : the file and its time column (for the messages)

    Returns
    -------
    selection : indices of the rows to keep, in time order (``None`` when nothing changes)
    warnings : the repairs made, each naming its rows

    Raises
    ------
    ValidationError
        Non-finite time stamps, a clock reset, conflicting duplicates or a clock jump, naming
        the file, the time column and the rows.
    """
    t = np.asarray(t, dtype=float)
    rows = np.asarray(rows)
    n = t.size
    if n == 0:
        return None, []
    bad = ~np.isfinite(t)
    if bad.any():
        raise ValidationError("time stamp missing or not finite", file=file, column=column,
                              rows=rows[bad])
    if n < 2:
        return None, []
    dt = np.diff(t)
    if np.all(dt > 0):
        jumps = _clock_jumps(t, values, nominal_interval_s(t))
        if jumps.size:
            _raise_jump(t, rows, jumps, file, column)
        return None, []
    warns: list[str] = []
    period = nominal_interval_s(t)
    sel = _resort_local_swaps(t, rows, dt, period, file, column, warns)
    sel = _drop_exact_duplicates(t, rows, values, sel, file, column, warns)
    jumps = _clock_jumps(t[sel], {k: v[sel] for k, v in values.items()}, period)
    if jumps.size:
        _raise_jump(t[sel], rows[sel], jumps, file, column)
    return sel, warns


def _resort_local_swaps(t: np.ndarray, rows: np.ndarray, dt: np.ndarray, period: float,
                        file: str, column: str, warns: list[str]) -> np.ndarray:
    """Rows in time order when every backward step is a local swap (at most
    :data:`LOCAL_SWAP_PERIODS` sample periods deep); a deeper one is a clock reset.

    Raises
    ------
    ValidationError
        A clock reset (or files appended), naming the rows.
    """
    n = t.size
    back = np.flatnonzero(dt < 0) + 1
    if not back.size:
        return np.arange(n)
    running_max = np.maximum.accumulate(t)
    depth = running_max[back - 1] - t[back]
    limit = LOCAL_SWAP_PERIODS * period if np.isfinite(period) else 0.0
    reset = depth > limit
    if reset.any():
        i = back[reset]
        raise ValidationError(
            f"time goes backward by {depth[reset][0]:.6g} s at the first row named "
            f"({int(reset.sum())} such step(s); more than {LOCAL_SWAP_PERIODS:g} sample "
            f"periods of {period:.6g} s): a clock reset or files appended, which cannot be "
            "re-sorted unambiguously", file=file, column=column, rows=rows[i].tolist())
    sel = np.argsort(t, kind="stable")
    moved = np.flatnonzero(sel != np.arange(n))
    warns.append(f"{file}: column '{column}': {back.size} local swap(s) of rows out of time "
                 f"order re-sorted ({_rows_text(rows[moved])})")
    return sel


def _drop_exact_duplicates(t: np.ndarray, rows: np.ndarray, values: dict[str, np.ndarray],
                           sel: np.ndarray, file: str, column: str, warns: list[str]
                           ) -> np.ndarray:
    """``sel`` without the exact repeats of an earlier row at the same time (complementary
    rows, each with channels the other lacks, stay).

    Raises
    ------
    ValidationError
        Duplicates with different values, or neither repeats nor complementary.
    """
    ts = t[sel]
    dup = np.flatnonzero(np.diff(ts) == 0) + 1          # positions in the sorted order
    if not dup.size:
        return sel
    a, b = sel[dup - 1], sel[dup]
    same, complementary, conflict, first = _same_values(values, a, b)
    ambiguous = ~same & ~complementary
    if ambiguous.any():
        pair = np.flatnonzero(ambiguous)
        what = ("with different values" if conflict[pair].any()
                else "that are neither exact repeats nor complementary")
        raise ValidationError(
            f"duplicate timestamps {what} ({pair.size} time stamp(s); the rows named repeat "
            f"the time of an earlier row, first row {int(rows[a[pair[0]]])}, and share "
            f"channel {first} with it): which row is right cannot be told",
            file=file, column=column, rows=rows[b[pair]].tolist())
    drop_pos = dup[same]
    if drop_pos.size:
        keep = np.ones(t.size, dtype=bool)
        keep[drop_pos] = False
        warns.append(f"{file}: column '{column}': {drop_pos.size} exact duplicate row(s) "
                     f"dropped ({_rows_text(rows[sel[drop_pos]])})")
        sel = sel[keep]
    return sel


def _raise_jump(t: np.ndarray, rows: np.ndarray, jumps: np.ndarray, file: str, column: str):
    step = t[jumps[0]] - t[jumps[0] - 1]
    raise ValidationError(
        f"clock jump: time leaps forward by {step:.6g} s at the first row named while the "
        "aircraft's GNSS positions either side are much closer than its speed over that time "
        "would take it (split the file at these rows, or correct its clock)", file=file,
        column=column, rows=rows[jumps])


def _rows_text(r: np.ndarray, limit: int = 8) -> str:
    rows = [int(x) for x in r]
    word = "row" if len(rows) == 1 else "rows"
    more = f" and {len(rows) - limit} more" if len(rows) > limit else ""
    return f"{word} {', '.join(map(str, rows[:limit]))}{more}"
