"""ADS/ARMS filters and smoothers: stage 1 (ground velocity), stage 2 (compensation), the
cascade and the joint form, and the estimate they give."""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.estimation.kalman import (
    FilterRun,
    SmoothedRun,
    joseph_update,
    kalman_filter,
    predict,
    rts_smooth_run,
)
from flightrecon.methods.arms.model import (
    _LIN_CODE,
    CONVERTED_AT,
    LINEARISATIONS,
    AirData,
    ArmsModel,
    RadarPlots,
    converted_covariance,
    converted_measurement,
    cv_process_noise,
    cv_transition,
    gm_process_noise,
    gm_transition,
    joint_process_noise,
    joint_transition,
)


@dataclass(frozen=True)
class ArmsEstimate:
    """Estimates at a form's step times (time-major; x east, y north; SI).

    Attributes
    ----------
    t_s : (N,) step times
    pos, vel : (N, 2) position [x, y] and ground velocity [Vx, Vy]
    pos_cov, vel_cov : (N, 2, 2) their covariances
    dv, dv_cov : (N, 2) air-data error estimate dV_hat and (N, 2, 2) covariance
    smoothed : whether these are smoothed (True) or filtered (False) estimates
    """

    t_s: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    pos_cov: np.ndarray
    vel_cov: np.ndarray
    dv: np.ndarray
    dv_cov: np.ndarray
    smoothed: bool


@dataclass(frozen=True)
class Stage1Run:
    """Stage-1 CV tracker run: forward pass, optional backward pass, step times."""

    t_s: np.ndarray
    filt: FilterRun
    smooth: SmoothedRun | None
    radar_used: np.ndarray


@dataclass(frozen=True)
class Stage2Run:
    """Stage-2 compensation run at the plot times."""

    t_s: np.ndarray
    filt: FilterRun
    smooth: SmoothedRun | None


@dataclass(frozen=True)
class ArmsJointRun:
    """Joint-model run on the union of plot and air-data times."""

    t_s: np.ndarray
    filt: FilterRun
    smooth: SmoothedRun | None
    radar_used: np.ndarray
    air_used: np.ndarray


@dataclass(frozen=True)
class CascadeResult:
    """The paper's cascade: stage 1 then stage 2 (its stage-2 input uses the stage-1 estimate
    of the same kind: filtered into filtered, smoothed into smoothed)."""

    stage1: Stage1Run
    stage2: Stage2Run


# --------------------------------------------------------------------------------------------
# the forward kernel (EKF / converted measurements, optional air-data velocity measurement)
# --------------------------------------------------------------------------------------------

