"""Time-base repair of one file's rows, with a report: what is repaired, what is refused.

A recorder's time column goes wrong in a few recognisable ways.  Most have one obvious repair,
which is applied and reported with the rows it touched; a time base that cannot be recovered is
refused, naming the rows (docs/ingest.md, "Repaired, warned, refused"):

* **rows before the clock was set** (an empty time cell in the first rows of the file: avionics
  that log before they have a date): dropped (:func:`.time_cells.unset_clock_rows`);
* **a short backward step of the clock** (at most :data:`CLOCK_STEP_MAX_S`, the rows after the
  step repeating the stamps of the rows before it at the logging period: a clock corrected
  backward while logging): the rows before the step are re-timed earlier by the step plus one
  period, so that the record runs on at its period (the clock after the step is kept: it is
  the one that runs to the end of the record);
* **a repeated stamp next to a missing one** (a logger that stamps whole periods and writes
  ``t, t, t+2``, or ``t, t+2, t+2``): the row whose neighbours in the file bracket exactly one
  missing stamp is re-timed onto that stamp;
* **local swaps** (a row whose time stamp is earlier than the row before it by at most
  :data:`LOCAL_SWAP_PERIODS` nominal sample periods, e.g. two adjacent rows exchanged): the rows
  are sorted back into time order; the order is unambiguous because every displaced row
  belongs within a few rows of where it was written;
* **exact duplicate rows** (the same time stamp and the same value in every channel, a
  recorder word written twice): the repeats are dropped;
* rows sharing a time stamp whose channels **complement** each other (one row has the loads,
  the other the GNSS fix) are kept, and merged by the cleaning layer (``docs/signals.md``);
* **conflicting duplicates** on a few rows (one time stamp, rows sharing a channel with
  different values, on at most :data:`MERGE_MAX_FRACTION` of the rows): merged into one row,
  channel by channel the mean of the values written (angles on the circle); on more rows the
  file's time base is coarser than its sampling and is refused;
* **clock resets** (time stamps going back by more than a few sample periods and not a short
  step as above: a recorder restart, two files appended): refused;
* **clock jumps** (time stamps leaping forward while the aircraft, by its GNSS positions in the
  same file, hardly moved): refused; without GNSS positions a forward jump cannot be told from
  a recording gap and is left to the gap handling of the cleaning layer.

Everything but the few repaired rows is vectorised; a file whose time stamps already increase
costs one ``np.diff``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.schema import BY_NAME

__all__ = [
    "CLOCK_JUMP_MIN_S",
    "CLOCK_STEP_MAX_S",
    "LOCAL_SWAP_PERIODS",
    "MERGE_MAX_FRACTION",
    "TimeRepair",
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

#: a backward step of the clock of at most this many seconds, the rows after it repeating the
#: stamps before it at the logging period, is a clock correction (re-timed, not refused)
CLOCK_STEP_MAX_S = 5.0
#: conflicting duplicate stamps on at most this fraction of the rows are merged; on more the
#: file's time base is coarser than its sampling (refused)
MERGE_MAX_FRACTION = 0.01
#: relative tolerance on "one period" when matching stamps of a regular logger
_PERIOD_RTOL = 1e-6

_EARTH_R_M = 6_371_000.0


@dataclass(frozen=True)
class TimeRepair:
    """What :func:`repair_time_order` did to one file's rows.

    Attributes
    ----------
    t : (N,) time stamps of every row in file order, re-timed where repaired [s]
    values : channel -> (N,) values in file order (the input arrays unless rows were merged,
        then copies with the merged values on the row kept)
    selection : indices of the rows to keep, in time order (``None``: all, as they are)
    warnings : the repairs made, each naming its file, column and rows
    """

    t: np.ndarray
    values: dict[str, np.ndarray]
    selection: np.ndarray | None
    warnings: list[str]


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
                      file: str, column: str) -> TimeRepair:
    """Bring one file's rows into time order by the rules of the module docstring.

    Parameters
    ----------
    t : (N,) time stamps [s], in file order
    rows : (N,) 1-based data rows of the file (for the messages)
    values : channel -> (N,) values in file order (NaN where not sampled); not modified
    file, column : the file and its time column (for the messages)

    Returns
    -------
    TimeRepair
        The time stamps (re-timed where repaired), the values (merged where conflicting
        duplicates were), the rows to keep in time order and the repairs made.

    Raises
    ------
    ValidationError
        Non-finite time stamps, a clock reset, conflicting duplicates on too many rows or a
        clock jump, naming the file, the time column and the rows.
    """
    t = np.asarray(t, dtype=float)
    rows = np.asarray(rows)
    n = t.size
    if n == 0:
        return TimeRepair(t, values, None, [])
    bad = ~np.isfinite(t)
    if bad.any():
        raise ValidationError("time stamp missing or not finite", file=file, column=column,
                              rows=rows[bad])
    if n < 2:
        return TimeRepair(t, values, None, [])
    dt = np.diff(t)
    if np.all(dt > 0):
        jumps = _clock_jumps(t, values, nominal_interval_s(t))
        if jumps.size:
            _raise_jump(t, rows, jumps, file, column)
        return TimeRepair(t, values, None, [])
    warns: list[str] = []
    period = nominal_interval_s(t)
    t = _retime_clock_steps(t, rows, period, file, column, warns)
    t = _retime_repeats(t, rows, period, file, column, warns)
    dt = np.diff(t)
    if np.all(dt > 0):
        sel = np.arange(n)
    else:
        sel = _resort_local_swaps(t, rows, dt, period, file, column, warns)
        sel, values = _drop_exact_duplicates(t, rows, values, sel, file, column, warns)
    jumps = _clock_jumps(t[sel], {k: v[sel] for k, v in values.items()}, period)
    if jumps.size:
        _raise_jump(t[sel], rows[sel], jumps, file, column)
    return TimeRepair(t, values, sel, warns)


def _regular(t: np.ndarray, period: float) -> bool:
    """Most intervals (at least half) are one nominal period: a regular logger."""
    if not np.isfinite(period) or period <= 0:
        return False
    dt = np.diff(t)
    return bool(np.mean(np.abs(dt - period) <= _PERIOD_RTOL * period + 1e-9) >= 0.5)


def _retime_clock_steps(t: np.ndarray, rows: np.ndarray, period: float, file: str,
                        column: str, warns: list[str]) -> np.ndarray:
    """Short backward steps of the clock re-timed (module docstring): at a step back of ``d``
    (at most :data:`CLOCK_STEP_MAX_S`) after which the next ``d / period + 1`` rows repeat,
    at the period, the stamps up to the one before the step, every row before the step is
    moved ``d + period`` earlier.  Other backward steps are left to the local-swap and reset
    rules."""
    back = np.flatnonzero(np.diff(t) < 0) + 1
    if not back.size or not _regular(t, period):
        return t
    t = t.copy()
    tol = _PERIOD_RTOL * period + 1e-9
    done = []
    for i in back:
        d = t[i - 1] - t[i]
        if not 0 < d <= CLOCK_STEP_MAX_S:
            continue
        m = int(round(d / period)) + 1
        if i + m > t.size or abs(m - 1 - d / period) > 1e-6:
            continue
        after = t[i:i + m]
        if np.all(np.abs(after - (t[i] + period * np.arange(m))) <= tol) \
                and abs(after[-1] - t[i - 1]) <= tol:
            shift = d + period
            t[:i] -= shift
            done.append((int(rows[i]), d, shift, i))
    for r, d, shift, i in done:
        warns.append(f"{file}: column '{column}': the clock steps back by {d:.6g} s at row {r} "
                     f"(the {int(round(d / period)) + 1} rows after it repeat the stamps before "
                     f"it at the logging period of {period:.6g} s: a clock corrected while "
                     f"logging): the {i} row(s) before it (rows {int(rows[0])}..{int(rows[i - 1])}"
                     f") re-timed {shift:.6g} s earlier")
    return t


def _retime_repeats(t: np.ndarray, rows: np.ndarray, period: float, file: str, column: str,
                    warns: list[str]) -> np.ndarray:
    """Whole-period stamps that repeat next to a missing one re-timed (module docstring): a
    row whose stamp repeats or goes behind its predecessor's, or repeats in its successor,
    whose neighbours in the file are two periods apart with no row stamped between them, and
    whose own stamp is within :data:`LOCAL_SWAP_PERIODS` periods of that missing stamp, is
    moved onto it."""
    n = t.size
    if n < 3 or not _regular(t, period):
        return t
    dt = np.diff(t)
    cand = np.zeros(n, dtype=bool)
    cand[1:] |= dt <= 0
    cand[:-1] |= dt == 0
    cand[0] = cand[-1] = False
    idx = np.flatnonzero(cand)
    if not idx.size:
        return t
    t = t.copy()
    tol = _PERIOD_RTOL * period + 1e-9
    stamps = np.sort(t)
    filled: list[float] = []
    moved = []
    for i in idx:
        lo, hi = t[i - 1], t[i + 1]
        if abs(hi - lo - 2 * period) > tol:
            continue
        slot = lo + period
        if abs(t[i] - slot) > LOCAL_SWAP_PERIODS * period + tol:
            continue
        k = np.searchsorted(stamps, slot - tol)
        if (k < stamps.size and stamps[k] <= slot + tol) or any(abs(f - slot) <= tol
                                                                for f in filled):
            continue
        t[i] = slot
        filled.append(slot)
        moved.append(i)
    if moved:
        warns.append(f"{file}: column '{column}': {len(moved)} row(s) stamped with a repeated "
                     "time next to a missing one (a logger stamping whole periods writes t, t, "
                     f"t+2) re-timed onto the missing stamp ({_rows_text(rows[moved])})")
    return t


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
                           ) -> tuple[np.ndarray, dict[str, np.ndarray]]:
    """``sel`` without the exact repeats of an earlier row at the same time (complementary
    rows, each with channels the other lacks, stay); conflicting duplicates on a few rows
    merged (:func:`_merge_conflicts`).

    Raises
    ------
    ValidationError
        Conflicting duplicates on more than :data:`MERGE_MAX_FRACTION` of the rows.
    """
    ts = t[sel]
    dup = np.flatnonzero(np.diff(ts) == 0) + 1          # positions in the sorted order
    if not dup.size:
        return sel, values
    a, b = sel[dup - 1], sel[dup]
    same, complementary, conflict, first = _same_values(values, a, b)
    ambiguous = ~same & ~complementary
    if ambiguous.any():
        pair = np.flatnonzero(ambiguous)
        if pair.size > max(1.0, MERGE_MAX_FRACTION * t.size):
            what = ("with different values" if conflict[pair].any()
                    else "that are neither exact repeats nor complementary")
            raise ValidationError(
                f"duplicate timestamps {what} ({pair.size} time stamp(s), more than "
                f"{100 * MERGE_MAX_FRACTION:g} % of the {t.size} rows; the rows named repeat the "
                f"time of an earlier row, first row {int(rows[a[pair[0]]])}, and share channel "
                f"{first} with it): the time base is coarser than the sampling and which row "
                "belongs where cannot be told (write the time with more resolution)",
                file=file, column=column, rows=rows[b[pair]].tolist())
        starts = np.flatnonzero(np.r_[True, np.diff(ts) != 0])
        head = sel[starts[np.searchsorted(starts, dup[pair], side="right") - 1]]
        values = _merge_conflicts(values, head, b[pair])
        warns.append(f"{file}: column '{column}': {pair.size} time stamp(s) written twice with "
                     f"different values (first shared channel {first}): each pair merged into "
                     "its first row, channel by channel the mean (angles on the circle) "
                     f"({_rows_text(rows[b[pair]])} merged into the row before)")
    drop_pos = dup[same | ambiguous]
    if drop_pos.size:
        keep = np.ones(sel.size, dtype=bool)
        keep[drop_pos] = False
        n_same = int(same.sum())
        if n_same:
            warns.append(f"{file}: column '{column}': {n_same} exact duplicate row(s) "
                         f"dropped ({_rows_text(rows[sel[dup[same]]])})")
        sel = sel[keep]
    return sel, values


def _merge_conflicts(values: dict[str, np.ndarray], a: np.ndarray, b: np.ndarray
                     ) -> dict[str, np.ndarray]:
    """Copies of ``values`` with each row ``b[k]`` merged into row ``a[k]`` (the first row of
    its run of equal stamps): the mean of the two where both are sampled (angles on the
    circle), the one sampled otherwise.  A run of more than two rows merges in order, so its
    values are chained means."""
    out = {}
    for name, v in values.items():
        v = v.copy()
        ch = BY_NAME.get(name)
        for i, j in zip(a, b, strict=True):
            x, y = v[i], v[j]
            if np.isnan(x):
                v[i] = y
            elif not np.isnan(y):
                if ch is not None and ch.angle:
                    r = np.radians([x, y])
                    v[i] = np.degrees(np.arctan2(np.sin(r).sum(), np.cos(r).sum())) % 360.0
                else:
                    v[i] = 0.5 * (x + y)
        out[name] = v
    return out


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
