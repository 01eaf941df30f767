"""Every filter/smoother implementation against one reference on a linear case.

The reference is exact Gaussian conditioning of the whole trajectory at once: the prior on the
first state, the transitions and the measurements form one quadratic in all states; its
minimiser is the smoothed mean and the inverse of its Hessian (the information matrix) holds
the smoothed covariances.  Any correct forward filter plus RTS smoother reproduces it to
rounding, whatever its order of operations (Stone Soup runs its smoothers against common
reference vectors the same way).

Two references:

* exact batch conditioning (:func:`batch_reference`) on a Singer target, as before;
* the plain numpy Kalman filter + RTS smoother of ``tests/reference_kalman.py`` on a 2-D
  constant-velocity target with position plots (the Stone Soup-style comparison: every
  implementation against one reference, filtered, predicted and smoothed, to 1e-9 of a standard
  deviation).

Where a kernel's model is nonlinear or specific (the SNS filter's dead reckoning, the joint
smoother's 24-state transition and measurement functions), the test drives the estimation-core
functions that the kernel now calls, in the kernel's own sequence, so that what is compared is
the code path the kernel runs; the kernels' model parts are checked against brute-force
conditioning and finite differences in ``test_sns_models.py`` and ``test_joint_models.py``.
"""

import numpy as np
import pytest
from reference_kalman import constant_velocity_case, correlated_one_step, kalman_rts

from flightrecon.estimation.discretise import singer_process_noise, singer_transition
from flightrecon.estimation.kalman import kalman_filter, rts_smooth, rts_smooth_run
from flightrecon.estimation.predict import predict
from flightrecon.estimation.updates import scalar_update_short


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


def _azimuth_forward(x0, P0, F, Q, eps, var):
    """The azimuth channel's model (``methods/azimuth/model.py``) on the core's forward loop,
    azimuth plots only (linear); its filtered and predicted arrays."""
    from flightrecon.estimation.filtering import forward_pass
    from flightrecon.methods.azimuth import azimuth_model

    N = len(eps)
    m = azimuth_model(F, Q, eps, var, np.full((N, 2), np.nan), np.zeros((N, 2, 2)),
                      np.zeros((N, 2, 2)), np.full(N, 1e4), np.zeros(N), np.zeros((N, 2, 2)),
                      1.0)
    forward_pass(m, x0, P0, N)
    return m.x_f, m.P_f, m.x_p, m.P_p


def _arms_forward(x0, P0, F, Q, air, Rv):
    """The ADS/ARMS track model (``methods/arms/model.py``) on the core's forward loop with
    the air-data velocity as its only measurement (linear); its filtered and predicted arrays."""
    from flightrecon.estimation.filtering import forward_pass
    from flightrecon.methods.arms import arms_track_model

    N = len(air)
    m = arms_track_model(F, Q, np.full((N, 2), np.nan), np.ones((N, 2)), air, Rv, 0)
    forward_pass(m, x0, P0, N)
    return m.x_f, m.P_f, m.x_p, m.P_p


def test_azimuth_kernel(singer_case):
    x0, P0, F, Q, z, R, ref = singer_case
    xf, Pf, xp, Pp = _azimuth_forward(x0, P0, F, Q, z, R[:, 0])
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
    from flightrecon.methods.arms import joint_process_noise, joint_transition

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
    out = _arms_forward(x0, P0, F, Q, air, Rv)
    sm = rts_smooth(out[0], out[1], out[2], out[3], F)
    H = np.zeros((2, 6))
    H[0, 1] = H[0, 4] = H[1, 3] = H[1, 5] = 1.0
    # the positions are observed only through their prior (P0) and the velocity chain, so the
    # reference's information matrix is ill-conditioned (condition number 1.5e9 here): its own
    # rounding is about 1.5e9 x 1e-16 = 1.5e-7 of a standard deviation, hence 1e-6
    ref = batch_reference(x0, P0, F, Q, air, H, np.full((N, 2), 0.3 ** 2))
    _check(sm.x, sm.P, ref, tol=1e-6)


# ---- the constant-velocity case against tests/reference_kalman.py ---------------------------


@pytest.fixture(scope="module")
def cv_case():
    x0, P0, F, Q, z, H, R = constant_velocity_case()
    return (x0, P0, F, Q, z, H, R), kalman_rts(x0, P0, F, Q, z, H, R)