@nb.njit(cache=True, nogil=True)
def _arms_kernel(x0, P0, F, Q, radar, radar_sd, air, Rv, lin):
    """Forward pass of the CV (n=4) or joint (n=6) model.

    radar (N, 2): [r, theta] (NaN: no plot); radar_sd (N, 2): [sigma_r, sigma_theta];
    air (N, 2): [V*x, V*y] (NaN: none; only used when n == 6); Rv (2, 2) its noise;
    lin: 0 EKF, 1 converted at measured, 2 converted at predicted.
    Innovation components: 0-1 radar (range/azimuth or x/y), 2-3 air data.
    """
    N = F.shape[0]
    n = x0.shape[0]
    xs = np.empty((N, n))
    Ps = np.empty((N, n, n))
    xp = np.empty((N, n))
    Pp = np.empty((N, n, n))
    nus = np.full((N, 4), np.nan)
    Ss = np.full((N, 4, 4), np.nan)
    nis = np.full(N, np.nan)
    nmeas = np.zeros(N, dtype=np.int64)
    radar_used = np.zeros(N, dtype=np.bool_)
    air_used = np.zeros(N, dtype=np.bool_)
    x = x0.copy()
    P = P0.copy()
    for k in range(N):
        if k > 0:
            x, P = predict(x, P, F[k], Q[k])
        xp[k] = x
        Pp[k] = P
        nu = np.zeros(4)
        Hk = np.zeros((4, n))
        Rk = np.zeros((4, 4))
        slot = np.empty(4, dtype=np.int64)
        c = 0
        if not (np.isnan(radar[k, 0]) or np.isnan(radar[k, 1])):
            rho = radar[k, 0]
            th = radar[k, 1]
            sr2 = radar_sd[k, 0] ** 2
            st2 = radar_sd[k, 1] ** 2
            px = x[0]
            py = x[2]
            r2 = px * px + py * py
            if r2 > 1.0:  # at the station the azimuth is undefined: skip such a plot
                rp = np.sqrt(r2)
                if lin == 0:
                    nu[0] = rho - rp
                    d = th - np.arctan2(px, py)
                    nu[1] = np.pi - np.mod(np.pi - d, 2.0 * np.pi)
                    Hk[0, 0] = px / rp
                    Hk[0, 2] = py / rp
                    Hk[1, 0] = py / r2
                    Hk[1, 2] = -px / r2
                    Rk[0, 0] = sr2
                    Rk[1, 1] = st2
                else:
                    nu[0] = rho * np.sin(th) - px
                    nu[1] = rho * np.cos(th) - py
                    Hk[0, 0] = 1.0
                    Hk[1, 2] = 1.0
                    if lin == 1:
                        re = rho
                        te = th
                    else:
                        re = rp
                        te = np.arctan2(px, py)
                    s = np.sin(te)
                    co = np.cos(te)
                    ct2 = re * re * st2
                    Rk[0, 0] = sr2 * s * s + ct2 * co * co
                    Rk[1, 1] = sr2 * co * co + ct2 * s * s
                    Rk[0, 1] = s * co * (sr2 - ct2)
                    Rk[1, 0] = Rk[0, 1]
                slot[0] = 0
                slot[1] = 1
                c = 2
                radar_used[k] = True
        if n == 6 and not (np.isnan(air[k, 0]) or np.isnan(air[k, 1])):
            nu[c] = air[k, 0] - (x[1] + x[4])
            nu[c + 1] = air[k, 1] - (x[3] + x[5])
            Hk[c, 1] = 1.0
            Hk[c, 4] = 1.0
            Hk[c + 1, 3] = 1.0
            Hk[c + 1, 5] = 1.0
            for a in range(2):
                for b in range(2):
                    Rk[c + a, c + b] = Rv[a, b]
            slot[c] = 2
            slot[c + 1] = 3
            c += 2
            air_used[k] = True
        if c > 0:
            v = nu[:c].copy()
            x, P, S, nis[k] = joseph_update(x, P, v, Hk[:c].copy(), Rk[:c, :c].copy())
            nmeas[k] = c
            for a in range(c):
                nus[k, slot[a]] = v[a]
                for b in range(c):
                    Ss[k, slot[a], slot[b]] = S[a, b]
        xs[k] = x
        Ps[k] = P
    return xs, Ps, xp, Pp, nus, Ss, nis, nmeas, radar_used, air_used


def _lin_code(linearisation: str, converted_at: str) -> int:
    if linearisation not in LINEARISATIONS:
        raise ValidationError(f"unknown ARMS linearisation '{linearisation}'; choose from "
                              f"{', '.join(LINEARISATIONS)}")
    if converted_at not in CONVERTED_AT:
        raise ValidationError(f"unknown converted-covariance point '{converted_at}'; choose from "
                              f"{', '.join(CONVERTED_AT)}")
    return _LIN_CODE[(linearisation, converted_at)]


def _initial_position(plots: RadarPlots) -> tuple[np.ndarray, np.ndarray]:
    """Position prior from the first plot: its converted value and converted covariance (eq. 15
    at the measured values).  The first plot is then *not* used again as a measurement."""
    p = converted_measurement(plots.range_m[0], plots.azimuth_rad[0])
    R = converted_covariance(plots.range_m[0], plots.azimuth_rad[0], plots.sigma_range_m[0],
                             plots.sigma_azimuth_rad[0])
    return p, R


def _radar_arrays(plots: RadarPlots) -> tuple[np.ndarray, np.ndarray]:
    z = np.column_stack([plots.range_m, plots.azimuth_rad])
    sd = np.column_stack([plots.sigma_range_m, plots.sigma_azimuth_rad])
    return np.ascontiguousarray(z), np.ascontiguousarray(sd)


def _dt(t: np.ndarray) -> np.ndarray:
    return np.concatenate([[0.0], np.diff(t)])


# --------------------------------------------------------------------------------------------
# stage 1, stage 2, cascade, joint
# --------------------------------------------------------------------------------------------

