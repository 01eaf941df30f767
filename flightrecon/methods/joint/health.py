"""The checks of a joint smoother run and their warnings, run once by :func:`run_health`
(docs/output.md, "Method health"; docs/joint.md, "Outputs"): per-source residual statistics, the
innovations' chi-square, the sensor errors and how far from their priors, clock offsets and gusts
that deserve a word, the wind-walk check, and how far the track still was from its fixed point
when the passes stopped short of the convergence test (:func:`settling`, the geometric tail of
the last pass's change: docs/output.md, "Method status", "Stopped short"; docs/joint.md, "Filter,
smoother, iterations"), by which the output track's sd is widened."""

from __future__ import annotations

import warnings as _warnings
from dataclasses import dataclass
from typing import Any

import numpy as np

from flightrecon.errors import FlightReconWarning
from flightrecon.estimation.consistency import ChiSquareVerdict, chi_square_verdict
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.problem import JointProblem
from flightrecon.methods.joint.settings import PRIOR_STATES, SOURCES
from flightrecon.methods.joint.solve import JointRun


def source_report(run: JointRun, flag_fraction: float = 0.01) -> dict[str, Any]:
    """Per source: measurements used, mean squared normalised residual, down-weighted ones and their
    time spans; a source with more than ``flag_fraction`` of its residuals beyond 5 sigma is flagged
    inconsistent."""
    out: dict[str, Any] = {}
    m = run.meas
    for s_i, name in enumerate(SOURCES):
        sel = m.source == s_i
        if not sel.any():
            continue
        rn = run.resid_norm[sel]
        t = m.t[sel]
        big = np.abs(rn) > 5.0
        spans: list[list[float]] = []
        if big.any():   # the times beyond 5 sigma, split where more than 10 s apart
            tb = np.unique(t[big])
            cut = np.flatnonzero(np.diff(tb) > 10.0)
            spans = [[float(a), float(b)]
                     for a, b in zip(tb[np.r_[0, cut + 1]], tb[np.r_[cut, -1]])]
        innov_ok = np.isfinite(run.innov[sel]) & (run.innov_var[sel] > 0)
        nis = run.innov[sel][innov_ok] ** 2 / run.innov_var[sel][innov_ok]
        out[name] = {"count": int(sel.sum()),
                     "mean_norm_residual_sq": float(np.nanmean(rn ** 2)),
                     "mean_nis": float(np.mean(nis)) if len(nis) else None,
                     "downweighted": int((run.weights[sel] < 0.999).sum()),
                     "beyond_5_sigma": int(big.sum()),
                     "flagged_inconsistent": bool(big.mean() > flag_fraction),
                     "flagged_spans_s": spans[:50]}
    return out


def clock_warnings(run: JointRun) -> list[str]:
    """A warning per clock offset estimated beyond 3 sd and 0.05 s (it was corrected).  The GNSS
    velocities' offset has no option of its own: `clean --gnss-clock-offset` shifts the positions
    and the velocities together, and the smoother estimates the velocities' from there."""
    out = []
    for name, (o, sd) in run.clock_offsets_s.items():
        if not (np.isfinite(sd) and abs(o) > 3 * sd and abs(o) > 0.05):
            continue
        how = (f"seconds added to the {name} times, as `clean --{name}-clock-offset` takes it"
               if name != "gnss_velocity" else
               "seconds added to the GNSS velocities' times, on top of any "
               "`clean --gnss-clock-offset`: the receiver's ground speed and track lag or lead "
               "its positions")
        out.append(f"joint: {name} clock offset {o:+.2f} s (sd {sd:.2f} s) estimated and "
                   f"corrected ({how})")
    return out


IMPLAUSIBLE_PRIOR_SD = 8.0
"""A sensor error estimated this many prior sd from its prior mean makes the joint track
unhealthy (docs/output.md, "Method health"): under the prior such a value has a probability
below 1e-15, and where it happened the smoother had used the error to explain a model mismatch
(JSBSim cross-country without the gust state: an airspeed scale of +26 %; a spin whose loads
saturate: -82 %)."""


def implausible_corrections(corrections: dict[str, Any],
                            limit: float = IMPLAUSIBLE_PRIOR_SD) -> dict[str, float]:
    """The sensor errors (the summary's ``corrections``: value, prior_mean, prior_sd) estimated more
    than ``limit`` prior sd from their prior mean, with that distance."""
    out = {}
    for name, c in corrections.items():
        sd = c.get("prior_sd")
        if sd and np.isfinite(c["value"]):
            z = abs(c["value"] - c["prior_mean"]) / sd
            if z > limit:
                out[name] = float(z)
    return out


