"""SNS dead-reckoning models, frame and filter algebra (flightrecon.methods.sns, METHODS.md 4)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from flightrecon.methods import sns as core

RNG = np.random.default_rng(7)
Z7 = np.zeros(7)  # no summed-sample noise: each filter step is one recorder sample


def _random_case(model, seed=7):
    rng = np.random.default_rng(seed)
    c = np.array([0.03, 0.01, 0.02]) if model == core.MODEL_DOPPLER else np.array([3.0, -2.0, 0.03])
    tau = 0.7
    ang = rng.uniform(0, 2 * np.pi)
    u = np.array([np.cos(ang), np.sin(ang)])
    A = 210.0 * tau * u + rng.normal(0, 3, 2)
    U = tau * u
    W = np.array([5.0, -8.0]) * tau if model == core.MODEL_AIRSPEED else np.zeros(2)
    sig = np.array([0.5, 0.004, 1.0, 1.0])
    return c, A, U, W, tau, sig


def _fd(fun, x, eps):
    f0 = fun(x)
    J = np.empty((f0.size, x.size))
    eps = np.broadcast_to(np.asarray(eps, float), x.shape)
    for i in range(x.size):
        dx = np.zeros_like(x)
        dx[i] = eps[i]
        J[:, i] = (fun(x + dx) - fun(x - dx)) / (2 * eps[i])
    return J


@pytest.mark.parametrize("model", [core.MODEL_AIRSPEED, core.MODEL_DOPPLER])
def test_increment_jacobian_matches_finite_differences(model):
    """dd/dc analytic vs central differences (step 1e-6: truncation ~1e-12 * 200 m, far below
    the 1e-6 relative tolerance; rounding ~1e-16 * 200 / 1e-6 = 2e-8)."""
    c, A, U, W, tau, sig = _random_case(model)
    _d, J, _Gs = core.increment(model, c, A, U, W, tau, sig)
    Jfd = _fd(lambda cc: core.increment(model, cc, A, U, W, tau, sig)[0], c, 1e-6)
    np.testing.assert_allclose(J, Jfd, rtol=1e-6, atol=1e-6)


@pytest.mark.parametrize("model", [core.MODEL_AIRSPEED, core.MODEL_DOPPLER])
def test_noise_columns_match_perturbed_readings(model):
    """Each column of G_s is the increment's derivative w.r.t. a reading error held over the
    interval, times its sd (speed error adds to A along U; angle errors rotate A; wind errors
    add tau per component).  Same finite-difference tolerance as above."""
    c, A, U, W, tau, sig = _random_case(model)
    _, _, Gs = core.increment(model, c, A, U, W, tau, sig)

    def inc(A_, W_, c_):
        return core.increment(model, c_, A_, U, W_, tau, sig)[0]

    eps = 1e-6
    col_speed = (inc(A + eps * U, W, c) - inc(A - eps * U, W, c)) / (2 * eps)
    np.testing.assert_allclose(Gs[:, 0], col_speed * sig[0], rtol=1e-6, atol=1e-9)
    dth = np.zeros(3)
    dth[2] = eps
    col_angle = (inc(A, W, c + dth) - inc(A, W, c - dth)) / (2 * eps)
    ang_cols = [1] if model == core.MODEL_AIRSPEED else [1, 2]
    for j in ang_cols:
        np.testing.assert_allclose(Gs[:, j], col_angle * sig[j], rtol=1e-6, atol=1e-9)
    if model == core.MODEL_AIRSPEED:
        for j in (0, 1):
            e = np.zeros(2)
            e[j] = eps * tau
            col = (inc(A, W + e, c) - inc(A, W - e, c)) / (2 * eps)
            np.testing.assert_allclose(Gs[:, 2 + j], col * sig[2 + j], rtol=1e-6, atol=1e-9)


@pytest.mark.parametrize("model", [core.MODEL_AIRSPEED, core.MODEL_DOPPLER])
def test_observation_jacobian_matches_finite_differences(model):
    """H = dh/dX for one fix (position through the partial increment, velocity through the held
    reading) vs central differences of h; position columns are the identity because h is the
    offset from the position at the start of the step.  Tolerance as above."""
    c, A, U, W, tau, sig = _random_case(model)
    a, u, w = A / tau, U / tau, W / tau
    _h, H, G = core.observation_rows(model, c, 0.4 * A, 0.4 * U, 0.4 * W, 0.4 * tau, a, u, w,
                                     sig, 0.4 * tau, Z7)
    Hfd = _fd(lambda cc: core.observation_rows(model, cc, 0.4 * A, 0.4 * U, 0.4 * W, 0.4 * tau,
                                               a, u, w, sig, 0.4 * tau, Z7)[0], c, 1e-6)
    np.testing.assert_allclose(H[:, 2:], Hfd, rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(H[:2, :2], np.eye(2))
    np.testing.assert_array_equal(H[2:, :2], np.zeros((2, 2)))
    # the velocity observation shares the step's sensor noise: G velocity rows = velocity noise
    _, _, Gv = core.increment(model, c, a, u, w, 1.0, sig)
    np.testing.assert_allclose(G[2:, :4], Gv)


def test_step_transition_jacobian_in_local_level_frame():
    """Phi (metric coordinates) vs finite differences of the full step f(X) in lat/lon: a
    position perturbation of 1 m maps to 1 m after the step (identity block) up to the rotation
    of the local axes over the step (distance * tan(lat) / R = 150 m * 1.3 / 6.4e6 = 3e-5, the
    term the frame neglects: tolerance 1e-4), and the correction columns match the increment
    Jacobian to the same 3e-5 relative (the round trip through lat/lon evaluates the radii 150 m
    apart): tolerance 1e-4 relative."""
    model = core.MODEL_AIRSPEED
    c, A, U, W, tau, sig = _random_case(model)
    lat, lon, h = np.deg2rad(52.0), np.deg2rad(13.0), 10000.0
    q = np.array([1e-4, 1e-4, 1e-8])
    star = np.stack([A / tau, U / tau, W / tau])
    _d, Phi, B = core.step_matrices(model, c, A, U, W, tau, sig, q, star, tau, Z7, Z7)

    def f(x):
        dd = core.increment(model, x[2:], A, U, W, tau, sig)[0]
        la, lo = core.boxplus(lat, lon, x[0], x[1], h)
        la2, lo2 = core.boxplus(la, lo, dd[0], dd[1], h)
        dn, de = core.boxminus(la2, lo2, lat, lon, h)
        return np.array([dn, de, *x[2:]])

    x = np.array([0.0, 0.0, *c])
    Jfd = np.column_stack([_fd(f, x, np.array(1.0))[:, :2],
                           _fd(f, x, np.array([1.0, 1.0, 1e-3, 1e-3, 1e-6]))[:, 2:]])
    np.testing.assert_allclose(Phi[:, :2], Jfd[:, :2], atol=1e-4)
    np.testing.assert_allclose(Phi[:, 2:], Jfd[:, 2:], rtol=1e-4, atol=1e-4)
    assert B.shape == (5, 11)
    np.testing.assert_allclose(B[2:, 8:], np.diag(np.sqrt(q * tau)))


def test_boxplus_boxminus_round_trip():
    """(+) then (-) returns the metric offset for a 5 km move: both use mid-latitude radii, so
    they differ only at third order (measured 1.3e-6 m): tolerance 1e-5 m."""
    lat, lon = np.deg2rad(-33.0), np.deg2rad(151.0)
    la, lo = core.boxplus(lat, lon, 3000.0, -4000.0, 500.0)
    dn, de = core.boxminus(la, lo, lat, lon, 500.0)
    assert abs(dn - 3000.0) < 1e-5 and abs(de + 4000.0) < 1e-5


def test_local_level_propagation_10h():
    """The moving local-level propagation over a 10-hour, 250 m/s flight (1 Hz steps, velocity
    held, heading 60 deg then 200 deg) against an adaptive ODE solution of
    lat' = vn/(M+h), lon' = ve/((N+h) cos lat): position error below 1 m over about 9000 km
    (mid-latitude radii: local error O(dt^3); measured ~1e-3 m)."""
    h = 11000.0
    lat, lon = np.deg2rad(40.0), np.deg2rad(10.0)

    def vel(t):
        ang = np.deg2rad(60.0 if t < 18000.0 else 200.0)
        return 250.0 * np.cos(ang), 250.0 * np.sin(ang)

    la, lo = lat, lon
    for k in range(36000):
        vn, ve = vel(float(k))
        la, lo = core.boxplus(la, lo, vn, ve, h)

    def rhs(t, y):
        vn, ve = vel(t)
        mh, nh = core.radii(y[0], h)
        return [vn / mh, ve / (nh * np.cos(y[0]))]

    y = [lat, lon]
    for t0, t1 in ((0.0, 18000.0), (18000.0, 36000.0)):
        y = solve_ivp(rhs, (t0, t1), y, rtol=1e-12, atol=1e-14, method="DOP853").y[:, -1]
    dn, de = core.boxminus(la, lo, y[0], y[1], h)
    assert np.hypot(dn, de) < 1.0


def test_pinv_sym_drops_null_space():
    """Pseudo-inverse of a rank-deficient symmetric matrix: Moore-Penrose conditions to 1e-12
    (well-conditioned non-zero eigenvalues 1..3)."""
    V = np.linalg.qr(RNG.normal(size=(4, 4)))[0]
    S = V @ np.diag([3.0, 1.0, 1e-18, 0.0]) @ V.T
    Sp, rank = core.pinv_sym(S, 1e-10)
    assert rank == 2
    np.testing.assert_allclose(S @ Sp @ S, S, atol=1e-12)
    np.testing.assert_allclose(Sp @ S @ Sp, Sp, atol=1e-12)


def _one_step_inputs(model, fixes_twice=False, tau_fix=0.3):
    c, A, U, W, tau, _sig = _random_case(model)
    lat0, lon0, h = np.deg2rad(45.0), np.deg2rad(5.0), 3000.0
    a, u, w = A / tau, U / tau, W / tau
    nfix = 2 if fixes_twice else 1
    flat, flon = core.boxplus(lat0, lon0, 40.0, -25.0, h)

    def one(v):
        return np.repeat(np.atleast_2d(v), nfix, axis=0)

    inp = core.StepInputs(
        t=np.array([0.0, tau]), h=np.array([h, h]), A=np.vstack([A, [0, 0]]),
        U=np.vstack([U, [0, 0]]), W=np.vstack([W, [0, 0]]),
        fix_start=np.array([0, nfix]), fix_end=np.array([nfix, nfix]),
        fix_lat=np.full(nfix, flat), fix_lon=np.full(nfix, flon),
        fix_v=one(a + w + np.array([0.3, -0.2])), fix_tau=np.full(nfix, tau_fix),
        fix_PA=one(a * tau_fix), fix_PU=one(u * tau_fix), fix_PW=one(w * tau_fix),
        fix_a=one(a), fix_u=one(u), fix_w=one(w))
    x0 = np.array([lat0, lon0, *c])
    P0 = np.diag([30.0 ** 2, 30.0 ** 2, 4.0, 4.0, 1e-3]) if model == 0 else \
        np.diag([30.0 ** 2, 30.0 ** 2, 1e-3, 1e-4, 1e-3])
    return inp, x0, P0


@pytest.mark.parametrize("model", [core.MODEL_AIRSPEED, core.MODEL_DOPPLER])
def test_consistent_prediction_equals_methods_formula(model):
    """The kernel's symmetric predictor form equals METHODS.md's expanded expression
    P_{k+1} = Phi P+ Phi^T + B B^T - B G^T S^+ G B^T - Phi P- H^T S^+ G B^T - (its transpose),
    the state gets B G^T S^+ nu, and the smoother numerator is P+ Phi^T - P- H^T S^+ G B^T
    (algebraic identities: 1e-9 relative)."""
    inp, x0, P0 = _one_step_inputs(model)
    noise = core.default_noise(model)
    run = core.sns_filter(inp, x0, P0, noise, model=model, form=core.FORM_CONSISTENT)
    sig = np.asarray(noise.sensor_sd)
    c = x0[2:]
    _, H, G = core.observation_rows(model, c, inp.fix_PA[0], inp.fix_PU[0], inp.fix_PW[0],
                                     inp.fix_tau[0], inp.fix_a[0], inp.fix_u[0], inp.fix_w[0],
                                     sig, inp.fix_tau[0], Z7)
    D = np.diag([noise.pos_sd_m] * 2 + [noise.vel_sd_mps] * 2)
    S = H @ P0 @ H.T + D @ D.T + G @ G.T
    Sp = np.linalg.pinv(S, hermitian=True)
    K = P0 @ H.T @ Sp
    Pplus = P0 - K @ H @ P0
    np.testing.assert_allclose(run.P[0], Pplus, rtol=1e-9, atol=1e-9 * np.abs(P0).max())
    cp = run.x[0, 2:]
    star = np.stack([inp.A[0], inp.U[0], inp.W[0]]) / inp.t[1]
    _, Phi, B = core.step_matrices(model, cp, inp.A[0], inp.U[0], inp.W[0], inp.t[1], sig,
                                   np.asarray(noise.rw_q), star, inp.t[1], Z7, Z7)
    BGS = B @ G.T @ Sp
    expect = (Phi @ Pplus @ Phi.T + B @ B.T - BGS @ G @ B.T - Phi @ K @ G @ B.T
              - B @ G.T @ K.T @ Phi.T)
    np.testing.assert_allclose(run.P_pred[1], expect, rtol=1e-9,
                               atol=1e-9 * np.abs(expect).max())
    np.testing.assert_allclose(run.diagnostics["cross"][0], Pplus @ Phi.T - K @ G @ B.T, rtol=1e-9,
                               atol=1e-9 * np.abs(expect).max())
    seed = core.sns_filter(inp, x0, P0, noise, model=model, form=core.FORM_SEED)
    np.testing.assert_allclose(seed.P_pred[1], Phi @ Pplus @ Phi.T + B @ B.T, rtol=1e-9,
                               atol=1e-9 * np.abs(expect).max())
    # the state correction B G^T S^+ nu moves only the position
    dn, de = core.boxminus(run.x_pred[1, 0], run.x_pred[1, 1], seed.x_pred[1, 0],
                           seed.x_pred[1, 1], 3000.0)
    assert np.isfinite(run.diagnostics["nis"][0]) and run.diagnostics["rank"][0] == 4
    assert np.hypot(dn, de) > 0.0
    np.testing.assert_allclose(run.x_pred[1, 2:], seed.x_pred[1, 2:], atol=1e-15)


def test_singular_innovation_covariance_uses_pseudo_inverse():
    """A fix given twice with zero GNSS noise and zero sensor noise makes the stacked S (8x8)
    singular (rank 4); the pseudo-inverse update must equal the update with the fix once
    (the duplicate carries no information).  Tolerance 1e-6 relative: eigenvalue threshold."""
    model = core.MODEL_AIRSPEED
    noise = core.SnsNoise((0.0, 0.0, 0.0, 0.0), (0.0, 0.0, 0.0), 0.0, 0.0, (2.0, 2.0, 0.02))
    inp2, x0, P0 = _one_step_inputs(model, fixes_twice=True)
    inp1, _, _ = _one_step_inputs(model, fixes_twice=False)
    r2 = core.sns_filter(inp2, x0, P0, noise, model=model)
    r1 = core.sns_filter(inp1, x0, P0, noise, model=model)
    assert r2.diagnostics["rank"][0] == 4 and r1.diagnostics["rank"][0] == 4
    np.testing.assert_allclose(r2.x[0], r1.x[0], rtol=1e-9, atol=1e-12)
    np.testing.assert_allclose(r2.P[0], r1.P[0], rtol=1e-6, atol=1e-6 * np.abs(P0).max())
    assert np.isfinite(r2.P_pred).all()


def test_bad_filter_arguments_raise():
    inp, x0, P0 = _one_step_inputs(core.MODEL_AIRSPEED)
    noise = core.default_noise(core.MODEL_AIRSPEED)
    with pytest.raises(ValueError):
        core.sns_filter(inp, x0, P0, noise, model=5)
    with pytest.raises(ValueError):
        core.sns_filter(inp, x0, P0[:3, :3], noise, model=0)


def _zero_innovation_case(model, N=6, tau_fix=0.4):
    """Inputs for N one-second steps through a turn, with every fix placed exactly where the
    uncorrected dead reckoning predicts it, so all innovations vanish, the corrections stay at
    their prior mean 0 and the filter's linearisation points equal the linear model's."""
    psi = np.deg2rad(30.0 + 25.0 * np.arange(N))
    u = np.column_stack([np.cos(psi), np.sin(psi)])
    a = 150.0 * u if model == core.MODEL_AIRSPEED else 170.0 * u
    w = np.tile([6.0, -9.0], (N, 1)) if model == core.MODEL_AIRSPEED else np.zeros((N, 2))
    sig = np.asarray(core.default_noise(model).sensor_sd)
    h = 2000.0
    lat, lon = np.deg2rad(48.0), np.deg2rad(2.0)
    pos = [(lat, lon)]
    flat, flon = [], []
    c0 = np.zeros(3)
    for k in range(N):
        dp = core.increment(model, c0, a[k] * tau_fix, u[k] * tau_fix, w[k] * tau_fix,
                            tau_fix, sig)[0]
        la, lo = core.boxplus(pos[k][0], pos[k][1], dp[0], dp[1], h)
        flat.append(la)
        flon.append(lo)
        d = core.increment(model, c0, a[k], u[k], w[k], 1.0, sig)[0]
        pos.append(core.boxplus(pos[k][0], pos[k][1], d[0], d[1], h))
    z2 = np.zeros((1, 2))
    inp = core.StepInputs(
        t=np.arange(N, dtype=float), h=np.full(N, h),
        A=np.vstack([a[:-1], z2]), U=np.vstack([u[:-1], z2]), W=np.vstack([w[:-1], z2]),
        fix_start=np.arange(N), fix_end=np.arange(N) + 1,
        fix_lat=np.array(flat), fix_lon=np.array(flon), fix_v=a + w,
        fix_tau=np.full(N, tau_fix), fix_PA=a * tau_fix, fix_PU=u * tau_fix,
        fix_PW=w * tau_fix, fix_a=a, fix_u=u, fix_w=w)
    return inp, np.array([lat, lon, 0.0, 0.0, 0.0])


@pytest.mark.parametrize("model", [core.MODEL_AIRSPEED, core.MODEL_DOPPLER])
def test_filter_and_smoother_covariances_equal_exact_conditioning(model):
    """Against brute force: the linear-Gaussian model with the correlated noise
    (x_{k+1} = Phi x_k + B eps1_k, y_k = H x_k + D eps2_k + G eps1_k) written as one joint
    Gaussian in [x_0, eps1, eps2]; Cov(x_k | y_0..k-1), Cov(x_k | y_0..k) and
    Cov(x_k | y_0..N-1) by direct conditioning must equal the consistent filter's predicted,
    filtered and smoothed covariances.  This checks the correlated-noise prediction, the
    smoother gain (P+ Phi^T - P- H^T S^+ G B^T) P_{k+1}^{-1} and the smoothed covariance
    recursion derived in docs/sns.md.  With zero innovations the linearisation points are the
    linear model's, so agreement is to rounding: 1e-7 of sqrt(P_ii P_jj) per entry."""
    N = 6
    inp, x0 = _zero_innovation_case(model, N)
    noise = core.default_noise(model)
    sig, q = np.asarray(noise.sensor_sd), np.asarray(noise.rw_q)
    P0 = np.diag([20.0 ** 2, 20.0 ** 2, *np.square(noise.prior_sd)])
    run = core.sns_filter(inp, x0, P0, noise, model=model, form=core.FORM_CONSISTENT)
    sm = core.sns_smooth(run)
    assert np.all(np.abs(run.x[:, 2:]) < 1e-9)  # innovations vanished: still at the prior mean

    n, ne, nm = 5, core.N_EPS1, 4
    nw = n + ne * N + nm * N
    Xc = [np.zeros((n, nw))]
    Xc[0][:, :n] = np.eye(n)
    Yc = []
    D = np.diag([noise.pos_sd_m] * 2 + [noise.vel_sd_mps] * 2)
    c0 = np.zeros(3)
    for k in range(N):
        e1 = slice(n + ne * k, n + ne * (k + 1))
        e2 = slice(n + ne * N + nm * k, n + ne * N + nm * (k + 1))
        _, H, G = core.observation_rows(model, c0, inp.fix_PA[k], inp.fix_PU[k], inp.fix_PW[k],
                                        inp.fix_tau[k], inp.fix_a[k], inp.fix_u[k],
                                        inp.fix_w[k], sig, inp.fix_tau[k], Z7)
        y = H @ Xc[k]
        y[:, e1] += G
        y[:, e2] += D
        Yc.append(y)
        if k < N - 1:
            star = np.stack([inp.A[k], inp.U[k], inp.W[k]])
            _, Phi, B = core.step_matrices(model, c0, inp.A[k], inp.U[k], inp.W[k], 1.0, sig, q,
                                           star, 1.0, Z7, Z7)
            xn = Phi @ Xc[k]
            xn[:, e1] += B
            Xc.append(xn)
    Lam = np.eye(nw)
    Lam[:n, :n] = P0

    def cond_cov(k, m):
        """Cov(x_k | y_0..m-1)."""
        X = Xc[k]
        if m == 0:
            return X @ Lam @ X.T
        Y = np.vstack(Yc[:m])
        Sxy = X @ Lam @ Y.T
        Syy = Y @ Lam @ Y.T
        return X @ Lam @ X.T - Sxy @ np.linalg.solve(Syy, Sxy.T)

    def same(P, Pexp):
        """Equal entry by entry relative to sqrt(P_ii P_jj) (variances differ by 1e8)."""
        d = np.sqrt(np.diag(Pexp))
        np.testing.assert_allclose(P / np.outer(d, d), Pexp / np.outer(d, d), atol=1e-7,
                                   rtol=0)

    for k in range(N):
        same(run.P_pred[k], cond_cov(k, k))
        same(run.P[k], cond_cov(k, k + 1))
        same(sm.P[k], cond_cov(k, N))


