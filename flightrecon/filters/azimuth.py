"""Azimuth channel of an approach radar: Singer model and load-factor-aided model (METHODS.md s. 3).

State ``x = [eps, omega, a]``: azimuth [rad, clockwise from true north at the station], azimuth
rate [rad/s] and azimuth angular acceleration [rad/s^2].  Two process models:

* **Singer** (Singer 1970; seed 002 equations (1)-(3) are its Euler form): ``a`` is a first-order
  Markov process, ``a' = -alpha_m a + w``, ``E[w w] = 2 alpha_m sigma_m^2``.  Exact transition
  :func:`singer_transition` and process noise :func:`singer_process_noise`.
* **Aided** (seed 002 equations (5)-(7)): ``a`` is a random walk driven by white noise on ``a'``
  of spectral density ``q``; exact discretisation :func:`random_walk_matrices`.

Observations (METHODS.md s. 3):

* radar azimuth ``eps_meas = eps + v``, innovation wrapped to (-pi, pi] (seed eq. (4)/(8));
* the *transverse acceleration* from the downlinked load factors and attitude (replacing the
  seed's garbled eq. (9); derivation in ``docs/azimuth.md``)::

      z = a_E cos(eps) - a_N sin(eps) = 2 r_dot omega + r a

  with horizontal range ``r`` and its rate from a range tracker (:func:`track_range`).  ``z`` is
  evaluated at the current azimuth estimate and linearised there (an extended-Kalman update of an
  implicit measurement): ``H = [-dz/deps, 2 r_dot, r]``, ``dz/deps = -(a_E sin eps + a_N cos eps)``.
  Its noise ``R_z`` is propagated to first order from the sensor errors
  (:func:`horizontal_acceleration_covariance`) and from the range tracker's covariance.

The angular process noises are set from physical ones: ``sigma_m = sigma_m_mps2 / r`` and
``q = q_jerk / r^2`` with the tracked range ``r`` at each step.

Every filter here runs forward (:func:`azimuth_filter`, compiled with numba) and is smoothed
backward by the generic Rauch-Tung-Striebel pass :func:`flightrecon.smoothing.rts.rts_smooth`.
"""

from __future__ import annotations

from dataclasses import dataclass
from fractions import Fraction
from math import factorial

import numba as nb
import numpy as np

from flightrecon.constants import G0
from flightrecon.errors import ValidationError
from flightrecon.filters.kalman import kalman_filter
from flightrecon.smoothing.rts import rts_smooth, rts_smooth_run

__all__ = [
    "AzimuthRun",
    "RangeTrack",
    "azimuth_filter",
    "horizontal_acceleration",
    "horizontal_acceleration_covariance",
    "horizontal_acceleration_jacobian",
    "random_walk_matrices",
    "singer_process_noise",
    "singer_transition",
    "track_range",
    "transverse_acceleration",
    "wrap_pi",
]

# ---------------------------------------------------------------------------------------------
# Process models
# ---------------------------------------------------------------------------------------------

_SERIES_X = 0.1
"""Below ``alpha_m T`` = 0.1 the Singer brackets are evaluated by their Taylor series (the closed
forms cancel to order (alpha T)^5 there); above it the closed forms lose at most ~1e-11."""
_SERIES_TERMS = 18


def _bracket_coeffs(terms: list[tuple[Fraction, int, int]], order: int) -> np.ndarray:
    """Exact Taylor coefficients of ``sum c x^p exp(-m x)`` divided by ``x^order``.

    ``terms`` holds ``(c, p, m)``.  Returns coefficients of ``x^0 ... x^(_SERIES_TERMS-1)`` of the
    bracket divided by ``x^order`` (lower coefficients must vanish; checked).
    """
    n = order + _SERIES_TERMS
    coef = [Fraction(0)] * n
    for c, p, m in terms:
        for k in range(n - p):
            coef[k + p] += c * Fraction((-m) ** k, factorial(k))
    if any(coef[:order]):
        raise RuntimeError("bracket does not vanish to the stated order")  # a bug, not user input
    return np.array([float(v) for v in coef[order:]])