def _check_cv(x, P, x_ref, P_ref, tol=1e-9):
    """``x``, ``P`` against the reference in units of the reference's standard deviations (the
    estimates are O(1e3) m, their sd O(1) m: 1e-9 sd is about 1e-12 relative, a thousand times
    the rounding of these 60-step recursions and far below any modelling error)."""
    sd = np.sqrt(np.diagonal(P_ref, axis1=1, axis2=2))
    np.testing.assert_allclose((x - x_ref) / sd, 0.0, atol=tol)
    norm = sd[:, :, None] * sd[:, None, :]
    np.testing.assert_allclose(P / norm, P_ref / norm, atol=tol)


def test_cv_generic_filter_and_rts(cv_case):
    """Guards ``estimation/kalman.py`` (core dense predict + Joseph update) and
    ``estimation/kalman.py`` (core RTS step, dense C^T = F P): filtered, predicted and smoothed."""
    (x0, P0, F, Q, z, H, R), ref = cv_case
    run = kalman_filter(x0, P0, F, Q, z, H, R[:, :, None] * np.eye(2))
    _check_cv(run.x, run.P, ref.xf, ref.Pf)
    _check_cv(run.x_pred, run.P_pred, ref.xp, ref.Pp)
    sm = rts_smooth_run(run)
    _check_cv(sm.x, sm.P, ref.xs, ref.Ps)
    assert sm.cholesky_fallbacks == 0


def test_cv_azimuth_kernel(cv_case):
    """Guards the azimuth channel's model (``methods/azimuth/model.py``: core predict and
    Joseph update with its angle wrap, on the core's forward loop) on one axis of the case, the
    state padded with a decoupled random walk to the model's three states; azimuth plots only
    (linear)."""
    (x0, P0, F, Q, z, H, R), _ = cv_case
    N = len(z)
    F3 = np.zeros((N, 3, 3))
    Q3 = np.zeros((N, 3, 3))
    F3[:, :2, :2] = F[:, :2, :2]
    F3[:, 2, 2] = 1.0
    Q3[:, :2, :2] = Q[:, :2, :2]
    Q3[:, 2, 2] = 1e-3
    # angles: the plots scaled to radians (1e-4 rad per metre keeps them far from the wrap)
    s = 1e-4
    x03, P03 = np.r_[x0[:2] * s, 0.0], np.diag(np.r_[np.diag(P0)[:2] * s**2, 1.0])
    Q3[:, :2, :2] *= s**2
    eps, var = z[:, 0] * s, R[:, 0] * s**2
    ref = kalman_rts(x03, P03, F3, Q3, eps[:, None], np.array([[1.0, 0.0, 0.0]]), var[:, None])
    xf, Pf, xp, Pp = _azimuth_forward(x03, P03, F3, Q3, eps, var)
    _check_cv(xf, Pf, ref.xf, ref.Pf)
    _check_cv(xp, Pp, ref.xp, ref.Pp)
    sm = rts_smooth(xf, Pf, xp, Pp, F3)
    _check_cv(sm.x, sm.P, ref.xs, ref.Ps)


def test_cv_arms_kernel():
    """Guards the ADS/ARMS track model (``methods/arms/model.py``: core predict and Joseph
    update, on the core's forward loop) on its linear part: constant velocity plus the air-data
    error as a Gauss-Markov state, measured through the air-data velocity ``V + dV``."""
    from flightrecon.methods.arms import joint_process_noise, joint_transition

    rng = np.random.default_rng(4)
    N = 40
    dt = np.r_[0.0, rng.uniform(0.5, 1.5, N - 1)]
    F = joint_transition(dt, 1 / 360.0)
    Q = joint_process_noise(dt, 0.05, 1 / 360.0, 20.0)
    x0 = np.array([1e3, 100.0, -2e3, 5.0, 3.0, -2.0])
    P0 = np.diag([100.0, 5.0, 100.0, 5.0, 20.0, 20.0]) ** 2
    air = np.column_stack([100.0 + rng.normal(0, 1, N), 5.0 + rng.normal(0, 1, N)])
    air[rng.choice(N, 8, replace=False)] = np.nan  # the model takes the pair or neither
    H = np.zeros((2, 6))
    H[0, 1] = H[0, 4] = H[1, 3] = H[1, 5] = 1.0
    ref = kalman_rts(x0, P0, F, Q, air, H, np.full((N, 2), 0.3**2))
    out = _arms_forward(x0, P0, F, Q, air, 0.3**2 * np.eye(2))
    _check_cv(out[0], out[1], ref.xf, ref.Pf)
    _check_cv(out[2], out[3], ref.xp, ref.Pp)
    sm = rts_smooth(out[0], out[1], out[2], out[3], F)
    _check_cv(sm.x, sm.P, ref.xs, ref.Ps)


