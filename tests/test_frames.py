"""Moving local-level frame (flightrecon.geo.navframe) against pyproj."""

import numpy as np
import pytest
from pyproj import Geod

from flightrecon.errors import ValidationError
from flightrecon.geo.frames import ecef_to_geodetic, geodetic_to_ecef
from flightrecon.geo.navframe import (
    ecef_to_ned_vector,
    integrate_local_level,
    ned_to_ecef_matrix,
    ned_to_ecef_vector,
    radii_of_curvature,
    transport_rate_ned,
)

GEOD = Geod(ellps="WGS84")
MM = 1e-3


def test_geodetic_ecef_round_trip():
    rng = np.random.default_rng(3)
    lat, lon, h = rng.uniform(-85, 85, 200), rng.uniform(-180, 180, 200), rng.uniform(-500, 2e4, 200)
    x, y, z = geodetic_to_ecef(lat, lon, h)
    lat2, lon2, h2 = ecef_to_geodetic(x, y, z)
    # PROJ's inverse is iterative: sub-micrometre (1e-9 deg ~ 0.1 mm is a loose bound)
    np.testing.assert_allclose(lat2, lat, atol=1e-9)
    np.testing.assert_allclose(lon2, lon, atol=1e-9)
    np.testing.assert_allclose(h2, h, atol=1e-6)


def test_ned_matrix_matches_pyproj_finite_differences():
    """The NED axes (columns of C_en) are the ECEF directions of small geodetic displacements."""
    lat, lon, h = 47.3, -122.1, 3000.0
    C = ned_to_ecef_matrix(lat, lon)[0]
    rm, rn = radii_of_curvature(lat)
    d = 1.0  # metres: second-order error d/R ~ 2e-7, far below the 1e-6 tolerance
    p0 = np.array(geodetic_to_ecef(lat, lon, h))
    north = np.array(geodetic_to_ecef(lat + np.degrees(d / (rm + h)), lon, h)) - p0
    east = np.array(geodetic_to_ecef(lat, lon + np.degrees(d / ((rn + h) * np.cos(np.radians(lat)))),
                                     h)) - p0
    down = np.array(geodetic_to_ecef(lat, lon, h - d)) - p0
    np.testing.assert_allclose(north, C[:, 0], atol=1e-6)
    np.testing.assert_allclose(east, C[:, 1], atol=1e-6)
    np.testing.assert_allclose(down, C[:, 2], atol=1e-6)
    v = np.array([[3.0, -4.0, 12.0]])
    np.testing.assert_allclose(ecef_to_ned_vector(lat, lon, ned_to_ecef_vector(lat, lon, v)), v,
                               atol=1e-12)


def test_transport_rate_values():
    w = transport_rate_ned(0.0, 0.0, 0.0, 250.0)[0]
    assert w[0] == pytest.approx(250.0 / 6378137.0, rel=1e-12)
    assert w[1] == 0.0 and abs(w[2]) < 1e-20


@pytest.mark.parametrize("h", [0.0, 11000.0])
def test_400km_meridian_leg_mm(h):
    """North along a meridian at constant height: distance on the ellipsoid from pyproj."""
    v, rate = 250.0, 16.0
    n = int(400e3 / v * rate)
    lat, lon, hh = integrate_local_level(40.0, 10.0, h, np.full(n, v), np.zeros(n), np.zeros(n),
                                         1.0 / rate)
    np.testing.assert_allclose(hh, h, atol=MM)  # altitude kept
    assert np.all(lon == 10.0)
    # at height h the meridian arc is s_h = s_0 + h * dlat (d s_h = (R_M + h) dlat): solve for
    # the surface arc s_0 that the 400 km flown at height correspond to, then ask pyproj
    dlat = np.radians(lat[-1] - 40.0)
    s0 = GEOD.inv(10.0, 40.0, 10.0, lat[-1])[2]
    err_m = (s0 + h * dlat) - 400e3
    assert abs(err_m) < MM


def test_400km_equator_leg_mm():
    v, rate = 230.0, 16.0
    n = int(400e3 / v * rate)
    dt = 400e3 / v / n
    lat, lon, _ = integrate_local_level(0.0, 179.0, 0.0, np.zeros(n), np.full(n, v), np.zeros(n), dt)
    lon2, lat2, _ = GEOD.fwd(179.0, 0.0, 90.0, 400e3)
    np.testing.assert_allclose(lat, 0.0, atol=1e-15)
    # longitude wrapped across the antimeridian like pyproj's
    dist = GEOD.inv(lon[-1], lat[-1], lon2, lat2)[2]
    assert dist < MM


def test_400km_oblique_geodesic_mm():
    """Follow pyproj's geodesic at 45 deg with the azimuth at each step's midpoint."""
    v, rate = 250.0, 16.0
    n = int(400e3 / v * rate)
    dt = 1.0 / rate
    s_mid = (np.arange(n) + 0.5) * v * dt
    lon0, lat0 = 10.0, 50.0
    _, _, back = GEOD.fwd(np.full(n, lon0), np.full(n, lat0), np.full(n, 45.0), s_mid)
    az = np.radians(back + 180.0)  # forward azimuth at the midpoint
    lat, lon, h = integrate_local_level(lat0, lon0, 0.0, v * np.cos(az), v * np.sin(az),
                                        np.zeros(n), dt)
    lon2, lat2, _ = GEOD.fwd(lon0, lat0, 45.0, n * v * dt)
    # piecewise-constant azimuth vs the continuously turning geodesic: the chord error per
    # 15.6 m step is ~ L dpsi^2 / 24 ~ 1e-12 m, so the whole leg must stay within a millimetre
    assert GEOD.inv(lon[-1], lat[-1], lon2, lat2)[2] < MM
    np.testing.assert_allclose(h, 0.0, atol=MM)