_F = Fraction
# Singer (1970) process-noise brackets B_ij(x), x = alpha T:  Q_ij = alpha sigma^2 T^m B_ij / x^m
# (Singer's q_ij = B_ij / (2 alpha^m) times the white-noise density 2 alpha sigma^2).
_Q_BRACKETS: dict[tuple[int, int], tuple[int, list[tuple[Fraction, int, int]]]] = {
    (0, 0): (5, [(_F(1), 0, 0), (_F(-1), 0, 2), (_F(2), 1, 0), (_F(2, 3), 3, 0), (_F(-2), 2, 0),
                 (_F(-4), 1, 1)]),
    (0, 1): (4, [(_F(1), 0, 2), (_F(1), 0, 0), (_F(-2), 0, 1), (_F(2), 1, 1), (_F(-2), 1, 0),
                 (_F(1), 2, 0)]),
    (0, 2): (3, [(_F(1), 0, 0), (_F(-1), 0, 2), (_F(-2), 1, 1)]),
    (1, 1): (3, [(_F(4), 0, 1), (_F(-3), 0, 0), (_F(-1), 0, 2), (_F(2), 1, 0)]),
    (1, 2): (2, [(_F(1), 0, 2), (_F(1), 0, 0), (_F(-2), 0, 1)]),
    (2, 2): (1, [(_F(1), 0, 0), (_F(-1), 0, 2)]),
}
_Q_SERIES = {ij: (m, _bracket_coeffs(t, m)) for ij, (m, t) in _Q_BRACKETS.items()}
# Phi_13 = T^2 (x - 1 + e^-x) / x^2
_PHI13 = [(_F(1), 1, 0), (_F(-1), 0, 0), (_F(1), 0, 1)]
_PHI13_SERIES = _bracket_coeffs(_PHI13, 2)


def _closed(terms: list[tuple[Fraction, int, int]], x: np.ndarray) -> np.ndarray:
    return sum(float(c) * x**p * np.exp(-m * x) for c, p, m in terms)


def _bracket_over_xm(terms, order, series, x: np.ndarray) -> np.ndarray:
    """``B(x) / x^order`` with the series below :data:`_SERIES_X` and the closed form above."""
    small = x < _SERIES_X
    out = np.empty_like(x)
    xs = x[small]
    out[small] = np.polynomial.polynomial.polyval(xs, series)
    xl = x[~small]
    out[~small] = _closed(terms, xl) / xl**order
    return out


def _check_steps(T) -> np.ndarray:
    T = np.atleast_1d(np.asarray(T, dtype=np.float64))
    if not np.all(np.isfinite(T)) or np.any(T < 0):
        raise ValidationError("time steps must be finite and non-negative")
    return T


def singer_transition(alpha_m: float, T) -> np.ndarray:
    """Exact Singer transition matrix over steps ``T``.

    ``Phi = [[1, T, (alpha T - 1 + e^{-alpha T})/alpha^2], [0, 1, (1 - e^{-alpha T})/alpha],
    [0, 0, e^{-alpha T}]]`` (Singer 1970, eq. for Phi(T); METHODS.md s. 3), which seed 002's
    equations (1)-(3) approximate for small ``alpha T``.

    Parameters
    ----------
    alpha_m : manoeuvre rate 1/tau [1/s], > 0
    T : step(s) [s], scalar or (N,)

    Returns
    -------
    (N, 3, 3) array
    """
    if not alpha_m > 0:
        raise ValidationError(f"Singer alpha_m must be > 0 [1/s], got {alpha_m}")
    T = _check_steps(T)
    x = alpha_m * T
    F = np.zeros((T.size, 3, 3))
    F[:, 0, 0] = F[:, 1, 1] = 1.0
    F[:, 0, 1] = T
    # (1 - e^-x)/alpha = T (-expm1(-x))/x, with its limit T at x = 0
    F[:, 1, 2] = T * np.where(x > 0, -np.expm1(-x) / np.where(x > 0, x, 1.0), 1.0)
    F[:, 0, 2] = T**2 * _bracket_over_xm(_PHI13, 2, _PHI13_SERIES, x)
    F[:, 2, 2] = np.exp(-x)
    return F


