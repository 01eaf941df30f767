"""Upsets to impact on the independent JSBSim truth (docs/jsbsim.md, "Upsets and impact").

* a spiral that rolls on past the knife edge (130 deg of bank at 10 deg/s, the truth reaching
  124-158 deg of bank and 78-87 deg nose down): the cleaning, the joint smoother and Sabziev
  run through it without a non-finite value where the recorder had data, the joint's track
  reaches the impact, and the impact is detected at the truth's time;
* the spiral and the spin as the scenarios fly them: the impact found, its peak loads at the
  recorder's range;
* the circuit's normal landing: no impact.

Tolerance of the impact time: 0.25 s (4 samples of the 16 Hz loads).  The truth's
``impact_t_s`` is the first truth sample with a contact point on the ground; the recorded loads
are means over the sample interval before their time stamp, so the first jolting sample is the
truth's or one or two before it when a wing tip or the nose touches first (measured on 22
flights: 0 to -0.125 s, scripts/impact_study.py).
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("jsbsim")

from flightrecon.cleaning import clean_flight
from flightrecon.events import detect_events
from flightrecon.methods.joint.method import run_joint
from flightrecon.sim import simulate
from flightrecon.types import Flight

TOL_S = 0.25


def _clean(r):
    return clean_flight(Flight(data=r.log, meta=r.meta))


def test_rollover_beyond_90_deg_bank_reconstructs_to_the_impact():
    r = simulate("jsbsim-spiral", 4, gnss_hz=0.0, scale=0.1, spiral_bank_deg=130.0,
                 spiral_roll_rate_dps=10.0)
    tr = r.truth
    assert np.abs(tr["roll_deg"]).max() > 120.0 and tr["pitch_deg"].min() < -75.0
    c = _clean(r)
    g = c.grid
    roll = g["roll_deg"].to_numpy()
    ok = np.isfinite(roll)
    assert ok.mean() > 0.999 and np.all((roll[ok] >= -180.0) & (roll[ok] < 180.0))
    # the recorded roll on the grid follows the truth through the knife edge (interpolated the
    # short way; attitude quantum 0.05 deg, 8 Hz against 16 Hz truth: 3 deg covers the roll
    # rate's 10 deg/s over the interpolation's half-interval and the recorder's errors)
    t_true = tr["t_s"].to_numpy()
    want = np.interp(g["t_s"], t_true, np.unwrap(np.radians(tr["roll_deg"]))) * 180.0 / np.pi
    err = (roll - want + 180.0) % 360.0 - 180.0
    air = ok & (g["t_s"].to_numpy() < t_true[-1] - 0.5)
    assert np.max(np.abs(err[air])) < 3.0
    ev = r.sensor_truth["events"]
    assert abs(c.phases.impact_t_s - ev["impact_t_s"]) <= TOL_S
    j = run_joint(c)
    tk = j.track
    pos = tk[["joint_north_m", "joint_east_m", "joint_up_m"]].to_numpy()
    assert np.isfinite(pos).all()
    assert tk["t_s"].iloc[-1] >= c.phases.impact_t_s
    assert np.isfinite(tk[["joint_north_sd_m", "joint_east_sd_m"]].to_numpy()).all()
    # the track runs to the wreckage (the sidecar's arrival, applied at the record's end as an
    # airfield reference point: sd 1500 m per axis), within 3 of its reported sd
    end = tk.iloc[-1]
    assert end["t_s"] == c.grid["t_s"].iloc[-1]
    d = np.hypot(end["joint_north_m"] - tr["north_m"].iloc[-1],
                 end["joint_east_m"] - tr["east_m"].iloc[-1])
    assert d < 3.0 * np.hypot(end["joint_north_sd_m"], end["joint_east_sd_m"])


@pytest.mark.parametrize("scenario", ["jsbsim-spiral", "jsbsim-spin"])
def test_scenario_upsets_end_at_a_detected_impact_with_saturated_peak_loads(scenario):
    r = simulate(scenario, 11, gnss_hz=0.0, scale=0.1)
    c = _clean(r)
    t_truth = r.sensor_truth["events"]["impact_t_s"]
    assert abs(c.phases.impact_t_s - t_truth) <= TOL_S
    rep = next(e for e in c.report if e["action"] == "impact")
    # the impact drives the normal accelerometer to the recorder's +6 g (or beyond -3 g)
    assert "n_norm_g" in rep["saturated"] or "n_long_g" in rep["saturated"]
    assert c.phases.impact_peak_load_g >= 4.0
    ev = [e for e in detect_events(c) if e.kind == "impact"]
    assert len(ev) == 1 and ev[0].t_s == c.phases.impact_t_s and ev[0].value >= 4.0
    assert not [e for e in detect_events(c) if e.kind == "end_airborne"]


def test_circuit_landing_is_no_impact():
    c = _clean(simulate("jsbsim-circuit", 11, gnss_hz=0.0))
    assert np.isnan(c.phases.impact_t_s) and np.isfinite(c.phases.touchdown_t_s)
    assert not [e for e in c.report if e["action"] in ("impact", "no_impact")]
    assert not [e for e in detect_events(c) if e.kind == "impact"]
