"""The azimuth channel's forward filter (the model :class:`AzimuthModel` on the estimation
core's forward loop) and its RTS smoothing (the linear backward loop)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.estimation.discretise import (
    random_walk_matrices,
    singer_process_noise,
    singer_transition,
)
from flightrecon.estimation.filtering import FilterRun, forward_pass
from flightrecon.estimation.kalman import rts_smooth
from flightrecon.estimation.smoothing import SmoothedRun
from flightrecon.methods.azimuth.model import azimuth_model
from flightrecon.methods.azimuth.range_track import RangeTrack

# ---------------------------------------------------------------------------------------------
# Azimuth filter and smoother
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class AzimuthRun:
    """The azimuth filter and its backward RTS smoother on the event times.

    Attributes
    ----------
    t_s : (N,) event times [s]
    filt : the core's :class:`~flightrecon.estimation.filtering.FilterRun`: filtered state
        ``x`` (N, 3) [rad, rad/s, rad/s^2] (azimuth continuous, not wrapped), ``P``, the
        one-step predictions, and the diagnostics ``F`` (transitions), ``nu_eps``, ``s_eps``
        (azimuth innovations [rad], wrapped, and their variances; NaN: no plot), ``nis_eps``,
        ``nu_z``, ``s_z``, ``r_z`` (transverse-acceleration innovations [m/s^2], their
        variances and the propagated observation variance R_z; NaN: no on-board observation)
        and ``nis_z``
    smooth : the core's :class:`~flightrecon.estimation.smoothing.SmoothedRun` (``x``, ``P``)
    model : ``"singer"`` or ``"aided"``
    n_corr : inflation of the correlated error variances of ``z`` (see :func:`azimuth_filter`)
    """

    t_s: np.ndarray
    filt: FilterRun
    smooth: SmoothedRun
    model: str
    n_corr: float

    @property
    def nis_eps(self) -> np.ndarray:
        """Normalised azimuth innovations squared (chi-square, 1 dof, where a plot was used)."""
        return self.filt.diagnostics["nis_eps"]

    @property
    def nis_z(self) -> np.ndarray:
        """Normalised transverse-acceleration innovations squared (1 dof)."""
        return self.filt.diagnostics["nis_z"]


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
    m = azimuth_model(F, Q, eps_used, eps_var, a_ne, a_ne_cov, a_ne_cov_corr, r,
                      range_track.r_dot, range_track.P, n_corr)
    forward_pass(m, x0, P0, t.size)
    sm = rts_smooth(m.x_f, m.P_f, m.x_p, m.P_p, m.F)
    diags = {"F": m.F, "nu_eps": m.nu_eps, "s_eps": m.s_eps, "nis_eps": m.nu_eps**2 / m.s_eps,
             "nu_z": m.nu_z, "s_z": m.s_z, "r_z": m.r_z, "nis_z": m.nu_z**2 / m.s_z}
    return AzimuthRun(t, FilterRun(m.x_f, m.P_f, m.x_p, m.P_p, diags, m), sm, model, n_corr)
