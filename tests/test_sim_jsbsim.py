"""The JSBSim truth source (docs/jsbsim.md): every scenario flies, its truth is physically sane,
the autopilot holds its targets, impact flights end on the ground, the same seed gives the same
bytes, and the recorder saturates at its range.

Short versions (``scale``) keep the suite fast: a scenario's schedule is the same at any scale,
only its en-route legs are shorter (JSBSim runs at 96 Hz, about 6-9 s of CPU per simulated
hour, docs/jsbsim.md).
"""

from __future__ import annotations

import builtins
import math

import numpy as np
import pytest

pytest.importorskip("jsbsim")

from flightrecon.errors import FlightReconError, ValidationError
from flightrecon.geo.frames import output_plane
from flightrecon.sim import simulate, write_simulation
from flightrecon.sim.jsbsim_flight import Approach, Leg, Runway
from flightrecon.sim.jsbsim_scenarios import (
    AIRFRAMES,
    JSBSIM_SCENARIOS,
    jsbsim_config,
    schedule,
)

SHORT = {"jsbsim-circuit": 1.0, "jsbsim-xc": 0.12, "jsbsim-jet": 0.05, "jsbsim-spiral": 0.1,
         "jsbsim-spin": 0.1, "jsbsim-airwork": 1.0, "jsbsim-holding": 0.25,
         "jsbsim-goaround": 1.0}
"""Scale of each scenario's short version in these tests."""


@pytest.fixture(scope="module")
def flights():
    """One short flight per scenario (seed 7), computed once."""
    return {name: simulate(name, 7, scale=SHORT[name]) for name in JSBSIM_SCENARIOS}


def test_every_scenario_flies_and_its_truth_is_finite(flights):
    for name, r in flights.items():
        tr = r.truth
        num = tr.select_dtypes("number")
        assert np.isfinite(num.to_numpy()).all(), name
        t = tr["t_s"].to_numpy()
        rate = r.sensor_truth["truth_rate_hz"]
        assert np.allclose(np.diff(t), 1.0 / rate), name  # the uniform truth grid
        # at rest at the start: on the runway, a few cm/s at most (gusts rock the aircraft)
        assert tr["on_ground"].iloc[0] and tr["gs_mps"].iloc[0] < 0.5, name
        assert tr["tas_mps"].max() < (260.0 if "jet" in name else 110.0), name
        # the log is the project's recorder: canonical columns, time first
        assert list(r.log.columns[:1]) == ["t_s"] and "n_norm_g" in r.log
        assert r.sensor_truth["truth_source"] == "jsbsim"


