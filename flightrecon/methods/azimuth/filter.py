"""The azimuth channel's forward filter (compiled kernel) and its RTS smoothing."""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.estimation.discretise import (
    random_walk_matrices,
    singer_process_noise,
    singer_transition,
)
from flightrecon.estimation.kalman import rts_smooth
from flightrecon.estimation.predict import predict
from flightrecon.estimation.updates import joseph_update
from flightrecon.methods.azimuth.range_track import RangeTrack

# ---------------------------------------------------------------------------------------------
# Azimuth filter and smoother
# ---------------------------------------------------------------------------------------------


@nb.njit(cache=True, nogil=True)
def _wrap(x):
    return np.pi - np.mod(np.pi - x, 2.0 * np.pi)


@nb.njit(cache=True, nogil=True)
def _azimuth_kernel(x0, P0, F, Q, eps_meas, eps_var, a_ne, Sa, Sb, r, rdot, Pr, n_corr):
    """Forward pass over the events (module docstring; docs/azimuth.md "Observations").

    Per event: predict with ``F[k]``, ``Q[k]``; radar update with the wrapped innovation; then
    the on-board update linearised at the current estimate, ``H = [-dz/deps, 2 r_dot, r]``,
    ``R_z = u Sa u^T + n_corr (u Sb u^T + [a, 2 omega] Pr [a, 2 omega]^T)``.
    """
    N = F.shape[0]
    xs = np.empty((N, 3))
    Ps = np.empty((N, 3, 3))
    xp = np.empty((N, 3))
    Pp = np.empty((N, 3, 3))
    nu_e = np.full(N, np.nan)
    s_e = np.full(N, np.nan)
    nu_z = np.full(N, np.nan)
    s_z = np.full(N, np.nan)
    r_z = np.full(N, np.nan)
    x = x0.copy()
    P = P0.copy()
    h_eps = np.array([[1.0, 0.0, 0.0]])
    r1 = np.empty((1, 1))
    nu1 = np.empty(1)
    for k in range(N):
        if k > 0:
            x, P = predict(x, P, F[k], Q[k])
        xp[k] = x
        Pp[k] = P
        if not np.isnan(eps_meas[k]):
            nu1[0] = _wrap(eps_meas[k] - x[0])
            r1[0, 0] = eps_var[k]
            x, P, S1, _ = joseph_update(x, P, nu1, h_eps, r1)
            nu_e[k] = nu1[0]
            s_e[k] = S1[0, 0]
        if not np.isnan(a_ne[k, 0]):
            e, om, a = x[0], x[1], x[2]
            s, c = np.sin(e), np.cos(e)
            zacc = a_ne[k, 1] * c - a_ne[k, 0] * s
            dz = -(a_ne[k, 1] * s + a_ne[k, 0] * c)
            h = np.empty((1, 3))
            h[0, 0], h[0, 1], h[0, 2] = -dz, 2.0 * rdot[k], r[k]
            u0, u1 = -s, c
            rs = (u0 * u0 * Sa[k, 0, 0] + 2.0 * u0 * u1 * Sa[k, 0, 1] + u1 * u1 * Sa[k, 1, 1])
            rb = (u0 * u0 * Sb[k, 0, 0] + 2.0 * u0 * u1 * Sb[k, 0, 1] + u1 * u1 * Sb[k, 1, 1])
            g0_, g1_ = a, 2.0 * om  # dz_model / d(r, r_dot)
            rr = g0_ * g0_ * Pr[k, 0, 0] + 2.0 * g0_ * g1_ * Pr[k, 0, 1] + g1_ * g1_ * Pr[k, 1, 1]
            R = rs + n_corr * (rb + rr)
            nu1[0] = zacc - 2.0 * rdot[k] * om - r[k] * a
            r1[0, 0] = R
            x, P, S1, _ = joseph_update(x, P, nu1, h, r1)
            nu_z[k] = nu1[0]
            s_z[k] = S1[0, 0]
            r_z[k] = R
        xs[k] = x
        Ps[k] = P
    return xs, Ps, xp, Pp, nu_e, s_e, nu_z, s_z, r_z


