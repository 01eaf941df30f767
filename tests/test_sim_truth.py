"""Truth self-consistency of the simulator (docs/simulator.md, "Tests").

The truth is what every estimator is judged against, so each relation that defines it is
checked independently: position vs velocity (an independent ODE solver and pyproj's ECEF),
velocity vs acceleration (finite differences), loads vs acceleration and attitude (METHODS.md
"Common ground"), the tangent plane (pyproj round trip), long legs (pyproj geodesic).
"""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pyproj import Geod
from scipy.integrate import quad, solve_ivp

from flightrecon.constants import G0
from flightrecon.geo.atmosphere import pressure_altitude_m
from flightrecon.geo.frames import TangentPlane, geodetic_to_ecef, output_plane
from flightrecon.geo.wgs84 import WGS84_A, WGS84_E2
from flightrecon.sim import acceleration_from_loads, simulate
from flightrecon.sim.kinematics import coordinated_roll_rad, loads_from_acceleration
from flightrecon.sim.plan import PlanBuilder
from flightrecon.sim.profiles import SmoothProfile
from flightrecon.sim.scenarios import build_plan, scenario_config
from flightrecon.sim.trajectory import kinematics, simulate_truth
from flightrecon.sim.weather import Atmosphere, WindField, geopotential_height_m
from flightrecon.types import FlightMeta


@pytest.fixture(scope="module")
def circuit():
    return simulate("circuit", seed=0)


@pytest.fixture(scope="module")
def circuit_plan():
    return build_plan("circuit", scenario_config("circuit"))[0]


def test_profile_derivative_and_integral_match_numerics():
    """Closed-form derivative and integral of a smooth-step profile vs finite differences and
    adaptive quadrature (both exact to ~1e-9 here: h = 1e-5 s, S''' <= 60 / d^3)."""
    p = SmoothProfile.build(2.0, [(1.0, 3.0, 5.0), (2.5, 2.0, -4.0), (10.0, 0.5, 1.0)])
    t = np.linspace(0.0, 12.0, 241)
    v, d, integ = p.evaluate(t)
    h = 1e-5
    fd = (p.value(t + h) - p.value(t - h)) / (2 * h)
    assert np.max(np.abs(fd - d)) < 1e-6  # truncation h^2/6*S''' ~ 1e-9, rounding 1e-11/h
    for tj, ij in zip(t[::20], integ[::20]):
        ref = quad(lambda x: float(p.value(np.array([x]))[0]), 0.0, tj, points=[1, 2.5, 4, 4.5,
                                                                                  10, 10.5],
                   epsabs=1e-12, limit=200)[0]
        assert abs(ref - ij) < 1e-8
    assert v[-1] == pytest.approx(p.final(), abs=1e-12)


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(st.floats(0.0, 50.0), st.floats(0.2, 20.0), st.floats(-50.0, 50.0)),
                min_size=1, max_size=6),
       st.floats(0.0, 80.0))
def test_profile_derivative_property(steps, t):
    """Any profile: derivative = central difference (h = 1e-4 s; truncation h^2/6 * 60 * 50 /
    0.2^3 ~ 6e-4 worst case, so 1e-3 absolute) and integral increments = Simpson's rule on a
    0.01 s panel (error 0.01^5/2880 max|v''''| < 4e-7 for the steepest step drawn: 50 in
    0.2 s; so 1e-6)."""
    p = SmoothProfile.build(1.0, steps)
    h = 1e-4
    v, d, i = p.evaluate(np.array([t, t + 0.01]))
    fd = (p.value(np.array([t + h])) - p.value(np.array([t - h])))[0] / (2 * h)
    assert abs(fd - d[0]) < 1e-3
    mid = p.value(np.array([t + 0.005]))[0]
    simpson = 0.01 / 6 * (v[0] + 4 * mid + v[1])
    assert abs((i[1] - i[0]) - simpson) < 1e-6