def test_cv_sns_kernels_through_the_core(cv_case):
    """Guards the SNS filter's update and prediction as its kernel composes them
    (``methods/sns/filter.py``, the ``SnsModel``'s update and prediction: core ``gain_into``
    with the pseudo-inverse, ``joseph_cov_into``, ``state_correction_into``,
    ``predict_cov_into`` plus the factored noise ``B B^T``), and the SNS smoother itself
    (``rts_smooth_cross``: the ``SnsModel`` on the core's backward pass, its cross-covariances
    ``P^+ F^T``), in the Euclidean geometry of this linear case."""
    from flightrecon.estimation.linalg import mdmt_acc_into, sym_into
    from flightrecon.estimation.manifold import EUCLIDEAN
    from flightrecon.estimation.predict import predict_cov_into
    from flightrecon.estimation.updates import (
        gain_into,
        joseph_cov_into,
        normalised_innovation,
        state_correction_into,
    )
    from flightrecon.methods.sns import rts_smooth_cross

    (x0, P0, F, Q, z, H, R), ref = cv_case
    N, n = len(z), 4
    xf, Pf = np.empty((N, n)), np.empty((N, n, n))
    xp, Pp = np.empty((N, n)), np.empty((N, n, n))
    cross = np.zeros((N, n, n))
    x, P = x0.copy(), P0.copy()
    ones = np.ones(n)
    for k in range(N):
        xp[k], Pp[k] = x, P
        ok = np.isfinite(z[k])
        m = int(ok.sum())
        xu, Pu = x.copy(), P.copy()
        if m:
            Hk, Rk = np.ascontiguousarray(H[ok]), np.diag(R[k, ok])
            PHt, S, Sp, K = (np.empty((n, m)), np.empty((m, m)), np.empty((m, m)),
                             np.empty((n, m)))
            rk = gain_into(P, Hk, Rk, 1e-12, PHt, S, Sp, K, np.empty((m, m)), np.empty((m, m)))
            assert rk == m
            joseph_cov_into(P, K, Hk, Rk, Pu, np.empty((n, n)), np.empty((n, n)),
                            np.empty((n, m)), np.empty((n, n)))
            nu = z[k, ok] - Hk @ x
            state_correction_into(EUCLIDEAN, x, K, nu, 0.0, np.empty(n), xu)
            nis = normalised_innovation(Sp, nu, np.empty(m))
            np.testing.assert_allclose(nis, nu @ np.linalg.solve(S, nu), rtol=1e-10)
        xf[k], Pf[k] = xu, Pu
        if k == N - 1:
            break
        B = np.linalg.cholesky(Q[k + 1])  # the SNS kernel's noise comes factored: Q = B B^T
        Pn = np.empty((n, n))
        predict_cov_into(Pu, F[k + 1], Pn, np.empty((n, n)))
        mdmt_acc_into(B, ones, B, Pn)
        cross[k] = Pu @ F[k + 1].T
        x = F[k + 1] @ xu
        P = np.empty((n, n))
        sym_into(Pn, P)
    _check_cv(xf, Pf, ref.xf, ref.Pf)
    _check_cv(xp, Pp, ref.xp, ref.Pp)
    sm = rts_smooth_cross(xp, xf, Pp, Pf, cross, np.zeros(N), EUCLIDEAN)
    assert sm.cholesky_fallbacks == 0
    _check_cv(sm.x, sm.P, ref.xs, ref.Ps)


