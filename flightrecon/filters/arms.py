"""ADS/ARMS estimators: ground velocity from range/azimuth plots and the air-data error.

METHODS.md section 2; Vasyliev (2025), seed ``000_92b8f66acbd1b85b.txt``.

Frame: the station's east-north-up tangent plane, ``x`` east, ``y`` north, station at the origin.
Azimuth ``theta`` clockwise from north, ``theta = atan2(x, y)``; ``r`` is the *horizontal* range
(see :func:`horizontal_range`).  SI inside: metres, seconds, radians.

Three forms, each filtered forward and (optionally) smoothed backward with the RTS smoother
(:func:`flightrecon.smoothing.rts.rts_smooth_run`):

* stage 1 (:func:`track_ground_velocity`): constant-velocity (CV) tracker of
  ``X = [x, Vx, y, Vy]`` from the plots at their own times, linearised either as an EKF
  (paper eq. 12) or by converted measurements (paper eqs. 13-15);
* stage 2 (:func:`compensate`): the paper's compensation filter, state ``dV = [dVx, dVy]``
  (first-order Gauss-Markov per axis, paper eq. 4), measurement ``V* - W_hat`` at the plot times;
  :func:`run_cascade` chains the two as in the paper's Fig. 1;
* joint (:func:`run_joint`): one model ``[x, Vx, y, Vy, dVx, dVy]`` with range/azimuth and the
  air-data velocity ``V* = [Vx + dVx, Vy + dVy]`` as measurements, each at its own time: the
  consistent form (METHODS.md section 2, "Two cautions") and the product default.

Discretisations are exact for the step ``T`` taken from the data:
CV per axis ``F = [[1, T], [0, 1]]``, ``Q = q [[T^3/3, T^2/2], [T^2/2, T]]`` (q: acceleration
power spectral density, m^2/s^3); Gauss-Markov ``dV_i = e^{-a T} dV_{i-1} + w_i`` with
``var(w_i) = sigma^2 (1 - e^{-2 a T})`` (METHODS.md section 2: the seed's eq. 9 noise factor is
dimensionally inconsistent and is not used).

The nonlinear measurement update (EKF and converted-at-predicted forms) runs in a numba kernel
(:func:`_arms_kernel`) with the Joseph-form covariance update; the transition is linear, so the
generic RTS smoother applies unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.filters.kalman import FilterRun, joseph_update, kalman_filter, predict
from flightrecon.smoothing.rts import SmootherRun, rts_smooth_run

__all__ = [
    "CONVERTED_AT",
    "LINEARISATIONS",
    "AirData",
    "ArmsEstimate",
    "ArmsModel",
    "CascadeResult",
    "PaperScenario",
    "RadarPlots",
    "compensate",
    "converted_covariance",
    "converted_measurement",
    "cv_process_noise",
    "cv_transition",
    "estimate_of",
    "gm_process_noise",
    "gm_transition",
    "horizontal_range",
    "joint_process_noise",
    "joint_transition",
    "range_azimuth",
    "range_azimuth_jacobian",
    "run_cascade",
    "run_joint",
    "simulate_paper_scenario",
    "track_ground_velocity",
    "wrap_angle",
]

LINEARISATIONS = ("ekf", "converted")
"""Stage-1 / joint radar linearisations: EKF on (range, azimuth) or converted x/y measurements."""

CONVERTED_AT = ("predicted", "measured")
"""Where the converted-measurement covariance is evaluated (range and azimuth of the predicted
state, or the measured ones).  ``predicted`` avoids the correlation between the measurement noise
and its own covariance that ``measured`` introduces (Bar-Shalom, Li & Kirubarajan 2001, sec. 10.4)."""

_LIN_CODE = {("ekf", "predicted"): 0, ("ekf", "measured"): 0,
             ("converted", "measured"): 1, ("converted", "predicted"): 2}

EARTH_RADIUS_M = 6371008.8
"""Mean Earth radius [m], for the drop of the station's tangent plane below the aircraft."""