def test_truth_gravity_and_loads_agree_with_geo_modules(circuit):
    """The truth uses flightrecon.geo.gravity, and its loads agree with the estimators'
    flightrecon.geo.kinematics relation (two implementations of METHODS.md "Common ground"):
    the sensed f + g plus the frame's rotation (Coriolis and transport rate,
    geo.navframe.frame_rate_acceleration) is the truth's dv/dt, to rounding (1e-9 m/s^2; the
    frame term itself is about 1e-2 here, so leaving it out on either side fails)."""
    from flightrecon.geo.gravity import normal_gravity
    from flightrecon.geo.kinematics import kinematic_acceleration_ned
    from flightrecon.geo.navframe import frame_rate_acceleration
    tr = circuit.truth
    assert np.array_equal(tr.gravity_mps2, normal_gravity(tr.lat_deg, tr.alt_m))
    a = kinematic_acceleration_ned(tr.n_long_g, tr.n_lat_g, tr.n_norm_g, tr.roll_deg,
                                   tr.pitch_deg, tr.heading_deg, lat_deg=tr.lat_deg,
                                   h_m=tr.alt_m)
    v = np.column_stack([tr.vn_mps, tr.ve_mps, -tr.vu_mps])
    c = frame_rate_acceleration(tr.lat_deg, tr.alt_m, v)
    ref = np.column_stack([tr.an_mps2, tr.ae_mps2, -tr.au_mps2])
    assert np.max(np.abs(c)) > 1e-3
    assert np.max(np.abs(a + c - ref)) < 1e-9


def test_velocity_integrates_to_position_independent_solver(circuit_plan):
    """DOP853 (rtol 1e-12) on the geodetic ODE with the closed-form velocity reproduces the
    truth latitude/longitude; RK4 at dt = 1/16 s has a global error far below 1 mm here."""
    plan = circuit_plan
    cfg = scenario_config("circuit")
    truth = simulate_truth(plan, 16.0, output_plane(FlightMeta(
        departure=cfg.airfield, geoid_undulation_m=cfg.geoid_undulation_m)))

    def rhs(t, y):
        k = kinematics(plan, np.array([t]))
        s2 = np.sin(y[0]) ** 2
        w = np.sqrt(1 - WGS84_E2 * s2)
        h = k.h_msl_m[0] + plan.geoid_undulation_m
        return [k.vn_mps[0] / (WGS84_A * (1 - WGS84_E2) / w**3 + h),
                k.ve_mps[0] / ((WGS84_A / w + h) * np.cos(y[0]))]

    t_end = 400.0  # take-off, climb and two turns: keeps the solver fast
    sol = solve_ivp(rhs, (0, t_end), [np.radians(plan.lat0_deg), np.radians(plan.lon0_deg)],
                    method="DOP853", rtol=1e-12, atol=1e-14, max_step=2.0)
    i = int(t_end * 16)
    dn = (np.degrees(sol.y[0, -1]) - truth["lat_deg"].iloc[i]) * 111e3
    de = (np.degrees(sol.y[1, -1]) - truth["lon_deg"].iloc[i]) * 85e3
    assert abs(dn) < 1e-3 and abs(de) < 1e-3  # metres


def test_ecef_central_difference_matches_ned_velocity(circuit):
    """pyproj ECEF positions differenced over one step match the NED velocity rotated to ECEF
    at the mid time.  Central-difference truncation dt^2/24 * |v''| (mid-point form) with
    |v''| < 5 m/s^3 here gives < 1e-3 m/s."""
    tr = circuit.truth
    x, y, z = geodetic_to_ecef(tr.lat_deg, tr.lon_deg, tr.alt_m)
    dt = tr.t_s.diff().iloc[1]
    v_ecef = np.column_stack([np.diff(x), np.diff(y), np.diff(z)]) / dt
    lat = np.radians(tr.lat_deg.to_numpy())
    lon = np.radians(tr.lon_deg.to_numpy())
    vn, ve, vu = tr.vn_mps.to_numpy(), tr.ve_mps.to_numpy(), tr.vu_mps.to_numpy()
    # mid-point: average the rotated velocities of both ends (second order like the difference)
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    vx = -sl * co * vn - so * ve + cl * co * vu
    vy = -sl * so * vn + co * ve + cl * so * vu
    vz = cl * vn + sl * vu
    mid = np.column_stack([vx, vy, vz])
    mid = 0.5 * (mid[1:] + mid[:-1])
    jerk_dot = np.abs(np.diff(tr.an_mps2.to_numpy(), 2)).max() / dt**2
    bound = max(dt**2 / 8 * jerk_dot, 1e-4)  # trapezoid-vs-difference error, floor 0.1 mm/s
    assert np.max(np.abs(v_ecef - mid)) < bound


