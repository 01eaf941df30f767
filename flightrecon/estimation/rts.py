"""The Rauch-Tung-Striebel backward step (compiled), once for every smoother.

For a forward run with filtered ``x_f, P_f`` at step k, the prediction ``x_p, P_p`` of step k+1
and the cross-covariance ``C = Cov(x_k, x_{k+1} | Y_0..k)`` (``C = P_f F^T`` for a plain
transition ``F``; with noise correlated across the update and the prediction it has an extra
term, docs/sns.md)::

    G   = C P_p^-1                                   (one Cholesky factor of P_p)
    x_s = x_f (+) G (x_s,next (-) x_p)
    P_s = P_f + G (P_s,next - P_p) G^T

(Rauch, Tung & Striebel 1965; Simon 2006, section 9.4), with ``(+)``/``(-)`` the plus and minus
of the state's geometry (:mod:`flightrecon.estimation.manifold`: Euclidean, or latitude/longitude
whose tangent is north/east metres).  The covariances live in the tangent space throughout.

The caller computes ``C^T`` (dense, sparse, or with its correlated-noise term): that is where the
models differ.  The step takes ``C^T`` (n, n) rather than ``C`` because the solve
``G^T = P_p^-1 C^T`` then runs along contiguous rows.

:func:`rts_mean_solve` is the first half of a mean-only step, ``y = P_p^-1 (x_s,next (-) x_p)``,
for smoothers whose gain need not be formed: ``x_s = x_f (+) C y`` with ``C y`` computed by the
caller in its structure (``P_f (F^T y)`` with a sparse ``F``: O(n^2) instead of O(n^3)).

A predicted covariance whose Cholesky factorisation fails (not positive definite to rounding) is
solved through its symmetric eigen-decomposition instead
(:func:`~flightrecon.estimation.linalg.solve_sym_eig_into`: the inverse of a regular indefinite
matrix, as a general solve gives it; the minimum-norm solution of a singular one); the step
returns False so that the caller counts and reports it.  docs/estimation.md, "The RTS
backward step".

:func:`rts_gain_into`, :func:`rts_step` and :func:`rts_mean_solve` are inlined at numba's IR
level into their callers (``inline="always"``): no compilation of their own, once per calling
loop and geometry, on a cold cache (docs/performance.md, "The first run").
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flightrecon.estimation.linalg import (
    cholesky_factor,
    cholesky_solve_columns,
    cholesky_solve_vector,
    solve_sym_eig_into,
)
from flightrecon.estimation.manifold import state_minus_into, state_plus_into

#: eigenvalues at or below this fraction of the largest are treated as zero in the fallback
FALLBACK_RCOND = 1e-15


@nb.njit(cache=True, nogil=True, inline="always")
def rts_gain_into(CT, Pp, rel_tol, L, GT, G):
    """``G = C P_p^-1`` and ``GT = G^T = P_p^-1 C^T`` from ``CT`` (n, n); ``L`` (n, n) scratch.

    Returns False if the Cholesky factorisation of ``Pp`` failed (pivot not positive, or not
    above ``rel_tol`` times its diagonal entry) and the eigen-decomposition solve was used.
    """
    n = Pp.shape[0]
    ok = cholesky_factor(Pp, L, rel_tol)
    if ok:
        cholesky_solve_columns(L, CT, GT)
    else:
        solve_sym_eig_into(Pp, CT, FALLBACK_RCOND, GT)
    for i in range(n):
        for j in range(n):
            G[i, j] = GT[j, i]
    return ok


@nb.njit(cache=True, nogil=True, inline="always")
def rts_step(geom, filtered, predicted, smoothed_next, CT, heights, rel_tol, out, work):
    """One RTS backward step (module docstring).

    Parameters
    ----------
    geom : :data:`~flightrecon.estimation.manifold.EUCLIDEAN` or ``LATLON``
    filtered : ``(x_f, P_f)`` at step k
    predicted : ``(x_p, P_p)``, the prediction of step k+1
    smoothed_next : ``(x_s, P_s)`` at step k+1
    CT : (n, n) ``C^T``, the transposed cross-covariance ``Cov(x_k, x_{k+1} | Y_0..k)^T``
        (``F P_f`` for a plain transition)
    heights : ``(h, h_next)`` [m] at k and k+1 for a latitude/longitude state (else unused)
    rel_tol : Cholesky pivot tolerance (:func:`~flightrecon.estimation.linalg.cholesky_factor`)
    out : ``(x_s, P_s)`` at step k, written (its ``P_s`` may be the ``P_s`` of
        ``smoothed_next``: the step then runs in place)
    work : scratch from :func:`rts_step_work`, ``(L, GT, G, D, E, d, dx)``

    Returns
    -------
    bool
        False if ``P_p`` failed its Cholesky factorisation (a general solve was used).
    """
    xf, Pf = filtered
    xp, Pp = predicted
    xs_next, Ps_next = smoothed_next
    h, h_next = heights
    xs, Ps = out
    L, GT, G, D, E, d, dx = work
    n = xf.shape[0]
    ok = rts_gain_into(CT, Pp, rel_tol, L, GT, G)
    state_minus_into(geom, xs_next, xp, h_next, d)
    for i in range(n):
        v = 0.0
        for j in range(n):
            v += G[i, j] * d[j]
        dx[i] = v
    state_plus_into(geom, xf, dx, h, xs)
    for i in range(n):
        for j in range(n):
            D[i, j] = Ps_next[i, j] - Pp[i, j]
    # G (P_s,next - P_p) G^T: BLAS products into the buffers (at the joint's 24 states 20 %
    # faster than the loop products; the SNS's 5 states do not notice)
    np.dot(G, D, E)
    np.dot(E, GT, Ps)
    for i in range(n):
        for j in range(i, n):
            Ps[i, j] += Pf[i, j]
    for i in range(n):  # the upper triangle mirrored: exactly symmetric
        for j in range(i):
            Ps[i, j] = Ps[j, i]
    return ok


@nb.njit(cache=True, nogil=True)
def rts_step_work(n):
    """Scratch for :func:`rts_step` at state dimension ``n``."""
    return (np.empty((n, n)), np.empty((n, n)), np.empty((n, n)), np.empty((n, n)),
            np.empty((n, n)), np.empty(n), np.empty(n))


@nb.njit(cache=True, nogil=True, inline="always")
def rts_mean_solve(geom, xp, Pp, xs_next, h_next, rel_tol, L, d, y):
    """``y = P_p^-1 (x_s,next (-) x_p)`` (the mean-only step's solve; module docstring).

    ``L`` (n, n), ``d`` (n,) scratch.  Returns False if the Cholesky factorisation of ``Pp``
    failed and a general solve was used.
    """
    state_minus_into(geom, xs_next, xp, h_next, d)
    ok = cholesky_factor(Pp, L, rel_tol)
    if ok:
        cholesky_solve_vector(L, d, y)
    else:
        solve_sym_eig_into(Pp, d.reshape((-1, 1)), FALLBACK_RCOND, y.reshape((-1, 1)))
    return ok
