"""The standstill before the taxi calibrates the gyro biases of a heading propagated from the
body rates (flightrecon.cleaning.standstill, issue #35): at rest the heading does not change, so
the mean rates there are the biases.

On the real Citation II record anchored by its departure runway alone the rate-propagated
heading's sd grew to 84 deg over 80 minutes (the gyro-bias prior of 0.02 deg/s); its 167 s at
rest on the apron measure the yaw-rate bias at -0.0013 deg/s, and the other flight's 52 s at
rest agree with its two runways to 0.0001 deg/s (docs/realflights.md).  Here the simulated
circuit with rate gyros, anchored by its departure runway only."""

from __future__ import annotations

import dataclasses
import warnings

import numpy as np
import pytest
from _scripts import load_script

from flightrecon.cleaning import clean_flight
from flightrecon.errors import FlightReconWarning
from flightrecon.sim import simulate
from flightrecon.types import Flight

study = load_script("heading_from_rates_study")


def _flight(quiet_rest: bool) -> tuple[Flight, tuple[float, float, float], float]:
    """The circuit with rate gyros and no heading, no GNSS, the departure runway only; with
    ``quiet_rest`` the loads at rest are those of a parked aircraft (sd 0.0005 g), else of an
    aircraft moving about (sd 0.02 g: no standstill)."""
    r = simulate("circuit", seed=5001)
    log, bias = study.rates_log(r.log, r.truth, np.random.default_rng(1))
    log = log.drop(columns=[c for c in log.columns if c.startswith("gnss_")])
    rest_end = 50.0          # the simulated crew lines up and starts the roll at 56.5 s
    rng = np.random.default_rng(2)
    at_rest = (log["t_s"] < rest_end).to_numpy() & log["n_long_g"].notna().to_numpy()
    for c in ("n_long_g", "n_lat_g"):
        sd = 0.0005 if quiet_rest else 0.02
        log.loc[at_rest, c] = (float(np.median(log.loc[at_rest, c]))
                               + sd * rng.standard_normal(int(at_rest.sum())))
    bare = {"runway_true_deg": None, "threshold_lat_deg": None, "threshold_lon_deg": None}
    meta = dataclasses.replace(r.meta, arrival=dataclasses.replace(r.meta.arrival, **bare))
    return Flight(data=log, meta=meta), bias, rest_end


def _report(flight: Flight) -> tuple[dict, list[str]]:
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        clean = clean_flight(flight)
    rep = next(e for e in clean.report if e["action"] == "heading_from_rates")
    return rep, [str(w.message) for w in caught if issubclass(w.category, FlightReconWarning)]


def test_the_standstill_measures_the_yaw_rate_bias_and_says_so():
    flight, bias, rest_end = _flight(quiet_rest=True)
    rep, warned = _report(flight)
    # the rolling 10 s windows need their whole span at rest: about rest_end - 5 s
    assert rest_end - 15.0 < rep["standstill_s"] <= rest_end
    # 45 s of 0.05 deg/s white noise at 8 Hz average to 0.0026 deg/s; the stability allowance
    # of 0.002 deg/s adds in quadrature: sd about 0.003, against the prior's 0.02
    assert rep["gyro_bias_sd_dps"] < 0.005
    assert abs(rep["gyro_bias_r_dps"] - bias[2]) < 3.0 * rep["gyro_bias_sd_dps"]
    assert any("gyro biases calibrated on" in w for w in warned)
    assert "at rest on the ground" in rep["why"]


def test_without_a_standstill_the_bias_rests_on_its_prior_and_the_runway():
    flight, _, _ = _flight(quiet_rest=False)
    rep, warned = _report(flight)
    assert rep.get("standstill_s") is None
    assert not any("gyro biases calibrated on" in w for w in warned)
    quiet, _ = _report(_flight(quiet_rest=True)[0])
    # what the standstill buys: the bias's sd and the largest heading sd both shrink
    assert quiet["gyro_bias_sd_dps"] < 0.5 * rep["gyro_bias_sd_dps"]
    assert quiet["heading_sd_max_deg"] < rep["heading_sd_max_deg"]


def test_a_trimmed_standstill_still_counts():
    """``--start`` after the standstill (at the line-up): the part cut away still measures
    the biases, as on the real flight."""
    from flightrecon.cleaning import CleaningSettings

    flight, bias, rest_end = _flight(quiet_rest=True)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        clean = clean_flight(flight, settings=CleaningSettings(start=rest_end + 1.0))
    rep = next(e for e in clean.report if e["action"] == "heading_from_rates")
    assert rep["standstill_s"] > rest_end - 15.0
    assert abs(rep["gyro_bias_r_dps"] - bias[2]) < 3.0 * rep["gyro_bias_sd_dps"]


def test_the_propagated_heading_is_announced_with_its_growing_sd():
    """Issue #35 item 4: a heading propagated from the body rates is announced on the console
    with or without a standstill, with what anchors it (the take-off roll aligned with the
    runway) and how its sd grows away from the anchors; the summary's cleaning report holds
    the roll's alignment."""
    flight, _, _ = _flight(quiet_rest=False)
    rep, warned = _report(flight)
    (msg,) = [w for w in warned if w.startswith("heading from the body rates")]
    rolls = rep["runway_rolls"]
    assert [r["which"] for r in rolls] == ["departure"]
    rw = flight.meta.departure.runway_true_deg
    assert rolls[0]["runway_true_deg"] == pytest.approx(rw % 360.0, abs=1e-9)
    # one anchor and two biases with a prior: the fit meets the roll's mean heading to well
    # within the roll's own sd (RUNWAY_SD_DEG, 1 deg)
    assert abs(rolls[0]["residual_deg"]) < 0.1
    assert f"departure roll aligned with runway {rw % 360.0:.1f} deg" in msg
    assert f"at most {rep['heading_sd_max_deg']:.1f} deg" in msg
    assert f"median {rep['heading_sd_median_deg']:.1f}" in msg
    assert "gyro biases calibrated on" not in msg
    # with the standstill the same message says what it calibrated
    quiet, warned_q = _report(_flight(quiet_rest=True)[0])
    (msg_q,) = [w for w in warned_q if w.startswith("heading from the body rates")]
    assert "gyro biases calibrated on" in msg_q


def test_a_record_that_starts_airborne_has_no_standstill_and_does_not_fail():
    """A record cut after the lift-off (``--start`` in the air: neither a roll nor a lift-off
    in it) has no standstill; the search returned an error (``min()`` of nothing) on the real
    reference flight started at 1000 s instead of the clear refusal of a heading with nothing
    to anchor it."""
    import pandas as pd

    from flightrecon.cleaning.standstill import standstill
    from flightrecon.types import FlightPhases

    t = np.arange(0.0, 120.0, 0.1)
    grid = pd.DataFrame({"t_s": t, "r_dps": np.zeros(len(t)), "n_long_g": np.zeros(len(t)),
                         "n_lat_g": np.zeros(len(t))})
    nan = float("nan")
    airborne = FlightPhases(liftoff_t_s=nan, touchdown_t_s=nan, starts_airborne=True,
                            ends_airborne=True, liftoff_velocity_ned_mps=(nan, nan, nan))
    assert not standstill(grid, t, np.full(len(t), 60.0), airborne).any()
    # at 0 m/s with quiet rates and loads and no lift-off it is at rest (the guard, not the
    # phases, decides)
    parked = dataclasses.replace(airborne, starts_airborne=False, ends_airborne=False)
    assert standstill(grid, t, np.zeros(len(t)), parked).all()
