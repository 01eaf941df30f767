"""The backward smoother: one Rauch-Tung-Striebel loop over the time steps, for every method.

For k = N-1 .. 0 (docs/estimation.md, "One backward loop"; Rauch, Tung & Striebel 1965)::

    G_k   = C_k P_p[k+1]^-1,   C_k = Cov(x_k, x_{k+1} | Y_0..k)   (F P_f^T for a plain transition)
    x_s[k] = x_f[k] (+) G_k (x_s[k+1] (-) x_p[k+1])
    P_s[k] = P_f[k] + G_k (P_s[k+1] - P_p[k+1]) G_k^T               (not in the mean-only pass)

with the step of :mod:`flightrecon.estimation.rts` (:func:`~flightrecon.estimation.rts.rts_step`,
or in the mean-only mode :func:`~flightrecon.estimation.rts.rts_mean_solve` and the model's
``C y``: O(n^3 / 6) per step instead of O(n^3)).  The model
(:mod:`flightrecon.estimation.model`) supplies the covariances it kept, its cross-covariance and
its geometry, and takes the smoothed estimate of each step into its own outputs.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numba as nb
import numpy as np
from numba.core import types
from numba.extending import overload

from flightrecon.estimation.manifold import state_plus_into
from flightrecon.estimation.model import (
    FloatArray,
    ModelT,
    cross_times_into,
    cross_transposed_into,
    keep_smoothed,
    mean_only_pass_offered,
    rts_frame,
    smoothing_covariances,
    workspace,
)
from flightrecon.estimation.rts import rts_mean_solve, rts_step, rts_step_work

__all__ = ["SmoothedRun", "backward_pass", "mean_only_pass", "smoothed_step"]


def smoothed_step(model: ModelT, k: int, x_f: FloatArray, x_p: FloatArray, x_s: FloatArray,
                  Ps: FloatArray, ws: Any, work: tuple[FloatArray, ...]) -> bool:
    """One backward step of :func:`backward_pass` into ``x_s[k]`` (and ``Ps``): the RTS step
    with covariances, or the mean-only step where ``Ps`` is empty (0, 0).  A model class
    registered ``with_mean_only_pass`` (estimation.model) gets both steps in one compilation
    of the loop, chosen at run time (the mean-only pass is then no second compilation); any
    other class gets only the covariance step.  Returns False where the predicted covariance
    failed its Cholesky factorisation.  Compiled only (its two forms are the overload below);
    the Python body only raises."""
    raise NotImplementedError("smoothed_step runs only inside the compiled backward_pass")


def mean_only_pass(model) -> bool:
    """True when the model's class offers the mean-only backward pass
    (:func:`flightrecon.estimation.model.with_mean_only_pass`); a compile-time constant of the
    loop."""
    return mean_only_pass_offered(type(model))


def _offers_mean_only(model_type: types.Type) -> bool:
    return mean_only_pass_offered(getattr(model_type, "instance_class", None))


@overload(mean_only_pass, jit_options={"nogil": True, "cache": True})
def _mean_only_pass(model):
    offered = _offers_mean_only(model)
    return lambda model: offered


@overload(smoothed_step, jit_options={"nogil": True, "cache": True})
def _smoothed_step(model, k, x_f, x_p, x_s, Ps, ws, work):
    def with_covariances(model, k, x_f, x_p, x_s, Ps, ws, work):
        CT, rts_work, L, d, y, dx = work
        Pf, Pp = smoothing_covariances(model, k, ws)
        geom, h, h_next, rel_tol = rts_frame(model, k)
        cross_transposed_into(model, k, CT, ws)
        return rts_step(geom, (x_f[k], Pf), (x_p[k + 1], Pp), (x_s[k + 1], Ps), CT,
                        (h, h_next), rel_tol, (x_s[k], Ps), rts_work)

    if not _offers_mean_only(model):
        return with_covariances

    def either(model, k, x_f, x_p, x_s, Ps, ws, work):
        CT, rts_work, L, d, y, dx = work
        Pf, Pp = smoothing_covariances(model, k, ws)
        geom, h, h_next, rel_tol = rts_frame(model, k)
        if Ps.shape[0] > 0:
            cross_transposed_into(model, k, CT, ws)
            return rts_step(geom, (x_f[k], Pf), (x_p[k + 1], Pp), (x_s[k + 1], Ps), CT,
                            (h, h_next), rel_tol, (x_s[k], Ps), rts_work)
        # y = P_p^-1 (x_s[k+1] (-) x_p[k+1]), then x_s[k] = x_f[k] (+) C y
        ok = rts_mean_solve(geom, x_p[k + 1], Pp, x_s[k + 1], h_next, rel_tol, L, d, y)
        cross_times_into(model, k, y, dx, ws)
        state_plus_into(geom, x_f[k], dx, h, x_s[k])
        return ok
    return either


@nb.njit(cache=True, nogil=True)
def backward_pass(model, x_f, x_p, x_s, P_last):
    """Run the RTS backward pass of ``model``.

    ``x_f``, ``x_p`` (N, n) the filtered and predicted states; ``x_s`` (N, n) receives the
    smoothed states (``x_s[N-1]`` is set to ``x_f[N-1]``); ``P_last`` (n, n) the filtered
    covariance of the last step (the smoothed one there), or an empty (0, 0) array for the
    mean-only pass (the model's ``keep_smoothed`` then gets an empty covariance; only for a
    model class registered ``with_mean_only_pass``, else ValueError).  Both passes are one
    compilation of this loop per model class (:func:`smoothed_step`).

    Returns the number of steps whose predicted covariance failed its Cholesky factorisation
    (solved through its eigen-decomposition instead; the caller reports it).
    """
    N, n = x_f.shape
    ws = workspace(model)
    Ps = P_last.copy()
    with_cov = Ps.shape[0] > 0
    if not with_cov and not mean_only_pass(model):
        raise ValueError("this model has no mean-only backward pass "
                         "(estimation.model.with_mean_only_pass)")
    work = (np.empty((n, n)), rts_step_work(n), np.empty((n, n)), np.empty(n), np.empty(n),
            np.empty(n))
    n_fallback = 0
    for i in range(n):
        x_s[N - 1, i] = x_f[N - 1, i]
    for k in range(N - 1, -1, -1):
        if k < N - 1:
            if not smoothed_step(model, k, x_f, x_p, x_s, Ps, ws, work):
                n_fallback += 1
        keep_smoothed(model, k, x_s[k], Ps, with_cov, ws)
    return n_fallback


@dataclass(frozen=True)
class SmoothedRun:
    """A smoothed run of any method: state ``x`` (N, n), covariance ``P`` (N, n, n), and the
    number of ``cholesky_fallbacks`` (steps whose predicted covariance failed its
    factorisation; reported, never silent)."""

    x: np.ndarray
    P: np.ndarray
    cholesky_fallbacks: int = 0
