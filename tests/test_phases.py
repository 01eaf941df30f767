"""Flight-phase detection (flightrecon.cleaning.phases): lift-off and touchdown within 1 s."""

import numpy as np
import pandas as pd
import pytest
from test_cleaning_synth import LIFTOFF_S, TD_S, synthetic_flight

from flightrecon.cleaning import clean_flight, detect_phases
from flightrecon.errors import FlightReconWarning, ValidationError
from flightrecon.types import Flight

# Acceptance tolerance of the issue: lift-off and touchdown within 1 s of the truth.
TOL_S = 1.0


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_liftoff_touchdown_synthetic(seed):
    flight, _ = synthetic_flight(seed)
    ph = clean_flight(flight).phases
    assert abs(ph.liftoff_t_s - LIFTOFF_S) < TOL_S
    assert abs(ph.touchdown_t_s - TD_S) < TOL_S
    assert not ph.starts_airborne and not ph.ends_airborne


def test_liftoff_velocity_with_wind_channel():
    """Ground speed at lift-off (70 m/s along 020) from airspeed minus the recorded headwind.
    Airspeed noise is 0.3 m/s per 8 Hz sample, averaged over the 10 s fit: 0.5 m/s is ~10 sigma
    of the fit yet far below the 6 m/s wind that would be missed without the wind channel."""
    flight, _ = synthetic_flight(4, wind_ne=(-6.0, 2.0), wind_channel=True)
    clean = clean_flight(flight)
    v = np.array(clean.phases.liftoff_velocity_ned_mps)
    truth = 70.0 * np.array([np.cos(np.radians(20.0)), np.sin(np.radians(20.0)), 0.0])
    np.testing.assert_allclose(v, truth, atol=0.5)
    entry = [r for r in clean.report if r["action"] == "liftoff_velocity"][0]
    assert "headwind" in entry["why"]


def test_wind_unmodelled_is_reported():
    flight, _ = synthetic_flight(4, wind_ne=(-6.0, 2.0), wind_channel=False)
    clean = clean_flight(flight)
    entry = [r for r in clean.report if r["action"] == "liftoff_velocity"][0]
    assert "wind unmodelled" in entry["why"]


def test_record_cut_in_the_air():
    flight, _ = synthetic_flight(5)
    d = flight.data
    cut = d[(d["t_s"] >= 150.0) & (d["t_s"] <= 400.0)].reset_index(drop=True)
    with pytest.warns(FlightReconWarning, match=r"the arrival given .* is not where this "
                      "record ends: it ends in the air"):
        ph = clean_flight(Flight(cut, flight.meta)).phases
    assert ph.starts_airborne and ph.ends_airborne
    assert np.isnan(ph.liftoff_t_s) and np.isnan(ph.touchdown_t_s)
    assert all(np.isnan(ph.liftoff_velocity_ned_mps))
    # starts in the air, ends on the ground: touchdown only
    late = d[d["t_s"] >= 150.0].reset_index(drop=True)
    ph = clean_flight(Flight(late, flight.meta)).phases
    assert ph.starts_airborne and not ph.ends_airborne
    assert np.isnan(ph.liftoff_t_s) and abs(ph.touchdown_t_s - TD_S) < TOL_S


def test_ground_only_record_has_no_phases():
    flight, _ = synthetic_flight(6)
    d = flight.data
    ground = d[d["t_s"] <= 50.0].reset_index(drop=True)  # taxi and the start of the roll
    with pytest.warns(FlightReconWarning, match="the record ends fast"):   # mid-roll
        clean = clean_flight(Flight(ground, flight.meta))
    ph = clean.phases
    assert not ph.starts_airborne and np.isnan(ph.liftoff_t_s) and np.isnan(ph.touchdown_t_s)
    assert any(r["action"] == "no_liftoff" for r in clean.report)


def test_bad_grid_rejected():
    with pytest.raises(ValidationError):
        detect_phases(pd.DataFrame({"t_s": [0.0]}))
    with pytest.raises(ValidationError):
        detect_phases(pd.DataFrame({"t_s": [0.0, 1.0, 3.0], "tas_mps": [1.0, 2.0, 3.0],
                                    "baro_alt_m": [0.0, 0.0, 0.0]}))


SIM_SCENARIOS = [("circuit", 0), ("circuit", 1), ("regional", 0), ("landing", 0)]


def _sim():
    try:
        from flightrecon.sim import simulate
    except ImportError:  # the simulator is written in parallel; absent in early checkouts
        pytest.skip("flightrecon.sim is not available")
    return simulate


