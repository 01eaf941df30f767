"""The aided observation of the azimuth channel (METHODS.md s. 3, docs/azimuth.md).

* the transverse-acceleration relation ``a_E cos eps - a_N sin eps = 2 r_dot omega + r a``
  against numerical differentiation of the azimuth of simulated curved paths;
* horizontal acceleration from loads and attitude, its analytic Jacobian against finite
  differences, and the propagated covariance against a sampled one.
"""

import sys
from pathlib import Path

import numpy as np
import pytest

from flightrecon.constants import G0
from flightrecon.errors import ValidationError
from flightrecon.methods.azimuth import (
    horizontal_acceleration,
    horizontal_acceleration_covariance,
    horizontal_acceleration_jacobian,
    transverse_acceleration,
)

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "scripts"))
import mc_azimuth as mc


def circle_path(t, centre=(6000.0, -3000.0), radius=2500.0, w=0.04, phase=0.3):
    """A circle not centred on the station, in closed form (N, E, vN, vE, aN, aE)."""
    th = phase + w * t
    n = centre[0] + radius * np.cos(th)
    e = centre[1] + radius * np.sin(th)
    vn, ve = -radius * w * np.sin(th), radius * w * np.cos(th)
    an, ae = -radius * w**2 * np.cos(th), -radius * w**2 * np.sin(th)
    return n, e, vn, ve, an, ae


def numerical_polar(n, e, h):
    """Azimuth, its first two derivatives and the range rate by central differences (O(h^2))."""
    eps = np.unwrap(np.arctan2(e, n))
    r = np.hypot(n, e)
    om = (eps[2:] - eps[:-2]) / (2 * h)
    acc = (eps[2:] - 2 * eps[1:-1] + eps[:-2]) / h**2
    rd = (r[2:] - r[:-2]) / (2 * h)
    return eps[1:-1], r[1:-1], rd, om, acc


def test_transverse_relation_on_circle():
    """z = 2 r_dot omega + r a on a closed-form circle, derivatives by central differences.

    Step h = 0.01 s: the truncation error of the second difference is h^2/12 eps'''' ~ 1e-13
    rad/s^2 and round-off ~ 1e-16 * pi / h^2 ~ 3e-12 rad/s^2; times r (<= 1e4 m) that is
    < 1e-7 m/s^2 against z of ~4 m/s^2: tolerance 1e-6 m/s^2.
    """
    h = 0.01
    t = np.arange(0.0, 200.0, h)
    n, e, _, _, an, ae = circle_path(t)
    eps, r, rd, om, acc = numerical_polar(n, e, h)
    z = transverse_acceleration(np.stack([an, ae], -1)[1:-1], eps)
    assert np.max(np.abs(z)) > 1.0  # a real turn
    np.testing.assert_allclose(z, 2 * rd * om + r * acc, rtol=0, atol=1e-6)


def test_transverse_relation_on_simulated_landing():
    """The relation on the Monte Carlo landing paths (numerically integrated, 16 Hz).

    Positions are the trapezoid integral of velocity, so azimuth differs from the exact one by
    ~dt^2 effects: differentiate with h = 1/16 s and compare with tolerance 2e-3 m/s^2
    (second-difference truncation h^2/12 |eps''''| r ~ 1e-4, kinks of the trapezoidal roll-in
    at grid points give isolated larger values, so the 99th percentile is tested besides the
    bound on the median).
    """
    rng = np.random.default_rng(7)
    tr = mc.landing_truth(rng, 3)
    h = tr.t[1] - tr.t[0]
    for j in range(3):
        eps, r, rd, om, acc = numerical_polar(tr.north[j], tr.east[j], h)
        z = transverse_acceleration(np.stack([tr.an[j], tr.ae[j]], -1)[1:-1], eps)
        d = np.abs(z - (2 * rd * om + r * acc))
        assert np.median(d) < 2e-4
        assert np.quantile(d, 0.99) < 2e-3
        # and the generator's analytic omega and angular acceleration agree with the numbers
        # (1e-6 rad/s and 1e-7 rad/s^2: trapezoid integration error over the run)
        assert np.quantile(np.abs(om - tr.omega[j, 1:-1]), 0.99) < 1e-6
        assert np.quantile(np.abs(acc - tr.accel[j, 1:-1]), 0.99) < 1e-7


