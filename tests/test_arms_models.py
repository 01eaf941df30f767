"""ADS/ARMS models (flightrecon.methods.arms): measurement functions, Jacobian, converted
covariance, exact discretisations, horizontal range, and the kernel's single update."""

import numpy as np
import pytest
from scipy.linalg import expm

from flightrecon.errors import ValidationError
from flightrecon.estimation.filtering import forward_pass
from flightrecon.geo.frames import TangentPlane
from flightrecon.methods import arms as A


def test_jacobian_matches_finite_differences():
    """Guards the sign/ordering of H in paper eq. 12 (x east, y north, theta = atan2(x, y))."""
    rng = np.random.default_rng(3)
    for _ in range(20):
        X = np.concatenate([rng.uniform(-80e3, 80e3, 1), rng.normal(0, 100, 1),
                            rng.uniform(-80e3, 80e3, 1), rng.normal(0, 100, 1),
                            rng.normal(0, 20, 2)])
        H = A.range_azimuth_jacobian(X)
        h = 1.0  # central differences on a 1 m step: truncation error ~ h^2 / r^3 ~ 1e-15
        Hfd = np.empty((2, 6))
        for j in range(6):
            d = np.zeros(6)
            d[j] = h
            Hfd[:, j] = (A.range_azimuth(X + d) - A.range_azimuth(X - d)) / (2 * h)
        # relative 1e-7: rounding of atan2/hypot differences (1e-16 * r / h) dominates
        np.testing.assert_allclose(H, Hfd, rtol=1e-7, atol=1e-12)


def test_azimuth_convention_and_wrap():
    """Azimuth clockwise from north: a point due east is at +90 deg; wrap to (-pi, pi]."""
    z = A.range_azimuth(np.array([1000.0, 0, 0, 0]))
    assert z[1] == pytest.approx(np.pi / 2)
    w = A.wrap_angle(np.array([np.pi, -np.pi, 3 * np.pi, 0.1 - 2 * np.pi]))
    np.testing.assert_allclose(w, [np.pi, np.pi, np.pi, 0.1], atol=1e-12)


def test_converted_covariance_matches_monte_carlo():
    """Paper eq. 15 against the sample covariance of 400k converted noisy plots."""
    rng = np.random.default_rng(11)
    M = 400_000
    for rho, th in ((30e3, np.deg2rad(35.0)), (120e3, np.deg2rad(-150.0)), (5e3, 2.0)):
        sr, st = 50.0, np.deg2rad(0.25)
        z = A.converted_measurement(rho + sr * rng.standard_normal(M),
                                    th + st * rng.standard_normal(M))
        C = np.cov(z.T)
        R = A.converted_covariance(rho, th, sr, st)
        # sampling error of a covariance entry: sd ~ sqrt(2/M) * scale = 0.22 %; the first-order
        # formula neglects terms of relative size sigma_theta^2 ~ 2e-5; 1.5 % of the largest
        # entry covers both with margin
        scale = np.abs(R).max()
        np.testing.assert_allclose(C, R, atol=0.015 * scale)


def test_cv_process_noise_is_exact_van_loan():
    """Exact CV Q against the Van Loan matrix exponential (white acceleration, PSD q)."""
    q, T = 0.7, 3.3
    Fc = np.zeros((4, 4))
    Fc[0, 1] = Fc[2, 3] = 1.0
    G = np.zeros((4, 2))
    G[1, 0] = G[3, 1] = 1.0
    Qc = G @ (q * np.eye(2)) @ G.T
    V = np.block([[-Fc, Qc], [np.zeros((4, 4)), Fc.T]]) * T
    E = expm(V)
    Phi = E[4:, 4:].T
    Qd = Phi @ E[:4, 4:]
    np.testing.assert_allclose(A.cv_transition([0.0, T])[1], Phi, atol=1e-12)
    # expm is accurate to ~1e-13 relative here
    np.testing.assert_allclose(A.cv_process_noise([0.0, T], q)[1], Qd, rtol=1e-10, atol=1e-12)


def test_gm_discretisation_is_exact():
    """dV' = -a dV + sigma sqrt(2a) n: Phi = e^{-aT}, Qd = sigma^2 (1 - e^{-2aT}) (METHODS.md 2)."""
    a, s, T = 1 / 360.0, 20.0, 7.0
    V = np.array([[a, 2 * a * s**2], [0.0, -a]]) * T
    E = expm(V)
    phi = E[1, 1]
    qd = phi * E[0, 1]
    np.testing.assert_allclose(A.gm_transition([0.0, T], a)[1], phi * np.eye(2), rtol=1e-12)
    np.testing.assert_allclose(A.gm_process_noise([0.0, T], a, s)[1], qd * np.eye(2), rtol=1e-10)
    # stationarity: the variance sigma^2 is kept by the exact recursion for any step
    P = s**2
    for T in (0.1, 1.0, 100.0):
        phi = A.gm_transition([0, T], a)[1, 0, 0]
        P2 = phi**2 * P + A.gm_process_noise([0, T], a, s)[1, 0, 0]
        assert P2 == pytest.approx(P, rel=1e-12)


def test_non_positive_step_rejected():
    with pytest.raises(ValidationError):
        A.cv_transition([0.0, 1.0, 0.0])
    with pytest.raises(ValidationError):
        A.RadarPlots.from_arrays([0.0, 1.0, 1.0], [1e4] * 3, [0.1] * 3, A.ArmsModel())


def test_model_validation():
    with pytest.raises(ValidationError):
        A.ArmsModel(gm_tau_s=0.0)
    with pytest.raises(ValidationError):
        A.ArmsModel(sigma_air_mps=-1.0)


