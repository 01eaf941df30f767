"""SNS dead-reckoning models: increments, step matrices, SNS observation rows, inputs and noise
(see :mod:`flightrecon.methods.sns`).  The geodetic box-plus/minus of the latitude/longitude
state are the estimation core's (:mod:`flightrecon.estimation.manifold`)."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numba as nb
import numpy as np

from flightrecon.estimation.linalg import chol2_into

MODEL_AIRSPEED = 0


MODEL_DOPPLER = 1


FORM_CONSISTENT = 0


FORM_SEED = 1


N_STATE = 5


N_EPS1 = 11




STATE_NAMES = {
    MODEL_AIRSPEED: ("north_m", "east_m", "corr_wind_n_mps", "corr_wind_e_mps", "corr_psi_rad"),
    MODEL_DOPPLER: ("north_m", "east_m", "corr_W_scale", "corr_c_rad", "corr_psi_rad"),
}


@nb.njit(cache=True, nogil=True)
def _increment_into(model: int, c: np.ndarray, A0: float, A1: float, U0: float, U1: float,
                    W0: float, W1: float, tau: float, sig: np.ndarray, d: np.ndarray,
                    J: np.ndarray, Gs: np.ndarray) -> None:
    """:func:`increment` writing into caller-owned ``d`` (2,), ``J`` (2, 3), ``Gs`` (2, 4).

    The allocation-free core used by the filter kernel (every entry of the outputs is written).
    """
    s, th = scale_angle(model, c)
    increment_cs_into(model, s, np.cos(th), np.sin(th), c, A0, A1, U0, U1, W0, W1, tau, sig,
                       d, J, Gs)


@nb.njit(cache=True, nogil=True)
def increment_cs_into(model: int, s: float, ct: float, st: float, c: np.ndarray, A0: float,
                       A1: float, U0: float, U1: float, W0: float, W1: float, tau: float,
                       sig: np.ndarray, d: np.ndarray, J: np.ndarray, Gs: np.ndarray) -> None:
    """:func:`_increment_into` given the scale ``s`` and ``cos``/``sin`` of the rotation angle
    (``s = 1, theta = c[2]`` airspeed; ``s = 1 + c[0], theta = c[1] + c[2]`` Doppler)."""
    ra0 = ct * A0 - st * A1
    ra1 = st * A0 + ct * A1
    # derivative of R(theta) A with respect to theta
    dra0 = -ra1
    dra1 = ra0
    ru0 = ct * U0 - st * U1
    ru1 = st * U0 + ct * U1
    if model == MODEL_AIRSPEED:
        d[0] = ra0 + W0 + c[0] * tau
        d[1] = ra1 + W1 + c[1] * tau
        J[0, 0] = tau
        J[0, 1] = 0.0
        J[1, 0] = 0.0
        J[1, 1] = tau
        J[0, 2] = dra0
        J[1, 2] = dra1
        Gs[0, 0] = ru0 * sig[0]
        Gs[1, 0] = ru1 * sig[0]
        Gs[0, 1] = dra0 * sig[1]
        Gs[1, 1] = dra1 * sig[1]
        Gs[0, 2] = tau * sig[2]
        Gs[1, 2] = 0.0
        Gs[0, 3] = 0.0
        Gs[1, 3] = tau * sig[3]
    else:
        d[0] = s * ra0
        d[1] = s * ra1
        J[0, 0] = ra0
        J[1, 0] = ra1
        J[0, 1] = s * dra0
        J[1, 1] = s * dra1
        J[0, 2] = s * dra0
        J[1, 2] = s * dra1
        Gs[0, 0] = s * ru0 * sig[0]
        Gs[1, 0] = s * ru1 * sig[0]
        Gs[0, 1] = s * dra0 * sig[1]
        Gs[1, 1] = s * dra1 * sig[1]
        Gs[0, 2] = s * dra0 * sig[2]
        Gs[1, 2] = s * dra1 * sig[2]
        Gs[0, 3] = 0.0
        Gs[1, 3] = 0.0


@nb.njit(cache=True, nogil=True)
def increment(model: int, c: np.ndarray, A: np.ndarray, U: np.ndarray, Wv: np.ndarray,
              tau: float, sig: np.ndarray):
    """Dead-reckoning increment over an interval, its Jacobian and its noise matrix.

    Parameters
    ----------
    model : ``MODEL_AIRSPEED`` (0) or ``MODEL_DOPPLER`` (1)
    c : (3,) corrections (see module docstring)
    A, U, Wv : (2,) integrals over the interval of the measured velocity vector, of its unit
        vector and of the measured wind vector (north, east) [m, s, m]
    tau : interval length [s]
    sig : (4,) sensor noise standard deviations per recorder sample (module docstring)

    Returns
    -------
    d : (2,) increment north/east [m] (docs/sns.md, "Models", exact for held readings)
    J : (2, 3) ``dd/dc``
    Gs : (2, 4) ``dd/d eta`` times the noise standard deviations

    With ``A = a``, ``U = u``, ``Wv = w`` and ``tau = 1`` the same function gives the corrected
    velocity at an instant, its Jacobian and the velocity rows of ``G``.
    """
    d = np.empty(2)
    J = np.empty((2, 3))
    Gs = np.empty((2, 4))
    _increment_into(model, c, A[0], A[1], U[0], U[1], Wv[0], Wv[1], tau, sig, d, J, Gs)
    return d, J, Gs


@nb.njit(cache=True, nogil=True)
def _segment_factor_into(model: int, c: np.ndarray, Q: np.ndarray, sig: np.ndarray,
                         L: np.ndarray) -> None:
    """:func:`segment_factor` writing into a caller-owned (2, 2) ``L``."""
    s, th = scale_angle(model, c)
    _segment_factor_cs_into(model, s, np.cos(th), np.sin(th), Q, sig, L)


@nb.njit(cache=True, nogil=True)
def scale_angle(model: int, c: np.ndarray) -> tuple[float, float]:
    """Scale ``s`` and rotation angle ``theta`` of the corrected reading (module docstring)."""
    if model == MODEL_AIRSPEED:
        return 1.0, c[2]
    return 1.0 + c[0], c[1] + c[2]


@nb.njit(cache=True, nogil=True)
def _segment_factor_cs_into(model: int, s: float, ct: float, st: float, Q: np.ndarray,
                            sig: np.ndarray, L: np.ndarray) -> None:
    """:func:`_segment_factor_into` given ``s`` and ``cos``/``sin`` of ``theta``."""
    if model == MODEL_AIRSPEED:
        va = sig[1] * sig[1]
        wn = sig[2] * sig[2] * Q[6]
        we = sig[3] * sig[3] * Q[6]
    else:
        va = sig[1] * sig[1] + sig[2] * sig[2]
        wn = 0.0
        we = 0.0
    v0 = sig[0] * sig[0]
    m00 = v0 * Q[0] + va * Q[3]
    m01 = v0 * Q[1] + va * Q[4]
    m11 = v0 * Q[2] + va * Q[5]
    # R M R^T
    r00 = ct * ct * m00 - 2 * ct * st * m01 + st * st * m11
    r01 = ct * st * (m00 - m11) + (ct * ct - st * st) * m01
    r11 = st * st * m00 + 2 * ct * st * m01 + ct * ct * m11
    chol2_into(s * s * r00 + wn, s * s * r01, s * s * r11 + we, L)


@nb.njit(cache=True, nogil=True)
def segment_factor(model: int, c: np.ndarray, Q: np.ndarray, sig: np.ndarray) -> np.ndarray:
    """Factor L (2, 2) of the increment noise of whole recorder samples, ``L L^T = Cov``.

    ``Q`` (7,) holds sums over the samples of ``dt^2 u u^T`` (xx, xy, yy), ``dt^2 (Ja)(Ja)^T``
    (xx, xy, yy; ``Ja = [-a_e, a_n]``) and ``dt^2``.  With white errors per sample::

        Cov = s^2 R(theta) [sd_speed^2 Suu + sd_angle^2 Sjj] R(theta)^T + diag(sd_wn^2, sd_we^2) S

    (``sd_angle^2`` = heading, or drift + heading for the Doppler model).
    """
    L = np.empty((2, 2))
    _segment_factor_into(model, c, Q, sig, L)
    return L


class StepReadings(NamedTuple):
    """The readings of one filter step (:func:`step_matrices`): the integrals ``A``, ``U``,
    ``W`` (2,) of the held readings over the step, its length ``tau`` [s], the readings
    ``star`` (3, 2) of the recorder sample held at the step's fixes and their hold
    ``dt_star`` [s], and the noise sums ``Qb``, ``Qa`` (7,) of the samples before and after
    it."""

    A: np.ndarray
    U: np.ndarray
    W: np.ndarray
    tau: float
    star: np.ndarray
    dt_star: float
    Qb: np.ndarray
    Qa: np.ndarray


class FixReadings(NamedTuple):
    """The readings of one SNS fix (:func:`observation_rows`): the integrals ``PA``, ``PU``,
    ``PW`` (2,) from the start of its step to the fix, taken ``tau`` [s] after the step, the
    readings ``a``, ``u``, ``w`` (2,) of the recorder sample held at the fix and ``tau_in``
    [s], how long that sample is held before the fix."""

    PA: np.ndarray
    PU: np.ndarray
    PW: np.ndarray
    tau: float
    a: np.ndarray
    u: np.ndarray
    w: np.ndarray
    tau_in: float


@nb.njit(cache=True, nogil=True)
def step_matrices_into(model: int, c: np.ndarray, step: StepReadings, sig: np.ndarray,
                       q: np.ndarray, out: tuple, scratch: tuple) -> None:
    """:func:`step_matrices` writing ``out = (d (2,), Phi (5, 5), B (5, 11))`` in place.

    ``scratch = (J (2, 3), Gs (2, 4), d2 (2,), L (2, 2))``.
    """
    d, Phi, B = out
    J, Gs, d2, L = scratch
    A, U, Wv, tau, star, dt_star, Qb, Qa = step
    for i in range(N_STATE):
        for j in range(N_STATE):
            Phi[i, j] = 1.0 if i == j else 0.0
        for j in range(N_EPS1):
            B[i, j] = 0.0
    s, th = scale_angle(model, c)
    ct = np.cos(th)
    st = np.sin(th)
    increment_cs_into(model, s, ct, st, c, A[0], A[1], U[0], U[1], Wv[0], Wv[1], tau, sig, d,
                      J, Gs)
    for i in range(2):
        for j in range(3):
            Phi[i, 2 + j] = J[i, j]
    increment_cs_into(model, s, ct, st, c, star[0, 0] * dt_star, star[0, 1] * dt_star,
                      star[1, 0] * dt_star, star[1, 1] * dt_star, star[2, 0] * dt_star,
                      star[2, 1] * dt_star, dt_star, sig, d2, J, Gs)
    for i in range(2):
        for j in range(4):
            B[i, j] = Gs[i, j]
    _segment_factor_cs_into(model, s, ct, st, Qb, sig, L)
    for i in range(2):
        for j in range(2):
            B[i, 4 + j] = L[i, j]
    _segment_factor_cs_into(model, s, ct, st, Qa, sig, L)
    for i in range(2):
        for j in range(2):
            B[i, 6 + j] = L[i, j]
    for j in range(3):
        B[2 + j, 8 + j] = np.sqrt(q[j] * tau)


@nb.njit(cache=True, nogil=True)
def step_matrices(model: int, c: np.ndarray, A: np.ndarray, U: np.ndarray, Wv: np.ndarray,
                  tau: float, sig: np.ndarray, q: np.ndarray, star: np.ndarray, dt_star: float,
                  Qb: np.ndarray, Qa: np.ndarray):
    """Increment, ``Phi = df/dX`` (5, 5) and ``B`` (5, 11) of one filter step.

    ``eps1`` columns: the 4 errors of the recorder sample held at the step's fixes (``star``
    (3, 2): its ``a, u, w``; held for ``dt_star`` within the step; zero without a fix), the
    factors of the summed errors of the samples before (``Qb``) and after (``Qa``) it (see
    :func:`segment_factor`), and the random walks of the corrections: ``q`` (3,) intensities
    [unit^2/s], noise ``sqrt(q tau)``.  Position block of ``Phi`` is the identity in the
    re-centred local-level frame (module docstring, "Frame").
    """
    d = np.empty(2)
    Phi = np.empty((N_STATE, N_STATE))
    B = np.empty((N_STATE, N_EPS1))
    step_matrices_into(model, c, StepReadings(A, U, Wv, tau, star, dt_star, Qb, Qa), sig, q,
                       (d, Phi, B), (np.empty((2, 3)), np.empty((2, 4)), np.empty(2),
                                     np.empty((2, 2))))
    return d, Phi, B


@nb.njit(cache=True, nogil=True)
def observation_rows_into(model: int, c: np.ndarray, fix: FixReadings, sig: np.ndarray,
                          Qb: np.ndarray, out: tuple, scratch: tuple) -> None:
    """:func:`observation_rows` writing ``out = (h (4,), H (4, 5), G (4, 11))`` in place.

    ``scratch = (d (2,), J (2, 3), Gs (2, 4), L (2, 2))``.
    """
    h, H, G = out
    d, J, Gs, L = scratch
    PA, PU, PW, tau, a, u, w, tau_in = fix
    for i in range(4):
        for j in range(N_STATE):
            H[i, j] = 0.0
        for j in range(N_EPS1):
            G[i, j] = 0.0
    H[0, 0] = 1.0
    H[1, 1] = 1.0
    s, th = scale_angle(model, c)
    ct = np.cos(th)
    st = np.sin(th)
    increment_cs_into(model, s, ct, st, c, PA[0], PA[1], PU[0], PU[1], PW[0], PW[1], tau, sig,
                      d, J, Gs)
    h[0] = d[0]
    h[1] = d[1]
    for i in range(2):
        for j in range(3):
            H[i, 2 + j] = J[i, j]
    increment_cs_into(model, s, ct, st, c, a[0] * tau_in, a[1] * tau_in, u[0] * tau_in,
                      u[1] * tau_in, w[0] * tau_in, w[1] * tau_in, tau_in, sig, d, J, Gs)
    for i in range(2):
        for j in range(4):
            G[i, j] = Gs[i, j]
    _segment_factor_cs_into(model, s, ct, st, Qb, sig, L)
    for i in range(2):
        for j in range(2):
            G[i, 4 + j] = L[i, j]
    increment_cs_into(model, s, ct, st, c, a[0], a[1], u[0], u[1], w[0], w[1], 1.0, sig, d, J,
                      Gs)
    h[2] = d[0]
    h[3] = d[1]
    for i in range(2):
        for j in range(3):
            H[2 + i, 2 + j] = J[i, j]
        for j in range(4):
            G[2 + i, j] = Gs[i, j]


@nb.njit(cache=True, nogil=True)
def observation_rows(model: int, c: np.ndarray, PA: np.ndarray, PU: np.ndarray, PW: np.ndarray,
                     tau: float, a: np.ndarray, u: np.ndarray, w: np.ndarray, sig: np.ndarray,
                     tau_in: float, Qb: np.ndarray):
    """``h``, ``H = dh/dX`` (4, 5) and ``G`` (4, 11) of one SNS fix taken ``tau`` after the step.

    ``h = [partial increment north, east, corrected velocity north, east]`` relative to the
    position at the start of the step; ``PA, PU, PW`` are the integrals up to the fix time and
    ``a, u, w`` the readings of the recorder sample held at the fix time, held for ``tau_in``
    before it.  ``G``: velocity rows carry that sample's errors; position rows its errors over
    ``tau_in`` and the summed errors of the step's earlier samples (``Qb``), shared with ``B``.
    """
    h = np.empty(4)
    H = np.empty((4, N_STATE))
    G = np.empty((4, N_EPS1))
    observation_rows_into(model, c, FixReadings(PA, PU, PW, tau, a, u, w, tau_in), sig, Qb,
                          (h, H, G), (np.empty(2), np.empty((2, 3)), np.empty((2, 4)),
                                      np.empty((2, 2))))
    return h, H, G


@dataclass(frozen=True)
class StepInputs:
    """Everything the filter needs per filter step, precomputed from the recorder grid.

    Filter grid of ``N`` points ``t`` (s); step k runs from ``t[k]`` to ``t[k+1]``.

    Attributes
    ----------
    t : (N,) filter times [s]
    h : (N,) height used for the radii [m]
    A, U, W : (N, 2) integrals of the held readings over step k (row ``N-1`` zero)
    fix_start, fix_end : (N,) int: the fixes taken during step k are ``fix_start[k]:fix_end[k]``
        (the last point takes the fixes at its own time)
    fix_lat, fix_lon : (F,) centre-of-mass fix position [rad]
    fix_v : (F, 2) centre-of-mass ground velocity north/east [m/s] (NaN where absent)
    fix_tau : (F,) time of the fix after the start of its step [s]
    fix_PA, fix_PU, fix_PW : (F, 2) integrals from the start of the step to the fix
    fix_a, fix_u, fix_w : (F, 2) readings of the recorder sample held at the fix time
    star : (N, 3, 2) ``a, u, w`` of the recorder sample held at the fixes of step k (all fixes of
        a step fall in one recorder sample); ``dt_star`` (N,) how long it is held in the step
    Qb, Qa : (N, 7) noise sums (:func:`segment_factor`) of the step's recorder samples before and
        after that sample (steps without fixes: all samples in ``Qb``)
    fix_tau_in : (F,) time from the start of the fix's recorder sample to the fix [s]
    fix_pos_sd, fix_vel_sd : (F,) per-fix sd of the position / velocity components (the
        receiver's accuracy figures); ``None`` or NaN: ``SnsNoise.pos_sd_m`` / ``vel_sd_mps``

    ``star``, ``dt_star``, ``Qb``, ``Qa``, ``fix_tau_in`` may be left ``None`` when every filter
    step is one recorder sample (then ``star = A / tau`` etc., as :func:`fill_single_sample`).
    """

    t: np.ndarray
    h: np.ndarray
    A: np.ndarray
    U: np.ndarray
    W: np.ndarray
    fix_start: np.ndarray
    fix_end: np.ndarray
    fix_lat: np.ndarray
    fix_lon: np.ndarray
    fix_v: np.ndarray
    fix_tau: np.ndarray
    fix_PA: np.ndarray
    fix_PU: np.ndarray
    fix_PW: np.ndarray
    fix_a: np.ndarray
    fix_u: np.ndarray
    fix_w: np.ndarray
    star: np.ndarray | None = None
    dt_star: np.ndarray | None = None
    Qb: np.ndarray | None = None
    Qa: np.ndarray | None = None
    fix_tau_in: np.ndarray | None = None
    fix_pos_sd: np.ndarray | None = None
    fix_vel_sd: np.ndarray | None = None


def per_fix_sd(v: np.ndarray | None, default: float, n: int) -> np.ndarray:
    """(n,) per-fix standard deviations: ``v`` where finite and positive, else ``default``."""
    if v is None:
        return np.full(n, float(default))
    v = np.asarray(v, float).reshape(-1)
    return np.ascontiguousarray(np.where(np.isfinite(v) & (v > 0), v, float(default)))


def fill_single_sample(inp: StepInputs) -> StepInputs:
    """Complete the per-sample noise fields for filter steps of one recorder sample each."""
    if inp.star is not None:
        return inp
    t = np.asarray(inp.t, float)
    tau = np.zeros(len(t))
    tau[:-1] = np.diff(t)
    inv = np.divide(1.0, tau, out=np.zeros_like(tau), where=tau > 0)[:, None]
    star = np.stack([np.asarray(inp.A) * inv, np.asarray(inp.U) * inv,
                     np.asarray(inp.W) * inv], axis=1)
    z = np.zeros((len(t), 7))
    return replace(inp, star=star, dt_star=tau, Qb=z, Qa=z.copy(),
                   fix_tau_in=np.asarray(inp.fix_tau, float).copy())


@dataclass(frozen=True)
class SnsNoise:
    """Noise and prior settings of the SNS filter (SI; angles in radians).

    Attributes
    ----------
    sensor_sd : (4,) sensor noise per recorder sample (white): airspeed model ``[TAS m/s,
        heading rad, wind north m/s, wind east m/s]``; Doppler model ``[ground speed m/s, drift rad,
        heading rad, unused]``
    rw_q : (3,) random-walk intensities of the corrections [unit^2/s]
    pos_sd_m, vel_sd_mps : SNS position / velocity noise per component (``D``)
    prior_sd : (3,) prior standard deviations of the corrections
    rcond : relative eigenvalue tolerance of the pseudo-inverse of ``S``
    """

    sensor_sd: tuple[float, float, float, float]
    rw_q: tuple[float, float, float]
    pos_sd_m: float
    vel_sd_mps: float
    prior_sd: tuple[float, float, float]
    rcond: float = 1e-10


def default_noise(model: int) -> SnsNoise:
    """Default noise settings, typical of a transport aircraft's recorder and a GNSS receiver.

    Airspeed: TAS 0.5 m/s, heading 0.2 deg, wind reading 1 m/s white per recorder sample; heading
    bias prior 2 deg, wind-correction prior 10 m/s.  Doppler: ground speed 0.5 m/s, drift 0.2 deg,
    heading 0.2 deg; scale prior 0.03, drift and heading bias priors 1 and 2 deg.  Random walks let
    the corrections drift by about 0.1 deg/h, 1 m/s per hour and 0.1 %/h.  GNSS 3 m, 0.1 m/s.
    """
    d = np.deg2rad
    hour = 3600.0
    if model == MODEL_AIRSPEED:
        return SnsNoise((0.5, float(d(0.2)), 1.0, 1.0),
                        (1.0 / hour, 1.0 / hour, float(d(0.1)) ** 2 / hour),
                        3.0, 0.1, (10.0, 10.0, float(d(2.0))))
    if model == MODEL_DOPPLER:
        return SnsNoise((0.5, float(d(0.2)), float(d(0.2)), 0.0),
                        (1e-6 / hour, float(d(0.1)) ** 2 / hour, float(d(0.1)) ** 2 / hour),
                        3.0, 0.1, (0.03, float(d(1.0)), float(d(2.0))))
    raise ValueError(f"unknown model {model}")
