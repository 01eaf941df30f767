"""Kinematic acceleration from load factors (METHODS.md "Common ground") and normal gravity."""

import numpy as np
import pytest

from flightrecon.constants import G0
from flightrecon.geo.gravity import GAMMA_EQUATOR, GAMMA_POLE, normal_gravity
from flightrecon.geo.kinematics import (
    body_to_ned_matrix,
    kinematic_acceleration_ned,
    load_factors_from_acceleration,
)

# Every closed-form case below is exact algebra in float64; 1e-9 m/s^2 leaves room for the
# ~1e-15 relative rounding of the trigonometric functions and the 9.8 m/s^2 scale.
ATOL = 1e-9


def test_normal_gravity_reference_values():
    # TR8350.2 table 3.4 values on the ellipsoid (the formula reproduces them to rounding)
    assert normal_gravity(0.0, 0.0) == pytest.approx(GAMMA_EQUATOR, abs=1e-12)
    assert normal_gravity(90.0, 0.0) == pytest.approx(GAMMA_POLE, abs=1e-9)
    # independent check: the GRS80 series (Moritz 1980, Geodetic Reference System 1980, accurate
    # to 1e-10 relative); WGS-84 gamma_e is 1.4356e-6 m/s^2 smaller and the two ellipsoids differ
    # by 1.4306e-6 to 1.4356e-6 m/s^2 pole to equator, so the offset is pinned to +-1e-8
    lat = np.linspace(-90, 90, 37)
    s = np.sin(np.radians(lat)) ** 2
    grs80 = 9.7803267715 * (1 + 0.0052790414 * s + 0.0000232718 * s**2 + 0.0000001262 * s**3
                            + 0.0000000007 * s**4)
    np.testing.assert_allclose(normal_gravity(lat, 0.0) - grs80, -1.433e-6, atol=1e-8)
    # free-air gradient: -3.086e-6 s^-2 at mid latitudes (textbook value to 0.1 %)
    grad = (normal_gravity(45.0, 1000.0) - normal_gravity(45.0, 0.0)) / 1000.0
    assert grad == pytest.approx(-3.086e-6, rel=2e-3)


def test_body_to_ned_matrix_orthonormal_and_axes():
    rng = np.random.default_rng(1)
    r, p, h = rng.uniform(-180, 180, 50), rng.uniform(-89, 89, 50), rng.uniform(0, 360, 50)
    C = body_to_ned_matrix(r, p, h)
    assert C.shape == (50, 3, 3)
    np.testing.assert_allclose(C @ np.transpose(C, (0, 2, 1)), np.broadcast_to(np.eye(3), C.shape),
                               atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(C), 1.0, atol=1e-14)
    # heading 90, level: body forward points east, right wing points south
    C = body_to_ned_matrix(0.0, 0.0, 90.0)[0]
    np.testing.assert_allclose(C @ [1, 0, 0], [0, 1, 0], atol=1e-15)
    np.testing.assert_allclose(C @ [0, 1, 0], [-1, 0, 0], atol=1e-15)
    # pitch up 30: forward axis climbs (negative down component)
    C = body_to_ned_matrix(0.0, 30.0, 0.0)[0]
    np.testing.assert_allclose(C @ [1, 0, 0], [np.cos(np.pi / 6), 0, -0.5], atol=1e-15)
    # roll 30 right wing down: right wing gains a positive down component
    C = body_to_ned_matrix(30.0, 0.0, 0.0)[0]
    np.testing.assert_allclose(C @ [0, 1, 0], [0, np.cos(np.pi / 6), 0.5], atol=1e-15)


def test_level_unaccelerated_flight_is_zero():
    lat, h = 52.0, 3000.0
    g = float(normal_gravity(lat, h))
    a = kinematic_acceleration_ned([0.0], [0.0], [g / G0], [0.0], [0.0], [123.0], lat_deg=lat,
                                   h_m=h)
    np.testing.assert_allclose(a, 0.0, atol=ATOL)


def test_naive_triad_would_give_two_g():
    """Guards the sign of n_norm: feeding [n_long, n_lat, n_norm] into C_nb doubles gravity."""
    a = kinematic_acceleration_ned(0.0, 0.0, 1.0, 0.0, 0.0, 0.0, lat_deg=45.0, h_m=0.0)
    assert abs(a[0, 2]) < 0.01  # correct convention: ~0 (g(45 deg) - g0 = -4.5e-4 m/s^2)


