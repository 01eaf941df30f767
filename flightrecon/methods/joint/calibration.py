"""What the joint smoother calibrates on its own solution, each as an adjusted problem
(:func:`~flightrecon.methods.joint.problem.adjusted`) solved again: the wind walk re-estimated
where the smoothed wind outran it (:func:`wind_walk_rounds`; docs/joint.md, "Wind and
turbulence"), and the position sd inside GNSS gaps calibrated on held-out stretches
(:func:`calibrate_gaps`; docs/joint.md, "GNSS gaps: the sd calibrated on held-out stretches":
the stretches withheld, :func:`pseudo_gaps`; the withheld fixes' errors, :func:`fix_errors`, eq.
G4; the factor of the in-gap excess variance, :func:`calibration_factor`, eq. G3, applied to the
real gaps, :func:`apply_factor`, eq. G1/G2)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from typing import Any

import numpy as np
from scipy.special import chdtri

from flightrecon.errors import FlightReconError
from flightrecon.geo.frames import geodetic_to_ecef
from flightrecon.memory import release_unused
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.health import wind_walk_check
from flightrecon.methods.joint.inputs import JointInputs, per_fix_sd
from flightrecon.methods.joint.problem import JointProblem, SettingChoice, adjusted
from flightrecon.methods.joint.settings import JointSettings
from flightrecon.methods.joint.solve import JointRun, smooth_joint, smooth_joint_from


def gnss_gaps(inp: JointInputs, min_gap_s: float) -> list[tuple[float, float]]:
    """The stretches between consecutive horizontal GNSS fixes longer than ``min_gap_s`` [s] that
    lie (partly) in the air (between lift-off and touchdown, where known): (t0, t1) the last fix
    before and the first after each gap [s].  Only gaps with fixes on both sides (the ends of a
    record without GNSS are not gaps: no fix beyond them to calibrate on)."""
    g = inp.gnss
    if not len(g) or min_gap_s <= 0:
        return []
    ok = np.isfinite(g["lat_deg"].to_numpy(float)) & np.isfinite(g["lon_deg"].to_numpy(float))
    t = np.sort(g["t_s"].to_numpy(float)[ok])
    if len(t) < 2:
        return []
    lo = inp.liftoff_t if np.isfinite(inp.liftoff_t) else -np.inf
    hi = inp.touchdown_t if np.isfinite(inp.touchdown_t) else np.inf
    dt = np.diff(t)
    k = np.flatnonzero(dt > min_gap_s)
    return [(float(t[i]), float(t[i + 1])) for i in k if t[i + 1] > lo and t[i] < hi]


def pseudo_gaps(inp: JointInputs, gaps: list[tuple[float, float]], *, n_max: int,
                guard_s: float, min_gap_s: float) -> list[tuple[float, float]]:
    """Up to ``n_max`` held-out stretches (t0, t1) [s] of the real ``gaps``' lengths (the longest
    first, in turn) where the GNSS is present: in the air, at least ``guard_s`` after lift-off and
    before touchdown (the first and last fix where not known), at least ``guard_s`` from every real
    gap and from each other, with no interval between fixes longer than ``min_gap_s / 2`` from
    ``guard_s`` before to ``guard_s`` after (both edges covered, as a real gap's are).  Packed from
    the start, then ``n_max`` of them spread evenly over the flight."""
    g = inp.gnss
    ok = np.isfinite(g["lat_deg"].to_numpy(float)) & np.isfinite(g["lon_deg"].to_numpy(float))
    t = np.sort(g["t_s"].to_numpy(float)[ok])
    if not gaps or len(t) < 2 or n_max <= 0:
        return []
    lo = max(inp.liftoff_t if np.isfinite(inp.liftoff_t) else t[0], t[0]) + guard_s
    hi = min(inp.touchdown_t if np.isfinite(inp.touchdown_t) else t[-1], t[-1]) - guard_s
    lengths = sorted((b - a for a, b in gaps), reverse=True)
    busy = [(a - guard_s, b + guard_s) for a, b in gaps]
    dt = np.diff(t)
    holes = [(t[i], t[i + 1]) for i in np.flatnonzero(dt > 0.5 * min_gap_s)]
    found: list[tuple[float, float]] = []
    s = lo
    while True:
        L = lengths[len(found) % len(lengths)]
        if s + L > hi:
            break
        a, b = s, s + L
        clash = [(c, d) for c, d in busy + [(h0 - guard_s, h1 + guard_s) for h0, h1 in holes]
                 if c < b and d > a]
        if clash:
            s = max(d for _, d in clash)
            continue
        found.append((float(a), float(b)))
        busy.append((a - guard_s, b + guard_s))
        s = b + guard_s
        if len(found) > 50 * n_max:
            break
    if len(found) <= n_max:
        return found
    pick = np.unique(np.round(np.linspace(0, len(found) - 1, n_max)).astype(int))
    return [found[i] for i in pick]


def _edge_baseline(T: np.ndarray, cov_at: Callable[[np.ndarray], np.ndarray], a: float,
                   b: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The states strictly inside (a, b) and the covered level there: the covariances ``cov_at(k)``
    (K, 3, 3) of the last state at or before ``a`` and of the first at or after ``b``, interpolated
    linearly in time (eq. G1's ``P_b``); None without states on both sides."""
    i0 = int(np.searchsorted(T, a, side="right")) - 1
    i1 = int(np.searchsorted(T, b, side="left"))
    if i0 < 0 or i1 >= len(T) or i1 - i0 < 2:
        return None
    inside = np.arange(i0 + 1, i1)
    w = ((T[inside] - T[i0]) / (T[i1] - T[i0]))[:, None, None]
    P0, P1 = cov_at(np.array([i0, i1]))
    return inside, (1.0 - w) * P0 + w * P1


def _ned_cov(run: JointRun, k: np.ndarray) -> np.ndarray:
    """The smoothed position covariance in the local NED frame at the states ``k`` (K, 3, 3) (each
    state's on its own: the same numbers whichever states are asked for)."""
    C = run.Cen[k]
    return np.einsum("kji,kjl,klm->kim", C, run.P_pv[k, 0:3, 0:3], C)


def fix_errors(inp: JointInputs, run: JointRun, sel: np.ndarray, tf: np.ndarray, p: np.ndarray,
               sd_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The gap calibration's errors at the GNSS fixes ``sel`` (indices into ``inp.gnss``), at their
    own times ``tf`` where the smoothed ECEF positions are ``p`` (K, 3) [m]: the smoothed antenna
    position's error against the fix, north and east (K, 2) [m] (eq. G4: the body lever arm rotated
    to NED with the recorded attitude), the smoother's NED position covariance there (K, 3, 3), the
    declared horizontal sd (K,) [m] (:func:`~flightrecon.methods.joint.inputs.per_fix_sd`, ``sd_m``
    where the receiver gives none)."""
    g = inp.gnss
    T = run.t
    declared = per_fix_sd(g, "h_sd_m", sd_m)[sel]
    k = np.clip(np.searchsorted(T, tf), 0, len(T) - 1)
    j = np.clip(np.searchsorted(inp.t_in, tf), 0, len(inp.t_in) - 1)
    lever = np.einsum("kij,j->ki", inp.body_to_ned(j), np.asarray(inp.lever_arm, float))
    h_s = np.interp(tf, T, run.h_m)
    fx = np.stack(geodetic_to_ecef(g["lat_deg"].to_numpy(float)[sel],
                                   g["lon_deg"].to_numpy(float)[sel], h_s), axis=1)
    d = np.einsum("kji,kj->ki", run.Cen[k], fx - p)[:, :2] - lever[:, :2]
    # the covariance interpolated to the fixes from the states on either side of each
    i = np.searchsorted(T, tf)
    ks = np.unique(np.clip(np.concatenate([i - 1, i]), 0, len(T) - 1))
    Pn = _ned_cov(run, ks)
    P = np.stack([np.stack([np.interp(tf, T[ks], Pn[:, a, b]) for b in range(3)], axis=1)
                  for a in range(3)], axis=1)
    return d, P, declared


def fix_noise(d: np.ndarray, P: np.ndarray, declared_m: np.ndarray) -> np.ndarray:
    """The horizontal fixes' own variance per axis (2,) [m^2] measured on this flight from the
    smoothed residuals ``d`` (K, 2) and covariances ``P`` (K, 3, 3) of the used fixes
    (:func:`fix_errors`), ``R = mean(eps^2) + mean(P_s)`` (eq. G5: E[eps^2] = R - P_s), never above
    the rms of their declared sd ``declared_m``, which keeps the model's misfit from being credited
    as the fixes' noise (docs/joint.md, "GNSS gaps: the sd calibrated on held-out stretches")."""
    r = np.mean(d ** 2, axis=0) + np.mean(np.stack([P[:, 0, 0], P[:, 1, 1]], axis=1), axis=0)
    return np.minimum(r, float(np.sqrt(np.mean(declared_m ** 2))) ** 2)


def heldout_errors(run: JointRun, stretches: list[tuple[float, float]], t_s: np.ndarray,
                   errors: tuple[np.ndarray, np.ndarray, np.ndarray], r: np.ndarray
                   ) -> list[dict[str, np.ndarray]]:
    """Per held-out stretch, at its withheld fixes (stamps ``t_s``; ``errors``: their times, errors
    and covariances, :func:`fix_errors`): the error of the smoothed antenna position against the fix
    in north and east ``e`` (K, 2) [m], the smoother's variance ``v`` (K, 2), the covered level
    ``b`` (K, 2) (eq. G1) and the fixes' variance ``r`` (2,) [m^2] (:func:`fix_noise`).  ``run``
    is the run without them."""
    T = run.t
    out = []
    for a, b in stretches:
        base = _edge_baseline(T, lambda k: _ned_cov(run, k), a, b)
        sel = (t_s > a) & (t_s < b)
        if base is None or not sel.any():
            continue
        inside, Pb = base
        tf, d, P = (x[sel] for x in errors)
        v = np.stack([P[:, 0, 0], P[:, 1, 1]], axis=1)
        Ti = T[inside]
        bb = np.stack([np.interp(tf, Ti, Pb[:, i, i]) for i in (0, 1)], axis=1)
        out.append({"t0_s": a, "t1_s": b, "e": d, "v": v, "b": np.minimum(bb, v), "r": r})
    return out


def stretch_nees(held: list[dict[str, np.ndarray]], f: float) -> np.ndarray:
    """Mean NEES per stretch and axis (S, 2) with the excess scaled by ``f`` (eq. G2): ``e^2 / (b +
    f (v - b) + r)`` averaged over the stretch's fixes."""
    return np.array([np.mean(h["e"] ** 2 / (h["b"] + f * (h["v"] - h["b"]) + h["r"]), axis=0)
                     for h in held])


def calibration_factor(held: list[dict[str, np.ndarray]], bounds: tuple[float, float],
                       p_stretch: float, p_pool: float) -> dict[str, Any]:
    """The factor ``f`` of the in-gap excess variance (eq. G3; docs/joint.md, "GNSS gaps: the sd
    calibrated on held-out stretches"): the largest of ``f_hat`` (the mean over the stretches and
    the two horizontal axes of their mean NEES, eq. G2, is 1), ``f_pool`` (that mean is the
    ``p_pool`` quantile of chi-square(nu)/nu, ``nu = 2 S`` for S stretches whose fixes share one
    drifting error: the largest factor the held-out errors support at that one-sided level; where
    the stretches are few the sd is widened by what they cannot exclude) and ``f_floor`` (every
    stretch-axis's mean NEES within the ``p_stretch`` quantile of chi-square(1)), all within
    ``bounds``."""
    # imported here: scipy.optimize is a fifth of a second of every run's start, and only a
    # flight with GNSS gaps gets this far
    from scipy.optimize import brentq

    lo, hi = bounds
    m0 = stretch_nees(held, 1.0)
    dof = 2 * len(held)

    def solve(fun) -> float:
        a, b = np.log(lo), np.log(hi)
        if fun(a) <= 0:
            return lo
        if fun(b) >= 0:
            return hi
        return float(np.exp(brentq(fun, a, b, xtol=1e-6)))

    def pooled(target: float):
        return lambda lf: float(np.mean(stretch_nees(held, np.exp(lf)))) - target

    # chi-square quantiles q(p) = chdtri(dof, 1 - p) (scipy.stats costs a fifth of a second
    # of every run's start to import)
    limit = float(chdtri(1, 1.0 - p_stretch))
    q_pool = float(chdtri(dof, 1.0 - p_pool) / dof)
    f_hat = solve(pooled(1.0))
    f_pool = solve(pooled(q_pool))
    f_floor = solve(lambda lf: float(np.max(stretch_nees(held, np.exp(lf)))) - limit)
    f = max(f_hat, f_pool, f_floor)
    return {"factor": f, "f_hat": f_hat, "f_pool": f_pool, "f_floor": f_floor,
            "pool_quantile": q_pool, "stretch_limit": limit, "dof": dof,
            "nees_before": m0.tolist(), "nees_after": stretch_nees(held, f).tolist()}


def apply_factor(run: JointRun, gaps: list[tuple[float, float]], f: float) -> JointRun:
    """The run with the position covariance inside each gap rescaled (eq. G1/G2).  With ``P_b`` the
    covered level at the gap's edges: ``P' = P_b + f (P - P_b)`` for f <= 1 (convex in P and P_b,
    positive semidefinite; the position-velocity cross blocks scaled by ``sqrt(f)`` so that the 6x6
    block stays so) and ``P' = P + (f - 1) [P - P_b]_+`` for f > 1 (the excess's positive part
    added)."""
    T = run.t
    P = run.P_pv.copy()
    var = run.var.copy()
    Ppp = P[:, 0:3, 0:3]
    for a, b in gaps:
        base = _edge_baseline(T, lambda k: Ppp[k], a, b)
        if base is None:
            continue
        inside, Pb = base
        if f <= 1.0:
            new = Pb + f * (Ppp[inside] - Pb)
            P[inside, 0:3, 3:6] *= np.sqrt(f)
            P[inside, 3:6, 0:3] *= np.sqrt(f)
        else:
            E = Ppp[inside] - Pb
            E = 0.5 * (E + np.transpose(E, (0, 2, 1)))
            w, V = np.linalg.eigh(E)
            Epos = np.einsum("kij,kj,klj->kil", V, np.maximum(w, 0.0), V)
            new = Ppp[inside] + (f - 1.0) * Epos
        P[inside, 0:3, 0:3] = new
        var[inside, jl.IP:jl.IP + 3] = np.einsum("kii->ki", new)
    return replace(run, P_pv=P, var=var)


#: the held-out smoothing's passes stop once one moved the track by at most this many times
#: ``converge_m`` (the smoother's own rule for a step small enough to hold the gust sd)
HELDOUT_ENOUGH = 10.0


def heldout_smoothing(problem: JointProblem, keep: np.ndarray, run: JointRun) -> JointRun:
    """The flight smoothed once more without the held-out fixes (``keep`` False: withheld), an
    adjusted problem: by default ``settings.gap_heldout_passes`` Gauss-Newton passes from the
    converged ``run`` with its gust sd held (the gust estimate is the flight's;
    :func:`~flightrecon.methods.joint.solve.smooth_joint_from`; one pass costs a third of the whole
    iteration and gives the held-out errors and sd of the whole iteration to a few per cent of their
    spread: docs/joint.md, "GNSS gaps"); with 0 the whole iteration again from the nominal."""
    inp, s = problem.inputs, problem.settings
    held = replace(inp, gnss=inp.gnss[keep].reset_index(drop=True))
    warm = s.gap_heldout_passes > 0
    if warm and run.gust is not None and np.isfinite(run.gust.get("sd_mps", np.nan)):
        s = replace(s, estimate_gust=False,
                    noise=replace(s.noise, gust_mps=float(run.gust["sd_mps"])))
        problem_h = adjusted(problem, inputs=held, settings=s, choice=SettingChoice(
            "noise.gust_mps", s.noise.gust_mps,
            "held at the converged run's estimate for the held-out smoothing"))
    else:
        problem_h = adjusted(problem, inputs=held)
    if not warm:
        return smooth_joint(problem_h)
    return smooth_joint_from(problem_h, run, s.gap_heldout_passes,
                             enough_m=HELDOUT_ENOUGH * s.converge_m)


def calibrate_gaps(problem: JointProblem, run: JointRun) -> tuple[JointRun, dict[str, Any] | None]:
    """Held-out gap calibration: where the GNSS has gaps longer than ``settings.gap_min_s``,
    withhold up to ``settings.gap_stretches`` stretches of their lengths, smooth the adjusted
    problem without them from ``run`` (:func:`heldout_smoothing`), measure the held-out NEES and
    rescale the real gaps' position variance by the factor (:func:`calibration_factor`).  Returns
    the run (unchanged without gaps, with ``gap_stretches`` 0 or without room for a stretch) and
    the report (None without gaps)."""
    inp, settings = problem.inputs, problem.settings
    if settings.gap_stretches <= 0:
        return run, None
    gaps = gnss_gaps(inp, settings.gap_min_s)
    if not gaps:
        return run, None
    stretches = pseudo_gaps(inp, gaps, n_max=settings.gap_stretches,
                            guard_s=settings.gap_guard_s, min_gap_s=settings.gap_min_s)
    report: dict[str, Any] = {"gaps_s": [[a, b] for a, b in gaps],
                              "stretches_s": [[a, b] for a, b in stretches], "factor": None}
    if not stretches:
        report["note"] = "no room for a held-out stretch of the gaps' length"
        return run, report
    tg = inp.gnss["t_s"].to_numpy(float)
    keep = np.ones(len(tg), bool)
    for a, b in stretches:
        keep &= ~((tg > a) & (tg < b))
    # what the converged run freed goes back before the second smoothing's buffers are mapped
    # (its peak would otherwise add to the held-out one; flightrecon/memory.py)
    release_unused()
    try:
        run_h = heldout_smoothing(problem, keep, run)
    except (FlightReconError, ValueError, ArithmeticError) as exc:
        # the held-out smoothing's own breakdown leaves the flight's result standing: the
        # gaps keep the model's sd, said in the report (and by run_joint's warning)
        report["note"] = f"the held-out smoothing failed ({type(exc).__name__}: {exc})"
        return run, report
    sel = np.flatnonzero(np.isfinite(inp.gnss["lat_deg"].to_numpy(float))
                         & np.isfinite(inp.gnss["lon_deg"].to_numpy(float)))
    # the fixes at their own times: the stamps plus the GNSS clock offset the smoother
    # estimated (seconds added to the stamps, as in its measurements)
    off = run_h.clock_offsets_s.get("gnss", (0.0, 0.0))[0]
    tf = tg[sel] + (off if np.isfinite(off) else 0.0)
    p = run_h.positions_ecef(tf)
    d, P, declared = fix_errors(inp, run_h, sel, tf, p, settings.noise.gnss_h_m)
    used = keep[sel]
    r = fix_noise(d[used], P[used], declared[used])
    held = heldout_errors(run_h, stretches, tg[sel], (tf, d, P), r)
    if not held:
        report["note"] = "no held-out fix inside the stretches"
        return run, report
    cal = calibration_factor(held, settings.gap_factor_bounds, settings.gap_stretch_p,
                             settings.gap_pool_p)
    report.update(cal)
    report["fix_sd_m"] = np.sqrt(r).tolist()
    report["stretches_s"] = [[h["t0_s"], h["t1_s"]] for h in held]
    report["heldout_rms_m"] = [float(np.sqrt(np.mean(np.sum(h["e"] ** 2, axis=1)))) for h in held]
    report["heldout_pass_shifts_m"] = [float(i["max_position_change_m"]) for i in run_h.iterations]
    return apply_factor(run, gaps, cal["factor"]), report


def inertial_wind_share(inp: JointInputs, settings: JointSettings) -> float:
    """The PSD ``r`` of the loads' velocity random walk where a record sampled slower than its
    accelerations (:func:`~flightrecon.methods.joint.problem.sampled_loads_noise` set) has the loads
    as the wind's only witness (no GNSS, radar, known fixes, recorded wind, Doppler or winds-aloft
    prior), else 0 [m^2/s^3]: ``r = accel_noise_mps2_sqrt_hz^2 + (s_n^2 + s_e^2) / 2`` (``s`` the
    horizontal ``accel_sampling_mps2_sqrt_hz``), of which the smoothed wind change is the share
    ``kappa = Q / (Q + r L)`` (docs/joint.md, "Wind and turbulence")."""
    nz = settings.noise
    s = nz.accel_sampling_mps2_sqrt_hz
    if (not (s[0] > 0 or s[1] > 0) or len(inp.gnss) or len(inp.radar)
            or (inp.fixes is not None and len(inp.fixes)) or inp.wind_ne is not None
            or inp.doppler_gs is not None or inp.wind_aloft is not None):
        return 0.0
    return float(nz.accel_noise_mps2_sqrt_hz ** 2 + 0.5 * (s[0] ** 2 + s[1] ** 2))


#: how long after lift-off and before touchdown the rolls still witness the wind where the
#: loads are its only other witness: a derived ``n_long_g``'s bias prior (0.01 g) alone
#: integrates to 6 m/s in a minute, beyond the wind walk's 0.4 m/s (0.05 m/s/sqrt(s))
ROLL_WITNESS_S = 60.0
#: false-alarm probability of the wind-walk check where the loads are the wind's only
#: witness: the share kappa leaves out the other witnesses (the end points, the estimated
#: load biases), so its chi-square overstates a change and the check asks for stronger
#: evidence than the bound's 1 %
LOADS_WITNESS_P_FALSE = 1e-4


def wind_walk_rounds(problem: JointProblem, run: JointRun
                     ) -> tuple[JointProblem, JointRun, list[dict[str, Any]]]:
    """Where the smoothed wind moved faster than its random walk allows
    (:func:`~flightrecon.methods.joint.health.wind_walk_check`, with the loads' PSD ``r`` of
    :func:`inertial_wind_share`), the walk re-estimated from the flight and the adjusted problem,
    its choice and evidence appended, solved again, at most ``settings.wind_rounds`` times, until
    the smoothed wind is within the walk or the walk reaches ``wind_rw_max_mps_sqrt_s``
    (docs/joint.md, "Wind and turbulence": JSBSim's holding, 22 m/s turning 100 deg in 30 minutes).

    The check's worst window (length L, the model's variance ``Q`` of which ``Q_h`` from the height
    flown through, the loads' ``r L``) has ``z^2 = |dw|^2 / (kappa Q)``, ``kappa = Q / (Q + r L)``.
    With ``r = 0`` (another witness of the wind) the walk ``q`` is scaled so that this window would
    be a typical one, its chi-square the mean 2 of chi-square(2): ``q' = q z^2 / 2``; where the
    loads are the only witness, the smallest walk the check accepts: ``q' L = z^2 (Q + r L) / limit
    - r L - Q_h``; never below ``q``, kept below ``wind_rw_max_mps_sqrt_s``.  Returns the last
    problem, its run and the rounds (the walk each started from, the check's chi-square and limit,
    the loads' PSD)."""
    rounds: list[dict[str, Any]] = []
    inp, settings = problem.inputs, problem.settings
    r = inertial_wind_share(inp, settings)
    within = None
    if r > 0:   # windows clear of the rolls (a record without both: the check as it is)
        if not (np.isfinite(inp.liftoff_t) and np.isfinite(inp.touchdown_t)):
            r = 0.0
        else:
            within = (inp.liftoff_t + ROLL_WITNESS_S, inp.touchdown_t - ROLL_WITNESS_S)
    for _ in range(max(0, settings.wind_rounds)):
        s = problem.settings
        nz = s.noise
        c = wind_walk_check(run, nz.wind_rw_mps_sqrt_s, nz.wind_shear_mps_per_sqrt_m,
                            loads_psd_m2ps3=r, within_s=within,
                            p_false=LOADS_WITNESS_P_FALSE if r > 0 else 0.01)
        if c is None or nz.wind_rw_mps_sqrt_s >= settings.wind_rw_max_mps_sqrt_s:
            break
        rounds.append({"wind_rw_mps_sqrt_s": nz.wind_rw_mps_sqrt_s, "z2": c["z2"],
                       "limit": c["limit"], "loads_psd_m2ps3": r})
        L = c["t1_s"] - c["t0_s"]
        q = nz.wind_rw_mps_sqrt_s ** 2
        q_h = c["walk_var_m2ps2"] - q * L
        if r > 0:
            q_new = (c["z2"] * (c["walk_var_m2ps2"] + c["loads_var_m2ps2"]) / c["limit"]
                     - c["loads_var_m2ps2"] - q_h) / L
        else:
            q_new = q * 0.5 * c["z2"]
        q_new = max(q_new, q)
        walk = min(float(np.sqrt(q_new)), s.wind_rw_max_mps_sqrt_s)
        why = (f"the smoothed wind moved faster than the walk {nz.wind_rw_mps_sqrt_s:.3g} "
               f"m/s/sqrt(s) allows: chi-square {c['z2']:.3g} over {L:.0f} s from "
               f"t = {c['t0_s']:.0f} s, beyond {c['limit']:.3g}")
        problem = adjusted(problem, settings=replace(s, noise=replace(nz, wind_rw_mps_sqrt_s=walk)),
                           choice=SettingChoice("noise.wind_rw_mps_sqrt_s", walk, why))
        run = smooth_joint(problem)
    return problem, run, rounds