def _inputs(rng, n=50):
    return (rng.normal(0.05, 0.1, n), rng.normal(0.0, 0.05, n), rng.normal(1.2, 0.3, n),
            rng.uniform(-60, 60, n), rng.uniform(-20, 20, n), rng.uniform(0, 360, n))


def test_horizontal_acceleration_level_flight_and_turn():
    """Level unaccelerated flight -> 0; coordinated level turn -> centripetal g tan(roll)."""
    a = horizontal_acceleration([0.0], [0.0], [1.0], [0.0], [0.0], [123.0])
    np.testing.assert_allclose(a, 0.0, atol=1e-12)
    roll = 30.0
    a = horizontal_acceleration([0.0], [0.0], [1 / np.cos(np.radians(roll))], [roll], [0.0],
                                [90.0])  # heading east, right turn: acceleration to the south
    np.testing.assert_allclose(a[0], [-G0 * np.tan(np.radians(roll)), 0.0], atol=1e-12)


def test_loads_of_generator_reproduce_its_acceleration():
    """The Monte Carlo generator's loads/attitude give back its kinematic acceleration (1e-9)."""
    tr = mc.landing_truth(np.random.default_rng(3), 2)
    a = horizontal_acceleration(tr.n_long_g, tr.n_lat_g, tr.n_norm_g, tr.roll_deg,
                                tr.pitch_deg, tr.heading_deg)
    np.testing.assert_allclose(a[..., 0], tr.an, atol=1e-9)
    np.testing.assert_allclose(a[..., 1], tr.ae, atol=1e-9)


def test_jacobian_matches_finite_differences():
    """Analytic Jacobian vs central differences (step 1e-6 g / 1e-6 rad: error ~1e-9)."""
    rng = np.random.default_rng(11)
    x = np.stack(_inputs(rng), -1)
    J = horizontal_acceleration_jacobian(*x.T)
    for c in range(6):
        step = 1e-6 if c < 3 else np.degrees(1e-6)  # angles are given in degrees
        xp, xm = x.copy(), x.copy()
        xp[:, c] += step
        xm[:, c] -= step
        fd = (horizontal_acceleration(*xp.T) - horizontal_acceleration(*xm.T)) / 2e-6
        np.testing.assert_allclose(J[:, :, c], fd, rtol=0, atol=1e-7)


def test_propagated_covariance_matches_sampling():
    """J Sigma J^T against the sample covariance of (a_N, a_E) under sensor noise.

    20000 samples: the sample covariance has relative standard error sqrt(2/20000) = 1 %; the
    first-order propagation is exact to (sigma_angle)^2 ~ 1e-4 here.  Tolerance 5 % of the
    largest variance.
    """
    rng = np.random.default_rng(5)
    x0 = np.array([0.03, 0.01, 1.15, 28.0, 4.0, 210.0])
    sig = {"sigma_load_g": 0.01, "sigma_attitude_deg": 0.3, "sigma_heading_deg": 0.8}
    C = horizontal_acceleration_covariance(*[np.array([v]) for v in x0], **sig)[0]
    m = 20000
    s = np.array([0.01, 0.01, 0.01, 0.3, 0.3, 0.8])
    xs = x0 + s * rng.standard_normal((m, 6))
    a = horizontal_acceleration(*xs.T)
    np.testing.assert_allclose(np.cov(a.T), C, atol=0.05 * C.max())


def test_negative_sigma_raises():
    with pytest.raises(ValidationError):
        horizontal_acceleration_covariance([0.0], [0.0], [1.0], [0.0], [0.0], [0.0],
                                           sigma_load_g=-1.0, sigma_attitude_deg=0.1,
                                           sigma_heading_deg=0.1)
