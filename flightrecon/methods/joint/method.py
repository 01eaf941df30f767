"""Adapter: the joint post-flight smoother on a cleaned flight (the default result): the problem
built once, solved, its calibrations solved, the run checked, then the track with the prefix
``joint_`` (the pipeline writes it as the unprefixed default result) and the summary
(:func:`joint_result`; docs/joint.md, "How the joint is built and solved").  Nothing here reads
the cleaned flight after the problem is built.
"""

from __future__ import annotations

import warnings as _warnings
from dataclasses import replace

from flightrecon.errors import FlightReconWarning
from flightrecon.methods.joint.calibration import calibrate_gaps, wind_walk_rounds
from flightrecon.methods.joint.health import run_health
from flightrecon.methods.joint.output import PREFIX, joint_summary, joint_track
from flightrecon.methods.joint.problem import JointProblem, joint_problem
from flightrecon.methods.joint.settings import JointSettings
from flightrecon.methods.joint.solve import smooth_joint
from flightrecon.types import CleanFlight, MethodResult

__all__ = ["PREFIX", "joint_result", "run_joint"]


def run_joint(clean: CleanFlight, *, settings: JointSettings | None = None) -> MethodResult:
    """Joint smoother of every source on ``clean`` (see :mod:`flightrecon.methods.joint`): the
    problem built once (:func:`~flightrecon.methods.joint.problem.joint_problem`), then solved
    (:func:`joint_result`)."""
    return joint_result(joint_problem(clean, settings))


def joint_result(problem: JointProblem) -> MethodResult:
    """The joint smoother's result on ``problem``: solved, its wind walk re-estimated and its GNSS
    gaps calibrated (each an adjusted problem solved again:
    :mod:`~flightrecon.methods.joint.calibration`), checked, then the track (its position sd
    widened by a stopped run's remaining movement) and the summary."""
    run = smooth_joint(problem)
    if problem.attitude_note:
        _warnings.warn(problem.attitude_note, FlightReconWarning, stacklevel=3)
    problem, run, wind_rounds = wind_walk_rounds(problem, run)
    run, gap_cal = calibrate_gaps(problem, run)
    # the iteration-independent parts go before the checks and the track
    problem = replace(problem, flight=None)
    if problem.frame is None or problem.priors is None:
        raise ValueError("the joint result needs the problem's output frame and priors' table "
                         "(joint_problem builds them)")
    health = run_health(problem, run, wind_rounds, gap_cal, problem.priors)
    track = joint_track(problem.frame.t_s, problem.frame.plane, run, health.remaining_k_m)
    return MethodResult(name="joint", track=track, summary=joint_summary(
        problem, run, track, health, wind_rounds=wind_rounds, gap_calibration=gap_cal))