def test_correlated_noise_prediction_against_brute_force():
    """Guards the SNS consistent form's update-and-predict
    (``estimation.updates.correlated_noise_predict_into``: gain ``L = F K + B G^T S^+``)
    against Gaussian conditioning of the stacked linear system in which the measurement noise
    ``G w_k`` is the process noise ``B w_k`` of the next step: one-step predicted means and
    covariances to 1e-9 of a standard deviation."""
    from flightrecon.estimation.updates import correlated_noise_predict_into, gain_into

    rng = np.random.default_rng(11)
    n, nw, m, N = 4, 3, 2, 8
    F = np.eye(n) + 0.1 * rng.standard_normal((n, n))
    B = 0.5 * rng.standard_normal((n, nw))
    H = rng.standard_normal((m, n))
    G = 0.7 * rng.standard_normal((m, nw))
    Rd = np.array([0.4, 0.9])
    x0, P0 = rng.standard_normal(n), np.diag([2.0, 1.0, 3.0, 0.5])
    z = rng.standard_normal((N, m))
    want_x, want_P = correlated_one_step(x0, P0, F, B, H, G, Rd, z)
    x, P = x0.copy(), P0.copy()
    for k in range(N):
        Rt = G @ G.T + np.diag(Rd)
        PHt, S, Sp, K = np.empty((n, m)), np.empty((m, m)), np.empty((m, m)), np.empty((n, m))
        gain_into(P, H, Rt, 1e-12, PHt, S, Sp, K, np.empty((m, m)), np.empty((m, m)))
        nu = z[k] - H @ x
        Pplus = P - K @ H @ P
        Pn, cross = np.empty((n, n)), Pplus @ F.T
        BGS = np.empty((n, m))
        work = (np.empty((n, m)), np.empty((n, m)), np.empty((n, n)), np.empty((n, n)),
                np.empty((n, nw)), np.ones(nw), -np.ones(m))
        correlated_noise_predict_into(P, F, B, K, H, G, Sp, Rd, Pn, cross, BGS, work)
        x = F @ (x + K @ nu) + BGS @ nu
        P = 0.5 * (Pn + Pn.T)
        sd = np.sqrt(np.diag(want_P[k]))
        np.testing.assert_allclose((x - want_x[k]) / sd, 0.0, atol=1e-9)
        np.testing.assert_allclose(P / np.outer(sd, sd), want_P[k] / np.outer(sd, sd),
                                   atol=1e-9)
        # the smoother's cross-covariance Cov(x_k, x_{k+1} | z_0..z_k) = P+ F^T - K G B^T
        np.testing.assert_allclose(cross, Pplus @ F.T - K @ G @ B.T, atol=1e-12)


def test_cv_joint_kernels_through_the_core(cv_case):
    """Guards the joint smoother's model as it composes the core
    (``methods/joint/model.py``): the row-compressed prediction ``predict_sparse`` with the
    process noise added after it (``predict_into``), one ``scalar_update_short`` per measurement
    component (``update_into``), the RTS step with the sparse ``C^T = F P_f``
    (``cross_transposed_into``) and the mean-only step, ``rts_mean_solve`` then ``P_f (F^T y)``
    (``cross_times_into``)."""
    from flightrecon.estimation.manifold import EUCLIDEAN, state_plus_into
    from flightrecon.estimation.predict import (
        predict_sparse,
        sparse_left_product,
        sparse_rmatvec,
        sparse_rows,
    )
    from flightrecon.estimation.rts import rts_mean_solve, rts_step, rts_step_work
    from flightrecon.estimation.updates import scalar_update_short

    (x0, P0, F, Q, z, H, R), ref = cv_case
    N, n = len(z), 4
    cols, vals, cnt = np.empty((n, n), np.int64), np.empty((n, n)), np.empty(n, np.int64)
    xf, Pf = np.empty((N, n)), np.empty((N, n, n))
    xp, Pp = np.empty((N, n)), np.empty((N, n, n))
    x, P = x0.copy(), P0.copy()
    for k in range(N):
        if k > 0:
            sparse_rows(np.ascontiguousarray(F[k]), cols, vals, cnt)
            predict_sparse(x, P, cols, vals, cnt, np.empty(n), np.empty((n, n)))
            P += Q[k]
        xp[k], Pp[k] = x, P
        for i in np.flatnonzero(np.isfinite(z[k])):
            PH = P @ H[i]
            scalar_update_short(x, P, PH, z[k, i] - H[i] @ x, H[i] @ PH + R[k, i])
        xf[k], Pf[k] = x, P
    _check_cv(xf, Pf, ref.xf, ref.Pf)
    _check_cv(xp, Pp, ref.xp, ref.Pp)
    xs, Ps, xm = xf.copy(), Pf.copy(), xf.copy()
    work = rts_step_work(n)
    CT, L, d, y, zz, dx = (np.empty((n, n)), np.empty((n, n)), np.empty(n), np.empty(n),
                           np.empty(n), np.empty(n))
    for k in range(N - 2, -1, -1):
        sparse_rows(np.ascontiguousarray(F[k + 1]), cols, vals, cnt)
        sparse_left_product(cols, vals, cnt, Pf[k], CT)
        assert rts_step(EUCLIDEAN, (xf[k], Pf[k]), (xp[k + 1], Pp[k + 1]),
                        (xs[k + 1], Ps[k + 1]), CT, (0.0, 0.0), 0.0, (xs[k], Ps[k]), work)
        assert rts_mean_solve(EUCLIDEAN, xp[k + 1], Pp[k + 1], xm[k + 1], 0.0, 0.0, L, d, y)
        sparse_rmatvec(cols, vals, cnt, y, zz)
        dx[:] = Pf[k] @ zz
        state_plus_into(EUCLIDEAN, xf[k], dx, 0.0, xm[k])
    _check_cv(xs, Ps, ref.xs, ref.Ps)
    _check_cv(xm, Ps, ref.xs, ref.Ps)


