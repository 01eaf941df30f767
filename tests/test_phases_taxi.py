"""A record that starts at the gate: taxi told apart from the take-off roll.

Synthetic ground run on a 16 Hz grid, kinematically consistent (load factors from the
accelerations, pitch and roll zero on the ground): push-back stand (20 s), taxi at 8 m/s with a
90 deg turn, hold short (20 s), a slow 90 deg turn onto the runway at 2 m/s (below the 3 m/s
"at rest" speed: the case that confuses a speed-only rule), lined up (30 s), take-off roll at
2 m/s^2, lift-off at 70 m/s with a 1 m/s^2 pull-up.
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from flightrecon.cleaning.phases import detect_phases_with_report
from flightrecon.constants import G0
from flightrecon.geo.kinematics import kinematic_acceleration_ned
from flightrecon.methods.joint import takeoff_roll

DT = 1.0 / 16.0


def _segments():
    # (duration s, speed at end m/s, heading rate deg/s)
    return [(20.0, 0.0, 0.0), (4.0, 8.0, 0.0), (40.0, 8.0, 0.0), (11.25, 8.0, 8.0),
            (30.0, 8.0, 0.0), (4.0, 0.0, 0.0), (20.0, 0.0, 0.0), (45.0, 2.0, 2.0),
            (1.0, 0.0, 0.0), (30.0, 0.0, 0.0), (35.0, 70.0, 0.0), (20.0, 75.0, 0.0)]


def _swerving_segments():
    """:func:`_segments` with a swerve on the take-off roll: 3 deg/s to the right for the first
    6 s (0 to 12 m/s), back at 1.5 deg/s for 4 s and 0.6 deg/s for 10 s, the rest straight
    (JSBSim's Cessna 310 on seed 6030: 18 deg at 1-12 m/s)."""
    return _segments()[:10] + [(6.0, 12.0, 3.0), (4.0, 20.0, -1.5), (10.0, 40.0, -0.6),
                               (15.0, 70.0, 0.0), (20.0, 75.0, 0.0)]


def ground_grid(segments=None, liftoff_segment: int = 10):
    """The grid and the true times: line-up, roll start, lift-off."""
    v, psi, t = [0.0], [70.0], [0.0]
    marks = {}
    for k, (dur, v_end, rate) in enumerate(segments or _segments()):
        n = int(round(dur / DT))
        v0 = v[-1]
        for i in range(1, n + 1):
            v.append(v0 + (v_end - v0) * i / n)
            psi.append(psi[-1] + rate * DT)
            t.append(t[-1] + DT)
        if k == 7:
            marks["lineup"] = t[-1]
        if k == 9:
            marks["roll"] = t[-1]
        if k == liftoff_segment:
            marks["liftoff"] = t[-1]
    t, v, psi = np.array(t), np.array(v), np.array(psi)
    a_al = np.gradient(v, DT)
    a_lat = v * np.radians(np.gradient(psi, DT))
    h = np.full(len(t), 10.0)
    a_up = np.zeros(len(t))
    air = t > marks["liftoff"]
    tau = t[air] - marks["liftoff"]
    vz = np.minimum(tau, 5.0)                       # 1 m/s^2 for 5 s, then 5 m/s
    h[air] = 10.0 + np.cumsum(vz) * DT
    a_up[air] = np.where(tau < 5.0, 1.0, 0.0)
    lat = 45.0
    g = -kinematic_acceleration_ned(np.zeros(1), np.zeros(1), np.ones(1), np.zeros(1),
                                    np.zeros(1), np.zeros(1), lat_deg=lat, h_m=np.array([10.0]))
    g_loc = G0 - g[0, 2]                             # local gravity seen through the model
    grid = pd.DataFrame({"t_s": t, "n_long_g": a_al / G0, "n_lat_g": a_lat / G0,
                         "n_norm_g": (g_loc + a_up) / G0, "roll_deg": 0.0, "pitch_deg": 0.0,
                         "heading_deg": psi % 360.0, "tas_mps": v, "baro_alt_m": h})
    return grid, marks, psi


def test_a_swerve_on_the_roll_is_not_taken_for_the_line_up():
    """A swerve of 18 deg in the first seconds of the roll: the runway heading taken 2 s into
    the fast run is 16 deg off the lined-up heading, so the stretch within 10 deg of it began
    on the roll (2 s in, at 4 m/s) and no rest was left before it ("rolling take-off").  The
    aircraft was at rest (ground speed integrated back along its own heading, at most
    3 m/s) with no taxi speed in between: the roll starts there, 1.5 s after the true start
    at 2 m/s^2 as on a straight roll, and the line-up is back on the turn onto the runway
    (within 10 deg of the heading at the roll start, 4.5 deg into the swerve: 2.75 s before the
    end of the 2 deg/s turn onto the runway)."""
    grid, marks, _ = ground_grid(_swerving_segments(), liftoff_segment=13)
    ph, rep = detect_phases_with_report(grid, lat_deg=45.0)
    assert ph.liftoff_t_s == pytest.approx(marks["liftoff"], abs=1.0)
    assert ph.roll_start_t_s == pytest.approx(marks["roll"] + 1.5, abs=0.3)
    assert ph.lineup_t_s == pytest.approx(marks["lineup"] - 2.75, abs=0.3)
    (rs,) = [e for e in rep if e["action"] == "roll_start"]
    assert "swerve" in rs["why"]


def test_lineup_and_roll_start_found():
    grid, marks, _ = ground_grid()
    ph, rep = detect_phases_with_report(grid, lat_deg=45.0)
    assert ph.liftoff_t_s == pytest.approx(marks["liftoff"], abs=1.0)
    # line-up: heading within 10 deg of the runway's: 5 s before the end of the 2 deg/s turn
    assert ph.lineup_t_s == pytest.approx(marks["lineup"] - 5.0, abs=0.2)
    # roll start: where the integrated speed leaves 3 m/s, 1.5 s after the true start at 2 m/s^2
    assert ph.roll_start_t_s == pytest.approx(marks["roll"] + 1.5, abs=0.3)
    (lu,) = [e for e in rep if e["action"] == "lineup"]
    assert lu["taxi_s"] == pytest.approx(marks["lineup"] - 5.0, abs=0.2)
    assert lu["runway_heading_deg"] == pytest.approx(250.0, abs=0.5)


def test_nothing_before_lineup_is_rest():
    """The joint smoother's rest stretch starts at the line-up; without it, the slow turn onto
    the runway and the hold short (moving, turning) would be taken as at rest."""
    grid, marks, psi = ground_grid()
    ph, _ = detect_phases_with_report(grid, lat_deg=45.0)
    g = grid
    acc = kinematic_acceleration_ned(*(g[c].to_numpy() for c in (
        "n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg", "heading_deg")),
        lat_deg=45.0, h_m=g["baro_alt_m"].to_numpy())
    args = (g["t_s"].to_numpy(), acc, np.radians(psi), g["tas_mps"].to_numpy(), ph.liftoff_t_s)
    old = takeoff_roll(*args)
    new = takeoff_roll(*args, not_before_t=ph.lineup_t_s)
    assert old.rest_t[0] < marks["lineup"] - 40.0          # the defect: the turn taken as rest
    assert new.rest_t[0] >= ph.lineup_t_s
    assert new.start_t == pytest.approx(old.start_t, abs=0.1)
    assert new.start_t == pytest.approx(marks["roll"] + 1.5, abs=0.3)
