"""Linear Kalman filter on stacked, time-major arrays (compiled with numba).

Shapes: ``N`` steps, state dimension ``n``, measurement dimension ``m``.

* ``F`` (N, n, n): ``F[k]`` takes the state from step k-1 to step k (``F[0]`` unused).
* ``Q`` (N, n, n): process-noise covariance added on that step (``Q[0]`` unused).
* ``z`` (N, m): measurements; NaN components are absent at that step (each measurement is used
  once, at its own step).
* ``H`` (N, m, n), ``R`` (N, m, m).

Equations (filterpy / Bar-Shalom notation)::

    x_k^- = F_k x_{k-1}^+,           P_k^- = F_k P_{k-1}^+ F_k^T + Q_k
    S = H P^- H^T + R,               K = P^- H^T S^{-1}
    x^+ = x^- + K (z - H x^-),       P^+ = (I - K H) P^- (I - K H)^T + K R K^T   (Joseph)

The linear-Gaussian model on the core's loops: :class:`LinearModel` supplies the prediction
and the update (the estimation core's :func:`flightrecon.estimation.predict.predict` and
:func:`flightrecon.estimation.updates.joseph_update`) to
:func:`flightrecon.estimation.filtering.forward_pass`, and ``C^T = F_{k+1} P_k`` to
:func:`flightrecon.estimation.smoothing.backward_pass`; :func:`kalman_filter` and
:func:`rts_smooth` are the array front ends.

Backward (Rauch, Tung & Striebel 1965; Simon, *Optimal State Estimation*, 2006, section 9.4)::

    G_k   = P_k F_{k+1}^T (P_{k+1}^-)^{-1}
    x_k^s = x_k + G_k (x_{k+1}^s - x_{k+1}^-)
    P_k^s = P_k + G_k (P_{k+1}^s - P_{k+1}^-) G_k^T
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from flightrecon.estimation.filtering import FilterRun, forward_pass, keep_dense_into
from flightrecon.estimation.linalg import mm_into
from flightrecon.estimation.manifold import EUCLIDEAN
from flightrecon.estimation.model import (
    cross_times_into,
    cross_transposed_into,
    implements,
    keep_filtered,
    keep_predicted,
    keep_smoothed,
    predict_into,
    rts_frame,
    smoothing_covariances,
    update_into,
    with_mean_only_pass,
    workspace,
)
from flightrecon.estimation.predict import predict, predict_in_place
from flightrecon.estimation.smoothing import SmoothedRun, backward_pass
from flightrecon.estimation.updates import joseph_update


@with_mean_only_pass
class LinearModel(NamedTuple):
    """A linear-Gaussian model on stacked arrays (module docstring for the shapes) and the
    buffers of its run: filtered ``x_f``, ``P_f``, predicted ``x_p``, ``P_p``, innovations
    ``nu`` (NaN where absent), their covariances ``S``, ``nis`` and ``n_meas`` per step, and
    the smoothed covariances ``P_s`` (N, n, n) (empty (0, n, n) in a forward run)."""


    F: np.ndarray
    Q: np.ndarray
    z: np.ndarray
    H: np.ndarray
    R: np.ndarray
    x_f: np.ndarray
    P_f: np.ndarray
    x_p: np.ndarray
    P_p: np.ndarray
    nu: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    n_meas: np.ndarray
    P_s: np.ndarray


@implements(workspace, LinearModel)
def _workspace(model):
    return np.empty(model.z.shape[1], dtype=np.int64)  # indices of the step's measurements


@implements(predict_into, LinearModel)
def _predict(model, k, x, P, ws):
    predict_in_place(x, P, model.F[k], model.Q[k])


@implements(keep_predicted, LinearModel, refcounted=False)
def _keep_predicted(model, k, x, P):
    keep_dense_into(model.x_p, model.P_p, k, x, P)


@implements(update_into, LinearModel)
def _update(model, k, x, P, ws):
    """Block Joseph update with the step's measurement components that are present."""
    z = model.z
    m = z.shape[1]
    n = x.shape[0]
    idx = ws
    c = 0
    for i in range(m):
        if not np.isnan(z[k, i]):
            idx[c] = i
            c += 1
    if c == 0:
        return
    Hk = np.empty((c, n))
    Rk = np.empty((c, c))
    nu = np.empty(c)
    for a in range(c):
        Hk[a] = model.H[k, idx[a]]
        for b in range(c):
            Rk[a, b] = model.R[k, idx[a], idx[b]]
    for a in range(c):
        nu[a] = z[k, idx[a]] - Hk[a] @ x
    xu, Pu, S, model.nis[k] = joseph_update(x, P, nu, Hk, Rk)
    x[:] = xu
    P[:, :] = Pu
    model.n_meas[k] = c
    for a in range(c):
        model.nu[k, idx[a]] = nu[a]
        for b in range(c):
            model.S[k, idx[a], idx[b]] = S[a, b]