def test_velocity_consistent_with_pyproj_ecef():
    """ECEF chord / dt equals the NED velocity rotated at the midpoint (climbing turn)."""
    n = 200
    t = np.arange(n) * 0.5
    vn, ve, vu = 200 * np.cos(t / 30), 200 * np.sin(t / 30), np.full(n, 8.0)
    lat, lon, h = integrate_local_level(35.0, 139.0, 1000.0, vn, ve, vu, 0.5)
    p = np.stack(geodetic_to_ecef(lat, lon, h), axis=1)
    chord = np.diff(p, axis=0) / 0.5
    mid_lat, mid_lon = 0.5 * (lat[1:] + lat[:-1]), 0.5 * (lon[1:] + lon[:-1])
    v_ecef = ned_to_ecef_vector(mid_lat, mid_lon, np.stack([vn, ve, -vu], axis=1))
    # chord vs midpoint tangent differs by O(v * (v dt / R)^2) ~ 1e-9 m/s plus the frame rotation
    # over half a step (v * dt * v / R / 2 ~ 2e-3 m/s of along-track curvature): 1e-2 m/s bound
    np.testing.assert_allclose(chord, v_ecef, atol=1e-2)
    assert lat.shape == (n + 1,)


def test_bad_input_raises():
    with pytest.raises(ValidationError):
        integrate_local_level(40.0, 10.0, 0.0, [1.0, np.nan], [0.0, 0.0], [0.0, 0.0], 1.0)
    with pytest.raises(ValidationError):
        integrate_local_level(40.0, 10.0, 0.0, [1.0], [0.0], [0.0], 0.0)
    with pytest.raises(ValidationError):
        integrate_local_level(89.95, 10.0, 0.0, [1.0], [0.0], [0.0], 1.0)


def test_speed_10h_flight():
    import time

    n = 576_000
    integrate_local_level(40.0, 10.0, 0.0, np.ones(3), np.ones(3), np.ones(3), 1.0)  # compile
    t0 = time.perf_counter()
    integrate_local_level(40.0, 10.0, 10000.0, np.full(n, 20.0), np.full(n, 200.0), np.zeros(n),
                          1 / 16)
    # compiled loop: ~0.1 s; 5 s allows for a loaded shared machine
    assert time.perf_counter() - t0 < 5.0


@pytest.mark.parametrize("lat0", [0.0, 50.0, -35.0, 75.0])
def test_frame_rate_acceleration_closes_the_ecef_kinematics(lat0):
    """Guards the joint smoother's Coriolis and transport-rate term against an independent
    derivation: a curved, climbing, accelerating path given in geodetic coordinates, its
    Earth-fixed velocity and acceleration by central differences of the ECEF positions, the
    sensed kinematic acceleration f + g = r_ee'' + 2 Omega x r_ee' (rotating-frame mechanics, in
    ECEF), and the NED velocity's own rate dv/dt by central differences: dv/dt must equal
    (f + g)_NED + frame_rate_acceleration.  A term missing was measured on JSBSim's jet as a
    0.024 m/s^2 gap between the recorded loads and the truth's dv/dt.  Tolerance 2e-5 m/s^2:
    the differences' truncation at a 0.5 s step (the terms themselves are 1e-3 to 3e-2)."""
    from flightrecon.constants import WGS84_OMEGA
    from flightrecon.geo.navframe import frame_rate_acceleration

    t = np.arange(-2.0, 602.0, 0.5)
    lat = lat0 + 1.2e-3 * t + 2e-7 * t**2           # ~230 m/s north-east, turning
    lon = 10.0 + 2.0e-3 * t - 1e-6 * t**2
    h = 9000.0 + 5.0 * t - 4e-3 * t**2
    x, y, z = geodetic_to_ecef(lat, lon, h)
    r = np.c_[x, y, z]
    dt = 0.5
    rd = np.gradient(r, dt, axis=0, edge_order=2)
    rdd = np.gradient(rd, dt, axis=0, edge_order=2)
    W = np.array([0.0, 0.0, WGS84_OMEGA])
    fg_e = rdd + 2.0 * np.cross(W, rd)
    C = ned_to_ecef_matrix(lat, lon)                 # (n, 3, 3) NED -> ECEF
    v = np.einsum("kji,kj->ki", C, rd)
    fg = np.einsum("kji,kj->ki", C, fg_e)
    vdot = np.gradient(v, dt, axis=0, edge_order=2)
    c = frame_rate_acceleration(lat, h, v)
    inner = slice(10, -10)
    assert np.max(np.abs(c[inner])) > 1e-3          # the term is there to be checked
    np.testing.assert_allclose(vdot[inner], (fg + c)[inner], atol=2e-5)


def test_radii_of_arrays_are_the_compiled_scalar_radii_to_the_bit():
    """radii_of_curvature runs the formula in numpy on arrays (no array specialisation of the
    kernel to compile); each element must be the compiled kernel's scalar result exactly."""
    from flightrecon.geo.ellipsoid import radii_from_sin

    lat = np.concatenate([np.linspace(-90.0, 90.0, 721), [0.0, 1e-9, 45.123456789, 89.9999]])
    rm, rn = radii_of_curvature(lat)
    for k, phi in enumerate(lat):
        m, n = radii_from_sin(float(np.sin(np.radians(phi))))
        assert rm[k] == m and rn[k] == n, phi
