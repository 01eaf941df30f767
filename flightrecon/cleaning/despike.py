"""Robust despiking of one channel on its own samples (Hampel filter with an isolation rule).

Rule (documented in ``docs/signals.md``), applied to the channel's own samples ``x_i`` (angles
unwrapped first):

1. Local reference: ``m_i`` = running median over ``2 w + 1`` samples (``w = half_window``,
   default 7), ``s_i = 1.4826 * MAD_i`` (running median of ``|x - m|`` over the same window:
   Hampel 1974; Pearson 2002 "Outliers in process modeling and identification").
2. Scale floor: ``s_i`` is raised to at least ``max(1.4826 q, s_typ)``, where ``q`` is the
   quantisation step estimated from the data (the smallest spacing between distinct recorded
   values) and ``s_typ = 1.2533 * mean(|x - m|)`` over the channel, the largest 1 %
   excluded (the mean absolute deviation scaled to a Gaussian sigma; unlike a median it is not
   itself quantised), so plateaus (MAD = 0) of a quantised signal and quiet stretches of a smooth
   one are not flagged.
3. Candidate: ``|x_i - m_i| > n_sigma * s_i`` (default ``n_sigma = 5``: a Gaussian sample
   exceeds it with probability 6e-7).
4. Isolation (this is what keeps genuine transients such as a 2 g touchdown): a spike is a run
   of at most ``max_run`` consecutive candidates (default 2; at 16 Hz 0.125 s, shorter than any
   rigid-body transient seen through the recorder's anti-alias filter), and every sample of the
   run must also depart by more than the threshold from the straight line through the run's two
   neighbouring samples (the signal returns to where it was).  A longer excursion, or a step
   that does not come back, is kept as data.

5. Coincidence (physical consistency, applied by :class:`flightrecon.cleaning.steps.Despike`
   to the load factors): a spike in one load-factor channel within one sample period of a
   candidate in another load-factor channel is a physical event seen by several sensors (a
   touchdown shows in ``n_norm`` and ``n_long``) and is kept; a recorder spike hits one channel.

Spikes are removed (set missing); they are then short gaps that the resampling interpolates.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

__all__ = [
    "DespikeSettings",
    "despike_samples",
    "estimate_quantum",
    "hampel_candidates",
    "isolated_runs",
]

_MAD_TO_SIGMA = 1.4826
"""1 / Phi^-1(3/4): MAD of a Gaussian times this is its standard deviation."""


@dataclass(frozen=True)
class DespikeSettings:
    """Parameters of :func:`despike_samples` (module docstring).

    Attributes
    ----------
    half_window : half width ``w`` of the running median [samples]
    n_sigma : threshold in robust standard deviations
    max_run : longest run of consecutive outliers still called a spike [samples]
    """

    half_window: int = 7
    n_sigma: float = 5.0
    max_run: int = 2


def estimate_quantum(x: np.ndarray) -> float:
    """Quantisation step of a recorded channel, estimated from its distinct values.

    The smallest spacing between sorted distinct values, ignoring spacings below 1e-9 of the
    values' magnitude (floating-point noise of unit conversions): the step itself for a
    quantised signal, a tiny number for an unquantised one.  Returns 0 with fewer than two
    distinct values.
    """
    s = np.sort(x[np.isfinite(x)])  # the positive spacings of the sorted values are those of
    if len(s) < 2 or s[0] == s[-1]:  # the distinct values (np.unique is 3 times slower)
        return 0.0
    d = np.diff(s)
    d = d[d > 1e-9 * max(abs(float(s[0])), abs(float(s[-1])), 1.0)]
    return float(d.min()) if len(d) else 0.0


@nb.njit(cache=True)
def _running_median_kernel(x, w):
    """Centred running median over ``[i - w, i + w]`` (truncated at the ends), finite ``x``.

    Keeps the window sorted in a buffer and updates it by one insertion and one deletion per
    sample: O(n w), about 30 ms for 576 000 samples and w = 7.
    """
    n = x.shape[0]
    out = np.empty(n)
    buf = np.empty(2 * w + 2)
    m = 0
    lo = 0
    hi = 0
    for i in range(n):
        new_hi = min(n, i + w + 1)
        new_lo = max(0, i - w)
        while hi < new_hi:
            v = x[hi]
            j = m
            while j > 0 and buf[j - 1] > v:
                buf[j] = buf[j - 1]
                j -= 1
            buf[j] = v
            m += 1
            hi += 1
        while lo < new_lo:
            v = x[lo]
            j = 0
            while buf[j] != v:
                j += 1
            for k in range(j, m - 1):
                buf[k] = buf[k + 1]
            m -= 1
            lo += 1
        if m % 2 == 1:
            out[i] = buf[m // 2]
        else:
            out[i] = 0.5 * (buf[m // 2 - 1] + buf[m // 2])
    return out


#: series up to this many samples take the plain numpy running median (:func:`_median_at` at
#: every sample: the same values); longer ones the compiled kernel.  Measured (one core,
#: 2026-12-07): 0.3 ms against 0.1 ms at 2 839 samples (a 47-minute 1 Hz export), 4 ms
#: against 0.7 ms at 20 000, 44 ms against 9 ms at 200 000; the kernel costs 0.5-1.1 s of
#: compilation on a cold cache, which a short flight then never pays (docs/performance.md,
#: "The first run")
NUMPY_MEDIAN_MAX_SAMPLES = 20_000


def _running_median(x: np.ndarray, half_window: int) -> np.ndarray:
    """Centred running median of finite samples over ``2 half_window + 1``: plain numpy up to
    :data:`NUMPY_MEDIAN_MAX_SAMPLES` samples, compiled beyond.

    A read-only array is copied first: the kernel is then compiled for writable arrays only
    (one specialisation instead of two on a cold cache).
    """
    if len(x) <= NUMPY_MEDIAN_MAX_SAMPLES:
        return _median_at(x, np.arange(len(x)), int(half_window))
    x = np.ascontiguousarray(x, dtype=np.float64)
    if not x.flags.writeable:
        x = x.copy()
    return _running_median_kernel(x, int(half_window))


#: windows sorted at a time by :func:`_median_at` (15 samples each at the default window:
#: 7.9 MB of sorted copies at most)
_MEDIAN_BLOCK = 65536


def _median_at(x: np.ndarray, idx: np.ndarray, w: int) -> np.ndarray:
    """Median of ``x`` over ``[i - w, i + w]`` (truncated at the ends) at each ``i`` of ``idx``.

    The same windows, and the same middle element or mean of the two middle elements, as
    :func:`_running_median_kernel`, so the values are identical.  Plain numpy (the whole
    windows sorted row by row, blocks of :data:`_MEDIAN_BLOCK`; the truncated ones at the ends
    one by one): ``idx`` is usually a handful of samples, and a compiled kernel with its sort
    cost 1.2 s of compilation on a cold cache (docs/performance.md).
    """
    x = np.asarray(x, dtype=np.float64)
    idx = np.asarray(idx, dtype=np.int64)
    n = x.shape[0]
    out = np.empty(idx.shape[0])
    if idx.shape[0] == 0:
        return out
    whole = (idx >= w) & (idx + w < n)
    k_whole = np.flatnonzero(whole)
    if k_whole.size:
        windows = np.lib.stride_tricks.sliding_window_view(x, 2 * w + 1)
        for b in range(0, k_whole.size, _MEDIAN_BLOCK):
            kb = k_whole[b:b + _MEDIAN_BLOCK]
            out[kb] = np.sort(windows[idx[kb] - w], axis=1)[:, w]  # odd length: the middle
    for k in np.flatnonzero(~whole):
        i = int(idx[k])
        lo = max(0, i - w)
        hi = min(n, i + w + 1)
        buf = np.sort(x[lo:hi])
        m = hi - lo
        out[k] = buf[m // 2] if m % 2 == 1 else 0.5 * (buf[m // 2 - 1] + buf[m // 2])
    return out


def hampel_candidates(x: np.ndarray, settings: DespikeSettings = DespikeSettings(), *,
                      full_threshold: bool = True) -> tuple[np.ndarray, np.ndarray, float]:
    """Steps 1-3 of the rule (module docstring): outlier candidates and their thresholds.

    Parameters
    ----------
    x : numpy.ndarray, shape (n,)
        The channel's own samples, finite, in time order.
    settings : DespikeSettings
    full_threshold : bool
        ``True``: the running MAD, hence the threshold, is computed at every sample.
        ``False``: only where a sample could be a candidate at all, i.e. where
        ``|x - m| > n_sigma * floor`` (the threshold is never below ``n_sigma * floor``):
        usually a handful of samples instead of all of them, which halves the cost.  The
        candidates are identical; the threshold is exact at those samples (every candidate among
        them) and is its lower bound ``n_sigma * floor`` elsewhere, which is all that step 4
        (:func:`isolated_runs`, which reads it at candidates only) needs.

    Returns
    -------
    candidates : bool array, shape (n,)
    threshold : float array, shape (n,), ``n_sigma * max(1.4826 MAD_i, floor)``
    floor : float, the scale floor
    """
    x = np.asarray(x, dtype=float)
    n = len(x)
    if n < 3:
        return np.zeros(n, dtype=bool), np.full(n, np.inf), 0.0
    w = settings.half_window
    med = _running_median(x, w)
    dev = np.abs(x - med)
    trimmed = dev[dev <= np.percentile(dev, 99.0)]
    s_typ = 1.2533 * float(np.mean(trimmed)) if len(trimmed) else 0.0
    floor = max(_MAD_TO_SIGMA * estimate_quantum(x), s_typ)
    if full_threshold:
        mad = _running_median(dev, w)
        thr = settings.n_sigma * np.maximum(_MAD_TO_SIGMA * mad, floor)
        cand = dev > thr
    else:
        thr = np.full(n, settings.n_sigma * floor)
        idx = np.flatnonzero(dev > thr)
        mad = _median_at(dev, idx, int(w))
        thr[idx] = settings.n_sigma * np.maximum(_MAD_TO_SIGMA * mad, floor)
        cand = dev > thr
    if floor == 0.0:  # a constant channel: nothing can be an outlier of it
        cand[:] = False
    return cand, thr, floor


def isolated_runs(x: np.ndarray, cand: np.ndarray, thr: np.ndarray, max_run: int) -> np.ndarray:
    """Step 4 of the rule: candidates in runs of at most ``max_run`` that leave their neighbours.

    Returns a bool array, True at the samples of the accepted runs.
    """
    n = len(x)
    spikes = np.zeros(n, dtype=bool)
    if not cand.any():
        return spikes
    edges = np.diff(np.concatenate([[0], cand.astype(np.int8), [0]]))
    starts = np.flatnonzero(edges == 1)
    ends = np.flatnonzero(edges == -1)  # exclusive
    short = (ends - starts) <= max_run
    starts, ends = starts[short], ends[short]
    if len(starts) == 0:
        return spikes
    lengths = ends - starts
    idx = np.repeat(np.arange(len(starts)), lengths)
    members = (np.repeat(starts, lengths)
               + np.arange(idx.size) - np.repeat(np.cumsum(lengths) - lengths, lengths))
    # straight line through the neighbours of each run (one-sided at the ends)
    left, right = starts - 1, ends
    has_l, has_r = left >= 0, right < n
    xl = np.where(has_l, x[np.clip(left, 0, n - 1)], np.nan)
    xr = np.where(has_r, x[np.clip(right, 0, n - 1)], np.nan)
    xl = np.where(has_l, xl, xr)
    xr = np.where(has_r, xr, xl)
    span = (right - left).astype(float)
    pos = (members - left[idx]) / span[idx]
    line = xl[idx] + pos * (xr[idx] - xl[idx])
    away = np.abs(x[members] - line) > thr[members]
    ok_run = np.ones(len(starts), dtype=bool)
    np.logical_and.at(ok_run, idx, away)
    ok_run &= has_l | has_r
    spikes[members[ok_run[idx]]] = True
    return spikes


def despike_samples(x: np.ndarray, settings: DespikeSettings = DespikeSettings()
                    ) -> tuple[np.ndarray, np.ndarray, float]:
    """Find isolated spikes in one channel's samples (steps 1-4 of the module docstring).

    Parameters
    ----------
    x : numpy.ndarray, shape (n,)
        The channel's own samples, finite, in time order (angles unwrapped).
    settings : DespikeSettings

    Returns
    -------
    cleaned : numpy.ndarray, shape (n,)
        ``x`` with the spikes set to NaN (a new array).
    spikes : numpy.ndarray of bool, shape (n,)
        True at the removed samples.
    floor : float
        The scale floor used (for the report).
    """
    x = np.asarray(x, dtype=float)
    cand, thr, floor = hampel_candidates(x, settings, full_threshold=False)
    spikes = isolated_runs(x, cand, thr, settings.max_run)
    cleaned = x.copy()
    cleaned[spikes] = np.nan
    return cleaned, spikes, floor
