"""A method whose iterations stop short of their convergence test (issue 52, item 4): how far
the joint smoother's passes still had to go (``settling`` in flightrecon/methods/joint/health.py),
the status ``stopped`` with the figures, the sd widened by that movement, and, on a real SR22T
flight with its GPS and three stretches withheld (exit 8 before: "did not converge (50 passes):
the last moved the track by 0.3 m"), an answer whose sd covers the withheld GPS."""

from __future__ import annotations

import os
import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from flightrecon.errors import ConvergenceError
from flightrecon.methods.joint.health import (
    SETTLE_SD_FRACTION,
    settling,
    settling_sentence,
)
from flightrecon.pipeline.health import method_health
from flightrecon.pipeline.status import FEEDS_DEFAULT, method_status
from flightrecon.types import FlightMeta, MethodResult

ROOT = Path(__file__).resolve().parents[1]
REALDATA = ROOT.parent / "shared" / "realdata"
LFAQ = REALDATA / "g1000_sr22_LFAQ_20220417.csv"
WITHHELD = ((1000.0, 1300.0), (2000.0, 2300.0), (3000.0, 3300.0))


def _run(shifts: list[float], last_shift: np.ndarray, sd_m: float, converged: bool = False):
    """A stand-in for a JointRun: what settling() reads (the passes' largest changes, the last
    pass's change per state, the position covariance)."""
    k = len(last_shift)
    P = np.zeros((k, 6, 6))
    P[:, 0:3, 0:3] = np.eye(3) * sd_m ** 2
    return SimpleNamespace(converged=converged, last_shift_m=np.asarray(last_shift, float),
                           iterations=[{"max_position_change_m": s} for s in shifts], P_pv=P)


def test_a_contracting_run_is_bounded_by_its_geometric_tail():
    # changes shrinking by 0.9 a pass: the passes to come add 0.9 / 0.1 = 9 times the last
    shifts = [1.0 * 0.9 ** i for i in range(10)]
    last = np.array([0.2, shifts[-1], 0.1])
    s = settling(_run(shifts, last, sd_m=1.0))
    assert s["contraction"] == pytest.approx(0.9)
    assert s["remaining_m"] == pytest.approx(shifts[-1] * 9.0)
    assert s["remaining_k_m"] == pytest.approx(last * 9.0)
    assert s["verdict"] == "widened"      # 3.5 m against an sd of 1 m
    # the same movement against an sd a hundred times larger is within the tolerance
    s = settling(_run(shifts, last, sd_m=100.0))
    assert s["remaining_over_sd"] <= SETTLE_SD_FRACTION and s["verdict"] == "settled"


def test_a_run_still_moving_by_more_than_its_sd_is_unbounded():
    """The geometric tail is a bound only inside the region where the passes converge at the
    rate seen: a contracting run whose last pass still moved a state by more than its sd (the
    Citation reference flight recorder only: 8.5 km a pass, contracting by 0.991) is unbounded,
    not given an sd of a thousand kilometres."""
    shifts = [8000.0 * 0.99 ** i for i in range(10)]
    s = settling(_run(shifts, np.array([shifts[-1]]), sd_m=30.0))
    assert s["contraction"] == pytest.approx(0.99)
    assert s["last_change_over_sd"] > 100.0
    assert s["verdict"] == "unbounded" and "remaining_m" not in s
    assert "far from where its passes converge" in settling_sentence(s)
    # the same contraction once the passes move it by less than its sd: bounded
    s = settling(_run([x / 1e4 for x in shifts], np.array([shifts[-1] / 1e4]), sd_m=30.0))
    assert s["verdict"] in ("settled", "widened")


def test_the_slowest_contraction_of_the_last_passes_bounds_it():
    shifts = [1.0, 0.5, 0.45, 0.40, 0.2, 0.1]      # ratios 0.5, 0.9, 0.89, 0.5, 0.5
    s = settling(_run(shifts, np.array([0.1]), sd_m=1.0))
    assert s["contraction"] == pytest.approx(0.9)


def test_passes_that_do_not_shrink_are_unbounded():
    s = settling(_run([0.3, 0.31, 0.3, 0.31, 0.3, 0.31], np.array([0.31]), sd_m=1.0))
    assert s["verdict"] == "unbounded" and "remaining_m" not in s


def test_a_converged_run_has_no_settling():
    assert settling(_run([1.0, 0.1], np.array([0.1]), 1.0, converged=True)) is None


