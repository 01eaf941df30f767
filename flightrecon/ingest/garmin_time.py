"""The time stamps of Garmin exports whose 1 Hz rows carry their clock's whole second.

Older G1000 software (the Cessna 172S export of software 10.01 read for issue #49) writes a row
about once a second, each stamped with the second of its clock it fell in: the logging period
is not exactly one second (1.018 s there: 3966 rows over 4038 s), so one second now and then
holds two rows (a repeated stamp) and another none (a skipped one).  On that export 728
stamps repeat and 776 seconds are skipped (12 more steps of 3 s): the rows are a regular
series whose stamps were cut to the second, not several samples a second on a coarse clock.

:func:`whole_second_jitter` re-times such rows by a running straight line through the stamps
(the least-squares fit over :data:`WINDOW_ROWS` rows, plus the half second the cut removed on
average) held inside each row's own second (two rows stamped with one second share it in
order): the rows keep their order at the logging period, and no row leaves the second its
stamp says it fell in.
"""

from __future__ import annotations

import numpy as np

__all__ = ["WINDOW_ROWS", "whole_second_jitter"]

#: rows of the running straight-line fit (about half a minute at 1 Hz)
WINDOW_ROWS = 31
#: repeated stamps, as a share of the rows, from which the re-timing is considered (below it
#: the time-order repair of :mod:`.timestamps` deals with a few repeats)
MIN_REPEATS = 0.01
#: a step longer than this [s] is a real gap: the fit does not run across it
GAP_S = 3


def _running_fit(i: np.ndarray, s: np.ndarray, w: int) -> np.ndarray:
    """Least-squares line of ``s`` on ``i`` over a centred window of ``w`` points (clipped
    at the ends), evaluated at each point (cumulative sums: O(n))."""
    n = i.size
    h = w // 2
    lo = np.clip(np.arange(n) - h, 0, n)
    hi = np.clip(np.arange(n) + h + 1, 0, n)
    c = [np.concatenate(([0.0], np.cumsum(x))) for x in (np.ones(n), i, s, i * s, i * i)]
    k, si, ss, sis, sii = (x[hi] - x[lo] for x in c)
    den = k * sii - si * si
    slope = np.where(den > 0, (k * sis - si * ss) / np.where(den > 0, den, 1.0), 1.0)
    return ss / k + slope * (i - si / k)


def whole_second_jitter(t_ns: np.ndarray) -> tuple[np.ndarray, str | None]:
    """Times [ns] of rows (in file order) re-timed when their stamps are whole seconds cut
    from a regular series of about 1 Hz (module docstring), and the sentence saying so; the
    times unchanged and ``None`` otherwise.

    Applied when the stamps are whole seconds, their median step is 1 s, at least
    :data:`MIN_REPEATS` of them repeat the one before, and the skipped seconds (steps of 2-3 s)
    number at least half the repeats (the lost seconds come back: a regular series); each run
    between real gaps (a step back or beyond :data:`GAP_S` s) is fitted on its own.
    """
    t = np.asarray(t_ns, dtype=np.int64)
    if t.size < WINDOW_ROWS or np.any(t % 1_000_000_000):
        return t, None
    s = (t // 1_000_000_000).astype(np.float64)
    d = np.diff(s)
    repeats = int((d == 0).sum())
    skipped = int(((d >= 2) & (d <= GAP_S)).sum())
    if np.median(d) != 1.0 or repeats < MIN_REPEATS * t.size or skipped < 0.5 * repeats:
        return t, None
    out = s.copy()
    cuts = np.concatenate(([0], np.flatnonzero((d < 0) | (d > GAP_S)) + 1, [s.size]))
    for a, b in zip(cuts[:-1], cuts[1:], strict=True):
        if b - a >= 3:
            out[a:b] = _running_fit(np.arange(b - a, dtype=float), s[a:b], WINDOW_ROWS) + 0.5
    # each row stays in its stamp's second; rows sharing a stamp share the second in order
    start = np.concatenate(([True], d != 0))
    run_id = np.cumsum(start) - 1
    first = np.flatnonzero(start)
    k = np.arange(s.size) - first[run_id]
    m = np.diff(np.concatenate((first, [s.size])))[run_id]
    out = np.clip(out, s + k / m + 0.01, s + (k + 1) / m - 0.01)
    dev = out - s - 0.5
    if np.any(np.diff(out) <= 0):
        return t, None               # not the regular series assumed: left to the time checks
    note = (f"the rows' whole-second stamps jitter across the second ({repeats} repeated, "
            f"{skipped} skipped, {t.size} rows over {s[-1] - s[0]:.0f} s: a logging period of "
            f"{(s[-1] - s[0]) / max(t.size - 1, 1):.3f} s cut to the second): re-timed by a "
            f"running straight line through the stamps ({WINDOW_ROWS} rows) held in each "
            f"row's second (median {np.median(np.abs(dev)):.2f} s from the second's middle)")
    return np.round(out * 1e9).astype(np.int64), note