@dataclass(frozen=True)
class AzimuthRun:
    """A forward azimuth filter and its backward RTS smoother, on the event times.

    Attributes
    ----------
    t_s : (N,) event times [s]
    x, P : filtered state (N, 3) [rad, rad/s, rad/s^2] (azimuth continuous, not wrapped) and
        covariance (N, 3, 3)
    x_pred, P_pred, F : one-step predictions and transitions (for the backward pass)
    xs, Ps : smoothed state and covariance
    nu_eps, s_eps : azimuth innovations [rad] (wrapped) and their variances (NaN: no plot)
    nu_z, s_z, r_z : transverse-acceleration innovations [m/s^2], their variances and the
        propagated observation variance R_z (NaN: no on-board observation)
    model : ``"singer"`` or ``"aided"``
    n_corr : inflation of the correlated error variances of ``z`` (see :func:`azimuth_filter`)
    """

    t_s: np.ndarray
    x: np.ndarray
    P: np.ndarray
    x_pred: np.ndarray
    P_pred: np.ndarray
    F: np.ndarray
    xs: np.ndarray
    Ps: np.ndarray
    nu_eps: np.ndarray
    s_eps: np.ndarray
    nu_z: np.ndarray
    s_z: np.ndarray
    r_z: np.ndarray
    model: str
    n_corr: float

    @property
    def nis_eps(self) -> np.ndarray:
        """Normalised azimuth innovations squared (chi-square, 1 dof, where a plot was used)."""
        return self.nu_eps**2 / self.s_eps

    @property
    def nis_z(self) -> np.ndarray:
        """Normalised transverse-acceleration innovations squared (1 dof)."""
        return self.nu_z**2 / self.s_z


def _checked_events(t_s, eps_meas_rad, eps_var_rad2, range_track: RangeTrack):
    """The event times, plots, their variances and the tracked range, checked
    (:func:`azimuth_filter`'s parameters); contiguous float arrays."""
    t = np.ascontiguousarray(np.asarray(t_s, dtype=np.float64))
    if t.size < 2:
        raise ValidationError("the azimuth channel needs at least two events")
    if not np.all(np.diff(t) > 0):
        raise ValidationError("event times must be strictly increasing")
    eps = np.ascontiguousarray(np.asarray(eps_meas_rad, dtype=np.float64))
    eps_var = np.ascontiguousarray(np.asarray(eps_var_rad2, dtype=np.float64))
    if not np.isfinite(eps[0]):
        raise ValidationError("the azimuth channel must start at a radar plot")
    if not np.all(eps_var[np.isfinite(eps)] > 0):
        raise ValidationError("azimuth measurement variances must be positive")
    r = np.ascontiguousarray(range_track.r)
    if np.any(r <= 0) or not np.all(np.isfinite(r)):
        raise ValidationError("tracked horizontal range must be positive and finite")
    return t, eps, eps_var, r


def _model_matrices(model, T, r, a_ne, a_ne_cov, a_ne_cov_corr, alpha_m, sigma_m_mps2,
                    q_jerk_m2ps5):
    """Transition and process noise of the chosen model on the steps ``T`` (the Singer model's
    exact matrices, eqs. (1)-(4), or the aided model's random walk in the transverse
    acceleration, eqs. (5)-(8)), and the on-board acceleration with its covariances checked
    (none for the Singer model); docs/azimuth.md."""
    N = T.size
    if model == "singer":
        F = singer_transition(alpha_m, T)
        Q = singer_process_noise(alpha_m, sigma_m_mps2 / r, T)
        a_ne = np.full((N, 2), np.nan)
        a_ne_cov = np.zeros((N, 2, 2))
        a_ne_cov_corr = np.zeros((N, 2, 2))
    elif model == "aided":
        if not q_jerk_m2ps5 > 0:
            raise ValidationError(f"q_jerk_m2ps5 must be > 0, got {q_jerk_m2ps5}")
        F, Q = random_walk_matrices(q_jerk_m2ps5 / r**2, T)
        if a_ne is None or a_ne_cov is None:
            raise ValidationError("the aided model needs the on-board acceleration and its "
                                  "covariance")
        a_ne = np.ascontiguousarray(np.asarray(a_ne, dtype=np.float64))
        a_ne_cov = np.ascontiguousarray(np.asarray(a_ne_cov, dtype=np.float64))
        a_ne_cov_corr = (np.zeros((N, 2, 2)) if a_ne_cov_corr is None else
                         np.ascontiguousarray(np.asarray(a_ne_cov_corr, dtype=np.float64)))
        if a_ne.shape != (N, 2) or a_ne_cov.shape != (N, 2, 2) or a_ne_cov_corr.shape != (N, 2, 2):
            raise ValidationError("a_ne must be (N, 2), a_ne_cov and a_ne_cov_corr (N, 2, 2)")
    else:
        raise ValidationError(f"unknown azimuth model '{model}': choose 'singer' or 'aided'")
    return F, Q, a_ne, a_ne_cov, a_ne_cov_corr


