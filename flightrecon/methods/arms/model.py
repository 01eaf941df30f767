"""ADS/ARMS models: settings and inputs, the range/azimuth measurement (EKF and converted forms),
horizontal range, the exact constant-velocity and Gauss-Markov discretisations, and the track
filter's model on the estimation core (:class:`ArmsTrackModel`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numba as nb
import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.estimation.discretise import (
    check_steps,
    constant_velocity,
    gauss_markov,
)
from flightrecon.estimation.filtering import keep_dense_into
from flightrecon.estimation.model import (
    implements,
    keep_filtered,
    keep_predicted,
    predict_into,
    update_into,
    workspace,
)
from flightrecon.estimation.predict import predict_cov_into
from flightrecon.estimation.updates import joseph_update
from flightrecon.geo.radar import horizontal_range  # noqa: F401  (public here too)

LINEARISATIONS = ("ekf", "converted")
"""Stage-1 / joint radar linearisations: EKF on (range, azimuth) or converted x/y measurements."""


CONVERTED_AT = ("predicted", "measured")
"""Where the converted-measurement covariance is evaluated (range and azimuth of the predicted
state, or the measured ones).  ``predicted`` avoids the correlation between the measurement noise
and its own covariance that ``measured`` introduces (Bar-Shalom, Li & Kirubarajan 2001,
sec. 10.4)."""


_LIN_CODE = {("ekf", "predicted"): 0, ("ekf", "measured"): 0,
             ("converted", "measured"): 1, ("converted", "predicted"): 2}


def linearisation_code(linearisation: str, converted_at: str) -> int:
    """The :class:`ArmsTrackModel`'s ``lin`` of a linearisation (:data:`LINEARISATIONS`) and
    converted-covariance point (:data:`CONVERTED_AT`): 0 EKF, 1 converted at the measured
    range/azimuth, 2 converted at the predicted ones.

    Raises
    ------
    ValidationError
        For a name not among those.
    """
    if linearisation not in LINEARISATIONS:
        raise ValidationError(f"unknown ARMS linearisation '{linearisation}'; choose from "
                              f"{', '.join(LINEARISATIONS)}")
    if converted_at not in CONVERTED_AT:
        raise ValidationError(f"unknown converted-covariance point '{converted_at}'; choose from "
                              f"{', '.join(CONVERTED_AT)}")
    return _LIN_CODE[(linearisation, converted_at)]


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

        Air data is an *input* channel on the recorder grid (docs/schema.md, "Two kinds of
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


# --------------------------------------------------------------------------------------------
# measurement models
# --------------------------------------------------------------------------------------------

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
    """Converted measurement ``[x*, y*] = rho* [sin theta*, cos theta*]`` (paper eq. 13),
    (..., 2)."""
    r = np.asarray(range_m, dtype=np.float64)
    a = np.asarray(azimuth_rad, dtype=np.float64)
    return np.stack([r * np.sin(a), r * np.cos(a)], axis=-1)


def converted_covariance(range_m, azimuth_rad, sigma_range_m, sigma_azimuth_rad) -> np.ndarray:
    """Covariance of the converted measurement error (paper eq. 15, first order), (..., 2, 2).

    ``s_x^2 = s_r^2 sin^2 t + r^2 s_t^2 cos^2 t``, ``s_y^2 = s_r^2 cos^2 t + r^2 s_t^2 sin^2 t``,
    ``s_xy = sin t cos t (s_r^2 - r^2 s_t^2)`` (docs/arms.md), evaluated at the range and
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
    return check_steps(dt)


def cv_transition(dt) -> np.ndarray:
    """CV transition of ``[x, Vx, y, Vy]`` for steps ``dt`` (N,): (N, 4, 4), ``[[1, T], [0, 1]]``
    per axis (:func:`flightrecon.estimation.discretise.constant_velocity`)."""
    F1, _ = constant_velocity(dt, 0.0)
    F = np.zeros((len(F1), 4, 4))
    F[:, 0:2, 0:2] = F[:, 2:4, 2:4] = F1
    return F


def cv_process_noise(dt, q_m2ps3: float) -> np.ndarray:
    """Exact CV process noise (N, 4, 4): ``q [[T^3/3, T^2/2], [T^2/2, T]]`` per axis
    (:func:`flightrecon.estimation.discretise.constant_velocity`)."""
    _, Q1 = constant_velocity(dt, q_m2ps3)
    Q = np.zeros((len(Q1), 4, 4))
    Q[:, 0:2, 0:2] = Q[:, 2:4, 2:4] = Q1
    return Q


def gm_transition(dt, alpha_ps: float) -> np.ndarray:
    """Gauss-Markov transition of ``[dVx, dVy]`` (N, 2, 2): ``e^{-alpha T} I`` (paper eq. 9)."""
    phi, _ = gauss_markov(dt, alpha_ps, 0.0)
    return phi[:, None, None] * np.eye(2)