def test_latlon_plus_minus():
    """Guards the manifold hook of the SNS state (``estimation.manifold``): minus inverts plus
    (to second order in the move: 1e-9 of a 2 km move), and the longitude difference is taken
    the short way across the antimeridian (it was 2 pi the long way round)."""
    from flightrecon.estimation.manifold import (
        LATLON,
        boxminus,
        boxplus,
        state_minus_into,
        state_plus_into,
    )

    lat, lon, h = np.radians(50.0), np.radians(30.0), 3000.0
    lat1, lon1 = boxplus(lat, lon, 1500.0, -1200.0, h)
    dn, de = boxminus(lat1, lon1, lat, lon, h)
    assert abs(dn - 1500.0) < 2e-6 and abs(de + 1200.0) < 2e-6
    x = np.array([lat, np.pi - 1e-6, 1.0])
    y = np.array([lat, -np.pi + 1e-6, 3.0])
    d = np.empty(3)
    state_minus_into(LATLON, y, x, h, d)
    # 2e-6 rad of longitude at 50 deg latitude: about 8.2 m east, not 25 000 km west
    assert 7.0 < d[1] < 9.5 and d[2] == 2.0 and abs(d[0]) < 1e-9
    back = np.empty(3)
    state_plus_into(LATLON, x, d, h, back)
    assert abs(back[1] - (np.pi + 1e-6)) < 1e-12  # continuous longitude: no wrap on plus


def test_eigen_solve_fallback_matches_a_general_solve():
    """The RTS steps' fallback where a predicted covariance fails its Cholesky factorisation
    (estimation.linalg.solve_sym_eig_into, in place of np.linalg.solve inside the kernels):
    on a regular indefinite symmetric matrix it gives the general solve's answer (1e-10
    relative: Jacobi eigenvalues to round-off of the norm, condition number about 1e2 here);
    on a singular one the minimum-norm least-squares solution (numpy's lstsq), not an error;
    a non-finite matrix raises LinAlgError."""
    import pytest

    from flightrecon.estimation.linalg import solve_sym_eig_into

    rng = np.random.default_rng(11)
    for n in (5, 24):
        A = rng.standard_normal((n, n))
        S = A @ A.T + n * np.eye(n)
        S[2, 2] = -S[2, 2]                      # indefinite, regular
        B = rng.standard_normal((n, 3))
        X = np.empty_like(B)
        assert solve_sym_eig_into(S, B, 1e-15, X) == n
        ref = np.linalg.solve(S, B)
        np.testing.assert_allclose(X, ref, rtol=1e-10, atol=1e-10 * np.abs(ref).max())
        U = rng.standard_normal((n, n - 2))
        Ssing = U @ U.T                          # rank n - 2
        assert solve_sym_eig_into(Ssing, B, 1e-12, X) == n - 2
        ref = np.linalg.lstsq(Ssing, B, rcond=1e-12)[0]
        np.testing.assert_allclose(X, ref, rtol=1e-8, atol=1e-8 * np.abs(ref).max())
    S[0, 0] = np.nan
    with pytest.raises(np.linalg.LinAlgError):
        solve_sym_eig_into(S, B, 1e-15, X)
