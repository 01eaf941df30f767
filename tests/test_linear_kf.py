"""Generic linear Kalman filter and RTS smoother (flightrecon.estimation.kalman, smoothing.rts)."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from scipy import stats

from flightrecon.estimation.kalman import kalman_filter, rts_smooth_run


def cv_model(dt: float, q: float):
    F = np.array([[1.0, dt], [0.0, 1.0]])
    Q = q * np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    return F, Q


def simulate_cv(rng, N, dt, q, r, x0=(0.0, 10.0)):
    F, Q = cv_model(dt, q)
    L = np.linalg.cholesky(Q)
    x = np.empty((N, 2))
    x[0] = x0
    for k in range(1, N):
        x[k] = F @ x[k - 1] + L @ rng.standard_normal(2)
    z = x[:, :1] + np.sqrt(r) * rng.standard_normal((N, 1))
    return x, z


def reference_filter(x0, P0, F, Q, z, H, R):
    """Textbook KF in plain numpy (explicit inverse, simple update) as an independent check."""
    x, P = np.array(x0, float), np.array(P0, float)
    xs, Ps = [], []
    for k in range(len(z)):
        if k > 0:
            x = F @ x
            P = F @ P @ F.T + Q
        if np.isfinite(z[k]).all():
            S = H @ P @ H.T + R
            K = P @ H.T @ np.linalg.inv(S)
            x = x + K @ (z[k] - H @ x)
            P = (np.eye(len(x)) - K @ H) @ P
        xs.append(x.copy())
        Ps.append(P.copy())
    return np.array(xs), np.array(Ps)


def test_matches_textbook_filter():
    rng = np.random.default_rng(1)
    F, Q = cv_model(0.5, 0.2)
    _, z = simulate_cv(rng, 200, 0.5, 0.2, 4.0)
    z[::7] = np.nan
    H = np.array([[1.0, 0.0]])
    R = np.array([[4.0]])
    run = kalman_filter([0, 0], np.eye(2) * 100, F, Q, z, H, R)
    xr, Pr = reference_filter([0, 0], np.eye(2) * 100, F, Q, z, H, R)
    # Joseph form and the simple form agree to rounding for the optimal gain
    np.testing.assert_allclose(run.x, xr, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(run.P, Pr, rtol=1e-8, atol=1e-10)
    assert np.all(run.diagnostics["n_meas"][::7] == 0)


def test_nees_in_chi_square_band_monte_carlo():
    """Run-averaged NEES of filter and smoother inside the 95 % chi-square band (M=50 runs)."""
    N, dt, q, r, M = 300, 1.0, 0.05, 9.0, 50
    F, Q = cv_model(dt, q)
    nees_f = np.zeros(N)
    nees_s = np.zeros(N)
    for m in range(M):
        rng = np.random.default_rng(100 + m)
        P0 = np.diag([25.0, 4.0])
        x0_true = np.array([0.0, 10.0]) + np.sqrt(np.diag(P0)) * rng.standard_normal(2)
        x, z = simulate_cv(rng, N, dt, q, r, x0=x0_true)
        run = kalman_filter([0.0, 10.0], P0, F, Q, z, [[1.0, 0.0]], [[r]])
        sm = rts_smooth_run(run)
        ef, es = run.x - x, sm.x - x
        nees_f += np.einsum("ki,kij,kj->k", ef, np.linalg.inv(run.P), ef)
        nees_s += np.einsum("ki,kij,kj->k", es, np.linalg.inv(sm.P), es)
    # averaged over runs and time: sum of M*N chi2(2) variables (time-correlated, so the band on
    # the time-average uses the per-epoch band on M runs, which is wider and conservative)
    lo, hi = stats.chi2.ppf([0.025, 0.975], 2 * M) / M
    assert lo < nees_f.mean() / M < hi
    assert lo < nees_s.mean() / M < hi
    # per-epoch: at most ~5 % of epochs outside the band, allow 10 % for correlation
    frac_out = np.mean((nees_f / M < lo) | (nees_f / M > hi))
    assert frac_out < 0.10


@settings(max_examples=30, deadline=None)
@given(seed=st.integers(0, 10_000), q=st.floats(1e-3, 10.0), r=st.floats(0.1, 100.0),
       dt=st.floats(0.05, 5.0))
def test_smoothed_covariance_never_above_filtered(seed, q, r, dt):
    rng = np.random.default_rng(seed)
    F, Q = cv_model(dt, q)
    _, z = simulate_cv(rng, 60, dt, q, r)
    z[rng.random(60) < 0.3] = np.nan
    run = kalman_filter([0, 0], np.eye(2) * 1e3, F, Q, z, [[1.0, 0.0]], [[r]])
    sm = rts_smooth_run(run)
    for k in range(60):
        # P_f - P_s is positive semi-definite; P_s positive definite
        d = np.linalg.eigvalsh(run.P[k] - sm.P[k])
        assert d.min() > -1e-8 * np.abs(run.P[k]).max()
        assert np.linalg.eigvalsh(sm.P[k]).min() > 0


def test_shape_errors():
    with pytest.raises(ValueError):
        kalman_filter([0, 0], np.eye(3), np.eye(2), np.eye(2), np.zeros((5, 1)), [[1, 0]], [[1]])
