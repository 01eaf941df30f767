"""Updates of the joint smoother between its passes (docs/joint.md, "Filter, smoother,
iterations"): the IRLS weights of the robust loss, the clock offsets' Gauss-Newton steps, the
noise factors' EM step, the gust sd, and the report of why the iterations stopped.

The gust sd (docs/joint.md, "Wind and turbulence").  The gust ``u`` (layout: ``S_GUST``) is a
stationary first-order Gauss-Markov process of variance sigma_u^2 per axis.  Under the model,
the smoothed mean and variance of every sample satisfy E[u_hat^2 + var(u | data)] = sigma_u^2
(law of total variance), so

    sigma_u^2 <- mean over the airborne steps and both axes of (u_hat_k^2 + P_uu,k)

is a fixed point at the flight's own gust variance: with sigma_u too large the data shrink u_hat
and its variance below it, too small they push them above.  It is the moment form of the
expectation-maximisation update of a stationary variance; with ``JointSettings.estimate_gust``
the smoother applies it after each pass that computed the smoothed covariances and is not the
last (:func:`gust_round`), over-relaxed (twice the step in log space), while the pass moved the
track by more than 10 ``converge_m`` or the noise factors are estimated too, until it moves by
less than ``gust_tol`` (at most ``gust_rounds`` changes): it follows the Gauss-Newton passes and
adds none of its own where the track is already pinned down (GNSS).  A change is a new cost
function, and the pass after it says so (``parameters_changed``).  What the gust absorbs besides
the turbulence (the sideslip, the angle of attack in turns, the airspeed lag) counts into the
estimate: it is the air data's effective disagreement with a steady wind.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.layout import Measurements
from flightrecon.methods.joint.measurements import NOISE_GROUPS
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


CLOCK_SOURCES = (("gnss", ("gnss_pos",)), ("gnss_velocity", ("gnss_vel",)),
                 ("radar", ("radar",)))
"""The clock offsets estimated, in the order of the forward pass's clock columns
(:data:`~flightrecon.methods.joint.model.N_CLOCK`), and the sources each shifts.  The GNSS
velocities have their own: on the real G1000 exports the ground speed and track lag the
positions (docs/joint.md, "Filter, smoother, iterations", item 4).  The radar last: a flight
without one carries two columns, not three
(:func:`~flightrecon.methods.joint.model.joint_model`)."""

CLOCK_MIN_MEASUREMENTS = 10
"""Fewer measurements of a source than this: its offset is not estimated."""

CLOCK_DETECT_SD = 3.0
"""An offset still at zero is taken once its step exceeds this many of its sd (detected);
below, the source's stamps are kept: estimating an offset that is not there costs accuracy (the
simulated radar approaches, whose radar is on time: 15.1 m RMS with the offset held at zero
unless detected, 17.7 m estimated always), and a taken offset has its uncertainty in the
track's sd either way."""

CLOCK_STILL_SD = 0.1
"""A clock step of at most this fraction of the offset's sd is not taken (the offset stands
still for the convergence test): it would move the track by at most a tenth of the share of
the track's uncertainty the offset's own uncertainty carries."""


def clock_columns(meas: Measurements, settings: JointSettings
                  ) -> tuple[np.ndarray, np.ndarray] | None:
    """Each measurement's clock column for the forward pass (:data:`CLOCK_SOURCES`' index; -1
    for the measurements no offset shifts) and the rate of its prediction with its time that
    the kernel's gradient does not give (``Measurements.rate``); None when no source has
    :data:`CLOCK_MIN_MEASUREMENTS`.

    With a derived ``n_long_g`` (``settings.long_load_derived``) the GNSS positions' offset is
    not estimated (held at the cleaning's): the along-track acceleration then has the
    airspeed's timing, and the GNSS offset common to positions and velocities absorbs the
    airspeed's lag (the shipped circuit with its ``n_long_g`` dropped: +0.15 +- 0.02 s for a
    true 0, the track 9.4 m RMS from the truth against 1.0 m at 0); the velocities' offset,
    relative to the positions, is still estimated."""
    cols = np.full(len(meas.z), -1, dtype=np.int64)
    for c, (name, src) in enumerate(CLOCK_SOURCES):
        if name == "gnss" and settings.long_load_derived:
            continue
        sel = np.isin(meas.source, [SOURCES.index(x) for x in src])
        if sel.sum() >= CLOCK_MIN_MEASUREMENTS:
            cols[sel] = c
    if not np.any(cols >= 0):
        return None
    return cols, np.zeros(len(cols)) if meas.rate is None else meas.rate


