"""Exact discretisations of the process models, once for every method.

* constant velocity (white acceleration of spectral density ``q``), per axis:
  ``F = [[1, T], [0, 1]]``, ``Q = q [[T^3/3, T^2/2], [T^2/2, T]]``;
* first-order Gauss-Markov ``x' = -alpha x + w`` with stationary sd ``sigma``:
  ``phi = e^{-alpha T}``, ``var = sigma^2 (1 - e^{-2 alpha T})``;
* Singer's manoeuvring target (acceleration a Gauss-Markov process): transition and process
  noise in closed form, by series near ``alpha T = 0``;
* the integrated random walk of the aided azimuth model (random-walk acceleration).

Maths in docs/estimation.md, "Discretisations" (Singer's brackets: docs/azimuth.md).
"""

from __future__ import annotations

from fractions import Fraction
from math import factorial

import numba as nb
import numpy as np

from flightrecon.errors import ValidationError


def check_steps(dt) -> np.ndarray:
    """Steps ``dt`` (N,) as float64: 1-D, finite, positive after the first (the step into the
    first epoch, ``dt[0]``, is not used by the filters)."""
    dt = np.asarray(dt, dtype=np.float64)
    if dt.ndim != 1:
        raise ValidationError("time steps must be a 1-D array")
    if np.any(~np.isfinite(dt)) or np.any(dt[1:] <= 0):
        raise ValidationError("time steps must be finite and positive (times strictly increasing)")
    return dt


@nb.njit(cache=True, nogil=True)
def white_acceleration_q(q, T):
    """Process noise of one constant-velocity axis driven by white acceleration of spectral
    density ``q``: ``(Q_pp, Q_pv, Q_vv) = q (T^3/3, T^2/2, T)`` (Bar-Shalom et al. 2001, eq.
    6.2.2-12).  Compiled; ``T`` a float or an array (element-wise), so that the per-step kernels
    (the joint smoother's process noise) and the vectorised :func:`constant_velocity` share it.
    """
    return q * T ** 3 / 3.0, q * T ** 2 / 2.0, q * T


@nb.njit(cache=True, nogil=True)
def gauss_markov_step(alpha, var, T):
    """First-order Gauss-Markov ``x' = -alpha x + w`` of stationary variance ``var`` over a step
    ``T``: ``(phi, q) = (e^{-alpha T}, var (1 - e^{-2 alpha T}))``, the variance by ``-expm1``
    (accurate for small ``alpha T``).  Compiled; ``T`` a float or an array."""
    return np.exp(-alpha * T), var * -np.expm1(-2.0 * alpha * T)


def constant_velocity(dt, q: float) -> tuple[np.ndarray, np.ndarray]:
    """One axis of the constant-velocity model: ``F`` and ``Q``, each (N, 2, 2), for steps
    ``dt`` and white-acceleration spectral density ``q`` (Bar-Shalom et al. 2001, eq.
    6.2.2-12; :func:`white_acceleration_q`)."""
    T = check_steps(dt)
    F = np.zeros((len(T), 2, 2))
    F[:, 0, 0] = F[:, 1, 1] = 1.0
    F[:, 0, 1] = T
    Q = np.empty((len(T), 2, 2))
    qpp, qpv, qvv = white_acceleration_q(float(q), T)
    Q[:, 0, 0] = qpp
    Q[:, 0, 1] = Q[:, 1, 0] = qpv
    Q[:, 1, 1] = qvv
    return F, Q


def gauss_markov(dt, alpha: float, sigma: float) -> tuple[np.ndarray, np.ndarray]:
    """First-order Gauss-Markov process: ``phi = e^{-alpha T}`` and the exact step variance
    ``sigma^2 (1 - e^{-2 alpha T})`` (:func:`gauss_markov_step`), each (N,)."""
    T = check_steps(dt)
    return gauss_markov_step(float(alpha), float(sigma) ** 2, T)


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
    [0, 0, e^{-alpha T}]]`` (Singer 1970, eq. for Phi(T); docs/azimuth.md), which seed 002's
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
