"""Adapter: the joint post-flight smoother on a cleaned flight (the default result).

Builds the problem once (:func:`flightrecon.methods.joint.problem.joint_problem`: the inputs, the
end points, the settings the data call for), solves it
(:func:`flightrecon.methods.joint.smooth_joint`), solves the adjusted problems of the calibrations
(:mod:`~flightrecon.methods.joint.calibration`) and returns the track on the input grid with the
prefix ``joint_`` (the pipeline writes it as the unprefixed default result) and a summary with the
estimated sensor errors, clock offsets and per-source innovation statistics.  Nothing here reads the
cleaned flight after the problem is built.
"""

from __future__ import annotations

import warnings as _warnings
from dataclasses import asdict, replace
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.errors import FlightReconWarning
from flightrecon.estimation.consistency import ChiSquareVerdict, chi_square_verdict
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.calibration import calibrate_gaps, wind_walk_rounds
from flightrecon.methods.joint.health import (
    clock_warnings,
    far_warning,
    gust_warnings,
    implausible_corrections,
    settling,
    settling_sentence,
    source_report,
    wind_walk_check,
    wind_walk_warning,
)
from flightrecon.methods.joint.inputs import JointInputs
from flightrecon.methods.joint.output import (
    PREFIX,
    corrections_at_middle,
    fix_report,
    joint_track,
    wind_prior_report,
)
from flightrecon.methods.joint.problem import JointProblem, joint_problem
from flightrecon.methods.joint.settings import JointSettings
from flightrecon.methods.joint.solve import JointRun, smooth_joint
from flightrecon.types import CleanFlight, MethodResult

__all__ = ["PREFIX", "joint_result", "run_joint"]


def _run_warnings(run: JointRun, inp: JointInputs, settings: JointSettings,
                  sources: dict[str, Any], attitude_note: str | None) -> list[str]:
    """The run's warnings for the user: the inputs' notes, inconsistent sources, the noise
    estimation's and the iterations' convergence, clock offsets, gusts, Cholesky fallbacks."""
    warnings = list(inp.notes) + ([attitude_note] if attitude_note else [])
    for name, st in sources.items():
        if st["flagged_inconsistent"]:
            warnings.append(f"joint: source '{name}' inconsistent with the others in "
                            f"{st['beyond_5_sigma']} measurements "
                            f"(spans {st['flagged_spans_s'][:5]}"
                            " s); down-weighted")
    nc = run.noise_check
    if nc is not None and not nc["accepted"]:
        warnings.append("joint: the estimated noise did not raise the likelihood of the data "
                        f"(log-likelihood {nc['loglik_estimated']:.1f} vs "
                        f"{nc['loglik_default']:.1f} with the defaults): the default noise is "
                        "kept")
    elif nc is not None and nc["factors_at_bound"]:
        warnings.append(f"joint: noise factors at their bound {nc['bounds']}: "
                        f"{', '.join(nc['factors_at_bound'])} (the noise settings or the data "
                        "of these sources are far off)")
    if settings.estimate_noise and not run.iterations[-1].get("converged"):
        warnings.append(f"joint: noise estimation did not converge in {len(run.iterations)} "
                        "iterations; the last factors are used")
    # converged: the test of smooth_joint (the MAP cost and the track settled; docs/joint.md,
    # "Filter, smoother, iterations"), nothing looser; otherwise a warning with the reason
    if not run.converged:
        warnings.append(f"joint: not converged after {len(run.iterations)} passes: "
                        f"{run.stop_reason}")
    warnings += clock_warnings(run) + gust_warnings(run, settings.gust_bounds_mps[1])
    if run.cholesky_fallbacks:
        warnings.append(f"joint: on {run.cholesky_fallbacks} steps the predicted covariance was "
                        "not positive definite to rounding (Cholesky failed); the smoother gain "
                        "there came from a general solve")
    return warnings


def _innovation_verdict(run: JointRun) -> ChiSquareVerdict:
    """The chi-square verdict of the forward innovations of the measurements the smoother kept at
    full weight (the robustly down-weighted ones are reported per source, not held against the noise
    model)."""
    full = (run.weights >= 1.0) & (run.innov_var > 0)
    return chi_square_verdict(np.where(full, run.innov ** 2 / np.where(full, run.innov_var,
                                                                       1.0), np.nan))


def _summary(problem: JointProblem, run: JointRun, track: pd.DataFrame, *,
             verdict: ChiSquareVerdict, healthy: bool, converged: bool,
             extra: dict[str, Any]) -> dict[str, Any]:
    """The joint method's summary (docs/output.md, "The joint smoother's summary"): health,
    consistency, iterations, the data-chosen settings, the corrections, clock offsets, noise, end
    points, take-off roll, fixes, wind prior, sources, settings and warnings; ``extra`` the run's
    ``wind_rounds``, ``gap_calibration``, ``corrections``, ``sources`` and ``warnings``."""
    settings, frame = problem.settings, problem.frame
    return {
        "healthy": healthy,
        "consistency": verdict.as_dict(),
        "converged": converged,
        "stop_reason": run.stop_reason,
        "cholesky_fallbacks": run.cholesky_fallbacks,
        "iterations": run.iterations,
        "gust": run.gust,
        "wind_walk": {"wind_rw_mps_sqrt_s": settings.noise.wind_rw_mps_sqrt_s,
                      "rounds": extra["wind_rounds"]},
        "gap_calibration": extra["gap_calibration"],
        "state_rate_hz": settings.state_rate_hz,
        "attitude_tilt": {"source": None if frame is None else frame.attitude_source,
                          "gain_mps2_per_g": settings.noise.ahrs_tilt_mps2_per_g,
                          "gnss_evidence": problem.tilt_evidence},
        "corrections": extra["corrections"],
        "clock_offsets_s": {k: {"value": o, "sd": sd}
                            for k, (o, sd) in run.clock_offsets_s.items()},
        "noise_scale": run.noise_scale,
        "noise_check": run.noise_check,
        "end_points": [{"which": e.which, "model": e.model, "t_s": e.t_s,
                        "lat_deg": e.point[0], "lon_deg": e.point[1],
                        "runway_true_deg": (None if e.runway_rad is None
                                            else float(np.degrees(e.runway_rad) % 360.0)),
                        "sd_m": list(e.sd_m),
                        **({"flare": asdict(e.flare)} if e.flare is not None else {})}
                       for e in run.end_points],
        "takeoff_roll": {"start_t_s": run.roll.start_t, "rest_t_s": list(run.roll.rest_t)},
        "fixes": [] if frame is None else fix_report(frame, track),
        "wind_prior": wind_prior_report(problem),
        "sources": extra["sources"],
        "settings": asdict(settings),
        "chosen_settings": [asdict(c) for c in problem.choices],
        "warnings": extra["warnings"],
    }