def track_ground_velocity(plots: RadarPlots, model: ArmsModel, *, linearisation: str = "ekf",
                          converted_at: str = "predicted", smooth: bool = True) -> Stage1Run:
    """Stage 1: CV tracker of ``[x, Vx, y, Vy]`` from the plots at their own times.

    Paper eqs. 10-15 (docs/arms.md, stage 1).  One step per plot, ``T`` from the plot
    times; the prior is the first plot's converted position (eq. 13, covariance eq. 15) with zero
    velocity of standard deviation ``model.v0_sd_mps``; the first plot initialises and is not
    reused.  EKF: azimuth innovation wrapped to (-pi, pi].

    Returns
    -------
    Stage1Run
        ``filt`` (a :class:`FilterRun`; innovations in columns 0-1 of ``nu``) and, if ``smooth``,
        the RTS pass ``smooth``.
    """
    lin = _lin_code(linearisation, converted_at)
    t = plots.t_s
    dt = _dt(t)
    F = cv_transition(dt)
    Q = cv_process_noise(dt, model.q_m2ps3)
    p0, R0 = _initial_position(plots)
    x0 = np.array([p0[0], 0.0, p0[1], 0.0])
    P0 = np.zeros((4, 4))
    P0[np.ix_([0, 2], [0, 2])] = R0
    P0[1, 1] = P0[3, 3] = model.v0_sd_mps ** 2
    z, sd = _radar_arrays(plots)
    z[0] = np.nan
    air = np.full((len(t), 2), np.nan)
    out = _arms_kernel(x0, P0, F, Q, z, sd, air, np.zeros((2, 2)), lin)
    run = FilterRun(out[0], out[1], out[2], out[3], F, out[4], out[5], out[6], out[7])
    sm = rts_smooth_run(run) if smooth else None
    return Stage1Run(t, run, sm, out[8])


def compensate(stage1: Stage1Run, air: AirData, model: ArmsModel, *,
               use_smoothed_stage1: bool | None = None, smooth: bool = True,
               air_max_gap_s: float = np.inf) -> Stage2Run:
    """Stage 2: the paper's compensation filter (Fig. 1, eqs. 5-8).

    State ``dV = [dVx, dVy]``, Gauss-Markov per axis (exact discretisation).  Measurement at each
    plot time: ``z = V* - W_hat = dV - dW`` with ``H = I`` and ``R = cov(dW) + sigma_air^2 I``,
    where ``cov(dW)`` is stage 1's velocity covariance: the cascade treats the stage-1 error as
    white, which it is not (docs/arms.md, first caution), so this filter's covariance is
    optimistic.  The air data is taken at the plot times by interpolation (:meth:`AirData.at`).

    Parameters
    ----------
    use_smoothed_stage1 : feed stage 1's smoothed (True) or filtered (False) ground velocity;
        default: smoothed when stage 1 was smoothed.
    air_max_gap_s : plots inside an air-data gap longer than this get no stage-2 measurement
    """
    if use_smoothed_stage1 is None:
        use_smoothed_stage1 = stage1.smooth is not None
    if use_smoothed_stage1 and stage1.smooth is None:
        raise ValidationError("stage 1 was not smoothed; cannot feed its smoothed velocity")
    src = stage1.smooth if use_smoothed_stage1 else stage1.filt
    t = stage1.t_s
    W = src.x[:, [1, 3]]
    Pw = src.P[:, [1, 3]][:, :, [1, 3]]
    Vs = air.at(t, max_gap_s=air_max_gap_s)
    z = Vs - W
    R = Pw + model.sigma_air_mps ** 2 * np.eye(2)
    dt = _dt(t)
    F = gm_transition(dt, model.alpha_ps)
    Q = gm_process_noise(dt, model.alpha_ps, model.gm_sigma_mps)
    run = kalman_filter(np.zeros(2), model.gm_sigma_mps ** 2 * np.eye(2), F, Q, z, np.eye(2), R)
    sm = rts_smooth_run(run) if smooth else None
    return Stage2Run(t, run, sm)


def run_cascade(plots: RadarPlots, air: AirData, model: ArmsModel, *, linearisation: str = "ekf",
                converted_at: str = "predicted", smooth: bool = True,
                air_max_gap_s: float = np.inf) -> CascadeResult:
    """The paper's two-stage cascade (Fig. 1): :func:`track_ground_velocity` then
    :func:`compensate`; with ``smooth`` both stages are smoothed and stage 2 takes stage 1's
    smoothed velocity, else both are forward-only."""
    s1 = track_ground_velocity(plots, model, linearisation=linearisation,
                               converted_at=converted_at, smooth=smooth)
    s2 = compensate(s1, air, model, use_smoothed_stage1=smooth, smooth=smooth,
                    air_max_gap_s=air_max_gap_s)
    return CascadeResult(s1, s2)