def test_acceleration_is_derivative_of_velocity(circuit_plan):
    """Central differences (h = 1e-3 s) of the closed-form velocity equal the truth
    acceleration to 1e-5 m/s^2 (truncation h^2/6 |v'''| < 1e-6, rounding 1e-13/h)."""
    t = np.linspace(0.5, circuit_plan.t_end_s - 0.5, 3001)
    h = 1e-3
    k0 = kinematics(circuit_plan, t)
    kp = kinematics(circuit_plan, t + h)
    km = kinematics(circuit_plan, t - h)
    for v, a in (("vn_mps", "an_mps2"), ("ve_mps", "ae_mps2"), ("vu_mps", "au_mps2")):
        fd = (getattr(kp, v) - getattr(km, v)) / (2 * h)
        assert np.max(np.abs(fd - getattr(k0, a))) < 1e-5, v


def test_acceleration_continuous_on_grid(circuit):
    """Smooth commands: the sampled acceleration changes by less than 0.3 m/s^2 per 1/16 s
    (jerk below 4.8 m/s^3 everywhere, take-off and touchdown included; the circuit's largest
    is 3.2 m/s^3, a step change would show as g-sized jumps)."""
    for c in ("an_mps2", "ae_mps2", "au_mps2"):
        assert np.abs(np.diff(circuit.truth[c].to_numpy())).max() < 0.3


def test_loads_rebuild_acceleration(circuit):
    """METHODS.md "Common ground": C_nb g0 [n_long, n_lat, -n_norm] + [0, 0, g] = a_NED,
    the sensed acceleration, which is the truth's dv/dt less the frame's rotation (Coriolis and
    transport rate), exactly (rounding only)."""
    from flightrecon.geo.navframe import frame_rate_acceleration

    tr = circuit.truth
    n = tr[["n_long_g", "n_lat_g", "n_norm_g"]].to_numpy()
    a = acceleration_from_loads(n, tr.gravity_mps2.to_numpy(), np.radians(tr.heading_deg),
                                np.radians(tr.pitch_deg), np.radians(tr.roll_deg))
    c = frame_rate_acceleration(tr.lat_deg, tr.alt_m,
                                np.column_stack([tr.vn_mps, tr.ve_mps, -tr.vu_mps]))
    ref = np.column_stack([tr.an_mps2, tr.ae_mps2, -tr.au_mps2]) - c
    assert np.max(np.abs(a - ref)) < 1e-10
    assert np.max(np.abs(tr.n_lat_g)) < 1e-12  # coordinated flight


def test_noise_free_recorder_equals_truth_loads():
    """With ideal sensors the recorded loads, attitude, TAS and baro altitude equal the truth
    at their sample times (exactly: no noise, no lag, no quantisation)."""
    r = simulate("circuit", seed=0, ideal_sensors=True)
    tr = r.truth.set_index("t_s")
    log = r.log.set_index("t_s")
    for c in ("n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg", "heading_deg",
              "tas_mps"):
        s = log[c].dropna()
        assert np.max(np.abs(s.to_numpy() - tr.loc[s.index, c].to_numpy())) < 1e-12, c
    s = log["baro_alt_m"].dropna()
    assert np.max(np.abs(s.to_numpy() - tr.loc[s.index, "pressure_alt_m"].to_numpy())) < 1e-9