def far_warning(name: str, c: dict[str, Any], z: float) -> str:
    """The warning of an implausible sensor error ``name`` (``c``: its correction entry)."""
    return (f"joint: {name} estimated at {c['value']:+.4g} (sd {c['sd']:.2g}), {z:.0f} prior "
            f"sd from its prior {c['prior_mean']:+.4g} (sd {c['prior_sd']:.2g}): no sensor is "
            "that far off, the smoother explained something else with it (unhealthy)")


def gust_warnings(run: JointRun, upper_mps: float) -> list[str]:
    """A warning when the estimated gust sd ended at its upper bound ``upper_mps``: the air data
    then disagree with the rest by more than turbulence explains, and the smoother has all but
    stopped using them (JSBSim circuit 7009, departure only: 8 m/s, the pressure altitude and the
    air data both flagged inconsistent, the track unhealthy)."""
    g = run.gust or {}
    if g.get("rounds") and g.get("sd_mps", 0.0) >= upper_mps * (1.0 - 1e-9):
        return [f"joint: the turbulence's gust sd reached its upper bound {upper_mps:g} m/s: "
                "the air data disagree with the other sources by more than turbulence "
                "explains and carry little weight (check the airspeed and heading channels, "
                "their units, and the metadata)"]
    return []


def wind_walk_check(run: JointRun, wind_rw_mps_sqrt_s: float, shear_mps_per_sqrt_m: float,
                    window_s: float = 600.0, p_false: float = 0.01, loads_psd_m2ps3: float = 0.0,
                    within_s: tuple[float, float] | None = None) -> dict[str, float] | None:
    """Whether the smoothed wind moved faster than the wind's process model allows.

    The model (docs/joint.md, "Wind and turbulence", with the measurements): over a stretch of L the
    wind changes by its gradient times the climb, g dz, plus a random walk of variance
    ``Q = q_t L + q_h sum|dz|`` per component (``q_t`` = ``wind_rw_mps_sqrt_s``^2, ``q_h`` =
    ``shear_mps_per_sqrt_m``^2).  The smoothed change of a Gaussian random walk has at most that
    variance, so ``z^2 = |dw - g dz|^2 / Q`` is at most chi-square(2).  Windows of ``window_s`` (the
    record if shorter) every tenth of it; the limit is the chi-square(2) tail
    ``-2 ln(p_false / n)``, ``n`` the disjoint windows in the record (Bonferroni).

    Where the loads are the wind's only witness (recorder only), ``loads_psd_m2ps3`` is the PSD
    ``r`` of the loads' velocity random walk (:func:`~flightrecon.methods.joint.calibration.
    inertial_wind_share`): the smoothed change is then the share ``kappa = Q / (Q + r L)`` of the
    observed one, of variance ``kappa Q``, which replaces ``Q`` in ``z^2`` (0: ``kappa = 1``).
    ``within_s`` (t0, t1) keeps the windows of the full ``window_s`` inside that span (with
    ``loads_psd_m2ps3``: clear of the rolls, whose ground velocity is a second witness).

    Returns
    -------
    dict or None
        ``z2`` (the worst window's), ``limit``, ``t0_s``, ``t1_s`` (that window), ``change_mps``
        (its wind change less the gradient's part, magnitude), ``model_sd_mps`` (the sd per
        component its smoothed change may have, ``sqrt(kappa Q)``), ``walk_var_m2ps2`` (``Q``)
        and ``loads_var_m2ps2`` (``r L``); None where the worst window is within the limit.
    """
    t = np.asarray(run.t, dtype=float)
    if len(t) < 3 or not (wind_rw_mps_sqrt_s > 0):
        return None
    w = run.x[:, jl.S_WIND]
    g = run.x[:, jl.S_WIND_GRAD]
    h = np.asarray(run.h_m, dtype=float)
    dz = np.diff(h)
    # the gradient's part, sum g dz, and the height flown through, as running sums
    grad = np.vstack([np.zeros(2), np.cumsum(0.5 * (g[1:] + g[:-1]) * dz[:, None], axis=0)])
    climb = np.r_[0.0, np.cumsum(np.abs(dz))]
    lo, hi = (float(t[0]), float(t[-1])) if within_s is None else within_s
    span = float(t[-1] - t[0]) if within_s is None else hi - lo
    L = min(window_s, span) if within_s is None else window_s
    if not (L > 0 and span >= L):
        return None
    starts = np.arange(max(lo, float(t[0])), min(hi, float(t[-1])) - L + 1e-9, L / 10.0)
    i = np.searchsorted(t, starts)
    j = np.minimum(np.searchsorted(t, t[i] + L), len(t) - 1)
    ok = j > i
    i, j = i[ok], j[ok]
    if not len(i):
        return None
    dw = (w[j] - w[i]) - (grad[j] - grad[i])
    var = (wind_rw_mps_sqrt_s ** 2 * (t[j] - t[i])
           + shear_mps_per_sqrt_m ** 2 * (climb[j] - climb[i]))
    r_l = max(loads_psd_m2ps3, 0.0) * (t[j] - t[i])
    z2 = np.sum(dw ** 2, axis=1) / (var * var / (var + r_l))
    k = int(np.argmax(z2))
    limit = -2.0 * np.log(p_false / max(1.0, span / L))
    if not z2[k] > limit:
        return None
    return {"z2": float(z2[k]), "limit": float(limit), "t0_s": float(t[i[k]]),
            "t1_s": float(t[j[k]]), "change_mps": float(np.hypot(*dw[k])),
            "model_sd_mps": float(np.sqrt(var[k] * var[k] / (var[k] + r_l[k]))),
            "walk_var_m2ps2": float(var[k]), "loads_var_m2ps2": float(r_l[k])}