@pytest.mark.parametrize("roll", [15.0, -30.0, 45.0, 60.0])
@pytest.mark.parametrize("heading", [0.0, 77.0, 270.0])
def test_coordinated_level_turn_points_to_centre(roll, heading):
    lat, h = 30.0, 1500.0
    g = float(normal_gravity(lat, h))
    # coordinated level turn: body specific force along -z only, |f| = g / cos(roll)
    a = kinematic_acceleration_ned(0.0, 0.0, g / (G0 * np.cos(np.radians(roll))), roll, 0.0,
                                   heading, lat_deg=lat, h_m=h)[0]
    psi = np.radians(heading)
    right = np.array([-np.sin(psi), np.cos(psi), 0.0])  # horizontal unit vector to the right
    np.testing.assert_allclose(a, g * np.tan(np.radians(roll)) * right, atol=ATOL)


@pytest.mark.parametrize("gamma", [3.0, 10.0, -5.0])
def test_steady_climb_or_descent_is_zero(gamma):
    # steady straight climb at flight-path angle gamma with 4 deg angle of attack
    lat, h = 45.0, 2000.0
    g = float(normal_gravity(lat, h))
    theta = np.radians(gamma + 4.0)
    n_long = g * np.sin(theta) / G0
    n_norm = g * np.cos(theta) / G0
    a = kinematic_acceleration_ned(n_long, 0.0, n_norm, 0.0, np.degrees(theta), 200.0,
                                   lat_deg=lat, h_m=h)
    np.testing.assert_allclose(a, 0.0, atol=ATOL)


def test_pull_up_centripetal_up():
    # bottom of a loop / pull-up: wings level, pitch 0, V = 120 m/s, radius 1500 m
    lat, h = 45.0, 500.0
    g = float(normal_gravity(lat, h))
    v, r = 120.0, 1500.0
    a = kinematic_acceleration_ned(0.0, 0.0, (g + v**2 / r) / G0, 0.0, 0.0, 45.0,
                                   lat_deg=lat, h_m=h)[0]
    np.testing.assert_allclose(a, [0.0, 0.0, -v**2 / r], atol=ATOL)


def test_at_rest_with_pitch_and_roll_is_zero():
    lat, h = 60.0, 100.0
    g = float(normal_gravity(lat, h))
    phi, theta = np.radians(5.0), np.radians(8.0)
    # gravity reaction seen in body axes: f_b = -g * (third row of C_nb)
    n_long = g * np.sin(theta) / G0
    n_lat = -g * np.sin(phi) * np.cos(theta) / G0
    n_norm = g * np.cos(phi) * np.cos(theta) / G0
    a = kinematic_acceleration_ned(n_long, n_lat, n_norm, 5.0, 8.0, 310.0, lat_deg=lat, h_m=h)
    np.testing.assert_allclose(a, 0.0, atol=ATOL)


def test_inverse_round_trip_vectorised():
    rng = np.random.default_rng(7)
    n = 1000
    a = rng.normal(0, 5, (n, 3))
    r, p, h = rng.uniform(-80, 80, n), rng.uniform(-60, 60, n), rng.uniform(0, 360, n)
    lat, alt = rng.uniform(-70, 70, n), rng.uniform(0, 12000, n)
    nl = load_factors_from_acceleration(a, r, p, h, lat_deg=lat, h_m=alt)
    back = kinematic_acceleration_ned(nl[:, 0], nl[:, 1], nl[:, 2], r, p, h, lat_deg=lat, h_m=alt)
    np.testing.assert_allclose(back, a, atol=ATOL)


def test_speed_576k_samples():
    import time

    n = 576_000
    z = np.zeros(n)
    t0 = time.perf_counter()
    a = kinematic_acceleration_ned(z, z, z + 1.0, z, z, z, lat_deg=45.0, h_m=z)
    assert a.shape == (n, 3)
    # vectorised numpy: ~0.1 s here; 5 s leaves room for a loaded shared machine
    assert time.perf_counter() - t0 < 5.0


def test_given_rotation_gives_the_same_acceleration_and_nan_where_an_angle_is_missing():
    rng = np.random.default_rng(8)
    n = 50
    roll, pitch, hdg = rng.uniform(-60, 60, n), rng.uniform(-20, 20, n), rng.uniform(0, 360, n)
    nl, nt, nn = rng.normal(0, 0.1, n), rng.normal(0, 0.1, n), 1 + rng.normal(0, 0.2, n)
    roll[7] = np.nan
    want = kinematic_acceleration_ned(nl, nt, nn, roll, pitch, hdg, lat_deg=30.0, h_m=1000.0)
    C = body_to_ned_matrix(np.nan_to_num(roll), pitch, hdg)
    got = kinematic_acceleration_ned(nl, nt, nn, roll, pitch, hdg, lat_deg=30.0, h_m=1000.0,
                                     C_nb=C)
    assert np.isnan(got[7]).all() and np.isnan(want[7]).all()
    # same products in a different order: round-off of ~10 m/s^2 values
    np.testing.assert_allclose(np.delete(got, 7, 0), np.delete(want, 7, 0), atol=1e-12)