def test_level_flight_and_coordinated_turn():
    """Level unaccelerated flight: n = (g/g0) (sin pitch, 0, cos pitch).  Level coordinated turn
    without wind and angle of attack: tan(roll) = V psi_dot / g and n_norm = (g/g0)/cos(roll),
    n_lat = 0 (g/g0 because the load factor's unit is standard gravity).  To the frame's
    rotation, which these flat-Earth relations leave out: at 100 m/s and 45 deg, Coriolis and
    transport rate are below 1.2e-2 m/s^2, 1.2e-3 g (the exact relation, with them:
    test_loads_rebuild_acceleration); 2e-3 g and, in the turn's 5.2 m/s^2, 3e-3 relative."""
    b = PlanBuilder(lat_deg=45.0, lon_deg=10.0, elev_msl_m=1000.0, track_deg=30.0,
                    wind=WindField(), atmosphere=Atmosphere(), alpha_ref_deg=0.0,
                    airborne_tas_mps=100.0)
    b.hold(30).turn(90.0, 3.0, tau_s=4.0).hold(30)
    plan = b.plan()
    tr = simulate_truth(plan, 16.0, TangentPlane(45.0, 10.0, 0.0))
    gr = tr.gravity_mps2 / G0
    level = tr.t_s < 25
    assert np.allclose(tr.n_norm_g[level], gr[level], atol=2e-3)
    assert np.allclose(tr.n_long_g[level], 0.0, atol=2e-3)
    turning = (tr.t_s > 35) & (tr.t_s < 55)  # constant rate part of the turn
    rate = np.radians(3.0)
    assert np.allclose(np.tan(np.radians(tr.roll_deg[turning])),
                       100.0 * rate / tr.gravity_mps2[turning], rtol=3e-3)
    assert np.allclose(tr.n_norm_g[turning], gr[turning] / np.cos(np.radians(tr.roll_deg[turning])),
                       rtol=3e-3)
    # with angle of attack, level flight: n = (g/g0) (sin a, 0, cos a)
    b2 = PlanBuilder(lat_deg=45.0, lon_deg=10.0, elev_msl_m=1000.0, track_deg=30.0,
                     wind=WindField(), atmosphere=Atmosphere(), alpha_ref_deg=4.0,
                     alpha_ref_tas_mps=100.0, airborne_tas_mps=100.0)
    tr2 = simulate_truth(b2.hold(20).plan(), 4.0, TangentPlane(45.0, 10.0, 0.0))
    g2 = tr2.gravity_mps2 / G0
    assert np.allclose(tr2.n_long_g, g2 * np.sin(np.radians(4.0)), atol=2e-3)
    assert np.allclose(tr2.n_norm_g, g2 * np.cos(np.radians(4.0)), atol=2e-3)


def test_coordinated_roll_finite_difference_of_lateral_load():
    """The coordinated roll zeroes the lateral load: perturbing it by +-1e-6 rad changes n_lat
    with slope -n_norm (d n_lat / d roll = f2_z cos - f2_y sin = -n_norm), checked by finite
    differences."""
    rng = np.random.default_rng(1)
    a = rng.normal(0, 3, (50, 3))
    hd, pt = rng.uniform(0, 6, 50), rng.uniform(-0.3, 0.3, 50)
    g = np.full(50, 9.8)
    roll = coordinated_roll_rad(a, g, hd, pt)
    n0 = loads_from_acceleration(a, g, hd, pt, roll)
    assert np.max(np.abs(n0[:, 1])) < 1e-14
    h = 1e-6
    fd = (loads_from_acceleration(a, g, hd, pt, roll + h)[:, 1]
          - loads_from_acceleration(a, g, hd, pt, roll - h)[:, 1]) / (2 * h)
    assert np.allclose(fd, -n0[:, 2], atol=1e-8)


