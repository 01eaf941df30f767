"""Test reference for the Sabziev fusion: the paper's continuous closed forms (section IV,
corrected as docs/sabziev.md states) by adaptive quadrature.

Not part of the package: the tests compare the discrete recursion of
:mod:`flightrecon.methods.sabziev` with these.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np


# --------------------------------------------------------------------------------------------
# Closed forms of the paper (section IV), corrected per METHODS.md section 1, for checks
# --------------------------------------------------------------------------------------------
def _quad(f: Callable[[float], float], lo: float, hi: float) -> float:
    from scipy.integrate import quad

    if hi <= lo:
        return 0.0
    val, _err = quad(f, lo, hi, epsabs=1e-13, epsrel=1e-12, limit=2000)
    return float(val)


def _vertical_kernels(k2: float):
    """(S(s), C(s)): ``S = sin(w s)/w`` (k2 < 0), ``sinh(alpha s)/alpha`` (k2 > 0), ``s`` (0)."""
    if k2 < 0:
        w = np.sqrt(-k2)
        return (lambda s: np.sin(w * s) / w), (lambda s: np.cos(w * s))
    if k2 > 0:
        al = np.sqrt(k2)
        return (lambda s: np.sinh(al * s) / al), (lambda s: np.cosh(al * s))
    return (lambda s: s), (lambda s: 1.0)


def closed_form_vertical(t: float, k2: float, y0: float, a_fun: Callable[[float], float],
                         h_fun: Callable[[float], float]) -> tuple[float, float]:
    """Continuous solution ``(y(t), y'(t))`` of the vertical equation by its kernel integral.

    Paper equation (3) for k2 > 0 (sinh kernel, ``alpha = sqrt(k2)``) and METHODS.md section 1
    for k2 < 0 (sine kernel, ``w = sqrt(-k2)``)::

        y(t)  = y0 S(t) + int_0^t S(t - tau) (a_y(tau) - k2 h(tau)) dtau
        y'(t) = y0 C(t) + int_0^t C(t - tau) (a_y(tau) - k2 h(tau)) dtau

    The integrals are evaluated by adaptive quadrature (scipy ``quad``, rel. tol 1e-12): a
    reference for the discrete recursion, not a production path.
    """
    S, C = _vertical_kernels(k2)

    def u(tau):
        return a_fun(tau) - k2 * h_fun(tau)

    y = y0 * S(t) + _quad(lambda tau: S(t - tau) * u(tau), 0.0, t)
    yd = y0 * C(t) + _quad(lambda tau: C(t - tau) * u(tau), 0.0, t)
    return y, yd


def closed_form_horizontal(t: float, k: float, x0: float, a_fun: Callable[[float], float],
                           v_fun: Callable[[float], float]) -> tuple[float, float]:
    """Continuous solution ``(x(t), x'(t))`` of the horizontal equation (paper section IV)::

        x(t)  = x0 (e^{k t} - 1)/k + int_0^t (e^{k (t - tau)} - 1)/k (a(tau) - k v(tau)) dtau
        x'(t) = x0 e^{k t}          + int_0^t e^{k (t - tau)} (a(tau) - k v(tau)) dtau

    with ``(e^{k s} - 1)/k`` taken as ``s`` at ``k = 0``; quadrature as
    :func:`closed_form_vertical`.
    """
    def E(s):
        return np.expm1(k * s) / k if k != 0 else s

    def u(tau):
        return a_fun(tau) - k * v_fun(tau)

    x = x0 * E(t) + _quad(lambda tau: E(t - tau) * u(tau), 0.0, t)
    xd = x0 * np.exp(k * t) + _quad(lambda tau: np.exp(k * (t - tau)) * u(tau), 0.0, t)
    return x, xd


def paper_vertical_residual_alpha(alpha: float, T: float, y0: float, a_fun, h_fun,
                                  y_T: float) -> float:
    """Paper equation (4) with the factor 1/2 restored on its first term (METHODS.md section 1).

    ``F(alpha) = y0 (e^{aT} - e^{-aT})/(2 alpha) + int_0^T (e^{a(T-tau)} - e^{-a(T-tau)})/(2 alpha)
    (a_y - alpha^2 h) dtau - y_T``, for ``alpha = sqrt(k2) > 0``.
    """
    al = float(alpha)
    y = y0 * np.sinh(al * T) / al + _quad(
        lambda tau: np.sinh(al * (T - tau)) / al * (a_fun(tau) - al * al * h_fun(tau)), 0.0, T)
    return y - y_T


def paper_vertical_dresidual_dalpha(alpha: float, T: float, y0: float, a_fun, h_fun) -> float:
    """``dF/dalpha`` of equation (4), restated (the printed one is garbled; METHODS.md section 1).

    With ``D(s) = [e^{as}(as - 1) + e^{-as}(as + 1)] / (2 a^2) = d/da [sinh(as)/a]``::

        dF/da = y0 D(T) + int_0^T [ D(T - tau) (a_y - a^2 h) - 2 sinh(a (T - tau)) h ] dtau
    """
    al = float(alpha)

    def D(s):
        return (al * s * np.cosh(al * s) - np.sinh(al * s)) / (al * al)

    return y0 * D(T) + _quad(lambda tau: D(T - tau) * (a_fun(tau) - al * al * h_fun(tau))
                             - 2.0 * np.sinh(al * (T - tau)) * h_fun(tau), 0.0, T)


def paper_horizontal_residual(k: float, T: float, x0: float, a_fun, v_fun, x_T: float) -> float:
    """Paper's horizontal end-point residual ``F(k1) = x(k1, T) - x_T`` (section IV)."""
    return closed_form_horizontal(T, k, x0, a_fun, v_fun)[0] - x_T


def paper_horizontal_dresidual_dk(k: float, T: float, x0: float, a_fun, v_fun) -> float:
    """Paper's ``dF/dk1`` (section IV; printed correctly)::

        dF/dk = x0 (e^{kT}(kT - 1) + 1)/k^2
              + int_0^T [e^{k s}(a (k s - 1) - k^2 s v) + a] / k^2 dtau,   s = T - tau
    """
    k = float(k)

    def g(tau):
        s = T - tau
        return (np.exp(k * s) * (a_fun(tau) * (k * s - 1.0) - k * k * s * v_fun(tau))
                + a_fun(tau)) / (k * k)

    return x0 * (np.exp(k * T) * (k * T - 1.0) + 1.0) / (k * k) + _quad(g, 0.0, T)