def test_the_widened_sd_adds_the_remaining_movement_in_quadrature():
    """The track's north, east and up sd take the remaining movement (per state, interpolated
    to the track's times) in quadrature, each axis the whole of it; the rest is unchanged."""
    from flightrecon.geo.frames import TangentPlane, geodetic_to_ecef
    from flightrecon.geo.navframe import ned_to_ecef_matrix
    from flightrecon.methods.joint import layout as jl
    from flightrecon.methods.joint.output import joint_track
    from flightrecon.methods.joint.solve import hermite_positions

    T = np.array([0.0, 2.0])
    x = np.zeros((2, jl.N_STATE))
    x[:, jl.S_POS] = np.array(geodetic_to_ecef(45.0, 10.0, 500.0))
    C = np.asarray(ned_to_ecef_matrix(45.0, 10.0)).reshape(3, 3)
    P = np.zeros((2, 6, 6))
    P[:, 0:3, 0:3] = C @ np.diag([9.0, 1.0, 4.0]) @ C.T    # north, east, down sd 3, 1, 2
    run = SimpleNamespace(t=T, x=x, P_pv=P, var=np.ones((2, jl.N_STATE)),
                          Cen=np.repeat(C[None], 2, 0),
                          meas=SimpleNamespace(t=np.zeros(0), source=np.zeros(0, int)))
    # the smoothed positions as JointRun.positions_ecef gives them (at rest: the states')
    run.positions_ecef = lambda t_s: hermite_positions(t_s, T, x[:, jl.S_POS],
                                                       np.zeros((2, 3)))
    plane, t = TangentPlane(45.0, 10.0, 0.0), np.array([0.0, 1.0, 2.0])
    tr, base = joint_track(t, plane, run, np.array([4.0, 0.0])), joint_track(t, plane, run)
    assert tr["joint_north_sd_m"].tolist() == pytest.approx([5.0, np.hypot(3.0, 2.0), 3.0])
    assert tr["joint_east_sd_m"].iloc[0] == pytest.approx(np.hypot(1.0, 4.0))
    assert tr["joint_up_sd_m"].iloc[0] == pytest.approx(np.hypot(2.0, 4.0))
    rest = [c for c in tr.columns if c not in ("joint_north_sd_m", "joint_east_sd_m",
                                               "joint_up_sd_m")]
    pd.testing.assert_frame_equal(tr[rest], base[rest])


def _result(settle: dict | None) -> MethodResult:
    t = np.arange(5.0)
    track = pd.DataFrame({"t_s": t, "joint_north_m": t, "joint_east_m": t,
                          "joint_north_sd_m": np.ones(5), "joint_east_sd_m": np.ones(5)})
    summary = {"converged": False, "healthy": True,
               "stop_reason": "max passes reached (50): the last moved the track by 0.3 m"}
    if settle is not None:
        summary["settling"] = settle
    return MethodResult(name="joint", track=track, summary=summary)


def test_a_run_stopped_with_a_bound_is_stopped_and_feeds_the_default():
    res = _result({"verdict": "widened", "sentence": "stopped at 50 passes, ... widened"})
    health = method_health(res)
    assert health["healthy"] and health["stopped_short"].startswith("stopped at 50")
    st = method_status(res, health)
    assert st["status"] == "stopped" and st["status"] in FEEDS_DEFAULT
    assert st["reason"].startswith("stopped at 50 passes") and st["healthy"] is True


def test_a_run_stopped_without_a_bound_is_unhealthy_with_both_reasons():
    res = _result({"verdict": "unbounded", "sentence": "its passes' changes not shrinking"})
    st = method_status(res, method_health(res))
    assert st["status"] == "unhealthy" and st["healthy"] is False
    assert "max passes reached" in st["reason"] and "not shrinking" in st["reason"]
    # a method without a settling report that did not converge is unhealthy, as before
    st = method_status(_result(None), method_health(_result(None)))
    assert st["status"] == "unhealthy" and st["reason"].startswith("did not converge")


def test_strict_refuses_a_stopped_method(monkeypatch):
    from flightrecon.pipeline import registry, run

    res = _result({"verdict": "widened", "sentence": "stopped at 50 passes"})
    monkeypatch.setattr(run, "run_method", lambda name, clean, settings: res)
    monkeypatch.setattr(run, "_chosen_methods", lambda clean, settings: (["joint"], {}))
    monkeypatch.setattr(run, "method_health", lambda r, clean: method_health(r))
    clean = SimpleNamespace(grid=pd.DataFrame({"t_s": np.arange(5.0)}),
                            meta=FlightMeta())
    with pytest.raises(ConvergenceError, match="stopped"):
        run.reconstruct_clean(clean, registry.ReconstructSettings(strict=True), workers=1)


@pytest.mark.skipif(not LFAQ.is_file() and not os.environ.get("CI"),
                    reason=f"no real Garmin exports at {REALDATA}")
def test_a_real_flight_with_gnss_gaps_gets_an_answer_that_covers_the_gps():
    from flightrecon.cleaning import clean_flight
    from flightrecon.geo.frames import output_plane
    from flightrecon.ingest import load_flight
    from flightrecon.ingest.gnss_use import GnssUse
    from flightrecon.pipeline import ReconstructSettings, reconstruct

    rec = reconstruct(LFAQ, settings=ReconstructSettings(), record=False,
                      gnss_use=GnssUse(withhold_s=WITHHELD))
    assert rec.summary["result"]["method"] == "joint"
    joint = rec.summary["methods"]["joint"]
    assert joint["status"] in ("ok", "stopped")
    if joint["status"] == "stopped":
        assert "passes" in joint["reason"] and joint["settling"]["remaining_m"] > 0
    # the GPS withheld and used: every stretch's NEES per axis at most 5
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")   # the export's quirks, said when it is read
        flight = load_flight(LFAQ)
    g = flight.data.dropna(subset=["gnss_lat_deg", "gnss_lon_deg"])
    e, n, _ = output_plane(clean_flight(flight).meta).forward(
        g["gnss_lat_deg"].to_numpy(), g["gnss_lon_deg"].to_numpy(), g["gnss_alt_m"].to_numpy())
    t, tr = g["t_s"].to_numpy(), rec.track
    for a, b in (*WITHHELD, (0.0, np.inf)):
        m = (t >= a) & (t <= b)
        for axis, truth in (("north", n), ("east", e)):
            est = np.interp(t[m], tr["t_s"], tr[f"{axis}_m"])
            sd = np.interp(t[m], tr["t_s"], tr[f"{axis}_sd_m"])
            assert np.mean(((est - truth[m]) / sd) ** 2) <= 5.0, (a, b, axis)
