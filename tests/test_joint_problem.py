"""The joint smoother's problem, built once and then solved (methods/joint/problem.py;
docs/joint.md, "How the joint is built and solved"): frozen, every data-driven setting chosen
once with its evidence, the end points computed once, the result from the problem alone."""

from __future__ import annotations

from dataclasses import FrozenInstanceError, asdict, replace
from pathlib import Path

import numpy as np
import pytest

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"

#: few passes, no calibration rounds: the build and the plumbing are under test, not the
#: smoother's answer
QUICK = {"iterations": 2, "gap_stretches": 0, "wind_rounds": 0, "estimate_gust": False}


@pytest.fixture(scope="module")
def circuit():
    from flightrecon.cleaning import clean_flight
    from flightrecon.ingest import load_flight

    return clean_flight(load_flight(SAMPLES / "circuit.parquet"))


def test_the_problem_is_frozen_and_its_choices_are_its_settings(circuit):
    """Each choice names a setting the problem holds with that value, and says why; the
    circuit records the SAT, so the pressure-altitude scale's prior is one of them (docs/joint.md,
    "The pressure-altitude scale from the temperature"); the given settings are not changed."""
    from flightrecon.methods.joint.problem import joint_problem
    from flightrecon.methods.joint.settings import JointSettings

    given = JointSettings()
    problem = joint_problem(circuit, given)
    with pytest.raises(FrozenInstanceError):
        problem.settings = given  # type: ignore[misc]
    assert given == JointSettings()
    assert problem.choices and all(c.why for c in problem.choices)
    for c in problem.choices:
        kind, _, name = c.setting.partition(".")
        if kind == "noise":
            assert getattr(problem.settings.noise, name) == c.value
        else:
            assert kind == "priors" and (name, *c.value) in problem.settings.priors
    assert "priors.baro_scale" in {c.setting for c in problem.choices}
    # what the output needs of the flight is in the problem
    assert problem.frame is not None
    assert np.array_equal(problem.frame.t_s, circuit.grid["t_s"].to_numpy(float))


def test_the_end_points_are_computed_once(circuit, monkeypatch):
    """The end points are built with the inputs and read by the nominal path, every pass's
    measurements and the summary: the touchdown from the recorded flare (the circuit's
    arrival runway is known) is measured once per run, where each of them measured it
    again before (issue 51); the summary's end points are the problem's, the departure at
    the start of the smoother's refined take-off roll."""
    import flightrecon.methods.joint.inputs as ji
    from flightrecon.methods.joint.method import run_joint
    from flightrecon.methods.joint.settings import JointSettings

    calls = []
    measured = ji.float_touchdown
    monkeypatch.setattr(ji, "float_touchdown",
                        lambda *a, **k: calls.append(1) or measured(*a, **k))
    res = run_joint(circuit, settings=replace(JointSettings(), **QUICK))
    assert len(calls) == 1
    ends = res.summary["end_points"]
    assert [e["model"] for e in ends] == ["runway", "runway"]
    assert ends[0]["t_s"] == res.summary["takeoff_roll"]["start_t_s"]
    assert "flare" in ends[1]


def test_the_result_is_the_problems_alone(circuit):
    """``joint_result`` takes the problem, not the cleaned flight: the track on the problem's
    grid, the summary's settings and chosen settings the problem's, its end points the
    problem's (the departure's time the refined roll's)."""
    from flightrecon.methods.joint.method import joint_result
    from flightrecon.methods.joint.problem import joint_problem
    from flightrecon.methods.joint.settings import JointSettings

    problem = joint_problem(circuit, replace(JointSettings(), **QUICK))
    res = joint_result(problem)
    assert problem.frame is not None
    assert np.array_equal(res.track["t_s"].to_numpy(float), problem.frame.t_s)
    assert res.summary["settings"] == asdict(problem.settings)
    assert res.summary["chosen_settings"] == [asdict(c) for c in problem.choices]
    built = {e.which: e for e in problem.inputs.end_points}
    for e in res.summary["end_points"]:
        b = built[e["which"]]
        assert (e["model"], e["lat_deg"], e["lon_deg"], e["sd_m"]) == (
            b.model, b.point[0], b.point[1], list(b.sd_m))
        if e["which"] == "arrival":
            assert e["t_s"] == b.t_s
