"""Rauch-Tung-Striebel fixed-interval smoother on stacked arrays (compiled with numba).

Given filtered ``x``/``P`` (N, n)/(N, n, n), predictions ``x_pred``/``P_pred`` with
``x_pred[k] = F[k] x[k-1]`` and the transitions ``F`` (N, n, n)::

    C_k   = P_k F_{k+1}^T (P_{k+1}^-)^{-1}
    x_k^s = x_k + C_k (x_{k+1}^s - x_{k+1}^-)
    P_k^s = P_k + C_k (P_{k+1}^s - P_{k+1}^-) C_k^T

(Rauch, Tung & Striebel 1965; Simon, *Optimal State Estimation*, 2006, section 9.4.)  The step
is the estimation core's (:func:`flightrecon.estimation.rts.rts_step`: the gain through one
Cholesky factor of ``P_{k+1}^-``).
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from flightrecon.estimation.linalg import _mm
from flightrecon.estimation.manifold import EUCLIDEAN
from flightrecon.estimation.rts import rts_step, rts_step_work


@dataclass(frozen=True)
class SmootherRun:
    """Smoothed states ``x`` (N, n), covariances ``P`` (N, n, n) and gains ``C`` (N, n, n).

    ``cholesky_fallbacks``: steps whose predicted covariance failed its Cholesky factorisation
    (not positive definite to rounding), where the gain came from a general solve.
    """

    x: np.ndarray
    P: np.ndarray
    C: np.ndarray
    cholesky_fallbacks: int = 0


@nb.njit(cache=True, nogil=True)
def _rts_kernel(x, P, xp, Pp, F):
    """Backward pass on the core's step (:func:`flightrecon.estimation.rts.rts_step`) with the
    dense ``C^T = F_{k+1} P_k``."""
    N, n = x.shape
    xs = x.copy()
    Ps = P.copy()
    Cs = np.zeros((N, n, n))
    CT = np.empty((n, n))
    work = rts_step_work(n)
    n_fallback = 0
    for k in range(N - 2, -1, -1):
        _mm(F[k + 1], P[k], CT)
        if not rts_step(EUCLIDEAN, (x[k], P[k]), (xp[k + 1], Pp[k + 1]), (xs[k + 1], Ps[k + 1]),
                        CT, (0.0, 0.0), 0.0, (xs[k], Ps[k]), work):
            n_fallback += 1
        Cs[k] = work[2]  # the gain G = C P_p^-1 of this step
    return xs, Ps, Cs, n_fallback


def rts_smooth(x, P, x_pred, P_pred, F) -> SmootherRun:
    """Backward RTS pass over a forward run (see module docstring)."""
    args = [np.ascontiguousarray(np.asarray(a, dtype=np.float64))
            for a in (x, P, x_pred, P_pred, F)]
    xs, Ps, Cs, n_fallback = _rts_kernel(*args)
    return SmootherRun(xs, Ps, Cs, int(n_fallback))


def rts_smooth_run(run) -> SmootherRun:
    """Smooth a :class:`flightrecon.estimation.kalman.FilterRun`."""
    return rts_smooth(run.x, run.P, run.x_pred, run.P_pred, run.F)