@pytest.mark.parametrize("model", [core.MODEL_AIRSPEED, core.MODEL_DOPPLER])
def test_segment_factor_equals_sum_of_sample_noise(model):
    """The factor of the summed errors of several recorder samples: L L^T must equal the sum
    over the samples of (G_s dt)(G_s dt)^T built sample by sample with :func:`increment`
    (rotation and scale applied after summing: exact algebra, 1e-10 relative)."""
    rng = np.random.default_rng(3)
    c = np.array([0.02, 0.01, 0.03]) if model == core.MODEL_DOPPLER else np.array([1., 2., 0.03])
    sig = np.array([0.5, 0.004, 0.003, 0.0]) if model else np.array([0.5, 0.004, 1.0, 1.5])
    dt = rng.uniform(0.05, 0.1, 7)
    ang = rng.uniform(0, 2 * np.pi, 7)
    u = np.column_stack([np.cos(ang), np.sin(ang)])
    a = u * rng.uniform(150, 250, (7, 1))
    ja = np.column_stack([-a[:, 1], a[:, 0]])
    Q = np.zeros(7)
    expect = np.zeros((2, 2))
    for j in range(7):
        Q += dt[j] ** 2 * np.array([u[j, 0] ** 2, u[j, 0] * u[j, 1], u[j, 1] ** 2,
                                    ja[j, 0] ** 2, ja[j, 0] * ja[j, 1], ja[j, 1] ** 2, 1.0])
        _, _, Gs = core.increment(model, c, a[j] * dt[j], u[j] * dt[j], np.zeros(2), dt[j], sig)
        expect += Gs @ Gs.T
    L = core.segment_factor(model, c, Q, sig)
    np.testing.assert_allclose(L @ L.T, expect, rtol=1e-10, atol=1e-12 * np.abs(expect).max())


