"""Iterations of the joint smoother: forward filter, RTS backward pass and Gauss-Newton
relinearisation with robust re-weighting and clock-offset fits (:func:`smooth_joint`)."""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

import numpy as np

from flightrecon.filters.joint import layout as jl
from flightrecon.filters.joint import passes as jp
from flightrecon.filters.joint.inputs import (
    JointInputs,
    TakeoffRoll,
    end_points,
    enu_to_ecef_matrix,
    refined_roll,
)
from flightrecon.filters.joint.measurements import (
    Measurements,
    build_measurements,
    static_measurements,
)
from flightrecon.filters.joint.noise import (
    NOISE_GROUPS,
    _em_noise_scales,
    _noise_groups,
    innovation_loglik,
)
from flightrecon.filters.joint.nominal import (
    _attitude_step_means,
    _increments,
    _initial,
    _nominal_trajectory,
    _q_vector,
    _state_grid,
    relinearised_increments,
)
from flightrecon.filters.joint.settings import SOURCES, JointSettings
from flightrecon.geo.frames import ecef_to_geodetic, geodetic_to_ecef
from flightrecon.geo.navframe import ned_to_ecef_matrix


@dataclass(frozen=True)
class JointRun:
    """Result of :func:`smooth_joint` on the state grid."""

    t: np.ndarray
    x: np.ndarray            # smoothed states (N, n)
    P_pv: np.ndarray         # smoothed position-velocity covariance block (ECEF p, NED v)
    var: np.ndarray          # smoothed state variances (N, n)
    xf: np.ndarray           # filtered states
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    h_m: np.ndarray          # ellipsoidal height
    Cen: np.ndarray
    meas: Measurements
    weights: np.ndarray
    resid_norm: np.ndarray
    innov: np.ndarray
    innov_var: np.ndarray
    clock_offsets_s: dict[str, tuple[float, float]]  # (value, sd): seconds added to the stamps
    noise_scale: dict[str, float]
    iterations: list[dict[str, Any]]
    end_points: list[dict[str, Any]]   # as used in the last pass (end_points)
    roll: TakeoffRoll                  # the take-off roll of the last pass (refined_roll)
    noise_check: dict[str, Any] | None = None   # estimate_noise: the likelihood check
    # steps of the last pass whose predicted covariance failed its Cholesky factorisation (the
    # smoother gain then came from a general solve): reported, never silent
    cholesky_fallbacks: int = 0


