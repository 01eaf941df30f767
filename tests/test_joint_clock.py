"""The joint smoother's GNSS clock offset: estimated jointly with the track (its Gauss-Newton
step from the forward filter's clock columns, docs/joint.md, "Filter, smoother, iterations",
item 4), on a simulated circuit whose GNSS is stamped late (the simulator's clock fault:
the reading stamped t was taken at t - lag)."""

import numpy as np
import pytest
from _scripts import load_script

from flightrecon.cleaning import clean_flight
from flightrecon.methods.joint import JointSettings
from flightrecon.methods.joint.method import run_joint
from flightrecon.sim import simulate
from flightrecon.sim.sensors import Faults
from flightrecon.types import Flight

mc = load_script("mc_joint")


def _joint(late_s: float, seed: int, estimate_clock: bool = True):
    r = simulate("circuit", seed=seed, gnss_dropouts=((400.0, 120.0),),
                 faults=Faults(clock_offsets=(("gnss", late_s),)))
    lag = [e["offset_s"] for e in r.sensor_truth["faults"] if e["kind"] == "clock_offset"]
    clean = clean_flight(Flight(data=r.log, meta=r.meta))
    j = run_joint(clean, settings=JointSettings(noise=mc.noise_from_sensors(r.sensor_truth),
                                                estimate_clock=estimate_clock))
    err = mc.errors(j.track, "joint_", r.truth, ~r.truth["on_ground"].to_numpy(bool))
    return j, (lag[0] if lag else 0.0), err


@pytest.fixture(scope="module")
def late_run():
    return _joint(0.2, 2002)


def test_gnss_clock_offset_recovered(late_run):
    """GNSS stamped 0.1875 s late (0.2 s on the 16 Hz truth grid), positions and velocities
    alike: both offsets, in the convention of ``clean --gnss-clock-offset`` (seconds added to
    the stamps), are -0.1875 s within 3 of their sd (measured: positions -0.1981 +- 0.0061 s,
    1.7 sd, velocities -0.1961 +- 0.0049 s; seeds 2001 and 2003, 0.375 s and 0.1875 s late:
    0.8 and 1.3 sd; the flight without the fault -0.0009 s).  Regression: the offset was fitted
    between the passes from the smoothed residuals, which had absorbed it: it stayed 0 (sd
    1.2 ms), and with the GNSS velocities compared at the state step instead of their own time
    the offset's optimum was -0.05 s for a 0.375 s lag (the track 23 m RMS from the truth,
    NEES 2856)."""
    j, lag, err = late_run
    assert lag == pytest.approx(0.1875)
    for name in ("gnss", "gnss_velocity"):
        c = j.summary["clock_offsets_s"][name]
        assert np.isfinite(c["sd"]) and 0.0 < c["sd"] < 0.05, name
        assert abs(c["value"] + lag) < 3.0 * c["sd"], name
    # the clock-fault-free accuracy of this flight (0.6-0.9 m RMS on seeds 2001-2003) and
    # its consistency (NEES 0.5-1.8 per axis with the offsets' uncertainty in the track's sd)
    assert err["rms_h_m"] < 1.5
    assert err["nees_n"] < 4.0 and err["nees_e"] < 4.0


def test_gnss_clock_offset_converges_in_few_passes(late_run):
    """The offset's step is the Gauss-Newton step jointly with the track: the passes settle
    in about as many as with the clock fixed (5 here, the same flight with the offset not
    estimated 6-8), where the residual fit recovered about 1.4 % of what was left of the
    offset per pass (32-50 passes on real G1000 exports)."""
    j, _, _ = late_run
    its = j.summary["iterations"]
    assert j.summary["converged"]
    assert len(its) <= 10
    steps = [abs(i["clock_gnss_step_s"]) for i in its if "clock_gnss_step_s" in i]
    # the first pass's step takes most of the offset, the last ones stand still
    assert steps[0] > 0.5 * 0.1875
    assert steps[-1] < 0.1 * j.summary["clock_offsets_s"]["gnss"]["sd"] + 1e-12


def test_an_offset_that_is_not_there_is_not_taken():
    """GNSS on time: the offsets' first steps stay within 3 of their sd (not detected), so the
    stamps are kept and the track is the one with the clock not estimated, to rounding (an
    offset estimated always cost the simulated radar approaches 15.1 -> 17.7 m RMS); the sd
    is still reported."""
    j, lag, _ = _joint(0.0, 2001)
    fixed, _, _ = _joint(0.0, 2001, estimate_clock=False)
    assert lag == 0.0
    for name in ("gnss", "gnss_velocity"):
        c = j.summary["clock_offsets_s"][name]
        assert c["value"] == 0.0 and 0.0 < c["sd"] < 0.05, name
    for ax in ("north", "east"):
        np.testing.assert_allclose(j.track[f"joint_{ax}_m"], fixed.track[f"joint_{ax}_m"],
                                   atol=1e-6)