def singer_process_noise(alpha_m: float, sigma_m, T) -> np.ndarray:
    """Exact Singer process-noise covariance over steps ``T``.

    ``Q = 2 alpha sigma_m^2 [q_ij]`` with Singer's (1970) closed forms, e.g.
    ``q_33 = (1 - e^{-2 alpha T}) / (2 alpha)``,
    ``q_11 = (1 - e^{-2aT} + 2aT + 2a^3T^3/3 - 2a^2T^2 - 4aT e^{-aT}) / (2 a^5)``; evaluated as
    ``alpha sigma^2 T^m B(x)/x^m`` (x = alpha T) with a Taylor series for small x.  As
    ``alpha -> 0`` with ``2 alpha sigma^2 = q`` fixed it tends to :func:`random_walk_matrices`.

    Parameters
    ----------
    alpha_m : manoeuvre rate [1/s], > 0
    sigma_m : standard deviation of the angular acceleration [rad/s^2], scalar or (N,)
    T : step(s) [s], scalar or (N,)

    Returns
    -------
    (N, 3, 3) array
    """
    if not alpha_m > 0:
        raise ValidationError(f"Singer alpha_m must be > 0 [1/s], got {alpha_m}")
    T = _check_steps(T)
    sigma_m = np.broadcast_to(np.asarray(sigma_m, dtype=np.float64), T.shape)
    x = alpha_m * T
    Q = np.empty((T.size, 3, 3))
    scale = alpha_m * sigma_m**2
    for (i, j), (m, terms) in _Q_BRACKETS.items():
        val = scale * T**m * _bracket_over_xm(terms, m, _Q_SERIES[(i, j)][1], x)
        Q[:, i, j] = Q[:, j, i] = val
    return Q


def random_walk_matrices(q, T) -> tuple[np.ndarray, np.ndarray]:
    """Exact discretisation of the aided model: ``a`` a random walk (white noise on ``a'``).

    ``Phi = [[1, T, T^2/2], [0, 1, T], [0, 0, 1]]`` (seed 002 eqs. (5)-(7)) and
    ``Q = q [[T^5/20, T^4/8, T^3/6], [T^4/8, T^3/3, T^2/2], [T^3/6, T^2/2, T]]``.

    Parameters
    ----------
    q : spectral density of ``a'`` [rad^2/s^5], scalar or (N,)
    T : step(s) [s], scalar or (N,)

    Returns
    -------
    Phi, Q : (N, 3, 3) arrays
    """
    T = _check_steps(T)
    q = np.broadcast_to(np.asarray(q, dtype=np.float64), T.shape)
    F = np.zeros((T.size, 3, 3))
    F[:, 0, 0] = F[:, 1, 1] = F[:, 2, 2] = 1.0
    F[:, 0, 1] = F[:, 1, 2] = T
    F[:, 0, 2] = T**2 / 2
    Q = np.empty((T.size, 3, 3))
    pw = {(0, 0): (5, 20), (0, 1): (4, 8), (0, 2): (3, 6), (1, 1): (3, 3), (1, 2): (2, 2),
          (2, 2): (1, 1)}
    for (i, j), (p, d) in pw.items():
        Q[:, i, j] = Q[:, j, i] = q * T**p / d
    return F, Q


# ---------------------------------------------------------------------------------------------
# The aided observation
# ---------------------------------------------------------------------------------------------


