"""The joint smoother's forward filter and RTS backward passes: its model
(:class:`~flightrecon.methods.joint.model.JointModel`) on the estimation core's loops,
:func:`~flightrecon.estimation.filtering.forward_pass` and
:func:`~flightrecon.estimation.smoothing.backward_pass` (docs/joint.md, "Filter, smoother,
iterations"; docs/estimation.md, "The joint model").

The front ends take the filter buffers and the pass's layouts and return the outputs as
arrays: :func:`forward` the innovations, :func:`backward` the smoothed states and covariance
blocks with the residuals, :func:`backward_mean` the smoothed states and residuals of the
mean-only pass.  Both backward passes run with the GIL released (the core's loops are
``nogil``), so the covariance pass can run on a second thread beside the mean pass.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

import numpy as np

from flightrecon.estimation.filtering import forward_pass
from flightrecon.estimation.linalg import packed_size, unpack_sym
from flightrecon.estimation.smoothing import backward_pass
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.layout import N_STATE, Dynamics, Geometry, Scalars
from flightrecon.methods.joint.model import joint_model


def filter_buffers(N: int, store_predicted: bool = True) -> tuple[np.ndarray, ...]:
    """Outputs of :func:`forward` for N steps: ``xf`` (N, n), ``Pf`` (N, n (n + 1) / 2),
    ``xp``, ``Pp`` (the covariances as packed lower triangles, :func:`~flightrecon.estimation.
    linalg.pack_sym`: half the memory, 190 MB less on a 10-hour flight at 1 Hz; an empty ``Pp``
    without ``store_predicted``: recomputed backward, bit-identical, 0.2-0.3 s more per pass on
    that flight)."""
    n = N_STATE
    L = packed_size(n)
    return (np.empty((N, n)), np.empty((N, L)), np.empty((N, n)),
            np.empty((N if store_predicted else 0, L)))


def forward(xf: np.ndarray, Pf: np.ndarray, xp: np.ndarray, Pp: np.ndarray, x0: np.ndarray,
            P0: np.ndarray, dyn: Dynamics, meas: Scalars, geo: Geometry, gate: float,
            xlin: np.ndarray, clock: tuple[np.ndarray, np.ndarray] | None = None
            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, tuple[np.ndarray, ...]]:
    """Forward extended Kalman filter with sequential scalar updates (the model's
    ``predict_into`` and ``update_into``, :mod:`~flightrecon.methods.joint.model`).

    With ``xlin`` (N, n) the measurements are linearised about it (the smoothed states of the
    last pass: an iterated extended Kalman smoother, Gauss-Newton on the whole record); with an
    empty ``xlin`` (0, n) about the filter's own prediction (the first pass).  ``gate`` (0: off)
    the normalised innovation beyond which a measurement's variance is inflated.

    Fills ``xf``, ``Pf``, ``xp``, ``Pp`` (:func:`filter_buffers`; an empty ``Pp`` is not filled:
    the backward passes then recompute each predicted covariance, bit for bit the same) and
    returns, per measurement, the innovation, its variance (before inflation) and the inflation
    factor (NaN, NaN, 1 for a measurement of weight 0), and the clock offsets' outputs when
    ``clock`` gives each measurement's clock column (0 GNSS, 1 radar, -1 none) and the rate of
    its prediction the gradient does not give: the normal equations of their Gauss-Newton
    step (A00, A01, A11, b0, b1: :func:`~flightrecon.methods.joint.model.
    _clock_column_update`) and their filter columns after and before each step's updates
    (2, N, n) (None: empty arrays).
    """
    model = joint_model((xf, Pf, xp, Pp), dyn, meas, geo, gate, xlin, forward=True,
                        clock=clock)
    forward_pass(model, x0, P0, xf.shape[0])
    return model.nu, model.S, model.infl, (model.cnorm, model.cxf, model.cxp)


def _backward(bufs: tuple[np.ndarray, ...], dyn: Dynamics, meas: Scalars, geo: Geometry,
              with_cov: bool, residuals: bool) -> tuple[np.ndarray, Any, int]:
    xf, Pf, xp, Pp = bufs
    N, n = xf.shape
    model = joint_model(bufs, dyn, meas, geo, residuals=residuals, covariances=with_cov)
    xs = np.empty((N, n))
    P_last = np.empty((n, n))
    unpack_sym(Pf[N - 1], P_last)
    n_fallback = backward_pass(model, xf, xp, xs, P_last if with_cov else np.empty((0, 0)))
    return xs, model, int(n_fallback)


def smoothed_columns(cxf: np.ndarray, cxp: np.ndarray, Pf: np.ndarray, Pp: np.ndarray,
                     dyn: Dynamics, meas: Scalars, geo: Geometry) -> np.ndarray:
    """The clock offsets' smoothed columns X_s,g (2, N, n) from their filtered and predicted
    ones (:func:`forward`'s, the same pass's ``Pf``, ``Pp``): the mean-only RTS recursion
    x_s[k] = x_f[k] + C (x_s[k+1] - x_p[k+1]) is linear in (x_f, x_p) with no input of its
    own, so on the columns it gives d x_s / d c up to sign: the track moved by an offset
    error dc is x_s - X_s,g dc, and an offset of covariance Sigma adds X_s,g Sigma X_s,g^T to
    the track's (the marginal covariance of the state augmented by the constant offsets)."""
    out = np.empty_like(cxf)
    for c in range(cxf.shape[0]):
        out[c] = _backward((cxf[c], Pf, cxp[c], Pp), dyn, meas, geo, False, False)[0]
    return out