def test_air_velocity_plus_wind_is_ground_velocity(circuit):
    """Airborne (crab weight 1): the air velocity is TAS C_nb (cos a, 0, sin a) (no sideslip,
    a the angle of attack; sim/kinematics.attitude_from_air), and it plus the wind is the
    ground velocity; in the turns the nose is off the air track by about a sin(roll)."""
    from flightrecon.geo.kinematics import body_to_ned_matrix

    tr = circuit.truth
    ev = circuit.sensor_truth["events"]
    air = (tr.t_s > ev["liftoff_t_s"] + 10) & (tr.t_s < ev["touchdown_t_s"] - 6)
    t = tr[air]
    C = body_to_ned_matrix(t.roll_deg.to_numpy(), t.pitch_deg.to_numpy(),
                           t.heading_deg.to_numpy())
    a = np.radians(t.alpha_deg.to_numpy())
    v_air = np.einsum("kij,kj->ki", C, np.c_[np.cos(a), np.zeros(len(a)), np.sin(a)])
    v_air *= t.tas_mps.to_numpy()[:, None]
    assert np.max(np.abs(v_air[:, 0] + t.wind_n_mps - t.vn_mps)) < 1e-9
    assert np.max(np.abs(v_air[:, 1] + t.wind_e_mps - t.ve_mps)) < 1e-9
    assert np.max(np.abs(v_air[:, 2] + t.vu_mps)) < 1e-9
    assert np.hypot(t.wind_n_mps, t.wind_e_mps).min() > 5.0  # the circuit has wind
    off = np.degrees(np.angle(np.exp(1j * (np.radians(t.heading_deg)
                                           - np.arctan2(v_air[:, 1], v_air[:, 0])))))
    bank = np.abs(t.roll_deg.to_numpy()) > 15.0
    want = np.degrees(a * np.sin(np.radians(t.roll_deg.to_numpy())))
    assert bank.any() and np.max(np.abs(off[bank] - want[bank])) < 0.1 * np.abs(want[bank]).max()


def test_tangent_plane_round_trip(circuit):
    """north/east/up -> pyproj inverse -> the truth's lat/lon/ellipsoidal height (1e-9 deg
    ~ 0.1 mm; 1e-4 m in height)."""
    tr = circuit.truth
    tp = output_plane(circuit.meta)
    lat, lon, h = tp.inverse(tr.east_m, tr.north_m, tr.up_m)
    assert np.max(np.abs(lat - tr.lat_deg)) < 1e-9
    assert np.max(np.abs(lon - tr.lon_deg)) < 1e-9
    assert np.max(np.abs(h - tr.alt_m)) < 1e-4
    assert np.allclose(tr.alt_m - tr.alt_msl_m, circuit.meta.geoid_undulation_m, atol=1e-9)


@pytest.mark.parametrize("track, lat0", [(0.0, 40.0), (90.0, 0.0)])
def test_400km_leg_matches_pyproj_geodesic(track, lat0):
    """A 400 km leg along a geodesic (a meridian; the equator) at zero ellipsoidal height ends
    where pyproj's geodesic puts it (RK4 at 1 s: error << 1 mm), and the geodesic distance
    equals the flown distance."""
    b = PlanBuilder(lat_deg=lat0, lon_deg=20.0, elev_msl_m=0.0, track_deg=track,
                    wind=WindField(), atmosphere=Atmosphere(), geoid_undulation_m=0.0,
                    airborne_tas_mps=200.0)
    tr = simulate_truth(b.hold(2000.0).plan(), 1.0, TangentPlane(lat0, 20.0, 0.0))
    geod = Geod(ellps="WGS84")
    lon_e, lat_e, _ = geod.fwd(20.0, lat0, track, 400e3)
    assert abs(tr.lat_deg.iloc[-1] - lat_e) * 111e3 < 1e-3
    assert abs(tr.lon_deg.iloc[-1] - lon_e) * 111e3 < 1e-3
    dist = geod.inv(20.0, lat0, tr.lon_deg.iloc[-1], tr.lat_deg.iloc[-1])[2]
    assert dist == pytest.approx(400e3, abs=1e-3)
    # and the tangent plane is far off the aircraft there (METHODS.md "Frames": ~12.6 km)
    assert tr.up_m.iloc[-1] < -12e3