def _attitude_terms(n_long_g, n_lat_g, n_norm_g, roll_deg, pitch_deg):
    f = G0 * np.stack(np.broadcast_arrays(n_long_g, n_lat_g, -np.asarray(n_norm_g, float)), -1)
    phi = np.radians(roll_deg)
    th = np.radians(pitch_deg)
    sf, cf, st, ct = np.sin(phi), np.cos(phi), np.sin(th), np.cos(th)
    fx, fy, fz = f[..., 0], f[..., 1], f[..., 2]
    vx = ct * fx + st * (sf * fy + cf * fz)
    vy = cf * fy - sf * fz
    return f, (sf, cf, st, ct), vx, vy


def horizontal_acceleration(n_long_g, n_lat_g, n_norm_g, roll_deg, pitch_deg,
                            heading_deg) -> np.ndarray:
    """Horizontal kinematic acceleration (a_N, a_E) from body load factors and Euler attitude.

    METHODS.md "Common ground": ``a_NED = C_nb(heading, pitch, roll) g0 [n_long, n_lat, -n_norm]
    + [0, 0, g]``; gravity is vertical, so the horizontal rows need neither latitude nor height:
    ``[a_N, a_E] = Rz(heading) [v_x, v_y]`` with ``v = Ry(pitch) Rx(roll) g0 [n_long, n_lat,
    -n_norm]`` (ZYX order).

    Parameters
    ----------
    n_long_g, n_lat_g, n_norm_g : body load factors [g] (FRD, ``n_norm = -f_z/g0``), shape (N,)
    roll_deg, pitch_deg, heading_deg : Euler angles [deg], shape (N,)

    Returns
    -------
    (N, 2) array [m/s^2]: columns a_N, a_E

    Notes
    -----
    Delegates to :func:`flightrecon.geo.kinematics.kinematic_acceleration_ned`; the Jacobian
    below is written out here and checked against finite differences of this function.
    """
    from flightrecon.geo.kinematics import kinematic_acceleration_ned

    # gravity is vertical: the horizontal rows do not depend on where it is evaluated
    return kinematic_acceleration_ned(n_long_g, n_lat_g, n_norm_g, roll_deg, pitch_deg,
                                      heading_deg)[..., :2]


def horizontal_acceleration_jacobian(n_long_g, n_lat_g, n_norm_g, roll_deg, pitch_deg,
                                     heading_deg) -> np.ndarray:
    """Jacobian of :func:`horizontal_acceleration` with respect to its inputs.

    Columns: d/d n_long, d/d n_lat, d/d n_norm [m/s^2 per g], d/d roll, d/d pitch, d/d heading
    [m/s^2 per **rad**].  Analytic; checked against finite differences in the tests.

    Returns
    -------
    (N, 2, 6) array
    """
    f, (sf, cf, st, ct), vx, vy = _attitude_terms(n_long_g, n_lat_g, n_norm_g, roll_deg,
                                                   pitch_deg)
    fx, fy, fz = f[..., 0], f[..., 1], f[..., 2]
    ps = np.radians(heading_deg)
    sp, cp = np.sin(ps), np.cos(ps)
    zero = np.zeros_like(vx)
    # d(vx, vy)/d(fx, fy, fz, roll, pitch)
    dvx = [ct, st * sf, st * cf, st * vy, -st * fx + ct * (sf * fy + cf * fz)]
    dvy = [zero, cf, -sf, -sf * fy - cf * fz, zero]
    scale = [G0, G0, -G0, 1.0, 1.0]  # f = g0 [n_long, n_lat, -n_norm]
    J = np.empty(vx.shape + (2, 6))
    for c in range(5):
        J[..., 0, c] = (cp * dvx[c] - sp * dvy[c]) * scale[c]
        J[..., 1, c] = (sp * dvx[c] + cp * dvy[c]) * scale[c]
    aN = cp * vx - sp * vy
    aE = sp * vx + cp * vy
    J[..., 0, 5] = -aE
    J[..., 1, 5] = aN
    return J