def wind_walk_warning(check: dict[str, float]) -> str:
    """The warning of :func:`wind_walk_check`'s finding."""
    return (f"joint: the wind changed by {check['change_mps']:.1f} m/s between t = "
            f"{check['t0_s']:.0f} and {check['t1_s']:.0f} s beyond its gradient with height, "
            f"against {check['model_sd_mps']:.1f} m/s (sd per component) that the wind's random "
            f"walk allows (chi-square {check['z2']:.0f} > {check['limit']:.0f}): the standard "
            "deviations assume a steadier wind than the one flown through (unhealthy)")


SETTLE_SD_FRACTION = 0.1
"""A remaining movement of at most this fraction of a state's smallest position sd is left out
of the sd: an error of 0.1 sd added in quadrature grows the sd by 0.5 % (``sqrt(1 + 0.1^2)``)
and the expected NEES by 1 %, below what a flight's NEES can resolve (its 95 % band on a
thousand independent samples is about +-9 %)."""

LINEAR_REGION_SD = 1.0
"""The geometric tail bounds the passes to come only once they move each state by at most this
many of its own position sd: inside that region the Gauss-Newton model linearised at the track
holds and the passes converge at the rate seen; a pass that still moves the track by more than
its sd (a real recorder-only flight stopped moving it by 8.5 km a pass, 314 sd, where the real
SR22T export with its GPS stopped at 0.4 sd) is far from its fixed point: unbounded."""

CONTRACTION_PASSES = 5
"""The contraction ``rho`` is the largest ratio of successive passes' largest position changes
over the last this many passes (the slowest of them: a bound, not an average)."""


def settling(run: JointRun) -> dict[str, Any] | None:
    """The remaining movement of a run that stopped unconverged, or ``None`` when it converged (or
    did not keep its last change).

    Returns
    -------
    dict or None
        ``verdict``: ``settled`` (the bound within :data:`SETTLE_SD_FRACTION` of every state's
        smallest sd), ``widened`` (beyond it: the sd is to be widened by the bound) or
        ``unbounded`` (the passes did not contract, or the last moved a state by more than
        :data:`LINEAR_REGION_SD` of its sd); ``passes``, ``last_change_m`` (the last
        pass's largest change), ``contraction`` (``rho``), ``remaining_m`` (the largest bound),
        ``remaining_over_sd`` (the largest bound over the state's smallest sd),
        ``tolerance_over_sd`` and, not for the summary, ``remaining_k_m`` (the bound per state).
    """
    if run.converged or run.last_shift_m is None:
        return None
    shifts = np.array([float(it.get("max_position_change_m", np.nan))
                       for it in run.iterations[-(CONTRACTION_PASSES + 1):]])
    out: dict[str, Any] = {"passes": len(run.iterations),
                           "last_change_m": float(shifts[-1]),
                           "tolerance_over_sd": SETTLE_SD_FRACTION}
    ratios = shifts[1:] / shifts[:-1] if len(shifts) > 1 else np.array([np.nan])
    rho = float(np.max(ratios)) if len(ratios) and np.isfinite(ratios).all() else np.nan
    out["contraction"] = rho if np.isfinite(rho) else None
    if not (0.0 < rho < 1.0):
        out["verdict"] = "unbounded"
        return out
    last = np.asarray(run.last_shift_m, float)
    sd = np.sqrt(np.maximum(np.linalg.eigvalsh(run.P_pv[:, 0:3, 0:3])[:, 0], 1e-12))
    last_over = float(np.max(last / sd))
    out["last_change_over_sd"] = last_over
    if last_over > LINEAR_REGION_SD:
        # still far from its fixed point: the contraction seen is no rate to extrapolate
        out["verdict"] = "unbounded"
        return out
    remaining = last * rho / (1.0 - rho)
    over = float(np.max(remaining / sd))
    out.update(verdict="settled" if over <= SETTLE_SD_FRACTION else "widened",
               remaining_m=float(np.max(remaining)), remaining_over_sd=over,
               remaining_k_m=remaining)
    return out


