"""Measurement updates (compiled): the scalar short form for one measurement at a time.

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
