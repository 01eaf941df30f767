"""Updates of the joint smoother between its passes: the IRLS weights of the robust loss and
the clock-offset fits (docs/joint.md, "Filter, smoother, iterations"), and the report of why
the iterations stopped."""

from __future__ import annotations

from typing import Any

import numpy as np

from flightrecon.methods.joint.measurements import Measurements
from flightrecon.methods.joint.settings import SOURCES, JointSettings


def robust_weights(res_n: np.ndarray, weights: np.ndarray, settings: JointSettings
                    ) -> np.ndarray:
    """IRLS weights of the robust loss from the normalised residuals of the iterate: 1 up to
    ``huber_c``, huber_c/|u| beyond (Huber), 1e-8 beyond ``reject_c`` (set aside: a jumped
    source cannot pull the track at all); unchanged without ``robust``."""
    if not settings.robust:
        return weights
    a = np.abs(res_n)
    w = np.where(a > settings.huber_c, settings.huber_c / np.maximum(a, 1e-12), 1.0)
    w = np.where(a > settings.reject_c, 1e-8, w)
    w[~np.isfinite(w)] = 1.0
    return w


def clock_update(meas: Measurements, res: np.ndarray, rate: np.ndarray, weights: np.ndarray,
                  r: np.ndarray, clock: dict[str, float], clock_sd: dict[str, float],
                  info: dict[str, Any]) -> None:
    """Clock offsets, in seconds added to the source's time stamps (the convention of
    `clean --gnss-clock-offset / --radar-clock-offset`), in place: a measurement stamped t_m
    and taken at t_m + c_true, used at t_m + c, has residual hdot (c_true - c); the weighted
    least-squares fit of the residuals against the rates, applied beyond 3 sd."""
    for name, src in (("gnss", ("gnss_pos",)), ("radar", ("radar",))):
        sel = np.isin(meas.source, [SOURCES.index(s) for s in src]) & np.isfinite(rate)
        if sel.sum() < 10:
            continue
        wv = weights[sel] / r[sel]
        den = np.sum(wv * rate[sel] ** 2)
        if den <= 0:
            continue
        o = np.sum(wv * rate[sel] * res[sel]) / den
        sd = 1.0 / np.sqrt(den)
        clock_sd[name] = sd
        if abs(o) > 3 * sd:
            clock[name] += o
        info[f"clock_{name}_s"] = clock[name]


def stop_reason_of(history: list[dict[str, Any]], settings: JointSettings) -> str:
    """Why the iterations stopped without converging: the line search failed, the cost rose
    from one pass to the next (through the updates between the passes: weights' residuals,
    clock offsets, take-off roll, noise factors), or the cap on the passes was reached."""
    last = history[-1]
    if last.get("line_search_failed"):
        lm = (f", nor a Levenberg-Marquardt step with damping up to {settings.lm_lambda_max:g}"
              if settings.levenberg_marquardt else "")
        return (f"line search failed: no step size down to 1/{2 ** settings.line_search_halvings}"
                f" of the Gauss-Newton step{lm} lowered the MAP cost (the full step moved the "
                f"track by {last['gauss_newton_position_change_m']:.0f} m)")
    if (len(history) > 1 and last.get("parameters_changed")
            and last["cost"] > history[-2]["cost"] * (1.0 + settings.cost_tol)):
        return (f"cost rising: {history[-2]['cost']:.6g} -> {last['cost']:.6g} over the last "
                "pass (the updates between the passes, of the take-off roll, the clock "
                "offsets or the noise factors, raised it)")
    return (f"max passes reached ({len(history)}): the last moved the track by "
            f"{last['max_position_change_m']:.1f} m, the cost by "
            f"{last.get('cost_relative_change', float('nan')):.2g} (relative)")