# --------------------------------------------------------------------------------------------
# data containers
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ArmsModel:
    """Noise model of the ADS/ARMS estimators (SI units).

    Attributes
    ----------
    sigma_range_m : standard deviation of the (horizontal) range error, sigma_rho (paper eq. 11)
    sigma_azimuth_rad : standard deviation of the azimuth error, sigma_theta, in radians
    q_m2ps3 : power spectral density of the CV model's acceleration noise [m^2/s^3]
    gm_sigma_mps : stationary standard deviation of each air-data error axis, sigma (paper eq. 4)
    gm_tau_s : its correlation time 1/alpha [s]
    sigma_air_mps : white noise on each air-data velocity component V* (0 allowed: paper)
    v0_sd_mps : prior standard deviation of each ground-velocity component at the first plot
    """

    sigma_range_m: float = 50.0
    sigma_azimuth_rad: float = float(np.deg2rad(0.25))
    q_m2ps3: float = 0.5
    gm_sigma_mps: float = 20.0
    gm_tau_s: float = 360.0
    sigma_air_mps: float = 0.5
    v0_sd_mps: float = 300.0

    def __post_init__(self) -> None:
        for name in ("sigma_range_m", "sigma_azimuth_rad", "q_m2ps3", "gm_sigma_mps",
                     "gm_tau_s", "v0_sd_mps"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v > 0):
                raise ValidationError(f"ARMS model: {name} must be positive and finite, got {v}")
        if not (np.isfinite(self.sigma_air_mps) and self.sigma_air_mps >= 0):
            raise ValidationError("ARMS model: sigma_air_mps must be >= 0 and finite, "
                                  f"got {self.sigma_air_mps}")

    @property
    def alpha_ps(self) -> float:
        """Inverse correlation time alpha = 1/tau [1/s]."""
        return 1.0 / self.gm_tau_s


@dataclass(frozen=True)
class RadarPlots:
    """Radar plots at their own times, one per row (station frame, SI).

    Attributes
    ----------
    t_s : (N,) plot times, strictly increasing [s]
    range_m : (N,) *horizontal* range r [m] (see :func:`horizontal_range`)
    azimuth_rad : (N,) azimuth, clockwise from true north [rad]
    sigma_range_m : (N,) standard deviation of ``range_m`` per plot [m]
    sigma_azimuth_rad : (N,) standard deviation of the azimuth per plot [rad]
    """

    t_s: np.ndarray
    range_m: np.ndarray
    azimuth_rad: np.ndarray
    sigma_range_m: np.ndarray
    sigma_azimuth_rad: np.ndarray

    @classmethod
    def from_arrays(cls, t_s, range_m, azimuth_rad, model: ArmsModel,
                    sigma_range_m=None) -> RadarPlots:
        """Build and validate plots; the sigmas default to the model's constants."""
        t = np.asarray(t_s, dtype=np.float64)
        r = np.asarray(range_m, dtype=np.float64)
        a = np.asarray(azimuth_rad, dtype=np.float64)
        if t.ndim != 1 or r.shape != t.shape or a.shape != t.shape:
            raise ValidationError("radar plots: t_s, range and azimuth must be 1-D of equal length")
        if len(t) < 2:
            raise ValidationError(f"radar plots: need at least 2 plots, got {len(t)}")
        bad = ~(np.isfinite(t) & np.isfinite(r) & np.isfinite(a))
        if bad.any():
            raise ValidationError("radar plots: non-finite time, range or azimuth",
                                  rows=np.flatnonzero(bad)[:20] + 1)
        if np.any(r <= 0):
            raise ValidationError("radar plots: range must be positive",
                                  rows=np.flatnonzero(r <= 0)[:20] + 1)
        if np.any(np.diff(t) <= 0):
            raise ValidationError("radar plots: times must be strictly increasing",
                                  rows=np.flatnonzero(np.diff(t) <= 0)[:20] + 2)
        sr = (np.full(t.shape, model.sigma_range_m) if sigma_range_m is None
              else np.asarray(sigma_range_m, dtype=np.float64))
        st = np.full(t.shape, model.sigma_azimuth_rad)
        return cls(t, r, a, sr, st)