def run_joint(clean: CleanFlight, *, settings: JointSettings | None = None) -> MethodResult:
    """Joint smoother of every source on ``clean`` (see :mod:`flightrecon.methods.joint`): the
    problem built once (:func:`~flightrecon.methods.joint.problem.joint_problem`), then solved
    (:func:`joint_result`)."""
    return joint_result(joint_problem(clean, settings))


def joint_result(problem: JointProblem) -> MethodResult:
    """The joint smoother's result on ``problem``: solved, its wind walk re-estimated and its GNSS
    gaps calibrated (each an adjusted problem solved again:
    :mod:`~flightrecon.methods.joint.calibration`), then the track and the summary."""
    run = smooth_joint(problem)
    if problem.attitude_note:
        _warnings.warn(problem.attitude_note, FlightReconWarning, stacklevel=3)
    problem, run, wind_rounds = wind_walk_rounds(problem, run)
    run, gap_cal = calibrate_gaps(problem, run)
    # the iteration-independent parts go before the track
    run, problem = replace(run, flight=None), replace(problem, flight=None)
    if problem.frame is None:
        raise ValueError("the joint result needs the problem's output frame "
                         "(joint_problem builds it)")
    settle = settling(run)
    widen = (None if settle is None or settle["verdict"] != "widened" else settle["remaining_k_m"])
    track = joint_track(problem.frame.t_s, problem.frame.plane, run, widen)
    summary = _checked_summary(problem, run, track, wind_rounds, gap_cal)
    if settle is not None:
        # stopped short of the convergence test: how far the passes still had to go
        # (settling.py); the pipeline's health reads it (status "stopped")
        summary["settling"] = {k: v for k, v in settle.items() if k != "remaining_k_m"}
        summary["settling"]["sentence"] = settling_sentence(settle)
    return MethodResult(name="joint", track=track, summary=summary)


def _checked_summary(problem: JointProblem, run: JointRun, track: pd.DataFrame,
                     wind_rounds: list[dict[str, Any]], gap_cal: dict[str, Any] | None
                     ) -> dict[str, Any]:
    """The summary with the run's checks: finite states, the innovations' chi-square, the
    corrections' plausibility, the wind walk, with their warnings."""
    inp, settings = problem.inputs, problem.settings
    finite = np.isfinite(run.x).all() and np.all(run.var[:, jl.IP:jl.IV + 3] > 0)
    sources = source_report(run)
    warnings = _run_warnings(run, inp, settings, sources, problem.attitude_note)
    if gap_cal is not None and gap_cal["factor"] is None:
        # on the console and at the summary's top level: the gaps' sd is not this flight's
        note = (f"joint: GNSS gaps {gap_cal['gaps_s'][:3]} s, but {gap_cal['note']}: their "
                "position sd is the model's, not calibrated on this flight")
        warnings.append(note)
        _warnings.warn(note, FlightReconWarning, stacklevel=4)
    verdict = _innovation_verdict(run)
    if verdict.gross:
        warnings.append(f"joint: mean NIS per measurement {verdict.mean:.1f} (expected 1): the "
                        "noise settings do not fit this flight")
    corrections = corrections_at_middle(run, settings)
    far = implausible_corrections(corrections)
    warnings += [far_warning(name, corrections[name], z) for name, z in far.items()]
    wind_walk = wind_walk_check(run, settings.noise.wind_rw_mps_sqrt_s,
                                settings.noise.wind_shear_mps_per_sqrt_m)
    if wind_rounds and wind_walk is None:
        warnings.append(
            f"joint: the wind changed faster than its default random walk "
            f"({wind_rounds[0]['wind_rw_mps_sqrt_s']:g} m/s/sqrt(s)); the walk re-estimated from "
            f"the smoothed wind in {len(wind_rounds)} round(s): "
            f"{settings.noise.wind_rw_mps_sqrt_s:.3g} m/s/sqrt(s)")
    if wind_walk is not None:
        warnings.append(wind_walk_warning(wind_walk))
    return _summary(problem, run, track, verdict=verdict,
                    healthy=bool(finite) and not verdict.gross and not far
                    and wind_walk is None, converged=bool(finite) and run.converged,
                    extra={"wind_rounds": wind_rounds, "gap_calibration": gap_cal,
                           "corrections": corrections, "sources": sources,
                           "warnings": warnings})