def horizontal_acceleration_covariance(n_long_g, n_lat_g, n_norm_g, roll_deg, pitch_deg,
                                       heading_deg, *, sigma_load_g: float,
                                       sigma_attitude_deg: float,
                                       sigma_heading_deg: float) -> np.ndarray:
    """First-order covariance of (a_N, a_E) from sensor errors: ``J Sigma J^T``.

    ``Sigma = diag(s_n^2 (x3), s_att^2, s_att^2, s_hdg^2)`` with ``s_n`` the load-factor error
    per axis, ``s_att`` the roll/pitch error and ``s_hdg`` the heading error (angles converted to
    radians), ``J`` from :func:`horizontal_acceleration_jacobian`.  Called once for the white
    errors and once for the correlated ones (load-factor bias), which the filter weights
    differently (see :func:`azimuth_filter`).

    Returns
    -------
    (N, 2, 2) array [m^2/s^4]
    """
    for name, v in (("sigma_load_g", sigma_load_g), ("sigma_attitude_deg", sigma_attitude_deg),
                    ("sigma_heading_deg", sigma_heading_deg)):
        if not (np.isfinite(v) and v >= 0):
            raise ValidationError(f"{name} must be finite and >= 0, got {v}")
    J = horizontal_acceleration_jacobian(n_long_g, n_lat_g, n_norm_g, roll_deg, pitch_deg,
                                         heading_deg)
    s_load = sigma_load_g**2
    var = np.array([s_load, s_load, s_load, np.radians(sigma_attitude_deg) ** 2,
                    np.radians(sigma_attitude_deg) ** 2, np.radians(sigma_heading_deg) ** 2])
    return (J * var) @ np.swapaxes(J, -1, -2)


def transverse_acceleration(a_ne: np.ndarray, eps_rad) -> np.ndarray:
    """``z = a_E cos(eps) - a_N sin(eps)``: horizontal acceleration across the line of sight.

    By the kinematics in polar coordinates (docs/azimuth.md) ``z = 2 r_dot omega + r a``.

    Parameters
    ----------
    a_ne : (N, 2) [m/s^2] (a_N, a_E)
    eps_rad : azimuth [rad], (N,)
    """
    a_ne = np.asarray(a_ne, dtype=np.float64)
    return a_ne[..., 1] * np.cos(eps_rad) - a_ne[..., 0] * np.sin(eps_rad)


def wrap_pi(x):
    """Wrap angles [rad] to (-pi, pi]."""
    return np.pi - np.mod(np.pi - np.asarray(x, dtype=np.float64), 2 * np.pi)


# ---------------------------------------------------------------------------------------------
# Range tracker
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RangeTrack:
    """Smoothed horizontal range on the event times.

    ``r`` [m], ``r_dot`` [m/s] (N,), ``P`` (N, 2, 2) their smoothed covariance, ``nis`` the
    per-plot normalised innovation squared of the forward pass (NaN where no plot).
    """

    r: np.ndarray
    r_dot: np.ndarray
    P: np.ndarray
    nis: np.ndarray