@pytest.mark.parametrize("scenario,seed", SIM_SCENARIOS)
def test_liftoff_touchdown_simulated(scenario, seed):
    """Acceptance on the project's simulator: truth ``on_ground`` transitions within 1 s."""
    simulate = _sim()
    res = simulate(scenario, seed)
    tr = res.truth
    og = tr["on_ground"].to_numpy().astype(bool)
    t = tr["t_s"].to_numpy()
    ups = t[np.flatnonzero(og[:-1] & ~og[1:]) + 1]
    downs = t[np.flatnonzero(~og[:-1] & og[1:]) + 1]
    ph = clean_flight(Flight(res.log, res.meta)).phases
    if len(ups):
        assert abs(ph.liftoff_t_s - ups[0]) < TOL_S
        assert not ph.starts_airborne
    else:
        assert ph.starts_airborne and np.isnan(ph.liftoff_t_s)
    if len(downs):
        assert abs(ph.touchdown_t_s - downs[-1]) < TOL_S
        assert not ph.ends_airborne
    else:
        assert ph.ends_airborne and np.isnan(ph.touchdown_t_s)


def test_filled_equals_pandas_interpolation():
    """The numpy fill of grid columns equals ``Series.interpolate(limit_direction="both")``
    (inner gaps linear in the row index, leading and trailing NaN held), bit for bit."""
    from flightrecon.cleaning.phases import _filled

    rng = np.random.default_rng(31)
    for n in (1, 2, 10, 500):
        for frac in (0.0, 0.3, 0.9):
            x = rng.normal(0, 1, n)
            x[rng.random(n) < frac] = np.nan
            x[: n // 10] = np.nan
            grid = pd.DataFrame({"a": x})
            if np.isnan(x).all():
                assert _filled(grid, "a") is None
                continue
            ref = pd.Series(x).interpolate(limit_direction="both").to_numpy()
            np.testing.assert_array_equal(_filled(grid, "a"), ref)
            np.testing.assert_array_equal(grid["a"].to_numpy(), x)  # input unchanged
    assert _filled(pd.DataFrame({"a": [1.0]}), "b") is None


def test_climb_onset_is_the_first_sustained_climb():
    """Guards the lift-off rule against a climb that pauses in ground effect (JSBSim's Cessna,
    seed 5104: 0.6 m/s seven seconds after lift-off): the *last* crossing of the threshold put
    the lift-off there, 7 s late. The onset is the first stretch above it that lasts the hold
    time or runs to the end (certainly airborne); a shorter excursion (ground noise) is not."""
    from flightrecon.cleaning.phases import _climb_onset

    dt = 0.0625
    t = np.arange(0.0, 20.0, dt)
    v = np.where(t < 5.0, 0.0, 1.5)                      # climb from 5 s ...
    v = np.where((t >= 11.0) & (t < 12.0), 0.5, v)       # ... pausing below 0.6 m/s at 11 s
    v = np.where((t >= 2.0) & (t < 3.0), 0.8, v)         # a 1 s excursion on the ground
    n_hold = int(round(3.0 / dt))
    assert t[_climb_onset(v, 0.6, n_hold)] == pytest.approx(5.0)
    # a stretch shorter than the hold counts when it runs to the end of the window
    assert t[_climb_onset(v[: int(round(6.0 / dt))], 0.6, n_hold)] == pytest.approx(5.0)
    assert _climb_onset(np.zeros(50), 0.6, n_hold) == -1


def test_take_off_run_starts_below_rolling_speed_or_at_the_fast_run():
    """Guards where the lift-off search starts: at the last sample below 15 m/s before the
    first at 30 m/s (a Cessna lifts off between the two); a record whose airspeed never reads
    that low (a strong wind at rest, or a record starting mid-roll) starts at the fast run, as
    before, instead of at the record's first sample."""
    from flightrecon.cleaning.phases import PhaseSettings, _take_off_run

    s = PhaseSettings()
    v = np.r_[np.zeros(10), np.linspace(0.0, 40.0, 41)]      # 1 m/s per sample from index 10
    assert _take_off_run(v, s) == (24, 40)                     # 14 m/s at 24, 30 m/s at 40
    windy = np.r_[np.full(10, 18.0), np.linspace(18.0, 40.0, 23)]
    assert _take_off_run(windy, s) == (22, 22)
    assert _take_off_run(np.full(20, 10.0), s) == (-1, -1)