def settling_sentence(s: dict[str, Any]) -> str:
    """The verdict in words, for the method's stop reason and the console."""
    head = (f"stopped at {s['passes']} passes, the last moving the track by "
            f"{s['last_change_m']:.2g} m")
    if s["verdict"] == "unbounded":
        if (s.get("last_change_over_sd") or 0.0) > LINEAR_REGION_SD:
            return head + (f", {s['last_change_over_sd']:.2g} of its sd: still far from where "
                           "its passes converge, nothing bounds what more passes would do")
        return head + (", its passes' changes not shrinking: nothing bounds what more passes "
                       "would do")
    tail = (f"; contracting by {s['contraction']:.3f} a pass, more passes would move it by at "
            f"most {s['remaining_m']:.2g} m, {s['remaining_over_sd']:.2g} of its sd")
    if s["verdict"] == "settled":
        return head + tail + f" (at most {s['tolerance_over_sd']:g}: as good as converged)"
    return head + tail + ": its position sd is widened by that movement"


CORRECTION_UNITS = {
    "heading_bias_deg": "deg (measured - true)",
    "tas_scale": "TAS_measured = (1 + s) TAS_true",
    "baro_offset_m": "m",
    "baro_scale": "h_p - h_p,field = (1 + c)(h - h_field) + b_h",
    "accel_bias_x_g": "g (body forward, measured - true)",
    "accel_bias_y_g": "g (body right)",
    "accel_bias_z_g": "g (body down, of -n_norm)",
    "doppler_scale": "W_measured = (1 + k) W_true",
    "accel_scale_x": "f_measured = (1 + s) f_true + b, body forward",
    "accel_scale_y": "body right",
    "accel_scale_z": "body down",
    "drift_bias_deg": "deg (measured - true)",
    "roll_bias_deg": "deg (measured - true)",
    "pitch_bias_deg": "deg (measured - true)",
    "wind_gradient_n_per_km": "(m/s)/km: change of the north wind with height (at the middle of "
                              "the record)",
    "wind_gradient_e_per_km": "(m/s)/km, east",
}
"""What each sensor error of the summary's ``corrections`` means (docs/joint.md, "Outputs")."""


def corrections_at_middle(run: JointRun, priors: dict[str, tuple[float, float]]
                          ) -> dict[str, Any]:
    """The sensor errors of :data:`~flightrecon.methods.joint.settings.PRIOR_STATES`, value and sd
    at the middle of the record in the reported unit, with the prior each was given (``priors``:
    :func:`~flightrecon.methods.joint.settings.prior_table`; ``prior_mean``, ``prior_sd``, same
    unit)."""
    k = len(run.t) // 2
    out = {}
    for name, (i, state_per_unit, _budget) in PRIOR_STATES.items():
        scale = 1.0 / state_per_unit
        mean, sd = priors[name]
        out[name] = {"value": float(run.x[k, i] * scale),
                     "sd": float(np.sqrt(max(run.var[k, i], 0.0)) * scale),
                     "unit": CORRECTION_UNITS[name], "prior_mean": mean, "prior_sd": sd}
    return out


@dataclass(frozen=True)
class RunHealth:
    """What :func:`run_health` found: the summary's entries of the same names (docs/output.md,
    "The summary JSON"; docs/joint.md, "Outputs"; ``settling`` only for a run stopped short) and
    the remaining movement per state that widens the track's sd (a ``widened`` settling only)."""

    healthy: bool
    converged: bool
    consistency: ChiSquareVerdict
    corrections: dict[str, Any]
    sources: dict[str, Any]
    warnings: list[str]
    settling: dict[str, Any] | None
    remaining_k_m: np.ndarray | None