@implements(keep_filtered, LinearModel, refcounted=False)
def _keep_filtered(model, k, x, P):
    keep_dense_into(model.x_f, model.P_f, k, x, P)


@implements(smoothing_covariances, LinearModel)
def _smoothing_covariances(model, k, ws):
    return model.P_f[k], model.P_p[k + 1]


@implements(cross_transposed_into, LinearModel)
def _cross_transposed(model, k, CT, ws):
    mm_into(model.F[k + 1], model.P_f[k], CT)  # C^T = F_{k+1} P_k


@implements(cross_times_into, LinearModel)
def _cross_times(model, k, y, out, ws):
    # C y = P_k F_{k+1}^T y
    Fy = model.F[k + 1].T @ y
    out[:] = model.P_f[k] @ Fy


@implements(rts_frame, LinearModel)
def _rts_frame(model, k):
    return EUCLIDEAN, 0.0, 0.0, 0.0


@implements(keep_smoothed, LinearModel)
def _keep_smoothed(model, k, x, P, with_cov, ws):
    if with_cov:
        model.P_s[k] = P


def _stack(a: np.ndarray, N: int, shape: tuple[int, ...]) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.shape == shape:
        a = np.broadcast_to(a, (N, *shape))
    if a.shape != (N, *shape):
        raise ValueError(f"expected shape {(N, *shape)} or {shape}, got {a.shape}")
    return np.ascontiguousarray(a)


def _c(a) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a, dtype=np.float64))


def kalman_filter(x0, P0, F, Q, z, H, R) -> FilterRun:
    """Run the linear Kalman filter over all steps (see module docstring for shapes).

    ``F``, ``Q``, ``H``, ``R`` may be given once (constant) or stacked per step.  Returns the
    core's :class:`~flightrecon.estimation.filtering.FilterRun` with the diagnostics ``F``,
    ``nu``, ``S``, ``nis`` and ``n_meas``.
    """
    z = _c(z)
    if z.ndim == 1:
        z = z[:, None]
    N, m = z.shape
    x0 = _c(x0)
    n = x0.shape[0]
    P0 = _c(P0)
    if P0.shape != (n, n):
        raise ValueError(f"P0 must be {(n, n)}, got {P0.shape}")
    model = LinearModel(_stack(F, N, (n, n)), _stack(Q, N, (n, n)), z, _stack(H, N, (m, n)),
                        _stack(R, N, (m, m)), np.empty((N, n)), np.empty((N, n, n)),
                        np.empty((N, n)), np.empty((N, n, n)), np.full((N, m), np.nan),
                        np.full((N, m, m), np.nan), np.full(N, np.nan),
                        np.zeros(N, dtype=np.int64), np.empty((0, n, n)))
    forward_pass(model, x0, P0, N)
    return FilterRun(model.x_f, model.P_f, model.x_p, model.P_p,
                     {"F": model.F, "nu": model.nu, "S": model.S, "nis": model.nis,
                      "n_meas": model.n_meas}, model)


def rts_smooth(x, P, x_pred, P_pred, F) -> SmoothedRun:
    """Backward RTS pass over a linear forward run given as arrays (module docstring)."""
    x, P, x_pred, P_pred, F = (_c(a) for a in (x, P, x_pred, P_pred, F))
    N, n = x.shape
    empty = np.empty((0, 0))
    model = LinearModel(F, empty.reshape(0, 0, 0), empty, empty.reshape(0, 0, 0),
                        empty.reshape(0, 0, 0), x, P, x_pred, P_pred, empty,
                        empty.reshape(0, 0, 0), np.empty(0), np.empty(0, dtype=np.int64),
                        np.empty((N, n, n)))
    model.P_s[N - 1] = P[N - 1]
    xs = np.empty((N, n))
    n_fallback = backward_pass(model, x, x_pred, xs, P[N - 1])
    return SmoothedRun(xs, model.P_s, int(n_fallback))


def rts_smooth_run(run: FilterRun) -> SmoothedRun:
    """Smooth a :class:`~flightrecon.estimation.filtering.FilterRun` of :func:`kalman_filter`
    (or any run with the diagnostic ``F``)."""
    return rts_smooth(run.x, run.P, run.x_pred, run.P_pred, run.diagnostics["F"])


__all__ = ["FilterRun", "LinearModel", "SmoothedRun", "joseph_update", "kalman_filter",
           "predict", "rts_smooth", "rts_smooth_run"]
