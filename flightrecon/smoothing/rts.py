"""Rauch-Tung-Striebel fixed-interval smoother on stacked arrays (compiled with numba).

Given filtered ``x``/``P`` (N, n)/(N, n, n), predictions ``x_pred``/``P_pred`` with
``x_pred[k] = F[k] x[k-1]`` and the transitions ``F`` (N, n, n)::

    C_k   = P_k F_{k+1}^T (P_{k+1}^-)^{-1}
    x_k^s = x_k + C_k (x_{k+1}^s - x_{k+1}^-)
    P_k^s = P_k + C_k (P_{k+1}^s - P_{k+1}^-) C_k^T

(Rauch, Tung & Striebel 1965; Simon, *Optimal State Estimation*, 2006, section 9.4.)
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np


@dataclass(frozen=True)
class SmootherRun:
    """Smoothed states ``x`` (N, n), covariances ``P`` (N, n, n) and gains ``C`` (N, n, n)."""

    x: np.ndarray
    P: np.ndarray
    C: np.ndarray


@nb.njit(cache=True, nogil=True)
def _rts_kernel(x, P, xp, Pp, F):
    N, n = x.shape
    xs = x.copy()
    Ps = P.copy()
    Cs = np.zeros((N, n, n))
    for k in range(N - 2, -1, -1):
        # C = P_k F^T Pp^-1  computed as solve(Pp, F P_k)^T (Pp symmetric)
        A = F[k + 1] @ P[k]
        C = np.linalg.solve(Pp[k + 1], A).T
        xs[k] = x[k] + C @ (xs[k + 1] - xp[k + 1])
        Pk = P[k] + C @ (Ps[k + 1] - Pp[k + 1]) @ C.T
        Ps[k] = 0.5 * (Pk + Pk.T)
        Cs[k] = C
    return xs, Ps, Cs


def rts_smooth(x, P, x_pred, P_pred, F) -> SmootherRun:
    """Backward RTS pass over a forward run (see module docstring)."""
    args = [np.ascontiguousarray(np.asarray(a, dtype=np.float64))
            for a in (x, P, x_pred, P_pred, F)]
    xs, Ps, Cs = _rts_kernel(*args)
    return SmootherRun(xs, Ps, Cs)


def rts_smooth_run(run) -> SmootherRun:
    """Smooth a :class:`flightrecon.filters.kalman.FilterRun`."""
    return rts_smooth(run.x, run.P, run.x_pred, run.P_pred, run.F)