def test_nonstandard_atmosphere_hydrostatic_and_pressure_altitude():
    """dp/dz = -rho g(z) with g = g0 (r/(r+z))^2 (geopotential), checked by central
    differences (h = 0.5 m; relative error ~ h^2 p'''/p'' < 1e-9); pressure altitude differs
    from geometric height when dT != 0 or p_sl != 1013.25 hPa, and equals the geopotential
    height in the ISA."""
    from flightrecon.geo.atmosphere import G0 as ATM_G0
    from flightrecon.geo.atmosphere import R_AIR
    atm = Atmosphere(temp_offset_k=12.0, p_sl_start_pa=100200.0, p_sl_end_pa=100200.0)
    z = np.array([0.0, 1000.0, 5000.0, 10000.0])
    h = 0.5
    dpdz = (atm.pressure_pa(z + h, 0.0) - atm.pressure_pa(z - h, 0.0)) / (2 * h)
    rho = atm.pressure_pa(z, 0.0) / (R_AIR * atm.temperature_k(z))
    g = ATM_G0 * (6356766.0 / (6356766.0 + z)) ** 2
    assert np.allclose(dpdz, -rho * g, rtol=1e-7)
    pa = atm.pressure_altitude_m(z, 0.0)
    assert np.all(np.abs(pa - z) > 40.0)  # 11 hPa low and 12 K warm: 50-350 m here
    isa = Atmosphere()
    assert np.allclose(isa.pressure_altitude_m(z, 0.0), geopotential_height_m(z), atol=1e-6)
    assert np.allclose(pressure_altitude_m(isa.pressure_pa(z, 0)), geopotential_height_m(z),
                       atol=1e-6)