@dataclass(frozen=True)
class AirData:
    """Air-data velocity V* = (TAS sin heading, TAS cos heading) at its own times (SI).

    Attributes
    ----------
    t_s : (M,) strictly increasing times [s]
    vx_mps, vy_mps : (M,) east and north components [m/s]
    """

    t_s: np.ndarray
    vx_mps: np.ndarray
    vy_mps: np.ndarray

    @classmethod
    def from_tas_heading(cls, t_s, tas_mps, heading_deg) -> AirData:
        """From true airspeed [m/s] and true heading [deg] (paper eq. 6: V* = V + dV)."""
        t = np.asarray(t_s, dtype=np.float64)
        v = np.asarray(tas_mps, dtype=np.float64)
        h = np.deg2rad(np.asarray(heading_deg, dtype=np.float64))
        return cls(t, v * np.sin(h), v * np.cos(h))

    def at(self, t_s: np.ndarray, max_gap_s: float = np.inf) -> np.ndarray:
        """(K, 2) components linearly interpolated to times ``t_s``.

        Air data is an *input* channel on the recorder grid (METHODS.md, "Two kinds of
        channel"), so taking it at a plot's time by interpolation between neighbouring grid
        samples reuses no measurement.  NaN outside the samples and where the two bracketing
        samples are more than ``max_gap_s`` apart (a gap in the air data is not bridged).
        """
        t = np.asarray(t_s, dtype=np.float64)
        out = np.column_stack([np.interp(t, self.t_s, self.vx_mps, left=np.nan, right=np.nan),
                               np.interp(t, self.t_s, self.vy_mps, left=np.nan, right=np.nan)])
        if np.isfinite(max_gap_s) and len(self.t_s) > 1:
            j = np.clip(np.searchsorted(self.t_s, t), 1, len(self.t_s) - 1)
            gap = self.t_s[j] - self.t_s[j - 1]
            exact = (self.t_s[j] == t) | (self.t_s[j - 1] == t)
            out[(gap > max_gap_s) & ~exact] = np.nan
        return out


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
    smooth: SmootherRun | None
    radar_used: np.ndarray


@dataclass(frozen=True)
class Stage2Run:
    """Stage-2 compensation run at the plot times."""

    t_s: np.ndarray
    filt: FilterRun
    smooth: SmootherRun | None


@dataclass(frozen=True)
class JointRun:
    """Joint-model run on the union of plot and air-data times."""

    t_s: np.ndarray
    filt: FilterRun
    smooth: SmootherRun | None
    radar_used: np.ndarray
    air_used: np.ndarray


@dataclass(frozen=True)
class CascadeResult:
    """The paper's cascade: stage 1 then stage 2 (its stage-2 input uses the stage-1 estimate
    of the same kind: filtered into filtered, smoothed into smoothed)."""

    stage1: Stage1Run
    stage2: Stage2Run


# --------------------------------------------------------------------------------------------
# measurement models
# --------------------------------------------------------------------------------------------

def horizontal_range(slant_m, *, elevation_deg=None, dh_m=None,
                     earth_radius_m: float = EARTH_RADIUS_M) -> np.ndarray:
    """Horizontal range in the station's tangent plane from the radar's slant range.

    With the elevation angle: ``r = rho cos(el)`` (METHODS.md section 2).  With the altitude
    difference ``dh`` (aircraft minus station, metres above the same datum): the aircraft's
    height above the station's tangent plane is ``u = dh - r^2 / (2 R_e)`` (the plane drops
    away from the sphere), and ``r`` solves ``r^2 + u^2 = rho^2``; two fixed-point steps from
    ``r0 = sqrt(rho^2 - dh^2)`` converge to well under a metre for ranges below 500 km.
    Refraction is ignored.  Without either, the slant range is returned unchanged.

    Raises
    ------
    ValidationError
        If the altitude difference exceeds the slant range (inconsistent data).
    """
    rho = np.asarray(slant_m, dtype=np.float64)
    if elevation_deg is not None:
        return rho * np.cos(np.deg2rad(np.asarray(elevation_deg, dtype=np.float64)))
    if dh_m is None:
        return rho.copy()
    dh = np.asarray(dh_m, dtype=np.float64)
    r2 = rho ** 2 - dh ** 2
    if np.any(r2 < 0):
        raise ValidationError("radar plots: altitude difference to the station exceeds the slant "
                              "range; check the station elevation and the altitude datum",
                              rows=np.flatnonzero(r2 < 0)[:20] + 1)
    r = np.sqrt(r2)
    for _ in range(2):
        u = dh - r ** 2 / (2.0 * earth_radius_m)
        r = np.sqrt(np.maximum(rho ** 2 - u ** 2, 0.0))
    return r