def run_health(problem: JointProblem, run: JointRun, wind_rounds: list[dict[str, Any]],
               gap_calibration: dict[str, Any] | None,
               priors: dict[str, tuple[float, float]]) -> RunHealth:
    """Every check of the solved and calibrated ``run``, once, with the warnings in the order the
    user reads them (``wind_rounds``, ``gap_calibration``: the calibrations' reports; ``priors``:
    the sensor errors' priors, :func:`~flightrecon.methods.joint.settings.prior_table`).  Healthy:
    finite states with positive position and velocity variances, no gross mean NIS of the
    innovations kept at full weight, no sensor error beyond :data:`IMPLAUSIBLE_PRIOR_SD`, the wind
    within its walk (:func:`wind_walk_check`); converged: finite and the passes' own test
    (docs/joint.md, "Filter, smoother, iterations")."""
    settings, nz, nc = problem.settings, problem.settings.noise, run.noise_check
    settle = settling(run)
    sources = source_report(run)
    warnings = [*problem.inputs.notes, *([problem.attitude_note] if problem.attitude_note else [])]
    warnings += [f"joint: source '{name}' inconsistent with the others in {st['beyond_5_sigma']} "
                 f"measurements (spans {st['flagged_spans_s'][:5]} s); down-weighted"
                 for name, st in sources.items() if st["flagged_inconsistent"]]
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
    if not run.converged:
        warnings.append(f"joint: not converged after {len(run.iterations)} passes: "
                        f"{run.stop_reason}")
    warnings += clock_warnings(run) + gust_warnings(run, settings.gust_bounds_mps[1])
    if run.cholesky_fallbacks:
        warnings.append(f"joint: on {run.cholesky_fallbacks} steps the predicted covariance was "
                        "not positive definite to rounding (Cholesky failed); the smoother gain "
                        "there came from a general solve")
    if gap_calibration is not None and gap_calibration["factor"] is None:
        # on the console and at the summary's top level: the gaps' sd is not this flight's
        warnings.append(f"joint: GNSS gaps {gap_calibration['gaps_s'][:3]} s, but "
                        f"{gap_calibration['note']}: their position sd is the model's, not "
                        "calibrated on this flight")
        _warnings.warn(warnings[-1], FlightReconWarning, stacklevel=4)
    corrections = corrections_at_middle(run, priors)
    far = implausible_corrections(corrections)
    walk = wind_walk_check(run, nz.wind_rw_mps_sqrt_s, nz.wind_shear_mps_per_sqrt_m)
    later = [far_warning(name, corrections[name], z) for name, z in far.items()]
    if wind_rounds and walk is None:
        later.append(f"joint: the wind changed faster than its default random walk "
                     f"({wind_rounds[0]['wind_rw_mps_sqrt_s']:g} m/s/sqrt(s)); the walk "
                     f"re-estimated from the smoothed wind in {len(wind_rounds)} round(s): "
                     f"{nz.wind_rw_mps_sqrt_s:.3g} m/s/sqrt(s)")
    if walk is not None:
        later.append(wind_walk_warning(walk))
    report = widen = None
    if settle is not None:
        report = {**{k: v for k, v in settle.items() if k != "remaining_k_m"},
                  "sentence": settling_sentence(settle)}
        widen = settle["remaining_k_m"] if settle["verdict"] == "widened" else None
    finite = bool(np.isfinite(run.x).all() and np.all(run.var[:, jl.IP:jl.IV + 3] > 0))
    # the forward innovations the smoother kept at full weight (the robustly down-weighted ones
    # are reported per source, not held against the noise model)
    full = (run.weights >= 1.0) & (run.innov_var > 0)
    nis = run.innov ** 2 / np.where(full, run.innov_var, 1.0)
    verdict = chi_square_verdict(np.where(full, nis, np.nan))
    gross = [f"joint: mean NIS per measurement {verdict.mean:.1f} (expected 1): the noise "
             "settings do not fit this flight"] if verdict.gross else []
    return RunHealth(healthy=finite and not verdict.gross and not far and walk is None,
                     converged=finite and run.converged, consistency=verdict,
                     corrections=corrections, sources=sources, warnings=warnings + gross + later,
                     settling=report, remaining_k_m=widen)
