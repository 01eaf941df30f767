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

The prediction and the update are the estimation core's
(:func:`flightrecon.estimation.predict.predict`,
:func:`flightrecon.estimation.updates.joseph_update`); the backward pass is
:func:`flightrecon.estimation.smoother.rts_smooth`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from flightrecon.estimation.predict import predict
from flightrecon.estimation.updates import joseph_update


@dataclass(frozen=True)
class FilterRun:
    """A forward filter run: everything the backward pass and the diagnostics need.

    ``x_pred``/``P_pred`` are the one-step predictions (``x_pred[0] = x0``), ``x``/``P`` the
    filtered estimates, ``F`` the transitions used, ``nu`` the innovations (NaN where no
    measurement), ``S`` their covariances, ``nis`` the normalised innovation squared per step
    and ``n_meas`` the number of measurement components used per step.
    """

    x: np.ndarray
    P: np.ndarray
    x_pred: np.ndarray
    P_pred: np.ndarray
    F: np.ndarray
    nu: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    n_meas: np.ndarray


@nb.njit(cache=True, nogil=True)
def _kf_kernel(x0, P0, F, Q, z, H, R):
    N = z.shape[0]
    n = x0.shape[0]
    m = z.shape[1]
    xs = np.empty((N, n))
    Ps = np.empty((N, n, n))
    xp = np.empty((N, n))
    Pp = np.empty((N, n, n))
    nus = np.full((N, m), np.nan)
    Ss = np.full((N, m, m), np.nan)
    nis = np.full(N, np.nan)
    nmeas = np.zeros(N, dtype=np.int64)
    x = x0.copy()
    P = P0.copy()
    for k in range(N):
        if k > 0:
            x, P = predict(x, P, F[k], Q[k])
        xp[k] = x
        Pp[k] = P
        idx = np.empty(m, dtype=np.int64)
        c = 0
        for i in range(m):
            if not np.isnan(z[k, i]):
                idx[c] = i
                c += 1
        if c > 0:
            Hk = np.empty((c, n))
            Rk = np.empty((c, c))
            nu = np.empty(c)
            for a in range(c):
                Hk[a] = H[k, idx[a]]
                for b in range(c):
                    Rk[a, b] = R[k, idx[a], idx[b]]
            for a in range(c):
                nu[a] = z[k, idx[a]] - Hk[a] @ x
            x, P, S, nis[k] = joseph_update(x, P, nu, Hk, Rk)
            nmeas[k] = c
            for a in range(c):
                nus[k, idx[a]] = nu[a]
                for b in range(c):
                    Ss[k, idx[a], idx[b]] = S[a, b]
        xs[k] = x
        Ps[k] = P
    return xs, Ps, xp, Pp, nus, Ss, nis, nmeas


def _stack(a: np.ndarray, N: int, shape: tuple[int, ...]) -> np.ndarray:
    a = np.asarray(a, dtype=np.float64)
    if a.shape == shape:
        a = np.broadcast_to(a, (N, *shape))
    if a.shape != (N, *shape):
        raise ValueError(f"expected shape {(N, *shape)} or {shape}, got {a.shape}")
    return np.ascontiguousarray(a)


def kalman_filter(x0, P0, F, Q, z, H, R) -> FilterRun:
    """Run the linear Kalman filter over all steps (see module docstring for shapes).

    ``F``, ``Q``, ``H``, ``R`` may be given once (constant) or stacked per step.
    """
    z = np.ascontiguousarray(np.asarray(z, dtype=np.float64))
    if z.ndim == 1:
        z = z[:, None]
    N, m = z.shape
    x0 = np.ascontiguousarray(np.asarray(x0, dtype=np.float64))
    n = x0.shape[0]
    P0 = np.ascontiguousarray(np.asarray(P0, dtype=np.float64))
    if P0.shape != (n, n):
        raise ValueError(f"P0 must be {(n, n)}, got {P0.shape}")
    F = _stack(F, N, (n, n))
    Q = _stack(Q, N, (n, n))
    H = _stack(H, N, (m, n))
    R = _stack(R, N, (m, m))
    out = _kf_kernel(x0, P0, F, Q, z, H, R)
    xs, Ps, xp, Pp, nus, Ss, nis, nmeas = out
    return FilterRun(xs, Ps, xp, Pp, F, nus, Ss, nis, nmeas)


__all__ = ["FilterRun", "joseph_update", "kalman_filter", "predict"]
