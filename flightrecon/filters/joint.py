"""Joint post-flight smoother: one trajectory from every source, with honest uncertainty.

The state, its propagation by the kinematic accelerations from load factors and attitude, and
the measurement models are in :mod:`flightrecon.filters.joint_kernels`.  This module builds
their inputs from a cleaned flight, runs the forward filter and the RTS backward pass, and
iterates (Gauss-Newton about the smoothed trajectory) with

* the linearisation refreshed on the smoothed trajectory (nominal positions through pyproj);
* robust re-weighting: each measurement's smoothed residual, normalised by its own standard
  deviation sqrt(R - H P_s H^T), enters a Huber weight (threshold ``huber_c``), so a source that
  jumps (a GNSS offset of 500 m for a minute) is down-weighted rather than trusted;
* clock offsets of the GNSS and radar against the recorder estimated by weighted least squares
  of the smoothed residuals against the rate of each predicted measurement (a plot stamped
  t_m that belongs to true time t_m - o has residual -hdot * o);
* optionally, a scale factor on each source's noise variance estimated from the flight
  (variance-component estimation from the normalised residuals).

Frame: position in ECEF, velocity in the local north-east-down frame of the (nominal) aircraft
position: valid on flights of any length; outputs converted to the departure tangent plane.
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from typing import Any

import numba as nb
import numpy as np
import pandas as pd

from flightrecon.filters import joint_kernels as jk
from flightrecon.filters.joint_kernels import G0 as G0_MPS2
from flightrecon.geo.frames import ecef_to_geodetic, geodetic_to_ecef, offset_latlon
from flightrecon.geo.navframe import ned_to_ecef_matrix

SOURCES = ("air", "baro", "gnss_pos", "gnss_vel", "radar", "endpoint", "ground", "runway",
           "doppler", "wind")


@dataclass(frozen=True)
class JointNoise:
    """Sensor error budget (one sigma unless stated) and process noise of the joint model.

    Defaults are a stated budget for a transport aircraft's recorder data; see docs/joint.md.
    """

    accel_noise_mps2_sqrt_hz: float = 0.05   # velocity random walk from load-factor noise
    accel_bias_g: float = 0.003              # accelerometer bias, Gauss-Markov sigma
    accel_bias_tau_s: float = 3600.0
    accel_scale: float = 0.005               # accelerometer scale errors, prior per axis
    wind_prior_mps: float = 15.0
    wind_rw_mps_sqrt_s: float = 0.05         # wind change with time
    wind_shear_mps_per_sqrt_m: float = 0.05  # wind change with altitude beyond the gradient:
    #                                          sd over 1 m of climb
    wind_gradient_per_km: float = 5.0        # prior of the wind's gradient with height [(m/s)/km]
    wind_gradient_rw_per_km_sqrt_s: float = 0.005  # its change with time
    heading_bias_deg: float = 2.0
    attitude_bias_deg: float = 0.5           # roll and pitch biases (attitude reference), each
    heading_bias_rw_deg_sqrt_s: float = 1e-4
    tas_scale: float = 0.03
    baro_offset_m: float = 60.0
    baro_offset_rw_m_sqrt_s: float = 0.05
    baro_scale: float = 0.05
    tas_mps: float = 1.5                     # airspeed noise (used at airdata_rate_hz)
    airspeed_lag_s: float = 0.0              # pitot-static lag (first order), from the data sheet
    heading_deg: float = 0.5
    baro_m: float = 8.0
    gnss_h_m: float = 5.0
    gnss_v_m: float = 10.0
    gnss_vel_mps: float = 0.3
    radar_range_m: float = 50.0
    radar_azimuth_deg: float = 0.25
    radar_elevation_deg: float = 0.3
    endpoint_h_m: float = 1500.0             # lift-off / touchdown point vs airfield reference
    endpoint_v_m: float = 30.0
    touchdown_m: float = 400.0               # touchdown distance past the runway threshold
    touchdown_sd_m: float = 150.0            # its dispersion
    roll_start_sd_m: float = 100.0           # start of the take-off roll vs the threshold
    ground_mps: float = 0.5                  # zero vertical and cross-track velocity on ground
    runway_halfwidth_m: float = 25.0         # cross-track offset from the runway centreline
    doppler_gs_mps: float = 0.5              # Doppler ground-speed noise (used at airdata rate)
    drift_deg: float = 0.3                   # drift-angle noise
    doppler_scale: float = 0.02              # prior of the Doppler scale error
    drift_bias_deg: float = 1.0              # prior of the drift-angle bias
    wind_sensor_mps: float = 4.0             # recorded / forecast wind, per component
    init_pos_m: float = 3000.0
    init_vel_mps: float = 30.0

    def __post_init__(self) -> None:
        for name in POSITIVE_NOISE:
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise ValueError(f"joint noise setting '{name}' must be a positive number "
                                 f"(it is a measurement's standard deviation or a time "
                                 f"constant), got {v!r}")


POSITIVE_NOISE = ("accel_bias_tau_s", "tas_mps", "heading_deg", "baro_m", "gnss_h_m", "gnss_v_m",
                  "gnss_vel_mps", "radar_range_m", "radar_azimuth_deg", "radar_elevation_deg",
                  "endpoint_h_m", "endpoint_v_m", "touchdown_sd_m", "roll_start_sd_m",
                  "ground_mps", "runway_halfwidth_m", "doppler_gs_mps", "drift_deg",
                  "wind_sensor_mps")
"""JointNoise fields that must be positive (a zero would be a measurement without noise)."""


@dataclass(frozen=True)
class JointSettings:
    """Settings of the joint smoother."""

    noise: JointNoise = field(default_factory=JointNoise)
    state_rate_hz: float = 1.0
    airdata_rate_hz: float = 1.0
    baro_rate_hz: float = 1.0
    wind_rate_hz: float = 1.0 / 1800.0       # recorded wind: errors correlated over ~15 min
    ground_rate_hz: float = 1.0
    min_airspeed_mps: float = 30.0
    crab_s: float = 10.0                     # no air-data heading this close to the runway
    iterations: int = 12                     # cap on the Gauss-Newton passes
    converge_m: float = 2.0                  # nominal shift below which the linearisation holds
    converge_weight: float = 0.01            # largest weight change that counts as settled
    huber_c: float = 3.0
    innovation_gate: float = 5.0
    reject_c: float = 8.0
    robust: bool = True
    estimate_clock: bool = True
    estimate_noise: bool = False
    noise_iterations: int = 30               # cap on the EM iterations with estimate_noise
    noise_tol: float = 0.01                  # EM stops when no variance moves by more
    noise_factor_bounds: tuple[float, float] = (0.01, 100.0)  # EM variance factors kept inside


@dataclass(frozen=True)
class Measurements:
    """Scalar measurements sorted by state step (see joint_kernels for the types).

    Only the ``LINEAR`` measurements have a row of H: ``H[hrow[j]]`` (``hrow`` is -1 for the
    others), so the table stays small when most measurements are nonlinear scalars.
    """

    step: np.ndarray
    source: np.ndarray      # index into SOURCES
    mtype: np.ndarray
    z: np.ndarray
    r: np.ndarray
    t: np.ndarray           # measurement time, recorder time base
    H: np.ndarray           # (M_linear, n)
    hrow: np.ndarray        # (M,) row of H, -1 where the measurement has none
    d: np.ndarray
    start: np.ndarray       # (N+1,)


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
    clock_offsets_s: dict[str, tuple[float, float]]
    noise_scale: dict[str, float]
    iterations: list[dict[str, Any]]
    end_points: list[dict[str, Any]]   # as used in the last pass (end_points)
    roll: TakeoffRoll                  # the take-off roll of the last pass (refined_roll)
    noise_check: dict[str, Any] | None = None   # estimate_noise: the likelihood check


def enu_to_ecef_matrix(lat_deg: float, lon_deg: float) -> np.ndarray:
    """(3, 3) rotation whose columns are the east, north, up unit vectors in ECEF."""
    C = ned_to_ecef_matrix(lat_deg, lon_deg)[0]
    return np.column_stack([C[:, 1], C[:, 0], -C[:, 2]])


@dataclass(frozen=True)
class TakeoffRoll:
    """The take-off roll found in the recorded data (:func:`takeoff_roll`).

    Attributes
    ----------
    start_t : start of the roll [s], NaN where not found
    rest_t : (first, last) time [s] of the rest before it (the aircraft lined up), NaN each where
        the aircraft was not seen at rest
    """

    start_t: float = np.nan
    rest_t: tuple[float, float] = (np.nan, np.nan)


@dataclass(frozen=True)
class JointInputs:
    """Everything the smoother needs, in SI, on the state grid / at measurement times.

    Attributes
    ----------
    t_in : input grid times (Ni,)
    acc_ned : measured kinematic acceleration on the input grid (Ni, 3), NaN where missing
    Cnb : body-to-NED rotations on the input grid (Ni, 3, 3)
    tas, heading_rad : airspeed and (unwrapped) true heading on the input grid
    baro_rel_m : pressure altitude minus the departure field's pressure altitude (input grid)
    gnss : DataFrame t_s, lat_deg, lon_deg, h_m (ellipsoidal; NaN: a horizontal-only fix),
        vn_mps, ve_mps, optionally h_sd_m, v_sd_m, vel_sd_mps (per-fix sd) (may be empty)
    radar : DataFrame t_s, range_m, azimuth_rad, elevation_rad (NaN if absent) (may be empty)
    station : (lat, lon, h_ellipsoidal) or None
    departure, arrival : (lat, lon, h_ellipsoidal) or None
    liftoff_t, touchdown_t : NaN where not in the record
    field_h : ellipsoidal height of the departure field (reference of baro_rel_m)
    lever_arm : GNSS antenna in body FRD [m]
    wind_ne : recorded wind (Ni, 2) where the air moves to, or None
    doppler_gs, drift_rad : Doppler ground speed [m/s] and drift angle [rad] (Ni,), or None
    f_body_g : measured specific force in body FRD axes [n_long, n_lat, -n_norm] (Ni, 3) [g]
    runway_rad : true directions of the departure and arrival runways [rad], ``None`` each
        where unknown
    thresholds : (lat, lon, h_ellipsoidal) of the departure and arrival runway thresholds,
        ``None`` each where unknown (used only with the runway's direction)
    roll : the take-off roll and the rest before it (:func:`takeoff_roll`)
    lineup_t : when the aircraft lined up on the take-off runway (cleaning phases); nothing
        before it is taken as at rest on the runway (NaN: no limit)
    """

    t_in: np.ndarray
    acc_ned: np.ndarray
    Cnb: np.ndarray
    tas: np.ndarray
    heading_rad: np.ndarray
    baro_rel_m: np.ndarray
    gnss: pd.DataFrame
    radar: pd.DataFrame
    station: tuple[float, float, float] | None
    departure: tuple[float, float, float] | None
    arrival: tuple[float, float, float] | None
    liftoff_t: float
    touchdown_t: float
    field_h: float
    lever_arm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    wind_ne: np.ndarray | None = None
    doppler_gs: np.ndarray | None = None
    drift_rad: np.ndarray | None = None
    f_body_g: np.ndarray | None = None
    runway_rad: tuple[float | None, float | None] = (None, None)
    thresholds: tuple[tuple[float, float, float] | None,
                      tuple[float, float, float] | None] = (None, None)
    roll: TakeoffRoll = field(default_factory=TakeoffRoll)
    lineup_t: float = np.nan


def takeoff_roll(t_in: np.ndarray, acc_ned: np.ndarray, heading_rad: np.ndarray,
                 tas: np.ndarray, liftoff_t: float, wind_ne: np.ndarray | None = None,
                 rest_mps: float = 3.0, max_rolling_mps: float = 10.0,
                 settle_s: float = 10.0, v_lo_mps: float | None = None,
                 accel_bias_mps2: float = 0.0, not_before_t: float = np.nan) -> TakeoffRoll:
    """Start of the take-off roll, and the rest before it, from the recorded data alone.

    The ground speed is integrated backwards from lift-off, v(t) = v_lo - int_t^t_lo a dt,
    with a the measured kinematic acceleration along the recorded heading and v_lo the
    along-track ground speed at lift-off: ``v_lo_mps`` where given (the smoother passes its
    smoothed velocity), else the recorded airspeed minus the recorded head wind (where
    given).  The roll starts at the last sample with v <= ``rest_mps``; a record whose aircraft
    never slows that much (a rolling take-off from the taxiway) starts it at the end of the
    slowest stretch, if that is below ``max_rolling_mps``.  A speed error dv moves the time by
    dv / a but the position only by about v dv / a (metres: the aircraft is slow there).  The
    rest is the stretch of v <= ``rest_mps`` that ends at the roll start, less its last
    ``settle_s`` (the first metres of the roll, where the detection lags).
    ``accel_bias_mps2`` is subtracted from the along-track acceleration (the accelerometer's
    forward bias, once the smoother has estimated it: 0.003 g is 1.8 m/s over a minute's rest).
    ``not_before_t`` (the line-up on the runway, from the cleaning's phases): the search and the
    rest stretch start there, so taxiing from the gate is never taken as the roll or the rest.

    Returns
    -------
    TakeoffRoll
        NaN times where the record has no ground roll or no rest is found.
    """
    if not np.isfinite(liftoff_t):
        return TakeoffRoll()
    i_lo = int(np.searchsorted(t_in, liftoff_t)) - 1
    if i_lo < 1 or not np.isfinite(tas[i_lo]):
        return TakeoffRoll()
    psi = np.where(np.isfinite(heading_rad[:i_lo + 1]), heading_rad[:i_lo + 1], 0.0)
    a = acc_ned[:i_lo + 1, 0] * np.cos(psi) + acc_ned[:i_lo + 1, 1] * np.sin(psi)
    a = np.where(np.isfinite(a), a, 0.0) - accel_bias_mps2
    if v_lo_mps is not None:
        v_lo = float(v_lo_mps)
    else:
        v_lo = float(tas[i_lo])
        if wind_ne is not None and np.all(np.isfinite(wind_ne[i_lo])):
            v_lo += float(wind_ne[i_lo, 0] * np.cos(psi[i_lo])
                          + wind_ne[i_lo, 1] * np.sin(psi[i_lo]))
    dv = 0.5 * (a[1:] + a[:-1]) * np.diff(t_in[:i_lo + 1])   # speed gained over each interval
    v = v_lo - np.r_[np.cumsum(dv[::-1])[::-1], 0.0]
    if np.isfinite(not_before_t):
        v = np.where(t_in[:i_lo + 1] >= not_before_t, v, np.inf)   # taxi: never at rest here
    slow = v <= rest_mps
    if not slow.any():
        if not np.isfinite(v.min()):
            return TakeoffRoll()
        # the end of the slowest stretch (within 0.5 m/s of the minimum)
        i_min = int(np.flatnonzero(v <= v.min() + 0.5)[-1])
        return TakeoffRoll(float(t_in[i_min]) if v.min() <= max_rolling_mps else np.nan)
    i_start = int(np.flatnonzero(slow)[-1])
    fast = np.flatnonzero(~slow[:i_start + 1])
    i_rest = int(fast[-1]) + 1 if len(fast) else 0
    t_end = t_in[i_start] - settle_s
    rest = (float(t_in[i_rest]), float(t_end)) if t_end > t_in[i_rest] else (np.nan, np.nan)
    return TakeoffRoll(float(t_in[i_start]), rest)


def refined_roll(inp: JointInputs, T: np.ndarray, vnom: np.ndarray | None,
                 accel_bias_g: np.ndarray | None = None) -> TakeoffRoll:
    """:func:`takeoff_roll` with the along-track component of the nominal (smoothed) ground
    velocity ``vnom`` (N, 3) at lift-off on the state grid ``T`` as the lift-off speed, and the
    smoothed forward accelerometer bias ``accel_bias_g`` (N, 3) [g] at lift-off removed from
    the acceleration; ``inp.roll`` without a nominal or without a roll."""
    roll = inp.roll
    if vnom is None or not np.isfinite(roll.start_t) or not np.isfinite(inp.liftoff_t):
        return roll
    t_in = inp.t_in
    k_lo = int(_nearest(T, np.array([inp.liftoff_t]))[0])
    psi_lo = inp.heading_rad[max(int(np.searchsorted(t_in, inp.liftoff_t)) - 1, 0)]
    if not np.isfinite(psi_lo):
        return roll
    bias = 0.0 if accel_bias_g is None else G0_MPS2 * float(accel_bias_g[k_lo, 0])
    return takeoff_roll(t_in, inp.acc_ned, inp.heading_rad, inp.tas, inp.liftoff_t,
                        v_lo_mps=float(vnom[k_lo, 0] * np.cos(psi_lo)
                                       + vnom[k_lo, 1] * np.sin(psi_lo)),
                        accel_bias_mps2=bias, not_before_t=inp.lineup_t)


def _along_runway_point(thr: tuple[float, float, float], runway_rad: float,
                        dist_m: float) -> tuple[float, float, float]:
    """(lat, lon, h) ``dist_m`` down the runway from its threshold ``thr``."""
    lat, lon = offset_latlon(thr[0], thr[1], dist_m * np.cos(runway_rad),
                             dist_m * np.sin(runway_rad))
    return lat, lon, float(thr[2])


def end_points(inp: JointInputs, nz: JointNoise,
               roll: TakeoffRoll | None = None) -> list[dict[str, Any]]:
    """The end-point constraints: where and when the record is tied to its airfields.

    With a runway's threshold and direction known: the take-off roll starts at the departure
    threshold (along-runway sd ``roll_start_sd_m``; the time from :func:`takeoff_roll`), and
    the touchdown is ``touchdown_m`` past the arrival threshold (sd ``touchdown_sd_m``); across
    the runway the centreline holds (``runway_halfwidth_m``). Otherwise the airfield reference
    point at lift-off / touchdown (or the first / last sample), ``endpoint_h_m`` in every
    horizontal direction. Vertically the airfield elevation, ``endpoint_v_m``.  ``roll``
    replaces ``inp.roll`` (the smoother refines it with its smoothed lift-off speed).

    Returns
    -------
    list of dict
        Keys ``which`` ("departure" / "arrival"), ``model`` ("runway" / "reference"),
        ``t_s``, ``point`` (lat, lon, h_ellipsoidal: the constrained point's mean), ``runway_rad``
        and ``sd_m`` (along, cross, vertical) for the runway model, (h, h, v) otherwise.
    """
    out = []
    t_in = inp.t_in
    for which, pos, thr, rw in (("departure", inp.departure, inp.thresholds[0], inp.runway_rad[0]),
                                ("arrival", inp.arrival, inp.thresholds[1], inp.runway_rad[1])):
        if pos is None:
            continue
        t_run = (inp.roll if roll is None else roll).start_t if which == "departure" \
            else inp.touchdown_t
        if thr is not None and rw is not None and np.isfinite(t_run):
            dist, sd = ((0.0, nz.roll_start_sd_m) if which == "departure"
                        else (nz.touchdown_m, nz.touchdown_sd_m))
            out.append({"which": which, "model": "runway", "t_s": float(t_run),
                        "point": _along_runway_point(thr, rw, dist), "runway_rad": float(rw),
                        "sd_m": (sd, nz.runway_halfwidth_m, nz.endpoint_v_m)})
            continue
        if which == "departure":
            tt = inp.liftoff_t if np.isfinite(inp.liftoff_t) else t_in[0]
        else:
            tt = inp.touchdown_t if np.isfinite(inp.touchdown_t) else t_in[-1]
        out.append({"which": which, "model": "reference", "t_s": float(tt), "point": tuple(pos),
                    "runway_rad": None,
                    "sd_m": (nz.endpoint_h_m, nz.endpoint_h_m, nz.endpoint_v_m)})
    return out


def _state_grid(t_in: np.ndarray, rate_hz: float) -> np.ndarray:
    """Indices of the input grid that are state steps (every ``stride``-th sample, and the last)."""
    dt_in = float(np.median(np.diff(t_in))) if len(t_in) > 1 else 1.0
    stride = max(1, int(round(1.0 / (rate_hz * dt_in))))
    idx = np.arange(0, len(t_in), stride)
    if idx[-1] != len(t_in) - 1:
        idx = np.append(idx, len(t_in) - 1)
    return idx


def _increments(t_in, acc, idx):
    """Exact velocity and position increments over each state step for held accelerations.

    Over step k (from t_in[idx[k-1]] to t_in[idx[k]]) with accelerations a_i held on
    [t_i, t_{i+1}): dV = sum a_i d_i, dP = sum a_i d_i (T_k - t_i - d_i / 2).
    """
    Ni = len(t_in)
    d = np.diff(t_in, append=t_in[-1])  # hold of sample i; the last sample holds for 0 s
    a = np.where(np.isfinite(acc), acc, 0.0)
    missing = (~np.isfinite(acc)).any(axis=1).astype(float)
    step_of = np.searchsorted(idx, np.arange(Ni), side="right")  # sample i belongs to step k
    N = len(idx)
    T = t_in[idx]
    Tk = T[np.minimum(step_of, N - 1)]
    w_p = d * (Tk - t_in - d / 2.0)
    dV = np.zeros((N, 3))
    dP = np.zeros((N, 3))
    miss = np.zeros(N)
    valid = step_of < N
    for j in range(3):
        dV[:, j] = np.bincount(step_of[valid], weights=(a[:, j] * d)[valid], minlength=N)[:N]
        dP[:, j] = np.bincount(step_of[valid], weights=(a[:, j] * w_p)[valid], minlength=N)[:N]
    miss = np.bincount(step_of[valid], weights=(missing * d)[valid], minlength=N)[:N]
    return dV, dP, miss


def attitude_jacobian(Cnb: np.ndarray, f_body: np.ndarray) -> np.ndarray:
    """Derivatives of the rotated specific force C_nb f with respect to roll and pitch.

    For C_nb = R_z(psi) R_y(theta) R_x(phi): dC/dphi f = C_nb (e_x x f) and
    dC/dtheta f = R_z R_y (e_y x R_x f) = C_nb (u x f) with u = R_x^T e_y = (0, cos phi,
    -sin phi); phi = atan2(C_32, C_33).  Returns (N, 3, 2): columns roll, pitch (per radian,
    in the units of ``f_body``).
    """
    phi = np.arctan2(Cnb[:, 2, 1], Cnb[:, 2, 2])
    ex = np.zeros_like(f_body)
    ex[:, 1], ex[:, 2] = -f_body[:, 2], f_body[:, 1]
    u = np.c_[np.zeros(len(phi)), np.cos(phi), -np.sin(phi)]
    out = np.empty((len(phi), 3, 2))
    out[:, :, 0] = np.einsum("kij,kj->ki", Cnb, ex)
    out[:, :, 1] = np.einsum("kij,kj->ki", Cnb, np.cross(u, f_body))
    return out


@nb.njit(cache=True, nogil=True)
def _attitude_step_means(Cnb, fb, idx):
    """Step means of C_nb, C_nb diag(f) and :func:`attitude_jacobian` in one pass over the
    input samples, without the per-sample intermediate arrays: over the samples i with
    idx[k-1] <= i < idx[k] (held over step k), the sample idx[0] itself for the first step."""
    N = idx.shape[0]
    Ni = Cnb.shape[0]
    C_m = np.zeros((N, 3, 3))
    S_m = np.zeros((N, 3, 3))
    J_m = np.zeros((N, 3, 2))
    for k in range(N):
        a = idx[k - 1] if k > 0 else idx[0]
        b = idx[k] if k > 0 else min(idx[0] + 1, Ni)
        cnt = b - a
        for i in range(a, b):
            f0, f1, f2 = fb[i, 0], fb[i, 1], fb[i, 2]
            phi = np.arctan2(Cnb[i, 2, 1], Cnb[i, 2, 2])
            uy, uz = np.cos(phi), -np.sin(phi)
            # e_x x f = (0, -f2, f1); u x f = (uy f2 - uz f1, uz f0, -uy f0)
            r0, r1, r2 = 0.0, -f2, f1
            p0, p1, p2 = uy * f2 - uz * f1, uz * f0, -uy * f0
            for r in range(3):
                c0, c1, c2 = Cnb[i, r, 0], Cnb[i, r, 1], Cnb[i, r, 2]
                C_m[k, r, 0] += c0
                C_m[k, r, 1] += c1
                C_m[k, r, 2] += c2
                S_m[k, r, 0] += c0 * f0
                S_m[k, r, 1] += c1 * f1
                S_m[k, r, 2] += c2 * f2
                J_m[k, r, 0] += c0 * r0 + c1 * r1 + c2 * r2
                J_m[k, r, 1] += c0 * p0 + c1 * p1 + c2 * p2
        if cnt > 0:
            C_m[k] /= cnt
            S_m[k] /= cnt
            J_m[k] /= cnt
    return C_m, S_m, J_m


def _nearest(t: np.ndarray, tq: np.ndarray) -> np.ndarray:
    """Index of the sample of sorted ``t`` nearest to each of ``tq`` (a tie goes to the later
    sample); the state step of a measurement, the input sample of a fix."""
    j = np.clip(np.searchsorted(t, tq), 0, len(t) - 1)
    p = np.clip(j - 1, 0, len(t) - 1)
    return np.where(np.abs(tq - t[p]) < np.abs(tq - t[j]), p, j)


def _decimate_mask(t: np.ndarray, rate_hz: float, origin: float | None = None) -> np.ndarray:
    """True for the first sample of each 1/rate_hz bin, bins counted from ``origin`` (default
    the first sample) (keeps each measurement used once)."""
    if rate_hz <= 0:
        return np.zeros(len(t), bool)
    b = np.floor((t - (t[0] if origin is None else origin)) * rate_hz + 1e-9).astype(np.int64)
    keep = np.ones(len(t), bool)
    keep[1:] = b[1:] != b[:-1]
    return keep


def _per_fix(g: pd.DataFrame, column: str, default: float) -> np.ndarray:
    """Per-fix standard deviations from ``column`` of the GNSS table (the receiver's own
    accuracy figures), ``default`` where absent or not finite."""
    if column not in g.columns:
        return np.full(len(g), float(default))
    v = g[column].to_numpy(float)
    return np.where(np.isfinite(v) & (v > 0), v, float(default))


class _MeasBuilder:
    def __init__(self, T: np.ndarray, n: int = jk.N_STATE):
        self.T = T
        self.n = n
        self.parts: list[dict[str, np.ndarray]] = []
        self.H: list[np.ndarray] = []
        self.n_rows = 0

    def copy(self) -> _MeasBuilder:
        b = _MeasBuilder(self.T, self.n)
        b.parts = list(self.parts)
        b.H = list(self.H)
        b.n_rows = self.n_rows
        return b

    def add(self, source: str, mtype: int, t, z, r, H=None, d=None):
        t = np.asarray(t, float)
        z = np.asarray(z, float)
        m = len(t)
        if m == 0:
            return
        r = np.broadcast_to(np.asarray(r, float), (m,)).copy()
        dm = np.zeros(m) if d is None else np.broadcast_to(np.asarray(d, float), (m,)).copy()
        ok = np.isfinite(z) & np.isfinite(t) & np.isfinite(r) & np.isfinite(dm)
        hrow = np.full(m, -1, dtype=np.int64)
        if H is not None:
            Hm = np.asarray(H, float)
            ok &= np.isfinite(Hm).all(axis=1)
            hrow = self.n_rows + np.arange(m)
            self.H.append(Hm)
            self.n_rows += m
        self.parts.append({"source": np.full(m, SOURCES.index(source)), "mtype": np.full(m, mtype),
                           "t": t, "z": z, "r": r, "hrow": hrow, "d": dm, "ok": ok})

    def build(self) -> Measurements:
        T = self.T
        N = len(T)
        keys = ("source", "mtype", "t", "z", "r", "hrow", "d", "ok")
        cat = {k: np.concatenate([p[k] for p in self.parts]) if self.parts else np.zeros(0)
               for k in keys}
        H = np.concatenate(self.H) if self.H else np.zeros((0, self.n))
        ok = cat["ok"].astype(bool) & (cat["t"] >= T[0] - 0.5 * (T[1] - T[0] if N > 1 else 1)) & (
            cat["t"] <= T[-1] + 0.5 * (T[-1] - T[-2] if N > 1 else 1))
        t = cat["t"][ok]
        step = _nearest(T, t)
        order = np.flatnonzero(ok)[np.lexsort((t, step))]
        step = np.sort(step, kind="stable")
        start = np.searchsorted(step, np.arange(N + 1), side="left")
        return Measurements(step=step.astype(np.int64),
                            source=cat["source"][order].astype(np.int64),
                            mtype=cat["mtype"][order].astype(np.int64), z=cat["z"][order],
                            r=cat["r"][order], t=cat["t"][order], H=np.ascontiguousarray(H),
                            hrow=cat["hrow"][order].astype(np.int64), d=cat["d"][order],
                            start=start.astype(np.int64))


def _on_ground_mask(inp: JointInputs, settings: JointSettings) -> np.ndarray:
    """Input samples used for the ground constraints: before lift-off and after touchdown (2 s
    margins), at the ground-constraint rate, with a heading."""
    t_in = inp.t_in
    on_ground = np.zeros(len(t_in), bool)
    if np.isfinite(inp.liftoff_t):
        on_ground |= t_in < inp.liftoff_t - 2.0
    if np.isfinite(inp.touchdown_t):
        on_ground |= t_in > inp.touchdown_t + 2.0
    return on_ground & _decimate_mask(t_in, settings.ground_rate_hz) & np.isfinite(inp.heading_rad)


def _runway_measurements(b: _MeasBuilder, inp: JointInputs, settings: JointSettings,
                         step_of, pnom: np.ndarray, vnom: np.ndarray,
                         psi_hat: np.ndarray | None = None) -> None:
    """Rolling on the runway: zero cross-track velocity, and zero cross-track offset from the
    centreline through the airfield reference point.

    The runway's direction is the airfield's ``runway_true_deg`` where the metadata give it
    (then the ground roll ties the heading reference: the recorded heading minus the heading
    bias must follow the runway). Otherwise it is the true heading, psi_rec - dpsi (the recorded
    heading carries the heading bias): c(psi_rec - dpsi) . v ~ c(psi_rec) . v + dpsi
    a(psi_rec) . v_nom, with c and a the cross- and along-runway unit vectors, linearised at
    dpsi = 0 and the nominal (the neglected term is dpsi^2 / 2 of the along-track value: 3 mm/s
    at 1 deg and 70 m/s). Taking the recorded heading as the runway's direction would tell the
    smoother that the heading bias is zero. ``psi_hat`` (per state step) is the heading bias
    of the last pass: the linearisation is about it, c(psi_rec - dpsi) . v ~ c(psi') . v +
    (dpsi - psi_hat) a(psi') . v_nom with psi' = psi_rec - psi_hat (exact at the solution
    however large the bias).
    """
    nz = settings.noise
    n = jk.N_STATE
    t_in = inp.t_in
    keep = _on_ground_mask(inp, settings)
    if not keep.any():
        return
    for pos, side, rw in ((inp.departure, t_in < (inp.liftoff_t if np.isfinite(inp.liftoff_t)
                                                   else -np.inf), inp.runway_rad[0]),
                          (inp.arrival, t_in > (inp.touchdown_t if np.isfinite(inp.touchdown_t)
                                                else np.inf), inp.runway_rad[1])):
        sel = keep & side
        if not sel.any():
            continue
        known = rw is not None
        # the direction of the runway (only its line matters: a reversed direction is the same)
        tt = t_in[sel]
        k = step_of(tt)
        ph = np.zeros(len(tt)) if known or psi_hat is None else psi_hat[k]
        psi = np.full(int(sel.sum()), rw) if known else inp.heading_rad[sel] - ph
        H = np.zeros((len(tt), n))
        H[:, jk.IV] = -np.sin(psi)
        H[:, jk.IV + 1] = np.cos(psi)
        if not known:
            H[:, jk.IPSI] = np.cos(psi) * vnom[k, 0] + np.sin(psi) * vnom[k, 1]
        b.add("ground", jk.LINEAR, tt, np.zeros(len(tt)), nz.ground_mps ** 2, H,
              -H[:, jk.IPSI] * ph)
        if pos is None:
            continue
        ex, ey, ez = geodetic_to_ecef(pos[0], pos[1], pos[2])
        arp = np.array([float(ex), float(ey), float(ez)])
        Ca = ned_to_ecef_matrix(pos[0], pos[1])[0]
        cross = np.c_[-np.sin(psi), np.cos(psi), np.zeros(len(psi))] @ Ca.T  # (m, 3) in ECEF
        along = np.c_[np.cos(psi), np.sin(psi), np.zeros(len(psi))] @ Ca.T
        H = np.zeros((len(tt), n))
        H[:, jk.IP:jk.IP + 3] = cross
        if not known:
            H[:, jk.IPSI] = np.einsum("mj,mj->m", along, pnom[k] - arp)
        b.add("runway", jk.LINEAR, tt, np.zeros(len(tt)), nz.runway_halfwidth_m ** 2, H,
              -cross @ arp - H[:, jk.IPSI] * ph)


def static_measurements(inp: JointInputs, settings: JointSettings, T: np.ndarray) -> _MeasBuilder:
    """The measurements that do not change between Gauss-Newton iterations: air data, Doppler,
    recorded wind, pressure altitude, ground and runway constraints (built once)."""
    nz = settings.noise
    b = _MeasBuilder(T)
    n = jk.N_STATE
    t_in = inp.t_in

    # air data: airspeed and heading, decimated, airborne speeds only
    ok = np.isfinite(inp.tas) & np.isfinite(inp.heading_rad) & (inp.tas >= settings.min_airspeed_mps)
    keep = ok & _decimate_mask(t_in, settings.airdata_rate_hz)
    # a first-order lag delays a ramp by its time constant: the airspeed recorded at t is the
    # airspeed at t - lag; sampled at the state steps plus the lag, so that it is used at a step
    lag = nz.airspeed_lag_s
    keep_tas = ok & _decimate_mask(t_in, settings.airdata_rate_hz, t_in[0] + lag) if lag else keep
    b.add("air", jk.TAS, t_in[keep_tas] - lag, inp.tas[keep_tas], nz.tas_mps ** 2)
    # the heading is the air velocity's direction only in the air: on the runway the nose
    # follows the runway (a crosswind of 5 m/s at 40 m/s is 7 deg), and the crab is taken up
    # within seconds after lift-off and taken out in the flare; none within crab_s of them
    air = keep.copy()
    if np.isfinite(inp.liftoff_t):
        air &= t_in > inp.liftoff_t + settings.crab_s
    if np.isfinite(inp.touchdown_t):
        air &= t_in < inp.touchdown_t - settings.crab_s
    b.add("air", jk.HEADING, t_in[air], inp.heading_rad[air], np.radians(nz.heading_deg) ** 2)
    # Doppler ground speed and drift (track = heading + drift), at the air-data rate
    if inp.doppler_gs is not None:
        okd = np.isfinite(inp.doppler_gs) & (inp.doppler_gs >= settings.min_airspeed_mps)
        okd &= _decimate_mask(t_in, settings.airdata_rate_hz)
        b.add("doppler", jk.DOPPLER, t_in[okd], inp.doppler_gs[okd], nz.doppler_gs_mps ** 2)
        if inp.drift_rad is not None:
            okc = okd & np.isfinite(inp.drift_rad) & np.isfinite(inp.heading_rad)
            b.add("doppler", jk.TRACK, t_in[okc], inp.heading_rad[okc] + inp.drift_rad[okc],
                  np.radians(nz.drift_deg) ** 2 + np.radians(nz.heading_deg) ** 2)
    # recorded (or forecast) wind, sparsely: its errors are correlated over minutes
    if inp.wind_ne is not None:
        okw = np.isfinite(inp.wind_ne).all(axis=1) & _decimate_mask(t_in, settings.wind_rate_hz)
        for i in range(2):
            H = np.zeros((int(okw.sum()), n))
            H[:, jk.IW + i] = 1.0
            b.add("wind", jk.LINEAR, t_in[okw], inp.wind_ne[okw, i], nz.wind_sensor_mps ** 2, H)
    # pressure altitude
    okb = np.isfinite(inp.baro_rel_m) & _decimate_mask(t_in, settings.baro_rate_hz)
    b.add("baro", jk.BARO, t_in[okb], inp.baro_rel_m[okb], nz.baro_m ** 2)
    # on the ground: zero vertical velocity (the cross-track constraints depend on the heading
    # bias and the nominal, see build_measurements)
    keep = _on_ground_mask(inp, settings)
    if keep.any():
        tt = t_in[keep]
        H = np.zeros((len(tt), n))
        H[:, jk.IV + 2] = 1.0
        b.add("ground", jk.LINEAR, tt, np.zeros(len(tt)), nz.ground_mps ** 2, H)
    return b


def build_measurements(inp: JointInputs, settings: JointSettings, T: np.ndarray, Cen: np.ndarray,
                       Cnb_T: np.ndarray, clock: dict[str, float],
                       static: _MeasBuilder | None = None, pnom: np.ndarray | None = None,
                       vnom: np.ndarray | None = None,
                       roll: TakeoffRoll | None = None,
                       psi_hat: np.ndarray | None = None) -> Measurements:
    """Every source as scalar measurements at its own time (recorder time base).

    ``static`` is :func:`static_measurements` (computed here if not given); the GNSS, radar,
    end-point and runway measurements depend on the linearisation (``Cen``, the nominal ECEF
    positions ``pnom`` and NED velocities ``vnom`` on the state grid) and on the clock offsets
    and are rebuilt on each call.  ``roll`` is :func:`refined_roll` (computed here if not
    given); ``psi_hat`` the heading bias of the last pass (per state step), about which the
    ground constraints are linearised.
    """
    nz = settings.noise
    b = (static if static is not None else static_measurements(inp, settings, T)).copy()
    n = jk.N_STATE
    t_in = inp.t_in

    def step_of(t):
        return _nearest(T, t)

    def linear_ned(source, t, comp_vals, sd, kind="pos", ecef=None):
        """NED components of a position (given in ECEF) or a velocity, with tau terms."""
        k = step_of(t)
        tau = t - T[k]
        for i in range(3 if kind == "pos" else 2):
            H = np.zeros((len(t), n))
            if kind == "pos":
                c = Cen[k][:, :, i]                  # NED axis i in ECEF at the step
                H[:, jk.IP:jk.IP + 3] = c
                H[:, jk.IV + i] = tau
                z = np.einsum("mj,mj->m", c, ecef)
            else:
                H[:, jk.IV + i] = 1.0
                z = comp_vals[i]
            b.add(source, jk.LINEAR, t, z, np.broadcast_to(sd[i] ** 2, (len(t),)), H)

    # GNSS
    g = inp.gnss
    if len(g):
        tg = g["t_s"].to_numpy() - clock.get("gnss", 0.0)
        k = step_of(tg)
        hg = g["h_m"].to_numpy(float)
        no_h = ~np.isfinite(hg)
        if no_h.any():
            # a fix without height is used horizontally: its north and east components only,
            # computed at a substitute height (the nominal's, else the field's plus the pressure
            # height); the north/east projection of the fix moves by (angle between the
            # verticals at the fix and at the step) x (height error): under 2e-4 m per m at 1 km
            if pnom is not None:
                h_sub = ecef_to_geodetic(pnom[k, 0], pnom[k, 1], pnom[k, 2])[2]
            else:
                ii = _nearest(t_in, tg)
                h_sub = inp.field_h + np.nan_to_num(inp.baro_rel_m[ii])
            hg = np.where(no_h, h_sub, hg)
        ex, ey, ez = geodetic_to_ecef(g["lat_deg"].to_numpy(), g["lon_deg"].to_numpy(), hg)
        ant = np.c_[ex, ey, ez]
        L = np.asarray(inp.lever_arm, float)
        v_arm = np.zeros((len(tg), 3))
        if np.any(L != 0):
            # attitude at the fix: nearest input sample
            ii = _nearest(t_in, tg)
            arm_ned = np.einsum("mij,j->mi", inp.Cnb[ii], L)
            ant = ant - np.einsum("mij,mj->mi", Cen[k], arm_ned)
            # the antenna's velocity adds d(C_nb L)/dt (0.26 m/s for a 5 m arm at 3 deg/s of
            # yaw): a central difference over +-0.5 s of the recorded attitude (its noise,
            # 0.05 deg at 8 Hz, then adds under 0.01 m/s)
            ip, im = _nearest(t_in, tg + 0.5), _nearest(t_in, tg - 0.5)
            span = np.maximum(t_in[ip] - t_in[im], 1e-9)[:, None]
            v_arm = np.einsum("mij,j->mi", inp.Cnb[ip] - inp.Cnb[im], L) / span
        # per-fix accuracy where the receiver gave it (horizontal sd per axis, vertical sd),
        # else the noise settings; no height: no vertical component
        sd_h = _per_fix(g, "h_sd_m", nz.gnss_h_m)
        sd_v = np.where(no_h, np.nan, _per_fix(g, "v_sd_m", nz.gnss_v_m))
        linear_ned("gnss_pos", tg, None, (sd_h, sd_h, sd_v), "pos", ant)
        if {"vn_mps", "ve_mps"} <= set(g.columns):
            sd_vel = _per_fix(g, "vel_sd_mps", nz.gnss_vel_mps)
            linear_ned("gnss_vel", tg, (g["vn_mps"].to_numpy() - v_arm[:, 0],
                                        g["ve_mps"].to_numpy() - v_arm[:, 1]),
                       (sd_vel, sd_vel), "vel")
    if pnom is not None and vnom is not None:
        _runway_measurements(b, inp, settings, step_of, pnom, vnom, psi_hat)
    # radar
    rd = inp.radar
    if len(rd) and inp.station is not None:
        tr = rd["t_s"].to_numpy() - clock.get("radar", 0.0)
        b.add("radar", jk.RANGE, tr, rd["range_m"].to_numpy(), nz.radar_range_m ** 2)
        b.add("radar", jk.AZIMUTH, tr, rd["azimuth_rad"].to_numpy(),
              np.radians(nz.radar_azimuth_deg) ** 2)
        if "elevation_rad" in rd.columns:
            b.add("radar", jk.ELEVATION, tr, rd["elevation_rad"].to_numpy(),
                  np.radians(nz.radar_elevation_deg) ** 2)
    # the take-off roll, with the smoothed lift-off speed once there is one (the recorded
    # airspeed carries the head wind); at rest before it (lined up): zero north and east velocity
    if roll is None:
        roll = refined_roll(inp, T, vnom)
    r0, r1 = roll.rest_t
    if np.isfinite(r0):
        tt = t_in[_on_ground_mask(inp, settings) & (t_in >= r0) & (t_in <= r1)]
        for i in range(2):
            H = np.zeros((len(tt), n))
            H[:, jk.IV + i] = 1.0
            b.add("ground", jk.LINEAR, tt, np.zeros(len(tt)), nz.ground_mps ** 2, H)
    # end points (end_points): the runway model along / across the runway and vertically,
    # the reference model in north, east, down
    for ep in end_points(inp, nz, roll):
        lat, lon, h = ep["point"]
        pe = np.array(geodetic_to_ecef(lat, lon, h), float).reshape(3)
        tt = np.array([ep["t_s"]])
        if ep["model"] == "reference":
            linear_ned("endpoint", tt, None, ep["sd_m"], "pos", pe[None, :])
            continue
        k = step_of(tt)[0]
        tau = tt[0] - T[k]
        psi = ep["runway_rad"]
        Ca = ned_to_ecef_matrix(lat, lon)[0]
        for u, sd in zip(([np.cos(psi), np.sin(psi), 0.0], [-np.sin(psi), np.cos(psi), 0.0],
                          [0.0, 0.0, 1.0]), ep["sd_m"]):
            u = np.asarray(u)
            H = np.zeros((1, n))
            H[0, jk.IP:jk.IP + 3] = Ca @ u
            H[0, jk.IV:jk.IV + 3] = u * tau
            b.add("endpoint", jk.LINEAR, tt, np.zeros(1), sd ** 2, H, -(Ca @ u) @ pe)
    return b.build()


def _q_vector(nz: JointNoise) -> np.ndarray:
    return np.array([nz.accel_noise_mps2_sqrt_hz ** 2, nz.wind_rw_mps_sqrt_s ** 2,
                     nz.wind_shear_mps_per_sqrt_m ** 2, nz.accel_bias_g ** 2, nz.accel_bias_tau_s,
                     np.radians(nz.heading_bias_rw_deg_sqrt_s) ** 2,
                     nz.baro_offset_rw_m_sqrt_s ** 2,
                     (nz.wind_gradient_rw_per_km_sqrt_s / 1000.0) ** 2])


def _initial(inp: JointInputs, nom_ecef, nz: JointNoise, min_speed: float):
    n = jk.N_STATE
    x0 = np.zeros(n)
    x0[jk.IP:jk.IP + 3] = nom_ecef[0]
    i0 = 0
    v0 = np.zeros(3)
    if np.isfinite(inp.tas[i0]) and inp.tas[i0] >= min_speed:
        v0[:2] = inp.tas[i0] * np.array([np.cos(inp.heading_rad[i0]), np.sin(inp.heading_rad[i0])])
    x0[jk.IV:jk.IV + 3] = v0
    P0 = np.zeros((n, n))
    P0[0:3, 0:3] = np.eye(3) * nz.init_pos_m ** 2
    P0[3:6, 3:6] = np.eye(3) * nz.init_vel_mps ** 2
    P0[6:8, 6:8] = np.eye(2) * nz.wind_prior_mps ** 2
    P0[8:11, 8:11] = np.eye(3) * nz.accel_bias_g ** 2
    P0[jk.IPSI, jk.IPSI] = np.radians(nz.heading_bias_deg) ** 2
    P0[jk.IS, jk.IS] = nz.tas_scale ** 2
    P0[jk.IBH, jk.IBH] = nz.baro_offset_m ** 2
    P0[jk.IC, jk.IC] = nz.baro_scale ** 2
    P0[jk.IDW, jk.IDW] = nz.doppler_scale ** 2
    P0[jk.IDC, jk.IDC] = np.radians(nz.drift_bias_deg) ** 2
    P0[jk.IKS:jk.IKS + 3, jk.IKS:jk.IKS + 3] = np.eye(3) * nz.accel_scale ** 2
    P0[jk.IATT:jk.IATT + 2, jk.IATT:jk.IATT + 2] = np.eye(2) * np.radians(nz.attitude_bias_deg) ** 2
    P0[jk.IG:jk.IG + 2, jk.IG:jk.IG + 2] = np.eye(2) * (nz.wind_gradient_per_km / 1000.0) ** 2
    return x0, P0


def _nominal_trajectory(inp: JointInputs, idx: np.ndarray, nz: JointNoise):
    """Iteration-0 linearisation trajectory on the state grid.

    Air-data dead reckoning (airspeed and heading, plus the recorded wind) integrated on the
    ellipsoid (:func:`flightrecon.geo.navframe.integrate_local_level`, valid on flights of any
    length), heights from pressure altitude; then tied to the data that fix position: to the
    GNSS fixes where there are any (the differences at the fixes, interpolated linearly in time;
    the track between fixes keeps the shape of the dead reckoning), otherwise to the end points
    of :func:`end_points` (started at the departure one; a correction growing linearly from it
    to the arrival one, as the DR+linear baseline).
    Only the starting point of the Gauss-Newton iterations: it decides how many are needed,
    not where they converge.
    """
    from flightrecon.geo.navframe import integrate_local_level

    t = inp.t_in
    tas = np.where(np.isfinite(inp.tas), inp.tas, 0.0)
    psi = np.where(np.isfinite(inp.heading_rad), inp.heading_rad, 0.0)
    vn, ve = tas * np.cos(psi), tas * np.sin(psi)
    if inp.wind_ne is not None:
        w = np.where(np.isfinite(inp.wind_ne), inp.wind_ne, 0.0)
        vn, ve = vn + w[:, 0], ve + w[:, 1]
    g = inp.gnss
    gok = np.zeros(0, bool)
    if len(g):
        gok = (np.isfinite(g["lat_deg"].to_numpy(float)) & np.isfinite(g["lon_deg"].to_numpy(float))
               & np.isfinite(g["t_s"].to_numpy(float)))
    ends = {ep["which"]: ep for ep in end_points(inp, nz)}
    ref, t_ref = None, t[0]
    if "departure" in ends:
        ref, t_ref = ends["departure"]["point"], ends["departure"]["t_s"]
    if ref is None and gok.any():
        i0 = int(np.flatnonzero(gok)[0])
        ref = (float(g["lat_deg"].iloc[i0]), float(g["lon_deg"].iloc[i0]),
               float(np.nan_to_num(g["h_m"].iloc[i0])))
        t_ref = float(g["t_s"].iloc[i0])
    if ref is None:
        ref = inp.station if inp.station is not None else (0.0, 0.0, 0.0)
    # state-grid velocities held over each step (the grid is fine enough for a nominal)
    T = t[idx]
    dts = np.diff(T)
    steps = np.maximum(dts, 1e-9)
    lat, lon, _ = integrate_local_level(ref[0], ref[1], 0.0, vn[idx[:-1]], ve[idx[:-1]], 0.0,
                                        steps) if len(idx) > 1 else (np.array([ref[0]]),
                                                                     np.array([ref[1]]), None)
    # the integration starts at the first sample; the reference holds at t_ref
    k_ref = int(np.clip(np.searchsorted(T, t_ref), 0, len(T) - 1))
    lat = lat - lat[k_ref] + ref[0]
    lon = lon - lon[k_ref] + ref[1]
    baro = np.where(np.isfinite(inp.baro_rel_m), inp.baro_rel_m, 0.0)[idx]
    h = inp.field_h + baro
    if gok.any():
        tg = g["t_s"].to_numpy(float)[gok]
        dlat = g["lat_deg"].to_numpy(float)[gok] - np.interp(tg, T, lat)
        dlon = (g["lon_deg"].to_numpy(float)[gok] - np.interp(tg, T, lon) + 180.0) % 360.0 - 180.0
        lat = lat + np.interp(T, tg, dlat)
        lon = lon + np.interp(T, tg, dlon)
        hg = g["h_m"].to_numpy(float)[gok]
        okh = np.isfinite(hg)
        if okh.any():
            h = h + np.interp(T, tg[okh], hg[okh] - np.interp(tg[okh], T, h))
    elif "arrival" in ends and np.isfinite(inp.touchdown_t):
        t_end, (lat_end, lon_end, _) = ends["arrival"]["t_s"], ends["arrival"]["point"]
        k_end = int(np.clip(np.searchsorted(T, t_end), 0, len(T) - 1))
        dlat = lat_end - lat[k_end]
        dlon = (lon_end - lon[k_end] + 180.0) % 360.0 - 180.0
        frac = np.clip((T - t_ref) / max(t_end - t_ref, 1e-9), 0.0, 1.0)
        lat = lat + frac * dlat
        lon = lon + frac * dlon
    lon = (lon + 180.0) % 360.0 - 180.0
    return lat, lon, h


NOISE_GROUPS = {("air", jk.TAS): "air_tas", ("air", jk.HEADING): "air_heading",
                ("baro", jk.BARO): "baro", ("gnss_pos", jk.LINEAR): "gnss_pos",
                ("gnss_vel", jk.LINEAR): "gnss_vel", ("radar", jk.RANGE): "radar_range",
                ("radar", jk.AZIMUTH): "radar_azimuth", ("radar", jk.ELEVATION): "radar_elevation",
                ("doppler", jk.DOPPLER): "doppler_speed", ("doppler", jk.TRACK): "doppler_track"}
"""Sensor error variances that ``estimate_noise`` scales, one factor per group (the end points,
ground and runway constraints and the sparse recorded wind are priors, not estimated)."""


def relinearised_increments(acc: np.ndarray, dV: np.ndarray, dP: np.ndarray, dt: np.ndarray,
                            psi_hat: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The step accelerations and increments for a transition linearised about the heading
    bias ``psi_hat`` (per step) instead of zero.

    The true increment is R(-dpsi) dV (the bias rotates the measured horizontal acceleration
    about the vertical); about psi_hat it is R(-psi_hat) dV + (dpsi - psi_hat) J R(-psi_hat) dV
    with J u = (u_E, -u_N, 0). The kernels build F[v, dpsi] = J a h (and J a h^2/2 for the
    position) from the acceleration they are given and add the increments, so they are given
    a' = R(-psi_hat) a, dV' = R(-psi_hat) dV - J a' h psi_hat and dP' likewise with h^2/2: the
    state keeps the whole bias, and the transition is exact at the solution, not only for a
    small bias (on recorder data without the runway's direction the bias is nearly
    unobservable and a first-order rotation let it wander by several degrees).
    """
    c, s = np.cos(psi_hat), np.sin(psi_hat)

    def rot(u: np.ndarray) -> np.ndarray:
        return np.c_[u[:, 0] * c + u[:, 1] * s, -u[:, 0] * s + u[:, 1] * c, u[:, 2]]

    a_r = rot(acc)
    ja = np.c_[a_r[:, 1], -a_r[:, 0], np.zeros(len(a_r))]
    dV_r = rot(dV) - ja * (dt * psi_hat)[:, None]
    dP_r = rot(dP) - ja * (0.5 * dt * dt * psi_hat)[:, None]
    return np.ascontiguousarray(a_r), np.ascontiguousarray(dV_r), np.ascontiguousarray(dP_r)


def _noise_groups(meas: Measurements) -> np.ndarray:
    """Index into NOISE_GROUPS of each measurement, -1 where its variance is not estimated."""
    g = np.full(len(meas.z), -1, dtype=np.int64)
    for i, (src, mt) in enumerate(NOISE_GROUPS):
        g[(meas.source == SOURCES.index(src)) & (meas.mtype == mt)] = i
    return g


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
    xlin = np.zeros((0, jk.N_STATE))   # smoothed states of the last pass (measurements' linearisation)
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
            x0, P0 = _initial(inp, pnom, nz, settings.min_airspeed_mps)
        tau = meas.t - T[meas.step]
        if it == 0:  # filter outputs, reused by every pass (allocated and paged in once)
            n = jk.N_STATE
            xf, xp = np.empty((len(T), n)), np.empty((len(T), n))
            # (an empty Pp would have the backward passes recompute the predicted covariances,
            # bit-identical: 139 MB less for 10 h of flight but 0.2-0.3 s more per pass)
            Pf, Pp = np.empty((len(T), n, n)), np.empty((len(T), n, n))
        innov, innov_var, infl = jk.forward(
            xf, Pf, xp, Pp, x0, P0, dt, Cen, Cnb, Csf, Jatt, acc_k, dP_k, dV_k, dz, qv_extra, q, meas.start, meas.mtype,
            meas.z, r, weights, tau, meas.H, meas.hrow, meas.d, pnom, hnom, pst, Cst,
            settings.innovation_gate if settings.robust else 0.0, xlin)
        r_used = r * infl
        # the iterations need the smoothed trajectory only; covariances once, after the last
        kern_args = (dt, Cen, Cnb, Csf, Jatt, acc_k, q, meas.start, meas.mtype, meas.z, r_used, tau,
                     meas.H, meas.hrow, meas.d, pnom, hnom, pst, Cst, dz, qv_extra)
        # EM needs the smoothed covariances in every pass; otherwise the first pass (far from
        # the solution) smooths the states only, the later ones (likely the last) everything
        with_cov = settings.estimate_noise or it > 0
        if settings.estimate_noise:
            xs, Pblk, var, _, res, rate, hph = jk.backward(xf, Pf, xp, Pp, *kern_args, True)
        elif with_cov:
            # the covariance recursion does not need the smoothed states: it runs on a second
            # thread beside the mean pass (the kernels release the GIL)
            cov: dict[str, Any] = {}

            def covariances(*args: Any) -> None:
                try:
                    cov["out"] = jk.backward(*args, False)
                except BaseException as exc:  # re-raised on the calling thread
                    cov["error"] = exc

            worker = threading.Thread(target=covariances, name="joint-covariances",
                                      args=(xf, Pf, xp, Pp, *kern_args))
            worker.start()
            xs, _, res, rate = jk.backward_mean(xf, Pf, xp, Pp, *kern_args)
            worker.join()
            if "error" in cov:
                raise cov["error"]
            _, Pblk, var, *_ = cov["out"]
        else:
            xs, _, res, rate = jk.backward_mean(xf, Pf, xp, Pp, *kern_args)
        # residual in units of the measurement's own (nominal, not inflated) standard deviation
        res_n = res / np.sqrt(r)
        # new nominal: the smoothed trajectory
        lat_new, lon_new, h_new = ecef_to_geodetic(xs[:, 0], xs[:, 1], xs[:, 2])
        shift = float(np.max(np.abs(np.c_[xs[:, 0:3] - pnom])))
        info = {"iteration": it, "max_position_change_m": shift, "roll_start_t_s": roll.start_t}
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
        # clock offsets: residual = -hdot * offset
        if settings.estimate_clock:
            for name, src in (("gnss", ("gnss_pos",)), ("radar", ("radar",))):
                sel = np.isin(meas.source, [SOURCES.index(s) for s in src]) & np.isfinite(rate)
                if sel.sum() < 10:
                    continue
                wv = weights[sel] / r[sel]
                den = np.sum(wv * rate[sel] ** 2)
                if den <= 0:
                    continue
                o = -np.sum(wv * rate[sel] * res[sel]) / den
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
        vnom = xs[:, jk.IV:jk.IV + 3]
        psi_new = np.ascontiguousarray(xs[:, jk.IPSI])
        psi_moved = float(np.max(np.abs(psi_new - (0.0 if psi_hat is None else psi_hat))))
        info["max_heading_bias_change_deg"] = float(np.degrees(psi_moved))
        psi_hat = psi_new
        ba_hat = xs[:, jk.IBA:jk.IBA + 3]
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
        xs, Pblk, var, *_ = jk.backward(xf, Pf, xp, Pp, *kern_args, False)
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
        innov1, innov_var1, infl1 = jk.forward(
            xf1, Pf1, xp1, Pp1, x0, P0, dt, Cen, Cnb, Csf, Jatt, acc_k, dP_k, dV_k, dz, qv_extra,
            q, meas.start, meas.mtype, meas.z, r1, w_before, tau, meas.H, meas.hrow, meas.d,
            pnom, hnom, pst, Cst, settings.innovation_gate if settings.robust else 0.0, xlin)
        # (w_before: the weights the last forward pass ran with)
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
            kern_args = (dt, Cen, Cnb, Csf, Jatt, acc_k, q, meas.start, meas.mtype, meas.z,
                         r_used, tau, meas.H, meas.hrow, meas.d, pnom, hnom, pst, Cst, dz,
                         qv_extra)
            xs, Pblk, var, _, res, rate, hph = jk.backward(xf1, Pf1, xp1, Pp1, *kern_args, True)
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
                    noise_check=noise_check)


def source_report(run: JointRun, flag_fraction: float = 0.01) -> dict[str, Any]:
    """Per source: measurements used, mean squared normalised residual, down-weighted ones
    and their time spans; a source with more than ``flag_fraction`` of its residuals beyond
    5 sigma is flagged inconsistent."""
    out: dict[str, Any] = {}
    m = run.meas
    for s_i, name in enumerate(SOURCES):
        sel = m.source == s_i
        if not sel.any():
            continue
        rn = run.resid_norm[sel]
        w = run.weights[sel]
        t = m.t[sel]
        down = w < 0.999
        big = np.abs(rn) > 5.0
        spans = []
        if big.any():
            tb = np.unique(t[big])
            start = prev = tb[0]
            for ti in tb[1:]:
                if ti - prev > 10.0:
                    spans.append([float(start), float(prev)])
                    start = ti
                prev = ti
            spans.append([float(start), float(prev)])
        innov_ok = np.isfinite(run.innov[sel]) & (run.innov_var[sel] > 0)
        nis = run.innov[sel][innov_ok] ** 2 / run.innov_var[sel][innov_ok]
        out[name] = {"count": int(sel.sum()),
                     "mean_norm_residual_sq": float(np.nanmean(rn ** 2)),
                     "mean_nis": float(np.mean(nis)) if len(nis) else None,
                     "downweighted": int(down.sum()),
                     "beyond_5_sigma": int(big.sum()),
                     "flagged_inconsistent": bool(big.mean() > flag_fraction),
                     "flagged_spans_s": spans[:50]}
    return out