def test_truth_columns_and_events(circuit):
    tr = circuit.truth
    assert tr.columns[0] == "t_s"
    for c in ("lat_deg", "lon_deg", "alt_m", "alt_msl_m", "north_m", "east_m", "up_m",
              "vn_mps", "ve_mps", "vu_mps", "an_mps2", "ae_mps2", "au_mps2", "roll_deg",
              "pitch_deg", "heading_deg", "tas_mps", "wind_n_mps", "wind_e_mps",
              "pressure_alt_m", "on_ground"):
        assert c in tr.columns
    assert tr.on_ground.dtype == bool
    ev = circuit.sensor_truth["events"]
    on = tr.on_ground.to_numpy()
    assert on[0] and on[-1] and not on[len(on) // 2]
    ground = tr[on]
    # on the ground the aircraft is at the runway elevation (within the 1 s touchdown step)
    assert np.allclose(ground.alt_msl_m, 3.0, atol=0.2)
    assert ev["liftoff_t_s"] < ev["touchdown_t_s"]
    assert tr.t_s.iloc[-1] == pytest.approx(900.0)


def test_circuit_length_and_touchdown_dispersion():
    """duration_s lengthens the circuit's record by the lined-up wait; touchdown_sd_m draws the
    touchdown's distance past the threshold per seed (the same seed, the same draw), and the
    simulated touchdown lands there: on the centre line, that far from the threshold."""
    import numpy as np

    from flightrecon.geo.frames import TangentPlane
    from flightrecon.sim import simulate

    base = simulate("circuit", seed=3, gnss_hz=0.0)
    longer = simulate("circuit", seed=3, gnss_hz=0.0, duration_s=1000.0)
    assert longer.truth["t_s"].iloc[-1] == pytest.approx(1000.0, abs=1.0 / 16.0)  # its grid
    ev0, ev1 = base.sensor_truth["events"], longer.sensor_truth["events"]
    # the wait grows by the 100 s (the legs are closed again in the wind of a later time:
    # the pattern itself changes by a second or two)
    assert ev1["liftoff_t_s"] - ev0["liftoff_t_s"] == pytest.approx(100.0, abs=3.0)
    draws = [simulate("circuit", seed=s, gnss_hz=0.0, touchdown_m=400.0, touchdown_sd_m=150.0)
             for s in (3, 3, 4)]
    d = [r.sensor_truth["events"]["touchdown_past_threshold_m"] for r in draws]
    assert d[0] == d[1] != d[2] and all(100.0 <= x <= 1000.0 for x in d)
    for r, dist in zip(draws[1:], d[1:]):
        a = r.meta.arrival
        ev = r.sensor_truth["events"]
        e, n, _ = TangentPlane(a.threshold_lat_deg, a.threshold_lon_deg).forward(
            ev["touchdown_lat_deg"], ev["touchdown_lon_deg"], 0.0)
        rw = np.radians(a.runway_true_deg)
        along = float(n * np.cos(rw) + e * np.sin(rw))
        cross = float(-n * np.sin(rw) + e * np.cos(rw))
        # the plan closes the circuit to 1 m, but the flown truth lands 15-20 m from the
        # planned point, in calm air as well (seed 4: 262 m for a drawn 272 m, 17 m off the
        # centre line; the smoother's runway prior is 25 m across)
        assert along == pytest.approx(dist, abs=25.0) and abs(cross) < 25.0


def test_attitude_from_air_is_coordinated_at_its_angle_of_attack():
    """Guards the point-mass simulator's attitude (docs/simulator.md): for any air-velocity
    direction, angle of attack and specific force, the body axes of ``attitude_from_air`` have
    no lateral load (n_lat = 0), put the air velocity at (cos a, 0, sin a) in body axes, and
    at a = 0 are the air velocity's own direction (heading, pitch = flight-path angle) with
    the coordinated roll, tan(roll) = V psi_dot / g in a level turn."""
    from flightrecon.sim.kinematics import (
        attitude_from_air,
        dcm_body_to_ned,
        loads_from_acceleration,
    )

    rng = np.random.default_rng(7)
    n = 300
    hx, gam = rng.uniform(-3.0, 3.0, n), rng.uniform(-0.2, 0.2, n)
    alpha = rng.uniform(-0.05, 0.25, n)
    a = rng.normal(0.0, 3.0, (n, 3))
    psi, th, ph = attitude_from_air(hx, gam, alpha, a, 9.81)
    assert np.max(np.abs(loads_from_acceleration(a, 9.81, psi, th, ph)[:, 1])) < 1e-12
    v = np.einsum("nij,nj->ni", dcm_body_to_ned(psi, th, ph),
                  np.c_[np.cos(alpha), np.zeros(n), np.sin(alpha)])
    np.testing.assert_allclose(np.angle(np.exp(1j * (np.arctan2(v[:, 1], v[:, 0]) - hx))), 0.0,
                               atol=1e-12)
    np.testing.assert_allclose(-np.arcsin(v[:, 2]), gam, atol=1e-12)
    # a level turn at 60 m/s and 3 deg/s, no angle of attack: heading along the air velocity,
    # tan(roll) = V psi_dot / g
    V, w = 60.0, np.radians(3.0)
    psi0, th0, ph0 = attitude_from_air(np.array([0.3]), np.zeros(1), np.zeros(1),
                                       np.array([[-V * w * np.sin(0.3), V * w * np.cos(0.3), 0.0]]),
                                       9.81)
    assert psi0[0] == pytest.approx(0.3, abs=1e-12) and th0[0] == pytest.approx(0.0, abs=1e-12)
    assert np.tan(ph0[0]) == pytest.approx(V * w / 9.81, rel=1e-12)
    # and at a = 0 in general the roll is coordinated_roll_rad's
    _, _, ph_c = attitude_from_air(hx, gam, np.zeros(n), a, 9.81)
    d = ph_c - coordinated_roll_rad(a, 9.81, hx, gam)
    np.testing.assert_allclose(np.angle(np.exp(1j * d)), 0.0, atol=1e-12)