def clock_covariance(cols: np.ndarray, normal: np.ndarray
                     ) -> tuple[list[int], np.ndarray, np.ndarray] | None:
    """The clock columns estimated (those with :data:`CLOCK_MIN_MEASUREMENTS` and a positive
    normal equation), the offsets' covariance A^-1 and their Gauss-Newton step A^-1 b from the
    forward pass's normal equations ``normal`` = [A b] (C, C + 1) (:func:`clock_step`); None
    when none is estimated or A is singular."""
    nc = normal.shape[0]
    act = [c for c in range(nc)
           if np.sum(cols == c) >= CLOCK_MIN_MEASUREMENTS and normal[c, c] > 0.0]
    if not act:
        return None
    A = normal[:, :nc][np.ix_(act, act)]
    try:
        cov = np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(cov)) or np.any(np.diag(cov) <= 0.0):
        return None
    return act, cov, cov @ normal[act, nc]


def clock_step(clock_cols: tuple[np.ndarray, np.ndarray], outputs: tuple[np.ndarray, ...],
               alpha: float, clock: dict[str, float], clock_sd: dict[str, float],
               info: dict[str, Any]) -> tuple[dict[str, float], dict[str, float]]:
    """The clock offsets' Gauss-Newton step jointly with the track (the new offsets and sd
    returned, the step written to ``info``), in seconds added
    to each source's time stamps (the convention of `clean --gnss-clock-offset /
    --radar-clock-offset`; docs/joint.md, "Filter, smoother, iterations", item 4).

    A measurement stamped t_m, taken at t_m + c_true and used at t_m + c has residual
    hdot (c_true - c).  The pass's forward filter carried the offsets as constant parameters
    of its linearised model (:func:`~flightrecon.methods.joint.model._clock_column_update`)
    and accumulated (its ``outputs``' first) the normal equations [A b]: the step
    dc = A^-1 b minimises the pass's cost profiled over the track (the track given the
    offsets is what the pass smoothed; moved by dc it is the next pass's business), A^-1 the
    offsets' covariance.  The step is scaled by the line search's ``alpha`` (0: a
    Levenberg-Marquardt step, which is not the pass's Gauss-Newton step; the offsets then
    stay) and taken when it exceeds :data:`CLOCK_STILL_SD` of its sd, and by an offset still
    at zero only beyond :data:`CLOCK_DETECT_SD` of it (as before: applied beyond 3 sd).

    Before, the offsets were fitted between the passes by weighted least squares of the
    smoothed residuals against hdot, the track held: the smoother had already absorbed most
    of the offset into the track, so each fit recovered about 1.4 % of what was left (32-50
    passes on the four real G1000 exports with their GPS, 6-18 now) and its sd, that of a
    known track, was 4 times too small (a simulated circuit: 1.2 ms, 4.9-6.0 ms now)."""
    est = clock_covariance(clock_cols[0], outputs[0])
    if est is None:
        return clock, clock_sd
    act, cov, d = est
    clock, clock_sd = dict(clock), dict(clock_sd)
    for i, c in enumerate(act):
        name = CLOCK_SOURCES[c][0]
        sd = float(np.sqrt(cov[i, i]))
        if not np.isfinite(d[i]):
            continue
        clock_sd[name] = sd
        step = float(alpha * d[i])
        detected = clock[name] != 0.0 or abs(step) > CLOCK_DETECT_SD * sd
        if detected and abs(step) > CLOCK_STILL_SD * sd:
            clock[name] += step
        info[f"clock_{name}_s"] = clock[name]
        info[f"clock_{name}_step_s"] = step
    return clock, clock_sd


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