def test_smoother_counts_cholesky_failures():
    """Regression: the SNS smoother fell back to a general solve, silently, where the predicted
    covariance P_p[k+1] failed its Cholesky factorisation.  The kernel now counts those steps
    (the adapter reports them as ``cholesky_fallbacks``): none for a positive-definite P_p, one
    for an indefinite (but regular) one, whose gain still equals the general solve's."""
    rng = np.random.default_rng(5)
    n = core.N_STATE
    A = rng.standard_normal((n, n))
    Pf = np.stack([A @ A.T + n * np.eye(n)] * 2)
    lat, lon = np.radians(50.0), np.radians(30.0)
    xf = np.array([[lat, lon, 0.0, 0.0, 0.0]] * 2)
    xp = xf + np.array([0.0, 0.0, 0.1, 0.2, 0.01])
    cross = np.stack([0.5 * Pf[0]] * 2)
    hgt = np.zeros(2)
    count = core.rts_smooth_cross(xp, xf, Pf.copy(), Pf, cross, hgt).cholesky_fallbacks
    assert count == 0
    Pp = Pf.copy()
    Pp[1, 2, 2] = -Pp[1, 2, 2]
    sm = core.rts_smooth_cross(xp, xf, Pp, Pf, cross, hgt)
    xs, count = sm.x, sm.cholesky_fallbacks
    assert count == 1
    C = np.linalg.solve(Pp[1], cross[0].T).T
    d = np.r_[0.0, 0.0, xf[1, 2:] - xp[1, 2:]]
    np.testing.assert_allclose(xs[0, 2:], xf[0, 2:] + (C @ d)[2:], rtol=1e-12, atol=1e-15)
