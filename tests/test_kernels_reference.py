"""Every filter/smoother implementation against one reference on a linear case.

The reference is exact Gaussian conditioning of the whole trajectory at once: the prior on the
first state, the transitions and the measurements form one quadratic in all states; its
minimiser is the smoothed mean and the inverse of its Hessian (the information matrix) holds
the smoothed covariances.  Any correct forward filter plus RTS smoother reproduces it to
rounding, whatever its order of operations (Stone Soup runs its smoothers against common
reference vectors the same way).

Covered: the generic linear filter (``filters/kalman.py`` + ``smoothing/rts.py``), the azimuth
channel's kernel (Singer model, azimuth plots only: linear), the ADS/ARMS kernel (joint model,
air-data velocity only: linear) and the estimation core's pieces composed by hand (dense
predict, scalar short-form update).  The SNS and joint kernels are nonlinear; they are checked
against brute-force conditioning and finite differences in their own tests
(``test_sns_models.py``, ``test_joint_models.py``).
"""

import numpy as np
import pytest

from flightrecon.estimation.discretise import singer_process_noise, singer_transition
from flightrecon.estimation.predict import predict
from flightrecon.estimation.updates import scalar_update_short
from flightrecon.filters.kalman import kalman_filter
from flightrecon.smoothing.rts import rts_smooth, rts_smooth_run


def batch_reference(x0, P0, F, Q, z, H, R):
    """Smoothed means (N, n) and covariances (N, n, n) by solving the information system.

    ``z`` (N, m) with NaN where absent, ``H`` (m, n), ``R`` (N, m) diagonal variances.
    """
    N, n = F.shape[0], x0.size
    Lam = np.zeros((N * n, N * n))
    eta = np.zeros(N * n)
    P0i = np.linalg.inv(P0)
    Lam[:n, :n] += P0i
    eta[:n] += P0i @ x0
    for k in range(1, N):
        Qi = np.linalg.inv(Q[k])
        a, b = slice((k - 1) * n, k * n), slice(k * n, (k + 1) * n)
        Lam[a, a] += F[k].T @ Qi @ F[k]
        Lam[a, b] -= F[k].T @ Qi
        Lam[b, a] -= Qi @ F[k]
        Lam[b, b] += Qi
    for k in range(N):
        b = slice(k * n, (k + 1) * n)
        for i in range(z.shape[1]):
            if np.isfinite(z[k, i]):
                h = H[i]
                Lam[b, b] += np.outer(h, h) / R[k, i]
                eta[b] += h * z[k, i] / R[k, i]
    cov = np.linalg.inv(Lam)
    mean = cov @ eta
    return mean.reshape(N, n), np.stack([cov[k * n:(k + 1) * n, k * n:(k + 1) * n]
                                         for k in range(N)])


@pytest.fixture(scope="module")
def singer_case():
    """A 3-state Singer target, 40 uneven steps, scalar position plots at 30 of them."""
    rng = np.random.default_rng(8)
    T = np.r_[0.0, rng.uniform(0.5, 2.0, 39)]
    F = singer_transition(0.1, T)
    Q = singer_process_noise(0.1, 0.02, T)
    Q[0] = np.eye(3)  # unused (no step into the first epoch)
    x0 = np.array([0.3, 0.01, 0.0])
    P0 = np.diag([1e-4, 1e-4, 1e-5])
    z = 0.3 + 0.01 * np.cumsum(T) + 1e-3 * rng.standard_normal(40)
    z[rng.choice(40, 10, replace=False)] = np.nan
    R = np.full((40, 1), 1e-6)
    ref = batch_reference(x0, P0, F, Q, z[:, None], np.array([[1.0, 0.0, 0.0]]), R)
    return x0, P0, F, Q, z, R, ref


def _check(xs, Ps, ref, tol=1e-9):
    mean, cov = ref
    sd = np.sqrt(np.diagonal(cov, axis1=1, axis2=2))
    np.testing.assert_allclose((xs - mean) / sd, 0.0, atol=tol)
    np.testing.assert_allclose(Ps / (sd[:, :, None] * sd[:, None, :]),
                               cov / (sd[:, :, None] * sd[:, None, :]), atol=tol)