def backward_mean(xf: np.ndarray, Pf: np.ndarray, xp: np.ndarray, Pp: np.ndarray,
                  dyn: Dynamics, meas: Scalars, geo: Geometry
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, int]:
    """RTS backward pass for the smoothed states only (no covariances), and the residuals.

    x_s[k] = x_f[k] + P_f[k] F_{k+1}^T P_p[k+1]^{-1} (x_s[k+1] - x_p[k+1]): the same smoothed
    mean as :func:`backward` (Rauch, Tung & Striebel 1965) at O(n^3 / 6) per step (one Cholesky
    solve with a vector) instead of O(n^3) products; used in the Gauss-Newton iterations, which
    need the trajectory and the residuals but not the smoothed covariances.

    Returns smoothed states, normalised residuals, raw residuals and rates (as :func:`backward`)
    and the number of steps whose predicted covariance failed its Cholesky factorisation (not
    positive definite to rounding: the gain then comes from the eigen-decomposition solve; the
    caller reports the count).
    """
    xs, m, n_fallback = _backward((xf, Pf, xp, Pp), dyn, meas, geo, False, True)
    return xs, m.res_n, m.res, m.rate, n_fallback


def backward(xf: np.ndarray, Pf: np.ndarray, xp: np.ndarray, Pp: np.ndarray, dyn: Dynamics,
             meas: Scalars, geo: Geometry, residuals: bool) -> tuple[Any, ...]:
    """RTS backward pass with covariances; also the smoothed residuals (see
    :func:`backward_mean`, which gives the same states without the covariances).

    Returns smoothed states, the smoothed position-velocity covariance block (N, 6, 6), the
    smoothed state variances (N, n), normalised residuals, raw residuals, rates and, per
    measurement, H P_s H^T (the smoothed variance of the predicted measurement), and the number
    of Cholesky failures (as :func:`backward_mean`).  With ``residuals`` False the residual
    outputs stay NaN (the covariances do not need them: this pass can then run beside
    :func:`backward_mean` on another thread).
    """
    xs, m, n_fallback = _backward((xf, Pf, xp, Pp), dyn, meas, geo, True, residuals)
    M = len(meas.mtype)
    if residuals:
        res_n, res, rate, hph = m.res_n, m.res, m.rate, m.hph
    else:
        res_n, res, rate, hph = (np.full(M, np.nan) for _ in range(4))
    return xs, m.Pblk, m.var, res_n, res, rate, hph, n_fallback


class BackgroundCovariances:
    """The RTS covariance pass (:func:`backward`, without the residuals) of the filter
    buffers ``bufs`` = (xf, Pf, xp, Pp) and the pass's layouts, started on a second thread to
    run beside the mean pass (:func:`backward_mean`) and whatever follows it until the
    covariances or the buffers are needed; :meth:`result` waits for it."""

    def __init__(self, bufs: tuple[np.ndarray, ...], dyn: Dynamics, meas: Scalars,
                 geo: Geometry) -> None:
        self.out: tuple[Any, ...] | None = None
        self.error: BaseException | None = None
        self.thread = threading.Thread(target=self._run, args=(bufs, dyn, meas, geo),
                                       name="joint-covariances")
        self.thread.start()

    def _run(self, bufs: tuple[np.ndarray, ...], dyn: Dynamics, meas: Scalars,
             geo: Geometry) -> None:
        try:
            xf, Pf, xp, Pp = bufs
            self.out = backward(xf, Pf, xp, Pp, dyn, meas, geo, False)
        except BaseException as exc:  # re-raised on the thread that waits for it
            self.error = exc

    def result(self) -> tuple[np.ndarray, np.ndarray, int]:
        """(Pblk, var, Cholesky fallbacks) of the pass, once the thread has finished."""
        self.thread.join()
        if self.error is not None:
            raise self.error
        assert self.out is not None
        _, Pblk, var, *_, n_fallback = self.out
        return Pblk, var, int(n_fallback)


@dataclass
class PassResult:
    """Outputs of one forward filter and backward smoother pass."""

    xs: np.ndarray
    xf: np.ndarray
    res: np.ndarray
    rate: np.ndarray
    hph: np.ndarray | None
    infl: np.ndarray
    innov: np.ndarray
    innov_var: np.ndarray
    Pblk: np.ndarray | None
    var: np.ndarray | None
    n_fallback: int
    kern_args: tuple[Any, ...]
    scalars: jl.Scalars
    pending: BackgroundCovariances | None = None  # its covariance pass, still on its thread
    #                                               (Pblk and var None until joined)
    info: dict[str, Any] | None = None   # the pass's entry in the iterations
    # the clock columns and rates of its forward pass, and the offsets' outputs of it (normal
    # equations, filter columns after and before each step's updates: passes.forward)
    clock: tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, ...]] | None = None