def track_range(t_s, r_meas_m, r_var_m2, *, q_range_m2ps3: float) -> RangeTrack:
    """Constant-velocity Kalman filter and RTS smoother on the horizontal range.

    Exact CV discretisation (METHODS.md s. 2): ``F = [[1, T], [0, 1]]``,
    ``Q = q [[T^3/3, T^2/2], [T^2/2, T]]``; the generic kernels
    :func:`flightrecon.filters.kalman.kalman_filter` and :func:`rts_smooth_run`.

    Parameters
    ----------
    t_s : (N,) strictly increasing event times [s]
    r_meas_m : (N,) horizontal range measurements [m], NaN where no plot (the first must be
        present)
    r_var_m2 : (N,) their variances [m^2]
    q_range_m2ps3 : white range-acceleration spectral density [m^2/s^3]
    """
    t = np.asarray(t_s, dtype=np.float64)
    r_meas = np.asarray(r_meas_m, dtype=np.float64)
    if not np.isfinite(r_meas[0]):
        raise ValidationError("the range tracker must start at a radar plot")
    if not q_range_m2ps3 > 0:
        raise ValidationError(f"q_range_m2ps3 must be > 0, got {q_range_m2ps3}")
    T = np.diff(t, prepend=t[0])
    F = np.zeros((t.size, 2, 2))
    F[:, 0, 0] = F[:, 1, 1] = 1.0
    F[:, 0, 1] = T
    Q = np.empty((t.size, 2, 2))
    Q[:, 0, 0] = q_range_m2ps3 * T**3 / 3
    Q[:, 0, 1] = Q[:, 1, 0] = q_range_m2ps3 * T**2 / 2
    Q[:, 1, 1] = q_range_m2ps3 * T
    # initial velocity sd: 300 m/s bounds any aircraft's range rate in a terminal area
    P0 = np.diag([float(r_var_m2[0]), 300.0**2])
    R = np.where(np.isfinite(r_meas), np.asarray(r_var_m2, float), 1.0)[:, None, None]
    run = kalman_filter(np.array([r_meas[0], 0.0]), P0, F, Q, r_meas[:, None],
                        np.array([[1.0, 0.0]]), R)
    sm = rts_smooth_run(run)
    return RangeTrack(sm.x[:, 0].copy(), sm.x[:, 1].copy(), sm.P, run.nis)


# ---------------------------------------------------------------------------------------------
# Azimuth filter and smoother
# ---------------------------------------------------------------------------------------------


@nb.njit(cache=True, nogil=True)
def _wrap(x):
    return np.pi - np.mod(np.pi - x, 2.0 * np.pi)


@nb.njit(cache=True, nogil=True)
def _predict(F, Q, x, P):
    """``x = F x``, ``P = F P F^T + Q`` (3 x 3, explicit loops), symmetrised."""
    xn = np.zeros(3)
    FP = np.zeros((3, 3))
    Pn = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            xn[i] += F[i, j] * x[j]
            for m in range(3):
                FP[i, j] += F[i, m] * P[m, j]
    for i in range(3):
        for j in range(3):
            v = Q[i, j]
            for m in range(3):
                v += FP[i, m] * F[j, m]
            Pn[i, j] = v
    for i in range(3):
        for j in range(i + 1, 3):
            v = 0.5 * (Pn[i, j] + Pn[j, i])
            Pn[i, j] = v
            Pn[j, i] = v
    return xn, Pn