def range_azimuth(X: np.ndarray) -> np.ndarray:
    """Measurement function h(X) = [sqrt(x^2 + y^2), atan2(x, y)] (paper eq. 10).

    ``X`` is (..., n) with x at index 0 and y at index 2; returns (..., 2).
    """
    X = np.asarray(X, dtype=np.float64)
    return np.stack([np.hypot(X[..., 0], X[..., 2]), np.arctan2(X[..., 0], X[..., 2])], axis=-1)


def range_azimuth_jacobian(X: np.ndarray) -> np.ndarray:
    """Jacobian H = dh/dX (paper eq. 12): ``[[x/r, 0, y/r, 0], [y/r^2, 0, -x/r^2, 0]]``.

    ``X`` is (..., n), n >= 4 (extra states get zero columns); returns (..., 2, n).
    """
    X = np.asarray(X, dtype=np.float64)
    x, y = X[..., 0], X[..., 2]
    r2 = x * x + y * y
    r = np.sqrt(r2)
    H = np.zeros(X.shape[:-1] + (2, X.shape[-1]))
    H[..., 0, 0] = x / r
    H[..., 0, 2] = y / r
    H[..., 1, 0] = y / r2
    H[..., 1, 2] = -x / r2
    return H


def wrap_angle(a):
    """Wrap angles [rad] to (-pi, pi] (used for the azimuth innovation)."""
    a = np.asarray(a, dtype=np.float64)
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


def converted_measurement(range_m, azimuth_rad) -> np.ndarray:
    """Converted measurement ``[x*, y*] = rho* [sin theta*, cos theta*]`` (paper eq. 13), (..., 2)."""
    r = np.asarray(range_m, dtype=np.float64)
    a = np.asarray(azimuth_rad, dtype=np.float64)
    return np.stack([r * np.sin(a), r * np.cos(a)], axis=-1)


def converted_covariance(range_m, azimuth_rad, sigma_range_m, sigma_azimuth_rad) -> np.ndarray:
    """Covariance of the converted measurement error (paper eq. 15, first order), (..., 2, 2).

    ``s_x^2 = s_r^2 sin^2 t + r^2 s_t^2 cos^2 t``, ``s_y^2 = s_r^2 cos^2 t + r^2 s_t^2 sin^2 t``,
    ``s_xy = sin t cos t (s_r^2 - r^2 s_t^2)`` (METHODS.md section 2), evaluated at the range and
    azimuth given (measured or predicted: see :data:`CONVERTED_AT`).
    """
    r = np.asarray(range_m, dtype=np.float64)
    t = np.asarray(azimuth_rad, dtype=np.float64)
    sr2 = np.asarray(sigma_range_m, dtype=np.float64) ** 2
    ct2 = r ** 2 * np.asarray(sigma_azimuth_rad, dtype=np.float64) ** 2
    s, c = np.sin(t), np.cos(t)
    shape = np.broadcast(r, t, sr2, ct2).shape
    R = np.empty(shape + (2, 2))
    R[..., 0, 0] = sr2 * s * s + ct2 * c * c
    R[..., 1, 1] = sr2 * c * c + ct2 * s * s
    R[..., 0, 1] = R[..., 1, 0] = s * c * (sr2 - ct2)
    return R


# --------------------------------------------------------------------------------------------
# transition models (exact discretisation, stacked over steps)
# --------------------------------------------------------------------------------------------

def _check_dt(dt) -> np.ndarray:
    dt = np.asarray(dt, dtype=np.float64)
    if dt.ndim != 1:
        raise ValidationError("time steps must be a 1-D array")
    if np.any(~np.isfinite(dt)) or np.any(dt[1:] <= 0):
        raise ValidationError("time steps must be finite and positive (times strictly increasing)")
    return dt