def test_generic_filter_and_rts(singer_case):
    x0, P0, F, Q, z, R, ref = singer_case
    run = kalman_filter(x0, P0, F, Q, z[:, None], np.array([[1.0, 0.0, 0.0]]),
                        R[:, :, None])
    sm = rts_smooth_run(run)
    _check(sm.x, sm.P, ref)


def test_azimuth_kernel(singer_case):
    from flightrecon.filters.azimuth.filter import _azimuth_kernel

    x0, P0, F, Q, z, R, ref = singer_case
    N = len(z)
    out = _azimuth_kernel(x0, P0, F, Q, z, R[:, 0], np.full((N, 2), np.nan),
                          np.zeros((N, 2, 2)), np.zeros((N, 2, 2)), np.full(N, 1e4),
                          np.zeros(N), np.zeros((N, 2, 2)), 1.0)
    xf, Pf, xp, Pp = out[:4]
    sm = rts_smooth(xf, Pf, xp, Pp, F)
    _check(sm.x, sm.P, ref)


def test_core_pieces_composed(singer_case):
    """Dense predict and the scalar short-form update of the estimation core, then RTS."""
    x0, P0, F, Q, z, R, ref = singer_case
    N, n = len(z), 3
    xf, Pf = np.empty((N, n)), np.empty((N, n, n))
    xp, Pp = np.empty((N, n)), np.empty((N, n, n))
    x, P = x0.copy(), P0.copy()
    for k in range(N):
        if k > 0:
            x, P = predict(x, P, F[k], Q[k])
        xp[k], Pp[k] = x, P
        if np.isfinite(z[k]):
            x, P = x.copy(), P.copy()
            PH = P[:, 0].copy()
            scalar_update_short(x, P, PH, z[k] - x[0], PH[0] + R[k, 0])
        xf[k], Pf[k] = x, P
    sm = rts_smooth(xf, Pf, xp, Pp, F)
    _check(sm.x, sm.P, ref, tol=1e-8)


def test_arms_kernel_on_its_linear_part():
    """The ADS/ARMS joint model [x, Vx, y, Vy, dVx, dVy] with the air-data velocity
    V* = V + dV as its only measurement (linear), against the same reference."""
    from flightrecon.filters.arms import joint_process_noise, joint_transition
    from flightrecon.filters.arms.filter import _arms_kernel

    rng = np.random.default_rng(4)
    N = 30
    dt = np.r_[0.0, rng.uniform(0.5, 1.5, N - 1)]
    F = joint_transition(dt, 1 / 360.0)
    Q = joint_process_noise(dt, 0.05, 1 / 360.0, 20.0)
    Q[0] = np.eye(6)
    x0 = np.array([1e3, 100.0, -2e3, 5.0, 3.0, -2.0])
    P0 = np.diag([100.0, 5.0, 100.0, 5.0, 20.0, 20.0]) ** 2
    air = np.column_stack([100.0 + rng.normal(0, 1, N), 5.0 + rng.normal(0, 1, N)])
    air[rng.choice(N, 6, replace=False)] = np.nan
    Rv = 0.3 ** 2 * np.eye(2)
    out = _arms_kernel(x0, P0, F, Q, np.full((N, 2), np.nan), np.ones((N, 2)), air, Rv, 0)
    sm = rts_smooth(out[0], out[1], out[2], out[3], F)
    H = np.zeros((2, 6))
    H[0, 1] = H[0, 4] = H[1, 3] = H[1, 5] = 1.0
    # the positions are observed only through their prior (P0) and the velocity chain, so the
    # reference's information matrix is ill-conditioned (condition number 1.5e9 here): its own
    # rounding is about 1.5e9 x 1e-16 = 1.5e-7 of a standard deviation, hence 1e-6
    ref = batch_reference(x0, P0, F, Q, air, H, np.full((N, 2), 0.3 ** 2))
    _check(sm.x, sm.P, ref, tol=1e-6)