def test_loads_agree_with_the_kinematics_in_flight(flights):
    """JSBSim's specific force and its own velocity history: C_nb g0 n + g = dv/dt within the
    turbulence-free part of the truth's resolution (the averaged loads lag half a sample; the
    comparison is on 2 s means, away from the ground)."""
    from flightrecon.sim.kinematics import acceleration_from_loads

    tr = flights["jsbsim-xc"].truth
    air = (~tr["on_ground"].to_numpy()) & (tr["agl_m"].to_numpy() > 50.0)
    a = acceleration_from_loads(tr[["n_long_g", "n_lat_g", "n_norm_g"]].to_numpy(),
                                tr["gravity_mps2"].to_numpy(), np.radians(tr["heading_deg"]),
                                np.radians(tr["pitch_deg"]), np.radians(tr["roll_deg"]))
    kin = np.column_stack([tr["an_mps2"], tr["ae_mps2"], -tr["au_mps2"]])
    k = 32  # 2 s at 16 Hz
    n = (air.sum() // k) * k
    d = (a[air][:n] - kin[air][:n]).reshape(-1, k, 3).mean(axis=1)
    # 0.05 m/s^2 (5 mg): Coriolis and transport-rate terms (~0.01 m/s^2 at 55 m/s) and the
    # half-sample lag of the boxcar in manoeuvres
    assert np.sqrt(np.mean(d**2, axis=0)).max() < 0.05


def _phase_rows(r, k):
    return r.truth["phase"].to_numpy() == k


def test_autopilot_holds_its_targets(flights):
    """After capturing a leg's altitude (within 15 m), the Cessna stays within 80 m of it (turns
    and moderate turbulence: the largest seen is 67 m) and
    within 6 m/s of the leg's airspeed, banks no more than 25 deg + 10 deg of turbulence; the
    cross-track error on a leg longer than 8 km falls below 300 m before its end."""
    checked = 0
    for name in ("jsbsim-circuit", "jsbsim-xc"):
        r = flights[name]
        cfg = jsbsim_config(name, scale=SHORT[name])
        phases = schedule(name, cfg)[0]
        tr = r.truth
        for k, ph in enumerate(phases):
            if not isinstance(ph, Leg):
                continue
            sel = _phase_rows(r, k)
            h = tr["alt_msl_m"].to_numpy()[sel]
            near = np.flatnonzero(np.abs(h - ph.alt_m) < 15.0)
            assert np.abs(tr["roll_deg"].to_numpy()[sel]).max() < 35.0, (name, k)
            if near.size == 0:
                continue  # a leg that ends before its altitude is reached (still climbing)
            after = slice(near[0], None)
            assert np.abs(h[after] - ph.alt_m).max() < 80.0, (name, k)
            cas = tr["cas_mps"].to_numpy()[sel][after]
            if cas.size > 16 * 60:  # a minute after capture: the speed has settled
                assert np.abs(cas[16 * 60:] - ph.cas).max() < 6.0, (name, k)
            checked += 1
    assert checked >= 4


def test_landings_on_the_runway_and_to_rest(flights):
    for name in ("jsbsim-circuit", "jsbsim-xc", "jsbsim-jet"):
        r = flights[name]
        cfg = jsbsim_config(name, scale=SHORT[name])
        phases, dest, _, _ = schedule(name, cfg)
        ev = r.sensor_truth["events"]
        assert "touchdown_t_s" in ev and "liftoff_t_s" in ev, name
        along, cross = dest.coords(ev["touchdown_lat_deg"], ev["touchdown_lon_deg"])
        assert 0.0 < along < cfg.runway_length_m and abs(cross) < 20.0, (name, along, cross)
        tr = r.truth
        i = int(np.searchsorted(tr["t_s"], ev["touchdown_t_s"]))
        # no crash landing: the Cessna's flare gives about 1 m/s, the 737's is firm (2-3.3 m/s
        # measured; its gear's limit is about 3 m/s at landing weight)
        assert tr["vu_mps"].iloc[max(i - 8, 0):i].min() > -3.5, name
        assert tr["on_ground"].iloc[-1] and tr["gs_mps"].iloc[-1] < 0.5, name  # at rest
        arr = r.meta.arrival
        assert arr.runway_true_deg == pytest.approx(dest.heading_deg % 360.0)
        assert arr.threshold == pytest.approx((dest.lat_deg, dest.lon_deg))
        assert any(isinstance(p, Approach) for p in phases)


@pytest.mark.parametrize("name", ["jsbsim-spiral", "jsbsim-spin"])
def test_upsets_end_at_ground_impact(flights, name):
    r = flights[name]
    tr = r.truth
    ev = r.sensor_truth["events"]
    assert ev["impact_t_s"] == pytest.approx(tr["t_s"].iloc[-1])
    assert tr["on_ground"].iloc[-1] and not tr["on_ground"].iloc[-2]
    rest = AIRFRAMES["c172p"].rest_agl_ft * 0.3048
    assert tr["agl_m"].iloc[-1] < rest + 1.0  # at the ground
    assert ev["upset_t_s"] < ev["impact_t_s"]
    # a loss of control: from cruise altitude to the ground, fast
    up = tr["t_s"].to_numpy() >= ev["upset_t_s"]
    assert tr["agl_m"][up].iloc[0] > 900.0
    assert ev["impact_speed_mps"] > 20.0 and ev["impact_vu_mps"] < -5.0
    # the wreckage is the sidecar's arrival, no runway
    arr = r.meta.arrival
    assert (arr.lat_deg, arr.lon_deg) == (tr["lat_deg"].iloc[-1], tr["lon_deg"].iloc[-1])
    assert arr.runway_true_deg is None
    e, n, _ = output_plane(r.meta).forward(arr.lat_deg, arr.lon_deg,
                                           arr.elev_m + r.meta.geoid_undulation_m)
    assert math.hypot(float(e) - tr["east_m"].iloc[-1], float(n) - tr["north_m"].iloc[-1]) < 1.0
    if name == "jsbsim-spiral":
        assert tr["roll_deg"][up].abs().max() > 60.0  # the spiral's bank


def test_recorder_saturates_at_its_range(flights):
    r = flights["jsbsim-spiral"]
    (lo, hi) = jsbsim_config("jsbsim-spiral").loads_range_g[2]
    log = r.log["n_norm_g"].dropna()
    assert log.max() <= hi and log.min() >= lo
    if r.truth["n_norm_g"].max() > hi + 0.1:  # the impact's loads are beyond the range
        assert (log == hi).any()


def test_same_seed_same_bytes(tmp_path):
    """Two flights of one seed in one process: byte-identical log, truth, sidecar and sensor
    truth (JSBSim is deterministic, its turbulence seeded per flight)."""
    written = []
    for k in range(2):
        (tmp_path / f"run{k}").mkdir()
        r = simulate("jsbsim-spin", 11, scale=0.05)
        written.append(write_simulation(r, tmp_path / f"run{k}" / "x.parquet"))
    for role in ("log", "truth", "meta", "sensors"):
        assert written[0][role].read_bytes() == written[1][role].read_bytes(), role
    other = simulate("jsbsim-spin", 12, scale=0.05)
    assert not np.array_equal(other.truth["lat_deg"].to_numpy()[-10:],
                              r.truth["lat_deg"].to_numpy()[-10:])


def test_settings_are_checked():
    with pytest.raises(ValidationError, match="unknown scenario setting"):
        simulate("jsbsim-circuit", 0, leg_scale=2.0)
    with pytest.raises(ValidationError, match="seed"):
        simulate("jsbsim-circuit", -1)
    with pytest.raises(ValidationError, match="point-mass"):
        from flightrecon.sim import simulate_fleet
        simulate_fleet("A1", 2, scenario="jsbsim-circuit")


def test_missing_jsbsim_is_a_clear_error(monkeypatch):
    real_import = builtins.__import__

    def no_jsbsim(name, *args, **kw):
        if name == "jsbsim":
            raise ImportError("No module named 'jsbsim'")
        return real_import(name, *args, **kw)

    monkeypatch.setattr(builtins, "__import__", no_jsbsim)
    with pytest.raises(FlightReconError, match=r"flightrecon\[jsbsim\]"):
        simulate("jsbsim-circuit", 0)


def test_runway_coordinates_round_trip():
    rw = Runway(40.46, 50.05, 160.0, 3.0)
    lat, lon = rw.point(1234.0, -56.0)
    along, cross = rw.coords(lat, lon)
    assert along == pytest.approx(1234.0, abs=0.5) and cross == pytest.approx(-56.0, abs=0.5)


def test_lift_off_and_line_up_of_every_airframe(flights):
    """Guards the phase detector on aircraft that lift off below its 30 m/s "possibly flying"
    airspeed (the Cessna at 26-30 m/s): it searched for the lift-off only from the first 30 m/s
    sample, after the real one, and put it 7.6 s late on these flights; the runway heading,
    taken from the 2 s after that sample, was the airborne crab's, so the line-up came after
    the lift-off and the joint smoother lost its take-off roll (the departure fell back to the
    airfield reference at 1500 m). The detector now searches from the last sample below
    15 m/s. Bound 1.5 s: the knee rule's spread (-0.9 to +0.4 s on 33 of the 34 JSBSim
    light flights in docs/jsbsim.md)."""
    from flightrecon.cleaning import clean_flight
    from flightrecon.types import Flight

    for name, r in flights.items():
        clean = clean_flight(Flight(data=r.log, meta=r.meta))
        truth_lo = r.sensor_truth["events"]["liftoff_t_s"]
        assert abs(clean.phases.liftoff_t_s - truth_lo) < 1.5, name
        assert clean.phases.lineup_t_s < truth_lo - 10.0, name   # lined up before the roll


def test_an_aircraft_overturned_on_the_ground_is_refused():
    """Guards the truth itself: on this seed JSBSim's ground reactions tip the Cessna over at
    rest in a gusty wind (roll 180 deg) and then launch it upwards at 48 m/s. Such a record is
    not a flight; it was counted as one in the Monte Carlo tables (the joint's 5.7 km)."""
    with pytest.raises(ValidationError, match="overturned"):
        simulate("jsbsim-spin", 5406, scale=0.1)


def test_ideal_sensors_put_the_antenna_where_the_sidecar_says():
    """Guards the sidecar of an ideal-sensor flight: the receiver sits at the centre of mass
    there, but the sidecar gave the aircraft's lever arm (2, 0, -1) m, so the smoother
    corrected velocities for an antenna offset that was not in the data (a heading-bias error
    of about -0.16 deg on a circuit). The sidecar and the sensor truth now say where the
    receiver is."""
    r = simulate("jsbsim-circuit", 7, scale=1.0, ideal_sensors=True)
    assert tuple(r.meta.gnss_lever_arm_m) == (0.0, 0.0, 0.0)
    assert r.sensor_truth["persistent_errors"]["gnss_lever_arm_m"] == [0.0, 0.0, 0.0]
    r2 = simulate("jsbsim-circuit", 7, scale=1.0)
    assert tuple(r2.meta.gnss_lever_arm_m) == tuple(
        r2.sensor_truth["sensors"]["gnss"]["lever_arm_m"])