def cv_transition(dt) -> np.ndarray:
    """CV transition of ``[x, Vx, y, Vy]`` for steps ``dt`` (N,): (N, 4, 4), ``[[1, T], [0, 1]]``
    per axis (``dt[0]``, the step into the first epoch, is not used by the filter)."""
    dt = _check_dt(dt)
    F = np.zeros((len(dt), 4, 4))
    for i in (0, 2):
        F[:, i, i] = 1.0
        F[:, i + 1, i + 1] = 1.0
        F[:, i, i + 1] = dt
    return F


def cv_process_noise(dt, q_m2ps3: float) -> np.ndarray:
    """Exact CV process noise (N, 4, 4): ``q [[T^3/3, T^2/2], [T^2/2, T]]`` per axis
    (white-acceleration model, Bar-Shalom et al. 2001, eq. 6.2.2-12)."""
    dt = _check_dt(dt)
    Q = np.zeros((len(dt), 4, 4))
    for i in (0, 2):
        Q[:, i, i] = q_m2ps3 * dt ** 3 / 3.0
        Q[:, i, i + 1] = Q[:, i + 1, i] = q_m2ps3 * dt ** 2 / 2.0
        Q[:, i + 1, i + 1] = q_m2ps3 * dt
    return Q


def gm_transition(dt, alpha_ps: float) -> np.ndarray:
    """Gauss-Markov transition of ``[dVx, dVy]`` (N, 2, 2): ``e^{-alpha T} I`` (paper eq. 9)."""
    dt = _check_dt(dt)
    return np.exp(-alpha_ps * dt)[:, None, None] * np.eye(2)


def gm_process_noise(dt, alpha_ps: float, sigma_mps: float) -> np.ndarray:
    """Exact Gauss-Markov process noise (N, 2, 2): ``sigma^2 (1 - e^{-2 alpha T}) I``
    (METHODS.md section 2; ``-expm1`` keeps it accurate for small ``alpha T``)."""
    dt = _check_dt(dt)
    return (sigma_mps ** 2 * -np.expm1(-2.0 * alpha_ps * dt))[:, None, None] * np.eye(2)


def joint_transition(dt, alpha_ps: float) -> np.ndarray:
    """Joint transition of ``[x, Vx, y, Vy, dVx, dVy]``: block-diag(CV, GM), (N, 6, 6)."""
    dt = _check_dt(dt)
    F = np.zeros((len(dt), 6, 6))
    for i in range(4):
        F[:, i, i] = 1.0
    F[:, 0, 1] = F[:, 2, 3] = dt
    F[:, 4, 4] = F[:, 5, 5] = np.exp(-alpha_ps * dt)
    return F


def joint_process_noise(dt, q_m2ps3: float, alpha_ps: float, sigma_mps: float) -> np.ndarray:
    """Joint process noise: block-diag(CV, GM), (N, 6, 6)."""
    dt = _check_dt(dt)
    Q = np.zeros((len(dt), 6, 6))
    for i in (0, 2):
        Q[:, i, i] = q_m2ps3 * dt ** 3 / 3.0
        Q[:, i, i + 1] = Q[:, i + 1, i] = q_m2ps3 * dt ** 2 / 2.0
        Q[:, i + 1, i + 1] = q_m2ps3 * dt
    g = sigma_mps ** 2 * -np.expm1(-2.0 * alpha_ps * dt)
    Q[:, 4, 4] = Q[:, 5, 5] = g
    return Q


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

    Paper eqs. 10-15 (METHODS.md section 2, stage 1).  One step per plot, ``T`` from the plot
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
    white, which it is not (METHODS.md section 2, first caution), so this filter's covariance is
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


