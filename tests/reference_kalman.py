"""A plain numpy Kalman filter and RTS smoother: the one reference every implementation is
compared with (``tests/test_kernels_reference.py``).

Written as in the textbooks (Simon 2006, eqs. 5.19 and 9.126-9.128; filterpy's ``update`` and
``rts_smoother``), with dense matrices, ``np.linalg.solve`` and no symmetrisation, so that it
shares no code and no order of operations with the package: the estimation core (Cholesky
solves, loop products, Joseph form, sparse rows) agrees with it only if both compute the same
equations.  Also a brute-force predictor for noise correlated across the update and the
prediction (Gaussian conditioning of the stacked linear system), the reference of
:func:`flightrecon.estimation.updates.correlated_noise_predict_into`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class ReferenceRun:
    """Filtered ``xf``/``Pf``, predicted ``xp``/``Pp`` (``xp[0] = x0``) and smoothed
    ``xs``/``Ps``, time first."""

    xf: np.ndarray
    Pf: np.ndarray
    xp: np.ndarray
    Pp: np.ndarray
    xs: np.ndarray
    Ps: np.ndarray


def kalman_rts(x0, P0, F, Q, z, H, R) -> ReferenceRun:
    """Kalman filter then RTS smoother on a linear model.

    ``F``, ``Q`` (N, n, n) (index 0 unused: no step into the first epoch), ``z`` (N, m) with
    NaN for an absent component, ``H`` (m, n), ``R`` (N, m) diagonal variances.  The present
    components of a step are used together (one vector update, standard form
    ``P+ = (I - K H) P``).
    """
    N, n = z.shape[0], len(x0)
    xf, Pf = np.empty((N, n)), np.empty((N, n, n))
    xp, Pp = np.empty((N, n)), np.empty((N, n, n))
    x, P = np.array(x0, float), np.array(P0, float)
    for k in range(N):
        if k > 0:
            x = F[k] @ x
            P = F[k] @ P @ F[k].T + Q[k]
        xp[k], Pp[k] = x, P
        ok = np.isfinite(z[k])
        if ok.any():
            Hk = H[ok]
            S = Hk @ P @ Hk.T + np.diag(R[k, ok])
            K = np.linalg.solve(S, Hk @ P).T
            x = x + K @ (z[k, ok] - Hk @ x)
            P = (np.eye(n) - K @ Hk) @ P
        xf[k], Pf[k] = x, P
    xs, Ps = xf.copy(), Pf.copy()
    for k in range(N - 2, -1, -1):
        C = Pf[k] @ F[k + 1].T @ np.linalg.inv(Pp[k + 1])
        xs[k] = xf[k] + C @ (xs[k + 1] - xp[k + 1])
        Ps[k] = Pf[k] + C @ (Ps[k + 1] - Pp[k + 1]) @ C.T
    return ReferenceRun(xf, Pf, xp, Pp, xs, Ps)


def constant_velocity_case(seed: int = 3, N: int = 60, q: float = 0.5, r_sd: float = 3.0):
    """A 2-D constant-velocity target ``[px, vx, py, vy]`` with position measurements.

    Uneven steps 0.5-2 s, white acceleration of spectral density ``q`` [m^2/s^3] per axis,
    position plots of sd ``r_sd`` [m] with each component missing at random (a quarter of
    them).  Returns ``x0, P0, F, Q, z, H, R``.
    """
    rng = np.random.default_rng(seed)
    dt = np.r_[0.0, rng.uniform(0.5, 2.0, N - 1)]
    F = np.zeros((N, 4, 4))
    Q = np.zeros((N, 4, 4))
    for k, T in enumerate(dt):
        f = np.array([[1.0, T], [0.0, 1.0]])
        qq = q * np.array([[T**3 / 3, T**2 / 2], [T**2 / 2, T]])
        F[k] = np.kron(np.eye(2), f)
        Q[k] = np.kron(np.eye(2), qq)
    Q[0] = np.eye(4)  # unused
    x0 = np.array([0.0, 50.0, 0.0, -20.0])
    P0 = np.diag([100.0, 25.0, 100.0, 25.0])
    truth = np.empty((N, 4))
    x = x0 + np.sqrt(np.diag(P0)) * rng.standard_normal(4)
    for k in range(N):
        if k > 0:
            x = F[k] @ x + np.linalg.cholesky(Q[k]) @ rng.standard_normal(4)
        truth[k] = x
    H = np.array([[1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0]])
    z = truth @ H.T + r_sd * rng.standard_normal((N, 2))
    z[rng.random((N, 2)) < 0.25] = np.nan
    R = np.full((N, 2), r_sd**2)
    return x0, P0, F, Q, z, H, R


def correlated_one_step(x0, P0, F, B, H, G, Rd, z):
    """Brute-force one-step predictions with correlated noise.

    Model ``x_{k+1} = F x_k + B w_k``, ``z_k = H x_k + G w_k + D v_k`` (``w_k``, ``v_k`` unit
    white, ``D D^T = diag(Rd)``, ``x_0 ~ N(x0, P0)``): every state and measurement is linear in
    ``(x_0, w_0.., v_0..)``, so ``E[x_{k+1} | z_0..z_k]`` and its covariance are plain
    Gaussian conditioning of the stacked system.  Returns the means (N, n) and covariances
    (N, n, n) of ``x_{k+1}`` given ``z_0..z_k`` for ``k = 0 .. N-1``.
    """
    N, m = z.shape
    n, nw = B.shape
    dim = n + N * nw + N * m  # the independent standard-normal-ish inputs
    cov_u = np.zeros((dim, dim))
    cov_u[:n, :n] = P0
    cov_u[n:, n:] = np.eye(dim - n)
    mean_u = np.zeros(dim)
    mean_u[:n] = x0
    # x_k = Ax[k] u
    Ax = [np.zeros((n, dim))]
    Ax[0][:, :n] = np.eye(n)
    Az = []
    for k in range(N):
        w = slice(n + k * nw, n + (k + 1) * nw)
        v = slice(n + N * nw + k * m, n + N * nw + (k + 1) * m)
        a = H @ Ax[k]
        a[:, w] += G
        a[:, v] += np.diag(np.sqrt(Rd))
        Az.append(a)
        nxt = F @ Ax[k]
        nxt[:, w] += B
        Ax.append(nxt)
    means, covs = np.empty((N, n)), np.empty((N, n, n))
    for k in range(N):
        Zk = np.vstack(Az[:k + 1])
        Xk = Ax[k + 1]
        Szz = Zk @ cov_u @ Zk.T
        Sxz = Xk @ cov_u @ Zk.T
        gain = np.linalg.solve(Szz, Sxz.T).T
        means[k] = Xk @ mean_u + gain @ (z[:k + 1].ravel() - Zk @ mean_u)
        covs[k] = Xk @ cov_u @ Xk.T - gain @ Sxz.T
    return means, covs