def run_joint_model(plots: RadarPlots, air: AirData, model: ArmsModel, *,
                    linearisation: str = "ekf", converted_at: str = "predicted",
                    smooth: bool = True, extra_times=None) -> ArmsJointRun:
    """Joint model ``[x, Vx, y, Vy, dVx, dVy]`` (docs/arms.md, product form).

    Steps: the union of the plot times, the air-data times and ``extra_times`` (steps without a
    measurement, e.g. the output grid, so that the estimate there is the exact prediction or
    smoothed state rather than an interpolation), all inside ``[first plot, last plot]``; each
    plot and each air-data sample is used once at its own time.
    Measurements: range/azimuth (EKF or converted, as in stage 1) and
    ``V* = [Vx + dVx, Vy + dVy] + e``, ``e ~ N(0, sigma_air^2 I)``.  Prior: first plot's converted
    position, zero ground velocity (sd ``v0_sd_mps``), zero air-data error with its stationary
    sd ``gm_sigma_mps``.
    """
    lin = _lin_code(linearisation, converted_at)
    tp = plots.t_s
    inside = (air.t_s >= tp[0]) & (air.t_s <= tp[-1])
    ta = air.t_s[inside]
    if np.any(np.diff(ta) <= 0):
        raise ValidationError("air data: times must be strictly increasing")
    t = np.union1d(tp, ta)
    if extra_times is not None:
        te = np.asarray(extra_times, dtype=np.float64)
        t = np.union1d(t, te[(te >= tp[0]) & (te <= tp[-1])])
    N = len(t)
    ip = np.searchsorted(t, tp)
    ia = np.searchsorted(t, ta)
    rz, rsd = _radar_arrays(plots)
    radar = np.full((N, 2), np.nan)
    radar_sd = np.ones((N, 2))
    radar[ip] = rz
    radar_sd[ip] = rsd
    radar[ip[0]] = np.nan  # the first plot initialises the position
    av = np.full((N, 2), np.nan)
    av[ia, 0] = air.vx_mps[inside]
    av[ia, 1] = air.vy_mps[inside]
    dt = _dt(t)
    F = joint_transition(dt, model.alpha_ps)
    Q = joint_process_noise(dt, model.q_m2ps3, model.alpha_ps, model.gm_sigma_mps)
    p0, R0 = _initial_position(plots)
    x0 = np.array([p0[0], 0.0, p0[1], 0.0, 0.0, 0.0])
    P0 = np.zeros((6, 6))
    P0[np.ix_([0, 2], [0, 2])] = R0
    P0[1, 1] = P0[3, 3] = model.v0_sd_mps ** 2
    P0[4, 4] = P0[5, 5] = model.gm_sigma_mps ** 2
    Rv = model.sigma_air_mps ** 2 * np.eye(2)
    out = _arms_kernel(x0, P0, F, Q, radar, radar_sd, av, Rv, lin)
    run = FilterRun(out[0], out[1], out[2], out[3], F, out[4], out[5], out[6], out[7])
    sm = rts_smooth_run(run) if smooth else None
    return ArmsJointRun(t, run, sm, out[8], out[9])


def _sub(P: np.ndarray, idx: list[int]) -> np.ndarray:
    return P[:, idx][:, :, idx]


def estimate_of(run: CascadeResult | ArmsJointRun, *, smoothed: bool = True) -> ArmsEstimate:
    """Collect positions, velocities and air-data errors of a run (smoothed or filtered).

    Raises
    ------
    ValidationError
        If the smoothed estimate is asked for a forward-only run.
    """
    if isinstance(run, CascadeResult):
        a, b = ((run.stage1.smooth, run.stage2.smooth) if smoothed
                else (run.stage1.filt, run.stage2.filt))
        if a is None or b is None:
            raise ValidationError("this cascade run was not smoothed")
        return ArmsEstimate(run.stage1.t_s, a.x[:, [0, 2]], a.x[:, [1, 3]], _sub(a.P, [0, 2]),
                            _sub(a.P, [1, 3]), b.x.copy(), b.P.copy(), smoothed)
    s = run.smooth if smoothed else run.filt
    if s is None:
        raise ValidationError("this joint run was not smoothed")
    return ArmsEstimate(run.t_s, s.x[:, [0, 2]], s.x[:, [1, 3]], _sub(s.P, [0, 2]),
                        _sub(s.P, [1, 3]), s.x[:, 4:6].copy(), _sub(s.P, [4, 5]), smoothed)