def gm_process_noise(dt, alpha_ps: float, sigma_mps: float) -> np.ndarray:
    """Exact Gauss-Markov process noise (N, 2, 2): ``sigma^2 (1 - e^{-2 alpha T}) I``
    (:func:`flightrecon.estimation.discretise.gauss_markov`)."""
    _, var = gauss_markov(dt, alpha_ps, sigma_mps)
    return var[:, None, None] * np.eye(2)


def joint_transition(dt, alpha_ps: float) -> np.ndarray:
    """Joint transition of ``[x, Vx, y, Vy, dVx, dVy]``: block-diag(CV, GM), (N, 6, 6)."""
    F = np.zeros((len(np.atleast_1d(dt)), 6, 6))
    F[:, 0:4, 0:4] = cv_transition(dt)
    F[:, 4, 4] = F[:, 5, 5] = gauss_markov(dt, alpha_ps, 0.0)[0]
    return F


def joint_process_noise(dt, q_m2ps3: float, alpha_ps: float, sigma_mps: float) -> np.ndarray:
    """Joint process noise: block-diag(CV, GM), (N, 6, 6)."""
    Q = np.zeros((len(np.atleast_1d(dt)), 6, 6))
    Q[:, 0:4, 0:4] = cv_process_noise(dt, q_m2ps3)
    Q[:, 4, 4] = Q[:, 5, 5] = gauss_markov(dt, alpha_ps, sigma_mps)[1]
    return Q


# --------------------------------------------------------------------------------------------
# the track filter's model on the estimation core (forward_pass)
# --------------------------------------------------------------------------------------------

class ArmsTrackModel(NamedTuple):
    """The CV (n = 4, ``[x, Vx, y, Vy]``) or joint (n = 6, ``[x, Vx, y, Vy, dVx, dVy]``) track
    filter as a model of the estimation core (:mod:`flightrecon.estimation.model`), run by
    :func:`flightrecon.estimation.filtering.forward_pass`.

    Inputs: ``F``, ``Q`` (N, n, n) the exact transitions and process noises
    (:func:`cv_transition` / :func:`joint_transition`); ``radar`` (N, 2) ``[rho*, theta*]``
    (NaN: no plot at that step); ``radar_sd`` (N, 2) ``[sigma_rho, sigma_theta]``; ``air``
    (N, 2) ``V* = [V*x, V*y]`` (NaN: none; used only when n = 6) with noise ``Rv`` (2, 2);
    ``lin`` the radar linearisation (:func:`linearisation_code`).

    Outputs (filled by the run): ``x_f``, ``P_f`` the filtered, ``x_p``, ``P_p`` the predicted
    estimates; ``nu`` (N, 4) the innovations (columns 0-1 the radar's: range/azimuth for the
    EKF, x/y for the converted form; 2-3 the air data's; NaN where none) and ``S`` (N, 4, 4)
    their covariances; ``nis`` and ``n_meas`` per step; ``radar_used``, ``air_used`` (N,) the
    steps whose plot / air-data sample was used.

    The transition is linear, so its backward pass is the linear model's
    (:func:`flightrecon.estimation.kalman.rts_smooth`: ``C^T = F_{k+1} P_f[k]``).
    """

    F: np.ndarray
    Q: np.ndarray
    radar: np.ndarray
    radar_sd: np.ndarray
    air: np.ndarray
    Rv: np.ndarray
    lin: int
    x_f: np.ndarray
    P_f: np.ndarray
    x_p: np.ndarray
    P_p: np.ndarray
    nu: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    n_meas: np.ndarray
    radar_used: np.ndarray
    air_used: np.ndarray


def arms_track_model(F: np.ndarray, Q: np.ndarray, radar: np.ndarray, radar_sd: np.ndarray,
                     air: np.ndarray, Rv: np.ndarray, lin: int) -> ArmsTrackModel:
    """An :class:`ArmsTrackModel` on these inputs with its output buffers (NaN innovations,
    no measurement used)."""
    N, n = F.shape[0], F.shape[1]
    c = np.ascontiguousarray
    return ArmsTrackModel(c(F), c(Q), c(radar), c(radar_sd), c(air), c(Rv), int(lin),
                          np.empty((N, n)), np.empty((N, n, n)), np.empty((N, n)),
                          np.empty((N, n, n)), np.full((N, 4), np.nan),
                          np.full((N, 4, 4), np.nan), np.full(N, np.nan),
                          np.zeros(N, dtype=np.int64), np.zeros(N, dtype=np.bool_),
                          np.zeros(N, dtype=np.bool_))


@implements(workspace, ArmsTrackModel)
def _workspace(model):
    n = model.F.shape[1]
    # the step's stacked innovation, Jacobian, noise and innovation slots (radar 0-1, air 2-3),
    # then the prediction's buffers (x^-, F P F^T, F P)
    return (np.zeros(4), np.zeros((4, n)), np.zeros((4, 4)), np.empty(4, dtype=np.int64),
            np.empty(n), np.empty((n, n)), np.empty((n, n)))