def azimuth_filter(t_s, eps_meas_rad, eps_var_rad2, range_track: RangeTrack, *, model: str,
                   a_ne=None, a_ne_cov=None, a_ne_cov_corr=None, alpha_m: float = 0.05,
                   sigma_m_mps2: float = 2.0, q_jerk_m2ps5: float = 0.2,
                   correlation_time_s: float = 0.0, v_max_mps: float = 150.0,
                   a_max_mps2: float = 5.0) -> AzimuthRun:
    """Filter and smooth the azimuth channel on the event times (docs/azimuth.md).

    Parameters
    ----------
    t_s : (N,) strictly increasing event times [s]; the first event must hold a radar plot
        (it initialises the azimuth and is used once, as the prior: its innovation is NaN)
    eps_meas_rad : (N,) radar azimuth [rad], NaN where no plot at that event
    eps_var_rad2 : (N,) azimuth measurement variance [rad^2]
    range_track : :func:`track_range` on the same events
    model : ``"singer"`` (eqs. (1)-(4), exact Singer matrices) or ``"aided"`` (eqs. (5)-(8) plus
        the transverse-acceleration observation)
    a_ne : (N, 2) horizontal kinematic acceleration [m/s^2] from the loads, NaN rows where no
        on-board observation (aided model only)
    a_ne_cov : (N, 2, 2) covariance of its white errors (load-factor and attitude noise,
        :func:`horizontal_acceleration_covariance`)
    a_ne_cov_corr : (N, 2, 2) covariance of its slowly varying errors (load-factor bias); zeros
        if ``None``
    alpha_m, sigma_m_mps2 : Singer manoeuvre rate [1/s] and transverse-acceleration sd [m/s^2]
        (angular: ``sigma_m_mps2 / r``)
    q_jerk_m2ps5 : aided model, spectral density of the transverse jerk [m^2/s^5]
        (angular: ``q_jerk / r^2``)
    correlation_time_s : correlation time of the slowly varying errors of ``z`` (range-rate
        error of the range tracker, load-factor bias).  Consecutive on-board observations share
        them, so the filter cannot average them down: their variance is multiplied by the number
        of on-board observations in one correlation time, ``n_c = max(1, tau_c / dt_onboard)``
        (first-order treatment of correlated measurement errors; docs/azimuth.md).  0 treats
        them as white.
    v_max_mps, a_max_mps2 : bounds on the aircraft's transverse speed and acceleration that set
        the initial rate and acceleration standard deviations (divided by the first range)

    Returns
    -------
    AzimuthRun
    """
    t, eps, eps_var, r = _checked_events(t_s, eps_meas_rad, eps_var_rad2, range_track)
    T = np.concatenate([[0.0], np.diff(t)])
    F, Q, a_ne, a_ne_cov, a_ne_cov_corr = _model_matrices(
        model, T, r, a_ne, a_ne_cov, a_ne_cov_corr, alpha_m, sigma_m_mps2, q_jerk_m2ps5)
    if not (np.isfinite(correlation_time_s) and correlation_time_s >= 0):
        raise ValidationError(f"correlation_time_s must be >= 0, got {correlation_time_s}")
    t_on = t[np.isfinite(a_ne[:, 0])]
    n_corr = 1.0
    if t_on.size > 1:
        n_corr = max(1.0, correlation_time_s / float(np.median(np.diff(t_on))))
    # the first plot is the prior; it is not used again as a measurement at the first event
    x0 = np.array([eps[0], 0.0, 0.0])
    P0 = np.diag([eps_var[0], (v_max_mps / r[0]) ** 2, (a_max_mps2 / r[0]) ** 2])
    eps_used = eps.copy()
    eps_used[0] = np.nan
    out = _azimuth_kernel(x0, P0, np.ascontiguousarray(F), np.ascontiguousarray(Q), eps_used,
                          eps_var, a_ne, a_ne_cov, a_ne_cov_corr, r,
                          np.ascontiguousarray(range_track.r_dot),
                          np.ascontiguousarray(range_track.P), n_corr)
    xf, Pf, xp, Pp, nu_e, s_e, nu_z, s_z, r_z = out
    sm = rts_smooth(xf, Pf, xp, Pp, F)
    return AzimuthRun(t, xf, Pf, xp, Pp, F, sm.x, sm.P, nu_e, s_e, nu_z, s_z, r_z, model, n_corr)