def run_joint(plots: RadarPlots, air: AirData, model: ArmsModel, *, linearisation: str = "ekf",
              converted_at: str = "predicted", smooth: bool = True,
              extra_times=None) -> JointRun:
    """Joint model ``[x, Vx, y, Vy, dVx, dVy]`` (METHODS.md section 2, product form).

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
    return JointRun(t, run, sm, out[8], out[9])


def _sub(P: np.ndarray, idx: list[int]) -> np.ndarray:
    return P[:, idx][:, :, idx]


def estimate_of(run: CascadeResult | JointRun, *, smoothed: bool = True) -> ArmsEstimate:
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


# --------------------------------------------------------------------------------------------
# the paper's simulation (section "Computer simulation results"), vectorised over runs
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class PaperScenario:
    """Simulated truth and measurements of ``M`` runs on a common 1-s time base (SI, station frame).

    Attributes
    ----------
    t_s : (N,) times
    pos, vel : (M, N, 2) true position [x, y] and ground velocity W
    dv : (M, N, 2) true air-data error (Gauss-Markov)
    range_m, azimuth_rad : (M, N) noisy plots (horizontal range, azimuth)
    air : (M, N, 2) air-data velocity V* = W + dV + white noise
    """

    t_s: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    dv: np.ndarray
    range_m: np.ndarray
    azimuth_rad: np.ndarray
    air: np.ndarray


def simulate_paper_scenario(model: ArmsModel, *, runs: int, duration_s: float = 1800.0,
                            dt_s: float = 1.0, speed_mps: float = 100.0,
                            start_xy_m: tuple[float, float] = (-60e3, 30e3),
                            track_deg: float = 90.0, seed: int = 0) -> PaperScenario:
    """The paper's simulation: nearly straight flight at ``speed_mps``, Gauss-Markov air-data
    error, noisy range/azimuth plots every ``dt_s``.

    The truth follows the filter's own models so that consistency can be tested: ground velocity
    a CV random walk of PSD ``model.q_m2ps3`` (set it small for the paper's straight flight),
    ``dV`` per axis the exact Gauss-Markov recursion started from its stationary distribution,
    plots with ``sigma_range_m``/``sigma_azimuth_rad``, ``V*`` with ``sigma_air_mps`` white noise.
    The paper gives no geometry; ``start_xy_m`` and ``track_deg`` set it (default: 67 km from the
    station, flying east, closest approach 30 km).
    """
    rng = np.random.default_rng(seed)
    N = round(duration_s / dt_s) + 1
    t = np.arange(N) * dt_s
    M = runs
    dt = np.full(N, dt_s)
    Qcv = cv_process_noise(dt[:2], model.q_m2ps3)[1][:2, :2]
    Lcv = np.linalg.cholesky(Qcv)
    Fcv = np.array([[1.0, dt_s], [0.0, 1.0]])
    phi = np.exp(-model.alpha_ps * dt_s)
    sw = model.gm_sigma_mps * np.sqrt(-np.expm1(-2.0 * model.alpha_ps * dt_s))
    trk = np.deg2rad(track_deg)
    pos = np.empty((M, N, 2))
    vel = np.empty((M, N, 2))
    dv = np.empty((M, N, 2))
    # per axis a = 0 (x, east), 1 (y, north)
    s0 = (np.array(start_xy_m), speed_mps * np.array([np.sin(trk), np.cos(trk)]))
    for a in range(2):
        st = np.empty((M, 2))
        st[:, 0] = s0[0][a]
        st[:, 1] = s0[1][a]
        g = model.gm_sigma_mps * rng.standard_normal(M)
        wn = rng.standard_normal((N, M, 2))
        wg = rng.standard_normal((N, M))
        for k in range(N):
            if k > 0:
                st = st @ Fcv.T + wn[k] @ Lcv.T
                g = phi * g + sw * wg[k]
            pos[:, k, a] = st[:, 0]
            vel[:, k, a] = st[:, 1]
            dv[:, k, a] = g
    r_true = np.hypot(pos[..., 0], pos[..., 1])
    az_true = np.arctan2(pos[..., 0], pos[..., 1])
    rng_m = r_true + model.sigma_range_m * rng.standard_normal((M, N))
    az = wrap_angle(az_true + model.sigma_azimuth_rad * rng.standard_normal((M, N)))
    air = vel + dv + model.sigma_air_mps * rng.standard_normal((M, N, 2))
    return PaperScenario(t, pos, vel, dv, rng_m, az, air)