def innovation_loglik(innov: np.ndarray, innov_var: np.ndarray, sel: np.ndarray) -> float:
    """Log-likelihood of the data by the prediction-error decomposition,
    ``-1/2 sum_j (nu_j^2 / S_j + ln(2 pi S_j))`` over the selected scalar innovations ``nu``
    with their variances ``S`` (the exact likelihood of the linearised model for the given
    noise; Harvey 1989, section 3.4)."""
    ok = sel & np.isfinite(innov) & np.isfinite(innov_var) & (innov_var > 0)
    if not ok.any():
        return float("nan")
    s = innov_var[ok]
    return float(-0.5 * np.sum(innov[ok] ** 2 / s + np.log(2.0 * np.pi * s)))


def _em_noise_scales(groups, res, hph, r0, use, min_count: int = 30) -> dict[int, float]:
    """M-step of expectation-maximisation for one variance factor c per group.

    With z_j = h_j(x) + v_j, v_j ~ N(0, c R0_j), the expected complete-data log-likelihood under
    the smoothed posterior is maximised by c = mean_j[(e_j^2 + H_j P_s H_j^T) / R0_j] over the
    group's measurements (e: smoothed residual; Shumway & Stoffer 1982, eq. 12 for a scalar
    factor; linearised at the smoothed trajectory).  Groups with fewer than ``min_count``
    measurements keep their factor.
    """
    out = {}
    for gi in np.unique(groups[groups >= 0]):
        sel = (groups == gi) & use & np.isfinite(res) & np.isfinite(hph)
        if sel.sum() >= min_count:
            out[int(gi)] = float(np.mean((res[sel] ** 2 + hph[sel]) / r0[sel]))
    return out


def noise_update(groups: np.ndarray, hph: np.ndarray, r0: np.ndarray, res: np.ndarray,
                  use: np.ndarray, scale: np.ndarray, settings: JointSettings,
                  info: dict[str, Any]) -> tuple[np.ndarray, bool]:
    """EM step of the noise factors (:func:`_em_noise_scales`) on the measurements taken at
    face value (``use``), bounded by ``noise_factor_bounds``; the new factors into ``info``.
    Returns them and whether any moved by more than ``noise_tol``."""
    new_scale = scale.copy()
    lo_b, hi_b = settings.noise_factor_bounds
    for gi, c in _em_noise_scales(groups, res, hph, r0, use).items():
        new_scale[gi] = min(max(c, lo_b), hi_b)   # bounded: no runaway factor
    moved = bool(np.any(np.abs(new_scale / scale - 1.0) > settings.noise_tol))
    info["noise_scale"] = {name: float(new_scale[i]) for i, name in enumerate(NOISE_GROUPS.values())
                           if np.any(groups == i)}
    return new_scale, moved


def gust_sd_estimate(xs: np.ndarray, var: np.ndarray, airborne: np.ndarray) -> float | None:
    """sqrt(mean(u_hat^2 + P_uu)) over the steps ``airborne`` and both gust axes (module
    docstring); None without such a step or with a non-finite value.

    Parameters
    ----------
    xs, var : (N, n) smoothed states and their variances.
    airborne : (N,) bool, the steps whose air data the smoother uses.
    """
    if not airborne.any():
        return None
    m = float(np.mean(xs[airborne, jl.S_GUST] ** 2 + var[airborne, jl.S_GUST]))
    return float(np.sqrt(m)) if np.isfinite(m) and m > 0 else None
