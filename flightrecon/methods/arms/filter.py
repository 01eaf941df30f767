"""ADS/ARMS filters and smoothers: stage 1 (ground velocity), stage 2 (compensation), the
cascade and the joint form, and the estimate they give.

Every filter runs on the estimation core: the track filters (stage 1, joint) as the model
:class:`~flightrecon.methods.arms.model.ArmsTrackModel` through
:func:`~flightrecon.estimation.filtering.forward_pass`, stage 2 as the linear model
(:func:`~flightrecon.estimation.kalman.kalman_filter`); all transitions are linear, so every
backward pass is the linear RTS pass (:func:`~flightrecon.estimation.kalman.rts_smooth_run`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.estimation.filtering import FilterRun, forward_pass
from flightrecon.estimation.kalman import kalman_filter, rts_smooth_run
from flightrecon.estimation.smoothing import SmoothedRun
from flightrecon.methods.arms.inputs import AirData, ArmsModel, RadarPlots, linearisation_code
from flightrecon.methods.arms.measurement import converted_covariance, converted_measurement
from flightrecon.methods.arms.model import arms_track_model
from flightrecon.methods.arms.transition import (
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
class ArmsRun:
    """One ADS/ARMS filter (stage 1, stage 2 or the joint form) on its step times: the core's
    forward run and, if smoothed, its backward run.

    Attributes
    ----------
    t_s : (N,) step times
    filt : the :class:`~flightrecon.estimation.filtering.FilterRun`; its diagnostics ``F``
        (the transitions), ``nu``, ``S``, ``nis``, ``n_meas`` and, for the track filters,
        ``radar_used`` / ``air_used`` (N,) (the steps whose plot / air-data sample was used)
    smooth : the :class:`~flightrecon.estimation.smoothing.SmoothedRun`, or None (forward only)
    """

    t_s: np.ndarray
    filt: FilterRun
    smooth: SmoothedRun | None


@dataclass(frozen=True)
class CascadeResult:
    """The paper's cascade: stage 1 then stage 2 (its stage-2 input uses the stage-1 estimate
    of the same kind: filtered into filtered, smoothed into smoothed)."""

    stage1: ArmsRun
    stage2: ArmsRun


def _track_run(x0: np.ndarray, P0: np.ndarray, F: np.ndarray, Q: np.ndarray, radar: np.ndarray,
               radar_sd: np.ndarray, air: np.ndarray, Rv: np.ndarray, lin: int,
               smooth: bool) -> tuple[FilterRun, SmoothedRun | None]:
    """The track filter (:class:`ArmsTrackModel`) forward on the core and, with ``smooth``,
    the linear RTS pass (its transition is linear)."""
    model = arms_track_model(F, Q, radar, radar_sd, air, Rv, lin)
    forward_pass(model, np.ascontiguousarray(x0), np.ascontiguousarray(P0), F.shape[0])
    run = FilterRun(model.x_f, model.P_f, model.x_p, model.P_p,
                    {"F": model.F, "nu": model.nu, "S": model.S, "nis": model.nis,
                     "n_meas": model.n_meas, "radar_used": model.radar_used,
                     "air_used": model.air_used}, model)
    return run, (rts_smooth_run(run) if smooth else None)


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
                          converted_at: str = "predicted", smooth: bool = True) -> ArmsRun:
    """Stage 1: CV tracker of ``[x, Vx, y, Vy]`` from the plots at their own times.

    Paper eqs. 10-15 (docs/arms.md, stage 1).  One step per plot, ``T`` from the plot
    times; the prior is the first plot's converted position (eq. 13, covariance eq. 15) with zero
    velocity of standard deviation ``model.v0_sd_mps``; the first plot initialises and is not
    reused.  EKF: azimuth innovation wrapped to (-pi, pi].

    Returns
    -------
    ArmsRun
        ``filt`` (a :class:`FilterRun`; innovations in columns 0-1 of ``nu``, the plots used in
        ``radar_used``) and, if ``smooth``, the RTS pass ``smooth``.
    """
    lin = linearisation_code(linearisation, converted_at)
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
    run, sm = _track_run(x0, P0, F, Q, z, sd, air, np.zeros((2, 2)), lin, smooth)
    return ArmsRun(t, run, sm)


def compensate(stage1: ArmsRun, air: AirData, model: ArmsModel, *,
               use_smoothed_stage1: bool | None = None, smooth: bool = True,
               air_max_gap_s: float = np.inf) -> ArmsRun:
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
    return ArmsRun(t, run, sm)


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
                    smooth: bool = True, extra_times=None) -> ArmsRun:
    """Joint model ``[x, Vx, y, Vy, dVx, dVy]`` (docs/arms.md, product form).

    Steps: the union of the plot times, the air-data times and ``extra_times`` (steps without a
    measurement, e.g. the output grid, so that the estimate there is the exact prediction or
    smoothed state rather than an interpolation), all inside ``[first plot, last plot]``; each
    plot and each air-data sample is used once at its own time.
    Measurements: range/azimuth (EKF or converted, as in stage 1) and
    ``V* = [Vx + dVx, Vy + dVy] + e``, ``e ~ N(0, sigma_air^2 I)``.  Prior: first plot's converted
    position, zero ground velocity (sd ``v0_sd_mps``), zero air-data error with its stationary
    sd ``gm_sigma_mps``.  The air-data samples used are the ``air_used`` diagnostic.
    """
    lin = linearisation_code(linearisation, converted_at)
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
    run, sm = _track_run(x0, P0, F, Q, radar, radar_sd, av, Rv, lin, smooth)
    return ArmsRun(t, run, sm)


def _sub(P: np.ndarray, idx: list[int]) -> np.ndarray:
    return P[:, idx][:, :, idx]


def estimate_of(run: CascadeResult | ArmsRun, *, smoothed: bool = True) -> ArmsEstimate:
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
