"""Measurement updates (compiled): the Joseph form, and the scalar short form for one
measurement at a time.  (The SNS filter's update with noise correlated with the process noise
is in its kernel, ``filters/sns/filter.py``.)

For a scalar measurement with row ``h``, ``PH = P h^T`` and ``S = h P h^T + r``, the optimal
gain is ``K = PH / S``.  The Joseph form ``(I - K h) P (I - K h)^T + r K K^T`` expands, at that
gain, to the *short form* ``P - PH PH^T / S``; the two are equal in exact arithmetic and differ by
rounding.  The short form costs O(n^2) per measurement and, written as below, keeps ``P``
bitwise symmetric (each entry subtracts the same product ``PH_a PH_b / S``); it does not guard
against the loss of positive definiteness that the Joseph form protects against when the gain
is not optimal (docs/estimation.md, "Updates").
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True)
def scalar_update_short(x, P, PH, nu, S):
    """In place: ``x += PH nu / S``, ``P -= PH PH^T / S`` (short form, optimal gain).

    Parameters
    ----------
    x : (n,) state, updated in place
    P : (n, n) covariance, updated in place (stays exactly symmetric if it was)
    PH : (n,) ``P h^T`` of the measurement row ``h`` (computed before the call)
    nu : innovation ``z - h(x)``
    S : innovation variance ``h P h^T + r`` (> 0)
    """
    n = x.shape[0]
    inv_s = 1.0 / S
    for a in range(n):
        pa = PH[a]
        for b in range(n):
            P[a, b] -= (pa * PH[b]) * inv_s
        x[a] += pa * inv_s * nu


@nb.njit(cache=True, nogil=True)
def joseph_update(x, P, nu, H, R):
    """Measurement update with innovation ``nu`` (m,), ``H`` (m, n), ``R`` (m, m).

    Gain through a Cholesky factor of S (no explicit inverse); Joseph-form covariance, then
    symmetrised.  Returns the updated ``x``, ``P``, the innovation covariance ``S`` and the
    normalised innovation squared ``nu^T S^-1 nu``.
    """
    n = x.shape[0]
    PHt = P @ H.T
    S = H @ PHt + R
    S = 0.5 * (S + S.T)
    L = np.linalg.cholesky(S)
    Kt = np.linalg.solve(L, PHt.T)
    Kt = np.linalg.solve(L.T, Kt)
    K = Kt.T
    x = x + K @ nu
    IKH = np.eye(n) - K @ H
    P = IKH @ P @ IKH.T + K @ R @ K.T
    P = 0.5 * (P + P.T)
    w = np.linalg.solve(L, nu)
    return x, P, S, w @ w