def test_horizontal_range_from_altitude_matches_geodesy():
    """r from slant range and altitude difference against pyproj's station tangent plane.

    Guards the 1.7 km slant/horizontal difference (docs/arms.md) and the plane's drop
    below the aircraft (785 m at 100 km)."""
    st = TangentPlane(47.0, 8.0, 400.0)
    rng = np.random.default_rng(5)
    lat = 47.0 + rng.uniform(-1.0, 1.0, 50)
    lon = 8.0 + rng.uniform(-1.3, 1.3, 50)
    h = rng.uniform(1000.0, 11000.0, 50)
    x, y, u = st.forward(lat, lon, h)
    rho = np.sqrt(x**2 + y**2 + u**2)
    r = A.horizontal_range(rho, lat_deg=47.0, dh_m=h - 400.0)
    # Gaussian radius at the station vs the ellipsoid along the path: a small part of r^2/2R
    np.testing.assert_allclose(r, np.hypot(x, y), atol=1.0)
    el = np.rad2deg(np.arcsin(u / rho))
    np.testing.assert_allclose(A.horizontal_range(rho, lat_deg=47.0, elevation_deg=el),
                               np.hypot(x, y),
                               rtol=1e-12)
    with pytest.raises(ValidationError):
        A.horizontal_range([1000.0], lat_deg=47.0, dh_m=[2000.0])


@pytest.mark.parametrize("lin,conv_at", [("ekf", "predicted"), ("converted", "measured"),
                                         ("converted", "predicted")])
def test_kernel_update_matches_numpy_reference(lin, conv_at):
    """One predict + update of the track model on the core's forward loop against a textbook
    numpy EKF step."""
    m = A.ArmsModel(q_m2ps3=0.3, sigma_air_mps=0.4)
    t = np.array([0.0, 2.5])
    dt = np.diff(t, prepend=t[0])
    F = A.joint_transition(dt, m.alpha_ps)
    Q = A.joint_process_noise(dt, m.q_m2ps3, m.alpha_ps, m.gm_sigma_mps)
    x0 = np.array([20e3, 80.0, -35e3, -40.0, 3.0, -2.0])
    P0 = np.diag([300.0, 5.0, 250.0, 4.0, 10.0, 12.0]) ** 2
    radar = np.array([[np.nan, np.nan], [40.4e3, np.deg2rad(150.1)]])
    sd = np.array([[1.0, 1.0], [m.sigma_range_m, m.sigma_azimuth_rad]])
    air = np.array([[np.nan, np.nan], [83.0, -43.5]])
    Rv = m.sigma_air_mps**2 * np.eye(2)
    model = A.arms_track_model(F, Q, radar, sd, air, Rv, A.linearisation_code(lin, conv_at))
    forward_pass(model, x0, P0, 2)
    xp = F[1] @ x0
    Pp = F[1] @ P0 @ F[1].T + Q[1]
    Hv = np.zeros((2, 6))
    Hv[0, 1] = Hv[0, 4] = Hv[1, 3] = Hv[1, 5] = 1.0
    if lin == "ekf":
        Hr = A.range_azimuth_jacobian(xp)
        nur = radar[1] - A.range_azimuth(xp)
        nur[1] = A.wrap_angle(nur[1])
        Rr = np.diag(sd[1] ** 2)
    else:
        Hr = np.zeros((2, 6))
        Hr[0, 0] = Hr[1, 2] = 1.0
        nur = A.converted_measurement(*radar[1]) - xp[[0, 2]]
        at = radar[1] if conv_at == "measured" else A.range_azimuth(xp)
        Rr = A.converted_covariance(at[0], at[1], *sd[1])
    H = np.vstack([Hr, Hv])
    nu = np.concatenate([nur, air[1] - Hv @ xp])
    R = np.zeros((4, 4))
    R[:2, :2] = Rr
    R[2:, 2:] = Rv
    S = H @ Pp @ H.T + R
    K = Pp @ H.T @ np.linalg.inv(S)
    x1 = xp + K @ nu
    P1 = (np.eye(6) - K @ H) @ Pp
    # Joseph and simple forms agree for the optimal gain up to rounding of a well-conditioned S
    np.testing.assert_allclose(model.x_p[1], xp, rtol=1e-12)
    np.testing.assert_allclose(model.x_f[1], x1, rtol=1e-9, atol=1e-8)
    np.testing.assert_allclose(model.P_f[1], P1, rtol=1e-7, atol=1e-7 * np.abs(P1).max())
    assert model.nis[1] == pytest.approx(nu @ np.linalg.solve(S, nu), rel=1e-9)
    assert model.radar_used[1] and model.air_used[1]


def test_joint_model_is_block_diagonal_of_cv_and_gm():
    """The joint transition/noise are exactly block-diag(CV, Gauss-Markov) (no cross terms)."""
    dt = np.array([0.0, 0.25, 1.0, 7.5])
    a, s, q = 1 / 360.0, 20.0, 0.3
    F = A.joint_transition(dt, a)
    Q = A.joint_process_noise(dt, q, a, s)
    np.testing.assert_array_equal(F[:, :4, :4], A.cv_transition(dt))
    np.testing.assert_array_equal(F[:, 4:, 4:], A.gm_transition(dt, a))
    np.testing.assert_array_equal(Q[:, :4, :4], A.cv_process_noise(dt, q))
    np.testing.assert_array_equal(Q[:, 4:, 4:], A.gm_process_noise(dt, a, s))
    assert not F[:, :4, 4:].any() and not F[:, 4:, :4].any()
    assert not Q[:, :4, 4:].any() and not Q[:, 4:, :4].any()
