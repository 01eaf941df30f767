"""Gap policy for input channels: interpolate short gaps, never fill long ones.

A *gap* is an interval between two consecutive samples of a channel longer than 1.5 times its
nominal period (median spacing); its length is that interval.  Gaps of at most ``max_gap_s``
(default 2 s) are bridged by linear interpolation when the channel is brought onto the grid;
grid points inside a longer gap get NaN and ``<channel>_valid = False``.  Before the first and
after the last sample a channel is held for half a nominal period, not further.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

__all__ = ["Gap", "find_gaps", "interpolate_with_gaps"]

GAP_FACTOR = 1.5
"""An interval longer than this many nominal periods is a gap (jitter below it is normal)."""


@dataclass(frozen=True)
class Gap:
    """One gap: the samples around it and its length [s]."""

    t_start_s: float
    t_end_s: float

    @property
    def length_s(self) -> float:
        return self.t_end_s - self.t_start_s


def find_gaps(t: np.ndarray, period_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Start and end times of the gaps in sample times ``t`` (module docstring)."""
    if len(t) < 2:
        return np.empty(0), np.empty(0)
    d = np.diff(t)
    g = np.flatnonzero(d > GAP_FACTOR * period_s)
    return t[g], t[g + 1]


def interpolate_with_gaps(t: np.ndarray, x: np.ndarray, grid: np.ndarray, period_s: float,
                          max_gap_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Linear interpolation of samples ``(t, x)`` onto ``grid`` that never fills a long gap.

    Parameters
    ----------
    t, x : numpy.ndarray, shape (n,)
        Sample times (strictly increasing) and finite values.
    grid : numpy.ndarray, shape (N,)
        Target times (increasing in the fast path; any order is accepted).
    period_s : float
        Nominal sample period of the channel.
    max_gap_s : float
        Longest interval between samples that is bridged.

    Returns
    -------
    values : numpy.ndarray, shape (N,)
        Interpolated values, NaN where not valid.
    valid : numpy.ndarray of bool, shape (N,)
    """
    N = len(grid)
    if len(t) == 0:
        return np.full(N, np.nan), np.zeros(N, dtype=bool)
    hold = 0.5 * period_s if np.isfinite(period_s) else 0.0
    values = np.interp(grid, t, x)
    valid = (grid >= t[0] - hold) & (grid <= t[-1] + hold)
    if len(t) >= 2:
        # grid points strictly inside an interval between samples longer than the bridge are
        # not valid; the (few) long intervals are located in the sorted grid, so the cost is
        # O(gaps log N) rather than a search of every grid point among the samples
        bridge = max(max_gap_s, GAP_FACTOR * period_s)
        long_ = np.flatnonzero(np.diff(t) > bridge)
        if len(long_) and not np.all(grid[1:] >= grid[:-1]):  # unsorted targets: search each
            j = np.clip(np.searchsorted(t, grid, side="right") - 1, 0, len(t) - 2)
            inside = (grid > t[j]) & (grid < t[j + 1])
            valid &= ~inside | (t[j + 1] - t[j] <= bridge)
        elif len(long_):
            lo = np.searchsorted(grid, t[long_], side="right")
            hi = np.searchsorted(grid, t[long_ + 1], side="left")
            inside = np.zeros(N + 1, dtype=np.int64)
            np.add.at(inside, lo, 1)
            np.add.at(inside, hi, -1)
            valid &= np.cumsum(inside[:N]) == 0
    values[~valid] = np.nan
    return values, valid