@implements(predict_into, ArmsTrackModel, refcounted=False)
def _predict(model, k, x, P, ws):
    """``x <- F_k x``, ``P <- F_k P F_k^T + Q_k`` symmetrised (exact CV / Gauss-Markov
    discretisation): :func:`~flightrecon.estimation.predict.predict`'s operations in the
    workspace's buffers (no allocation)."""
    xn, FPFt, T = ws[4], ws[5], ws[6]
    F = model.F[k]
    Q = model.Q[k]
    n = x.shape[0]
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += F[i, j] * x[j]
        xn[i] = acc
    predict_cov_into(P, F, FPFt, T)
    for i in range(n):
        x[i] = xn[i]
        for j in range(n):
            P[i, j] = Q[i, j] + FPFt[i, j]
    for i in range(n):
        for j in range(i + 1, n):
            v = 0.5 * (P[i, j] + P[j, i])
            P[i, j] = v
            P[j, i] = v


@implements(keep_predicted, ArmsTrackModel, refcounted=False)
def _keep_predicted(model, k, x, P):
    keep_dense_into(model.x_p, model.P_p, k, x, P)


@nb.njit(cache=True, nogil=True, inline="always")
def radar_rows_into(lin, rho, th, sr2, st2, x, nu, Hk, Rk):
    """The radar plot ``[rho*, theta*]`` (variances ``sr2``, ``st2``) as rows 0-1 of the step's
    innovation ``nu``, Jacobian ``Hk`` and noise ``Rk`` at the state ``x`` (paper eqs. 10-15).

    ``lin`` 0: EKF on ``[rho, theta]``, ``H`` of eq. 12, azimuth innovation wrapped to
    (-pi, pi]; 1 / 2: converted measurement ``[x*, y*]`` (eq. 13) with ``H`` selecting x, y and
    the covariance of eq. 15 at the measured (1) or predicted (2) range and azimuth.  Returns
    False (rows untouched) for a predicted position within 1 m of the station, where the
    azimuth is undefined.  Inlined into the model's update.
    """
    px = x[0]
    py = x[2]
    r2 = px * px + py * py
    if r2 <= 1.0:  # at the station the azimuth is undefined: skip such a plot
        return False
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
    return True


@implements(update_into, ArmsTrackModel)
def _update(model, k, x, P, ws):
    """The step's plot and air-data sample in one block Joseph update (docs/arms.md).

    Radar: :func:`radar_rows_into` (EKF or converted, ``model.lin``).  Air data (n = 6):
    ``V* = [Vx + dVx, Vy + dVy] + e``, ``e ~ N(0, Rv)``, rows ``H = [0 1 0 0 1 0; 0 0 0 1 0 1]``.
    Innovations are kept in slots 0-1 (radar) and 2-3 (air data) of ``model.nu`` / ``model.S``.
    """
    nu, Hk, Rk, slot = ws[0], ws[1], ws[2], ws[3]
    n = x.shape[0]
    radar = model.radar
    air = model.air
    nu[:] = 0.0
    Hk[:, :] = 0.0
    Rk[:, :] = 0.0
    c = 0
    if not (np.isnan(radar[k, 0]) or np.isnan(radar[k, 1])):
        radar_sd = model.radar_sd
        if radar_rows_into(model.lin, radar[k, 0], radar[k, 1], radar_sd[k, 0] ** 2,
                           radar_sd[k, 1] ** 2, x, nu, Hk, Rk):
            slot[0] = 0
            slot[1] = 1
            c = 2
            model.radar_used[k] = True
    if n == 6 and not (np.isnan(air[k, 0]) or np.isnan(air[k, 1])):
        nu[c] = air[k, 0] - (x[1] + x[4])
        nu[c + 1] = air[k, 1] - (x[3] + x[5])
        Hk[c, 1] = 1.0
        Hk[c, 4] = 1.0
        Hk[c + 1, 3] = 1.0
        Hk[c + 1, 5] = 1.0
        Rv = model.Rv
        for a in range(2):
            for b in range(2):
                Rk[c + a, c + b] = Rv[a, b]
        slot[c] = 2
        slot[c + 1] = 3
        c += 2
        model.air_used[k] = True
    if c > 0:
        v = nu[:c].copy()
        xu, Pu, S, model.nis[k] = joseph_update(x, P, v, Hk[:c].copy(), Rk[:c, :c].copy())
        x[:] = xu
        P[:, :] = Pu
        model.n_meas[k] = c
        nu_k = model.nu[k]
        S_k = model.S[k]
        for a in range(c):
            nu_k[slot[a]] = v[a]
            for b in range(c):
                S_k[slot[a], slot[b]] = S[a, b]


@implements(keep_filtered, ArmsTrackModel, refcounted=False)
def _keep_filtered(model, k, x, P):
    keep_dense_into(model.x_f, model.P_f, k, x, P)
