"""Take-off roll detection has one home, :mod:`flightrecon.cleaning.ground_roll` (issue 20).

Regression: the joint smoother's roll (``methods/joint/inputs.py``) repeated the cleaning's
back-integration of the ground speed.  After the move the joint uses
:func:`flightrecon.cleaning.ground_roll.takeoff_roll` and its refinement (smoothed lift-off
speed, estimated accelerometer bias) is a parameter of it.  The numbers below were measured with the
implementation before the move, on the shipped sample logs and on the synthetic taxi flight of
``test_phases_taxi``; the roll times lie on the recorder grid (1/16 s), so they must come back
exactly, not within a tolerance.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from flightrecon.cleaning import clean_flight, ground_roll, phases
from flightrecon.ingest import load_flight
from flightrecon.methods import joint
from flightrecon.methods.joint.problem import joint_inputs

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"

# sample -> (initial roll (start, rest from, rest to),
#            roll with v_lo = TAS at lift-off + 0.7 m/s and a 0.02 m/s^2 forward bias,
#            refined_roll with a nominal of (40, 10, 0) m/s and a 0.002 g forward bias)
BEFORE = {
    "circuit.parquet": ((56.125, 0.0, 46.125), (54.875, 0.0, 44.875), (73.625, 0.0, 63.625)),
    "handmade.csv": ((31.125, 0.0, 21.125), (30.625, 0.0, 20.625), (56.875, 0.0, 46.875)),
    "regional.parquet": ((6.0, np.nan, np.nan), (3.0, np.nan, np.nan), (19.5, 0.0, 9.5)),
}


def _times(r: ground_roll.TakeoffRoll) -> tuple[float, float, float]:
    return (r.start_t, *r.rest_t)


def test_one_implementation():
    """The joint package's names are the cleaning's objects, not a second copy."""
    assert joint.takeoff_roll is ground_roll.takeoff_roll
    assert joint.TakeoffRoll is ground_roll.TakeoffRoll


@pytest.mark.parametrize("name", sorted(BEFORE))
def test_joint_roll_equals_before_the_move(name):
    initial, biased, refined = BEFORE[name]
    inp = joint_inputs(clean_flight(load_flight(SAMPLES / name)))
    np.testing.assert_array_equal(_times(inp.roll), initial)
    i_lo = int(np.searchsorted(inp.t_in, inp.liftoff_t)) - 1
    r = ground_roll.takeoff_roll(inp.t_in, inp.acc_ned, inp.heading_rad, inp.tas,
                                 inp.liftoff_t, inp.wind_ne, v_lo_mps=float(inp.tas[i_lo]) + 0.7,
                                 accel_bias_mps2=0.02, not_before_t=inp.lineup_t)
    np.testing.assert_array_equal(_times(r), biased)
    T = inp.t_in[::4]
    vnom = np.zeros((len(T), 3))
    vnom[:, :2] = (40.0, 10.0)
    bias = np.zeros((len(T), 3))
    bias[:, 0] = 0.002
    np.testing.assert_array_equal(_times(joint.refined_roll(inp, T, vnom, bias)), refined)
    # the bias is a parameter of the one detection: 0.02 m/s^2 over a rest moves the start
    # (regional rolls onto the runway without stopping: nothing to move there)
    r0 = ground_roll.takeoff_roll(inp.t_in, inp.acc_ned, inp.heading_rad, inp.tas,
                                  inp.liftoff_t, inp.wind_ne,
                                  v_lo_mps=float(inp.tas[i_lo]) + 0.7, not_before_t=inp.lineup_t)
    assert (r0.start_t != biased[0]) == bool(np.isfinite(biased[1]))


def test_cleaning_roll_start_equals_before_the_move():
    """The cleaning's own roll start (line-up, then the speed integrated back from the fast
    run) now goes through the shared integration; same times as before on the taxi flight."""
    from test_phases_taxi import ground_grid

    grid, _, _ = ground_grid()
    ph, _ = phases.detect_phases_with_report(grid, lat_deg=45.0)
    assert (ph.lineup_t_s, ph.roll_start_t_s, ph.liftoff_t_s) == (169.3125, 206.6875, 240.25)


def test_speed_integrated_back_is_the_trapezoid():
    """v(t) = v_end - int_t^t_end a dt, exact for a linear acceleration (trapezoidal rule)."""
    t = np.linspace(0.0, 10.0, 161)
    a = 0.3 * t
    v = ground_roll.speed_integrated_back(a, np.diff(t), 20.0)
    np.testing.assert_allclose(v, 20.0 - 0.15 * (100.0 - t ** 2), rtol=0, atol=1e-12)
    # one step for a uniform grid: the same integral
    np.testing.assert_allclose(ground_roll.speed_integrated_back(a, 1.0 / 16.0, 20.0), v, rtol=0,
                               atol=1e-12)