def smooth_joint(inp: JointInputs, settings: JointSettings = JointSettings()) -> JointRun:
    """Run the joint smoother (forward EKF, RTS, Gauss-Newton/IRLS iterations)."""
    nz = settings.noise
    idx = _state_grid(inp.t_in, settings.state_rate_hz)
    T = inp.t_in[idx]
    dt = np.diff(T, prepend=T[0])
    dV, dP, miss = _increments(inp.t_in, inp.acc_ned, idx)
    acc = dV / np.where(dt > 0, dt, 1.0)[:, None]
    fb = np.zeros((len(inp.t_in), 3)) if inp.f_body_g is None else np.nan_to_num(inp.f_body_g)
    Cnb, Csf, Jatt = _attitude_step_means(np.ascontiguousarray(inp.Cnb, dtype=float),
                                          np.ascontiguousarray(fb), idx.astype(np.int64))
    qv_extra = np.where(dt > 0, miss / np.where(dt > 0, dt, 1.0), 0.0) * 1.0  # (1 m/s^2)^2/Hz
    q = _q_vector(nz)
    lat, lon, h = _nominal_trajectory(inp, idx, nz)
    clock = {"gnss": 0.0, "radar": 0.0}
    clock_sd = {"gnss": np.nan, "radar": np.nan}
    scale = np.ones(len(NOISE_GROUPS))       # variance factor per noise group (EM)
    weights = None
    history = []
    Cst = np.eye(3)
    pst = np.zeros(3)
    if inp.station is not None:
        Cst = enu_to_ecef_matrix(inp.station[0], inp.station[1])
        sx, sy, sz = geodetic_to_ecef(*inp.station)
        pst = np.array([float(sx), float(sy), float(sz)])
    x0 = P0 = None
    static = static_measurements(inp, settings, T)
    # nominal velocity (for the runway constraints' linearisation): air data at first, then
    # the smoothed velocity
    tas0 = np.nan_to_num(inp.tas[idx])
    psi0 = np.nan_to_num(inp.heading_rad[idx])
    vnom = np.c_[tas0 * np.cos(psi0), tas0 * np.sin(psi0), np.zeros(len(idx))]
    psi_hat = None   # heading bias of the last pass: the linearisation point of its rotation
    ba_hat = None    # accelerometer biases of the last pass (for the take-off roll)
    # smoothed states of the last pass (the measurements' linearisation)
    xlin = np.zeros((0, jl.N_STATE))
    n_iter = max(1, settings.iterations)
    if settings.estimate_noise:
        n_iter = max(n_iter, settings.noise_iterations)
    for it in range(n_iter):
        ex, ey, ez = geodetic_to_ecef(lat, lon, h)
        pnom = np.ascontiguousarray(np.c_[ex, ey, ez])
        Cen = np.ascontiguousarray(ned_to_ecef_matrix(lat, lon))
        hnom = h - inp.field_h
        dz = np.diff(h, prepend=h[0])   # signed height change: the wind moves along its gradient
        roll = refined_roll(inp, T, vnom, ba_hat)
        meas = build_measurements(inp, settings, T, Cen, Cnb, clock, static, pnom, vnom, roll,
                                  psi_hat)
        if psi_hat is None:
            acc_k, dV_k, dP_k = acc, dV, dP
        else:
            acc_k, dV_k, dP_k = relinearised_increments(acc, dV, dP, dt, psi_hat)
        groups = _noise_groups(meas)
        r = meas.r * np.where(groups >= 0, scale[np.maximum(groups, 0)], 1.0)
        if weights is None or len(weights) != len(meas.z):
            weights = np.ones(len(meas.z))
        if x0 is None:
            x0, P0 = _initial(inp, pnom, nz, settings.min_airspeed_mps, settings.priors)
        tau = meas.t - T[meas.step]
        if it == 0:  # filter outputs, reused by every pass (allocated and paged in once)
            n = jl.N_STATE
            xf, xp = np.empty((len(T), n)), np.empty((len(T), n))
            # (an empty Pp would have the backward passes recompute the predicted covariances,
            # bit-identical: 139 MB less for 10 h of flight but 0.2-0.3 s more per pass)
            Pf, Pp = np.empty((len(T), n, n)), np.empty((len(T), n, n))
        dyn = jl.Dynamics(dt, Cen, Cnb, Csf, Jatt, acc_k, dP_k, dV_k, dz, qv_extra, q)
        geo = jl.Geometry(pnom, hnom, pst, Cst)
        scalars = jl.Scalars(meas.start, meas.mtype, meas.z, r, weights, tau, meas.H, meas.hrow,
                             meas.d)
        innov, innov_var, infl = jp.forward(
            xf, Pf, xp, Pp, x0, P0, dyn, scalars, geo,
            settings.innovation_gate if settings.robust else 0.0, xlin)
        r_used = r * infl
        # the iterations need the smoothed trajectory only; covariances once, after the last
        kern_args = (dyn, scalars._replace(r=r_used), geo)
        # EM needs the smoothed covariances in every pass; otherwise the first pass (far from
        # the solution) smooths the states only, the later ones (likely the last) everything
        with_cov = settings.estimate_noise or it > 0
        if settings.estimate_noise:
            xs, Pblk, var, _, res, rate, hph, n_fallback = jp.backward(xf, Pf, xp, Pp, *kern_args,
                                                                       True)
        elif with_cov:
            # the covariance recursion does not need the smoothed states: it runs on a second
            # thread beside the mean pass (the kernels release the GIL)
            cov: dict[str, Any] = {}

            def covariances(*args: Any, cov: dict[str, Any] = cov) -> None:
                try:
                    cov["out"] = jp.backward(*args, False)
                except BaseException as exc:  # re-raised on the calling thread
                    cov["error"] = exc

            worker = threading.Thread(target=covariances, name="joint-covariances",
                                      args=(xf, Pf, xp, Pp, *kern_args))
            worker.start()
            xs, _, res, rate, n_fallback = jp.backward_mean(xf, Pf, xp, Pp, *kern_args)
            worker.join()
            if "error" in cov:
                raise cov["error"]
            _, Pblk, var, *_, n_fallback_cov = cov["out"]
            n_fallback = max(n_fallback, n_fallback_cov)
        else:
            xs, _, res, rate, n_fallback = jp.backward_mean(xf, Pf, xp, Pp, *kern_args)
        # residual in units of the measurement's own (nominal, not inflated) standard deviation
        res_n = res / np.sqrt(r)
        # new nominal: the smoothed trajectory
        lat_new, lon_new, h_new = ecef_to_geodetic(xs[:, 0], xs[:, 1], xs[:, 2])
        shift = float(np.max(np.abs(np.c_[xs[:, jl.S_POS] - pnom])))
        info = {"iteration": it, "max_position_change_m": shift, "roll_start_t_s": roll.start_t,
                "cholesky_fallbacks": int(n_fallback)}
        # robust weights from the smoothed residuals
        w_before = weights.copy()
        clock_before = dict(clock)
        if settings.robust:
            a = np.abs(res_n)
            weights = np.where(a > settings.huber_c, settings.huber_c / np.maximum(a, 1e-12), 1.0)
            # gross errors (beyond reject_c sigma from the smoothed track) are set aside: a
            # redescending rule, so a jumped source cannot pull the track at all
            weights = np.where(a > settings.reject_c, 1e-8, weights)
            weights[~np.isfinite(weights)] = 1.0
        # clock offsets, in seconds added to the source's time stamps (the convention of
        # `clean --gnss-clock-offset / --radar-clock-offset`): a measurement stamped t_m and
        # taken at t_m + c_true, used at t_m + c, has residual hdot * (c_true - c)
        if settings.estimate_clock:
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
        noise_moved = False
        if settings.estimate_noise:
            # measurements taken at face value in this pass: full weight, not gated
            use = (weights >= 1.0) & (w_before >= 1.0) & (infl <= 1.0)
            new_scale = scale.copy()
            lo_b, hi_b = settings.noise_factor_bounds
            for gi, c in _em_noise_scales(groups, res, hph, meas.r, use).items():
                new_scale[gi] = min(max(c, lo_b), hi_b)   # bounded: no runaway factor
            noise_moved = bool(np.any(np.abs(new_scale / scale - 1.0) > settings.noise_tol))
            scale = new_scale
            info["noise_scale"] = {name: float(scale[i])
                                   for i, name in enumerate(NOISE_GROUPS.values())
                                   if np.any(groups == i)}
        history.append(info)
        lat, lon, h = lat_new, lon_new, h_new
        vnom = xs[:, jl.S_VEL]
        psi_new = np.ascontiguousarray(xs[:, jl.IPSI])
        psi_moved = float(np.max(np.abs(psi_new - (0.0 if psi_hat is None else psi_hat))))
        info["max_heading_bias_change_deg"] = float(np.degrees(psi_moved))
        psi_hat = psi_new
        ba_hat = xs[:, jl.S_ACC_BIAS]
        xlin = xs
        # converged: the linearisation point, the weights, the clock offsets and (with
        # estimate_noise) the noise variances stand still
        # (a nominal within converge_m = 2 m changes a measurement's linearisation by about
        # shift^2 / (2 range), 0.4 mm for a radar 5 km away, and turns the local-level frame by
        # 3e-7 rad, 0.1 mm/s at 250 m/s: far below any sensor's noise)
        # (and the heading bias within 1e-4 rad of its linearisation point: 1 m at 10 km)
        if (it > 0 and shift < settings.converge_m and clock == clock_before and not noise_moved
                and psi_moved < 1e-4
                and np.all(np.abs(weights - w_before) <= settings.converge_weight)):
            info["converged"] = True
            break
    if not with_cov:
        # smoothed covariances of the last pass (its states equal those of the mean-only pass
        # to round-off: same gains, same linearisation)
        xs, Pblk, var, *_, n_fallback_cov = jp.backward(xf, Pf, xp, Pp, *kern_args, False)
        n_fallback = max(n_fallback, n_fallback_cov)
    noise_check = None
    if settings.estimate_noise:
        # the estimated noise must raise the likelihood of the data: the innovations'
        # log-likelihood (prediction-error decomposition) of the last pass against a forward
        # pass with the default variances at the same linearisation, weights and clock
        # offsets; otherwise the defaults are kept (docs/joint.md, "Noise estimation")
        lo_b, hi_b = settings.noise_factor_bounds
        xf1, xp1 = np.empty_like(xf), np.empty_like(xp)
        Pf1, Pp1 = np.empty_like(Pf), np.empty_like(Pp)
        r1 = meas.r.copy()
        # (w_before: the weights the last forward pass ran with)
        scalars1 = scalars._replace(r=r1, w=w_before)
        innov1, innov_var1, infl1 = jp.forward(
            xf1, Pf1, xp1, Pp1, x0, P0, dyn, scalars1, geo,
            settings.innovation_gate if settings.robust else 0.0, xlin)
        sel = (w_before >= 1.0) & (infl <= 1.0) & (infl1 <= 1.0)
        ll_est = innovation_loglik(innov, innov_var, sel)
        ll_def = innovation_loglik(innov1, innov_var1, sel)
        at_bound = [name for i, name in enumerate(NOISE_GROUPS.values())
                    if np.any(groups == i) and (scale[i] <= lo_b or scale[i] >= hi_b)]
        accepted = bool(np.isfinite(ll_est) and ll_est > ll_def)
        noise_check = {"loglik_estimated": ll_est, "loglik_default": ll_def,
                       "measurements": int(sel.sum()), "accepted": accepted,
                       "factors_at_bound": at_bound, "bounds": [lo_b, hi_b]}
        if not accepted:
            scale = np.ones(len(NOISE_GROUPS))
            r_used = r1 * infl1
            kern_args = (dyn, scalars1._replace(r=r_used), geo)
            xs, Pblk, var, _, res, rate, hph, n_fb1 = jp.backward(xf1, Pf1, xp1, Pp1,
                                                                   *kern_args, True)
            n_fallback = int(n_fb1)
            res_n = res / np.sqrt(r1)
            xf, innov, innov_var = xf1, innov1, innov_var1
            lat, lon, h = ecef_to_geodetic(xs[:, 0], xs[:, 1], xs[:, 2])
        del Pf1, Pp1
    del Pf, Pp
    return JointRun(t=T, x=xs, P_pv=Pblk, var=var, xf=xf, lat_deg=lat, lon_deg=lon, h_m=h,
                    Cen=Cen, meas=meas, weights=weights, resid_norm=res_n, innov=innov,
                    innov_var=innov_var,
                    clock_offsets_s={k: (clock[k], clock_sd[k]) for k in clock},
                    noise_scale={name: float(scale[i]) for i, name in
                                 enumerate(NOISE_GROUPS.values())},
                    iterations=history, end_points=end_points(inp, nz, roll), roll=roll,
                    noise_check=noise_check,
                    cholesky_fallbacks=int(n_fallback))