@nb.njit(cache=True, nogil=True)
def _scalar_update(x, P, h, nu, r):
    """Joseph-form scalar update ``P = (I - K h^T) P (I - K h^T)^T + r K K^T``; x, P, S."""
    Ph = np.zeros(3)
    for i in range(3):
        for j in range(3):
            Ph[i] += P[i, j] * h[j]
    S = r
    for i in range(3):
        S += h[i] * Ph[i]
    K = Ph / S
    xn = x + K * nu
    A = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            A[i, j] = (1.0 if i == j else 0.0) - K[i] * h[j]
    AP = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            for m in range(3):
                AP[i, j] += A[i, m] * P[m, j]
    Pn = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            v = r * K[i] * K[j]
            for m in range(3):
                v += AP[i, m] * A[j, m]
            Pn[i, j] = v
    for i in range(3):
        for j in range(i + 1, 3):
            v = 0.5 * (Pn[i, j] + Pn[j, i])
            Pn[i, j] = v
            Pn[j, i] = v
    return xn, Pn, S


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
    h_eps = np.array([1.0, 0.0, 0.0])
    for k in range(N):
        if k > 0:
            x, P = _predict(F[k], Q[k], x, P)
        xp[k] = x
        Pp[k] = P
        if not np.isnan(eps_meas[k]):
            nu = _wrap(eps_meas[k] - x[0])
            x, P, S = _scalar_update(x, P, h_eps, nu, eps_var[k])
            nu_e[k] = nu
            s_e[k] = S
        if not np.isnan(a_ne[k, 0]):
            e, om, a = x[0], x[1], x[2]
            s, c = np.sin(e), np.cos(e)
            zacc = a_ne[k, 1] * c - a_ne[k, 0] * s
            dz = -(a_ne[k, 1] * s + a_ne[k, 0] * c)
            h = np.array([-dz, 2.0 * rdot[k], r[k]])
            u0, u1 = -s, c
            rs = (u0 * u0 * Sa[k, 0, 0] + 2.0 * u0 * u1 * Sa[k, 0, 1] + u1 * u1 * Sa[k, 1, 1])
            rb = (u0 * u0 * Sb[k, 0, 0] + 2.0 * u0 * u1 * Sb[k, 0, 1] + u1 * u1 * Sb[k, 1, 1])
            g0_, g1_ = a, 2.0 * om  # dz_model / d(r, r_dot)
            rr = g0_ * g0_ * Pr[k, 0, 0] + 2.0 * g0_ * g1_ * Pr[k, 0, 1] + g1_ * g1_ * Pr[k, 1, 1]
            R = rs + n_corr * (rb + rr)
            nu = zacc - 2.0 * rdot[k] * om - r[k] * a
            x, P, S = _scalar_update(x, P, h, nu, R)
            nu_z[k] = nu
            s_z[k] = S
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


def azimuth_filter(t_s, eps_meas_rad, eps_var_rad2, range_track: RangeTrack, *, model: str,
                   a_ne=None, a_ne_cov=None, a_ne_cov_corr=None, alpha_m: float = 0.05,
                   sigma_m_mps2: float = 2.0, q_jerk_m2ps5: float = 0.2,
                   correlation_time_s: float = 0.0, v_max_mps: float = 150.0,
                   a_max_mps2: float = 5.0) -> AzimuthRun:
    """Filter and smooth the azimuth channel on the event times (METHODS.md s. 3).

    Parameters
    ----------
    t_s : (N,) strictly increasing event times [s]; the first event must hold a radar plot
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
    t = np.ascontiguousarray(np.asarray(t_s, dtype=np.float64))
    N = t.size
    if N < 2:
        raise ValidationError("the azimuth channel needs at least two events")
    dt = np.diff(t)
    if not np.all(dt > 0):
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
    T = np.concatenate([[0.0], dt])
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
    if not (np.isfinite(correlation_time_s) and correlation_time_s >= 0):
        raise ValidationError(f"correlation_time_s must be >= 0, got {correlation_time_s}")
    t_on = t[np.isfinite(a_ne[:, 0])]
    n_corr = 1.0
    if t_on.size > 1:
        n_corr = max(1.0, correlation_time_s / float(np.median(np.diff(t_on))))
    x0 = np.array([eps[0], 0.0, 0.0])
    P0 = np.diag([eps_var[0], (v_max_mps / r[0]) ** 2, (a_max_mps2 / r[0]) ** 2])
    out = _azimuth_kernel(x0, P0, np.ascontiguousarray(F), np.ascontiguousarray(Q), eps, eps_var,
                          a_ne, a_ne_cov, a_ne_cov_corr, r,
                          np.ascontiguousarray(range_track.r_dot),
                          np.ascontiguousarray(range_track.P), n_corr)
    xf, Pf, xp, Pp, nu_e, s_e, nu_z, s_z, r_z = out
    sm = rts_smooth(xf, Pf, xp, Pp, F)
    return AzimuthRun(t, xf, Pf, xp, Pp, F, sm.x, sm.P, nu_e, s_e, nu_z, s_z, r_z, model, n_corr)
