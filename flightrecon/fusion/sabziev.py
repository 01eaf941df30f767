"""Sabziev boundary-value fusion: the discrete analogue, its exact sensitivities, closed forms.

Implements METHODS.md section 1 (seed 001, Sabziev 2020, section IV) on a uniform time grid.
Frame (METHODS.md section 1): origin at the lift-off point, ``x`` north, ``y`` up, ``z`` east.

Model, one linear ODE per axis with one coefficient each::

    y'' - k2 y  = a_y - k2 h                       (vertical, state [y, y'])
    s'' - k  s' = a_s - k v_s      s in {x, z}     (horizontal, state [s, s'])

Both are ``q' = A(k) q + b u(t)`` with ``b = [0, 1]`` and the scalar input
``u = a - k w`` (``w = h`` for the vertical, ``w = v_s`` for the horizontal axes).

Discretisation (see docs/sabziev.md, "Discretisation")
------------------------------------------------------
The input is held *first-order* between samples (piecewise linear through the samples; option
``hold="zero"`` holds it constant) and the ODE is integrated exactly over each step ``h``::

    q_{i+1} = Phi q_i + G0 u_i + G1 (u_{i+1} - u_i)
    Phi = expm(A h),  G0 = int_0^h expm(A s) b ds,  G1 = (1/h) int_0^h expm(A s) b (h - s) ds

For the horizontal axes (``z = k h``, ``phi_j(z) = sum_m z^m / (m + j)!``, the exponential-
integrator functions, ``phi_1 = expm1(z)/z``)::

    Phi = [[1, h phi_1], [0, phi_0]],  G0 = [h^2 phi_2, h phi_1],  G1 = [h^2 phi_3, h phi_2]

For the vertical axis (``q = k2 h^2``, ``psi_j(q) = sum_m q^m / (2m + j)!``, so
``psi_0 = cosh(sqrt(q))`` or ``cos(sqrt(-q))``, ``psi_1 = sinh(sqrt q)/sqrt q`` or
``sin(sqrt(-q))/sqrt(-q)``)::

    Phi = [[psi_0, h psi_1], [k2 h psi_1, psi_0]],  G0 = [h^2 psi_2, h psi_1],
    G1 = [h^2 psi_3, h psi_2]

These functions are entire in ``k``: near ``k = 0`` they are summed as series (no cancellation),
elsewhere from ``exp``/``cosh``/``cos`` closed forms.  Their derivatives follow from
``z phi_j' = phi_{j-1} - j phi_j`` and ``2 q psi_j' = psi_{j-1} - j psi_j`` (series near 0).

The sensitivity ``sigma_i = d q_i / d k`` obeys the differentiated recursion (exact derivative
of the *discrete* end point, which is what Newton-Raphson solves)::

    sigma_{i+1} = Phi sigma_i + Phi' q_i + G0' u_i + G1' (u_{i+1} - u_i)
                  + G0 u'_i + G1 (u'_{i+1} - u'_i),     u' = d u / d k = -w

Both recursions are compiled with numba: one pass over 691,200 samples takes a few ms.  The
root scan, which needs ``F`` (not its derivative) at a few hundred ``k``, evaluates all of
them in one pass over the data (:func:`propagate_end_many`, SIMD across ``k``); every lane
does the same floating-point operations as the single evaluation, so the scan values, and
with them the brackets and the root taken, are bit-identical to point-by-point evaluation.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from functools import cached_property

import numba as nb
import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.fusion.newton import RootReport, find_coefficient

__all__ = [
    "KT_MAX",
    "AxisSolution",
    "SabzievSolution",
    "StepCoefficients",
    "air_velocity",
    "check_grid",
    "closed_form_horizontal",
    "closed_form_vertical",
    "fuse",
    "horizontal_end_point",
    "horizontal_step",
    "paper_horizontal_dresidual_dk",
    "paper_horizontal_residual",
    "paper_vertical_dresidual_dalpha",
    "paper_vertical_residual_alpha",
    "phi_functions",
    "propagate_end",
    "propagate_end_many",
    "propagate_path",
    "psi_functions",
    "solve_axis_horizontal",
    "solve_axis_y",
    "vertical_end_point",
    "vertical_step",
]

HOLDS = ("linear", "zero")
"""Input holds between samples: first-order (default) or zero-order."""

_SERIES_LIMIT = 1.0
"""Below this |argument| the phi/psi functions are summed as series (30 terms: 1/33! ~ 1e-37)."""
_SERIES_TERMS = 30


# --------------------------------------------------------------------------------------------
# phi_j(z) and psi_j(q) with their derivatives
# --------------------------------------------------------------------------------------------
@nb.njit(cache=True, nogil=True)
def phi_functions(z: float) -> tuple[np.ndarray, np.ndarray]:
    """Exponential-integrator functions ``phi_j(z) = sum_m z^m/(m+j)!``, j = 0..3, and derivatives.

    ``phi_0 = e^z``, ``phi_1 = expm1(z)/z``, ``phi_{j+1} = (phi_j - 1/j!)/z``;
    ``phi_j'(z) = sum_m m z^(m-1)/(m+j)!`` = ``(phi_{j-1} - j phi_j)/z`` (j >= 1), ``phi_0' = e^z``.
    Series for ``|z| < 1`` (no cancellation near the removable singularity ``k = 0``).

    Returns
    -------
    phi, dphi : arrays of shape (4,)
    """
    phi = np.zeros(4)
    dphi = np.zeros(4)
    if abs(z) < _SERIES_LIMIT:
        for j in range(4):
            term = 1.0
            for i in range(1, j + 1):
                term /= i  # 1/j!
            s = 0.0
            ds = 0.0
            zp = 1.0  # z^m
            zpm1 = 0.0  # m z^(m-1)
            for m in range(_SERIES_TERMS):
                s += zp * term
                ds += zpm1 * term
                zpm1 = (m + 1) * zp
                zp *= z
                term /= m + j + 1
            phi[j] = s
            dphi[j] = ds
    else:
        e = np.exp(z)
        phi[0] = e
        phi[1] = np.expm1(z) / z
        phi[2] = (phi[1] - 1.0) / z
        phi[3] = (phi[2] - 0.5) / z
        dphi[0] = e
        for j in range(1, 4):
            dphi[j] = (phi[j - 1] - j * phi[j]) / z
    return phi, dphi


@nb.njit(cache=True, nogil=True)
def psi_functions(q: float) -> tuple[np.ndarray, np.ndarray]:
    """Even kernels ``psi_j(q) = sum_m q^m/(2m+j)!``, j = 0..3, and their derivatives in ``q``.

    ``psi_0 = cosh(sqrt q)`` (``cos(sqrt(-q))`` for q < 0), ``psi_1 = sinh(sqrt q)/sqrt q``
    (``sin(w)/w``), ``psi_{j+2} = (psi_j - 1/j!)/q``; ``psi_0' = psi_1/2`` and
    ``psi_j' = (psi_{j-1} - j psi_j)/(2q)`` for j >= 1.  Series for ``|q| < 1``.

    Returns
    -------
    psi, dpsi : arrays of shape (4,)
    """
    psi = np.zeros(4)
    dpsi = np.zeros(4)
    if abs(q) < _SERIES_LIMIT:
        for j in range(4):
            term = 1.0
            for i in range(1, j + 1):
                term /= i  # 1/j!
            s = 0.0
            ds = 0.0
            qp = 1.0
            qpm1 = 0.0
            for m in range(_SERIES_TERMS):
                s += qp * term
                ds += qpm1 * term
                qpm1 = (m + 1) * qp
                qp *= q
                term /= (2 * m + j + 1) * (2 * m + j + 2)
            psi[j] = s
            dpsi[j] = ds
    else:
        if q > 0.0:
            r = np.sqrt(q)
            psi[0] = np.cosh(r)
            psi[1] = np.sinh(r) / r
        else:
            r = np.sqrt(-q)
            psi[0] = np.cos(r)
            psi[1] = np.sin(r) / r
        psi[2] = (psi[0] - 1.0) / q
        psi[3] = (psi[1] - 1.0) / q
        dpsi[0] = 0.5 * psi[1]
        for j in range(1, 4):
            dpsi[j] = (psi[j - 1] - j * psi[j]) / (2.0 * q)
    return psi, dpsi


# --------------------------------------------------------------------------------------------
# One-step coefficients
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StepCoefficients:
    """Exact one-step transition for a held input, and its derivatives in ``k``.

    Attributes
    ----------
    Phi, dPhi : (2, 2) transition ``expm(A h)`` and ``d Phi / d k``
    G0, dG0 : (2,) gain of ``u_i`` (zero-order part) and its derivative
    G1, dG1 : (2,) gain of ``u_{i+1} - u_i`` (first-order part; zero for ``hold="zero"``)
    """

    Phi: np.ndarray
    dPhi: np.ndarray
    G0: np.ndarray
    dG0: np.ndarray
    G1: np.ndarray
    dG1: np.ndarray

    def packed(self) -> tuple[np.ndarray, ...]:
        """The six arrays, contiguous float64, in kernel order."""
        return tuple(np.ascontiguousarray(a, dtype=np.float64)
                     for a in (self.Phi, self.dPhi, self.G0, self.dG0, self.G1, self.dG1))


@nb.njit(cache=True, nogil=True)
def _step_rows(vertical: bool, ks, dt: float, linear: bool):
    """(8, K) rows ``Phi00, Phi01, Phi10, Phi11, G0[0], G0[1], G1[0], G1[1]`` for many ``k``.

    The same floating-point operations as :func:`horizontal_step` / :func:`vertical_step`
    (bit-identical; tested), compiled: the scan needs hundreds of them.
    """
    K = ks.shape[0]
    C = np.zeros((8, K))
    h = dt
    h2 = h * h
    for j in range(K):
        k = ks[j]
        if vertical:
            psi, _ = psi_functions(k * h2)
            C[0, j] = psi[0]
            C[1, j] = h * psi[1]
            C[2, j] = k * h * psi[1]
            C[3, j] = psi[0]
            C[4, j] = h2 * psi[2]
            C[5, j] = h * psi[1]
            if linear:
                C[6, j] = h2 * psi[3]
                C[7, j] = h * psi[2]
        else:
            phi, _ = phi_functions(k * h)
            C[0, j] = 1.0
            C[1, j] = h * phi[1]
            C[2, j] = 0.0
            C[3, j] = phi[0]
            C[4, j] = h * h * phi[2]
            C[5, j] = h * phi[1]
            if linear:
                C[6, j] = h * h * phi[3]
                C[7, j] = h * phi[2]
    return C


def _check_hold(hold: str) -> None:
    if hold not in HOLDS:
        raise ValidationError(f"hold must be one of {HOLDS}, got {hold!r}")


def horizontal_step(k: float, dt: float, hold: str = "linear") -> StepCoefficients:
    """One-step coefficients of ``s'' - k s' = u`` (module docstring, horizontal axes).

    Parameters
    ----------
    k : coefficient k1 or k3 [1/s]
    dt : step [s]
    hold : ``"linear"`` (first-order hold) or ``"zero"`` (zero-order hold)
    """
    _check_hold(hold)
    h = float(dt)
    phi, dphi = phi_functions(float(k) * h)
    Phi = np.array([[1.0, h * phi[1]], [0.0, phi[0]]])
    dPhi = np.array([[0.0, h * h * dphi[1]], [0.0, h * dphi[0]]])
    G0 = np.array([h * h * phi[2], h * phi[1]])
    dG0 = np.array([h**3 * dphi[2], h * h * dphi[1]])
    if hold == "linear":
        G1 = np.array([h * h * phi[3], h * phi[2]])
        dG1 = np.array([h**3 * dphi[3], h * h * dphi[2]])
    else:
        G1 = np.zeros(2)
        dG1 = np.zeros(2)
    return StepCoefficients(Phi, dPhi, G0, dG0, G1, dG1)


def vertical_step(k2: float, dt: float, hold: str = "linear") -> StepCoefficients:
    """One-step coefficients of ``y'' - k2 y = u`` (module docstring, vertical axis).

    Parameters
    ----------
    k2 : coefficient [1/s^2]; negative: oscillatory (cos/sin kernel), positive: cosh/sinh
    dt : step [s]
    hold : ``"linear"`` or ``"zero"``
    """
    _check_hold(hold)
    h = float(dt)
    k2 = float(k2)
    h2 = h * h
    psi, dpsi = psi_functions(k2 * h2)
    # d psi_j(k2 h^2) / d k2 = h^2 psi_j'
    Phi = np.array([[psi[0], h * psi[1]], [k2 * h * psi[1], psi[0]]])
    dPhi = np.array([[h2 * dpsi[0], h**3 * dpsi[1]],
                     [h * psi[1] + k2 * h**3 * dpsi[1], h2 * dpsi[0]]])
    G0 = np.array([h2 * psi[2], h * psi[1]])
    dG0 = np.array([h2 * h2 * dpsi[2], h**3 * dpsi[1]])
    if hold == "linear":
        G1 = np.array([h2 * psi[3], h * psi[2]])
        dG1 = np.array([h2 * h2 * dpsi[3], h**3 * dpsi[2]])
    else:
        G1 = np.zeros(2)
        dG1 = np.zeros(2)
    return StepCoefficients(Phi, dPhi, G0, dG0, G1, dG1)


# --------------------------------------------------------------------------------------------
# Compiled recursions
# --------------------------------------------------------------------------------------------
@nb.njit(cache=True, nogil=True)
def _step(Phi, dPhi, G0, dG0, G1, dG1, q0, q1, s0, s1, u0, u1, du0, du1):
    d = u1 - u0
    dd = du1 - du0
    n0 = Phi[0, 0] * q0 + Phi[0, 1] * q1 + G0[0] * u0 + G1[0] * d
    n1 = Phi[1, 0] * q0 + Phi[1, 1] * q1 + G0[1] * u0 + G1[1] * d
    m0 = (Phi[0, 0] * s0 + Phi[0, 1] * s1 + dPhi[0, 0] * q0 + dPhi[0, 1] * q1
          + dG0[0] * u0 + dG1[0] * d + G0[0] * du0 + G1[0] * dd)
    m1 = (Phi[1, 0] * s0 + Phi[1, 1] * s1 + dPhi[1, 0] * q0 + dPhi[1, 1] * q1
          + dG0[1] * u0 + dG1[1] * d + G0[1] * du0 + G1[1] * dd)
    return n0, n1, m0, m1


@nb.njit(cache=True, nogil=True)
def _is_horizontal(Phi, dPhi) -> bool:
    """The horizontal structure ``Phi[:, 0] = (1, 0)``, ``dPhi[:, 0] = 0`` (module docstring).

    With it the terms ``1 * x``, ``0 * x`` of :func:`_step` are dropped: the same numbers for
    finite states (``1 x = x`` and ``x + 0 = x`` exactly in IEEE arithmetic; only the sign of
    an exact zero can differ), a fifth fewer operations on the hot loop.
    """
    return (Phi[0, 0] == 1.0 and Phi[1, 0] == 0.0 and dPhi[0, 0] == 0.0
            and dPhi[1, 0] == 0.0)


@nb.njit(cache=True, nogil=True)
def _run_end(Phi, dPhi, G0, dG0, G1, dG1, q0, s0, a, w, k, dscale):
    """End state, sensitivity and misfit; input ``u_i = a_i - k w_i``, ``du_i/dk = -dscale w_i``.

    Returns ``[q_N, sigma_N, rms(q[:, 0] - w)]`` (5 numbers); the misfit is the vertical
    track's RMS distance from the baro height used by the root selection.  The horizontal
    structure (:func:`_is_horizontal`) runs a loop without the unit and zero entries.
    """
    n = a.shape[0]
    x0 = q0[0]
    x1 = q0[1]
    y0 = s0[0]
    y1 = s0[1]
    u_prev = a[0] - k * w[0]
    du_prev = -dscale * w[0]
    m0 = (x0 - w[0]) ** 2
    if _is_horizontal(Phi, dPhi):
        p01 = Phi[0, 1]
        p11 = Phi[1, 1]
        dp01 = dPhi[0, 1]
        dp11 = dPhi[1, 1]
        g00 = G0[0]
        g01 = G0[1]
        g10 = G1[0]
        g11 = G1[1]
        dg00 = dG0[0]
        dg01 = dG0[1]
        dg10 = dG1[0]
        dg11 = dG1[1]
        for i in range(n - 1):
            u_next = a[i + 1] - k * w[i + 1]
            du_next = -dscale * w[i + 1]
            d = u_next - u_prev
            dd = du_next - du_prev
            n0 = x0 + p01 * x1 + g00 * u_prev + g10 * d
            n1 = p11 * x1 + g01 * u_prev + g11 * d
            z0 = (y0 + p01 * y1 + dp01 * x1 + dg00 * u_prev + dg10 * d + g00 * du_prev
                  + g10 * dd)
            z1 = (p11 * y1 + dp11 * x1 + dg01 * u_prev + dg11 * d + g01 * du_prev
                  + g11 * dd)
            x0 = n0
            x1 = n1
            y0 = z0
            y1 = z1
            m0 += (x0 - w[i + 1]) ** 2
            u_prev = u_next
            du_prev = du_next
    else:
        for i in range(n - 1):
            u_next = a[i + 1] - k * w[i + 1]
            du_next = -dscale * w[i + 1]
            x0, x1, y0, y1 = _step(Phi, dPhi, G0, dG0, G1, dG1, x0, x1, y0, y1,
                                   u_prev, u_next, du_prev, du_next)
            m0 += (x0 - w[i + 1]) ** 2
            u_prev = u_next
            du_prev = du_next
    out = np.empty(5)
    out[0] = x0
    out[1] = x1
    out[2] = y0
    out[3] = y1
    out[4] = np.sqrt(m0 / n)
    return out


@nb.njit(cache=True, nogil=True)
def _run_path(Phi, dPhi, G0, dG0, G1, dG1, q0, s0, a, w, k, dscale):
    """Whole path of state (n, 2) and sensitivity (n, 2); same inputs as :func:`_run_end`."""
    n = a.shape[0]
    Q = np.empty((n, 2))
    S = np.empty((n, 2))
    Q[0, 0] = q0[0]
    Q[0, 1] = q0[1]
    S[0, 0] = s0[0]
    S[0, 1] = s0[1]
    u_prev = a[0] - k * w[0]
    du_prev = -dscale * w[0]
    for i in range(n - 1):
        u_next = a[i + 1] - k * w[i + 1]
        du_next = -dscale * w[i + 1]
        x0, x1, y0, y1 = _step(Phi, dPhi, G0, dG0, G1, dG1, Q[i, 0], Q[i, 1], S[i, 0], S[i, 1],
                               u_prev, u_next, du_prev, du_next)
        Q[i + 1, 0] = x0
        Q[i + 1, 1] = x1
        S[i + 1, 0] = y0
        S[i + 1, 1] = y1
        u_prev = u_next
        du_prev = du_next
    return Q, S


@nb.njit(cache=True, nogil=True)
def _run_end_batch(C, q0, a, w, ks):
    """End state and misfit for many ``k`` in one pass over the data (no sensitivity).

    ``C`` is (8, K): rows ``Phi00, Phi01, Phi10, Phi11, G0[0], G0[1], G1[0], G1[1]`` of each
    lane's :class:`StepCoefficients`; lane ``j`` has input ``u = a - ks[j] w``.  Every lane
    performs the same floating-point operations in the same order as the state part of
    :func:`_run_end`, so its end state and first misfit are bit-identical to a single call
    (tested); the lanes are independent, so the inner loop over ``k`` runs in SIMD and the
    pass reads ``a`` and ``w`` once for all lanes instead of once per ``k``.

    Returns
    -------
    (K, 3): ``[q_N[0], q_N[1], rms(q[:, 0] - w)]`` per lane
    """
    n = a.shape[0]
    K = ks.shape[0]
    p00 = C[0]
    p01 = C[1]
    p10 = C[2]
    p11 = C[3]
    g00 = C[4]
    g01 = C[5]
    g10 = C[6]
    g11 = C[7]
    x0 = np.empty(K)
    x1 = np.empty(K)
    up = np.empty(K)
    m0 = np.empty(K)
    for j in range(K):
        x0[j] = q0[0]
        x1[j] = q0[1]
        up[j] = a[0] - ks[j] * w[0]
        m0[j] = (q0[0] - w[0]) ** 2
    horizontal = True
    for j in range(K):
        if p00[j] != 1.0 or p10[j] != 0.0:
            horizontal = False
    if horizontal:  # unit and zero entries dropped: same numbers (see _is_horizontal)
        for i in range(n - 1):
            ai = a[i + 1]
            wi = w[i + 1]
            for j in range(K):
                un = ai - ks[j] * wi
                u0 = up[j]
                d = un - u0
                X1 = x1[j]
                n0 = x0[j] + p01[j] * X1 + g00[j] * u0 + g10[j] * d
                x1[j] = p11[j] * X1 + g01[j] * u0 + g11[j] * d
                x0[j] = n0
                m0[j] += (n0 - wi) ** 2
                up[j] = un
    else:
        for i in range(n - 1):
            ai = a[i + 1]
            wi = w[i + 1]
            for j in range(K):
                un = ai - ks[j] * wi
                u0 = up[j]
                d = un - u0
                X0 = x0[j]
                X1 = x1[j]
                n0 = p00[j] * X0 + p01[j] * X1 + g00[j] * u0 + g10[j] * d
                n1 = p10[j] * X0 + p11[j] * X1 + g01[j] * u0 + g11[j] * d
                x0[j] = n0
                x1[j] = n1
                m0[j] += (n0 - wi) ** 2
                up[j] = un
    out = np.empty((K, 3))
    for j in range(K):
        out[j, 0] = x0[j]
        out[j, 1] = x1[j]
        out[j, 2] = np.sqrt(m0[j] / n)
    return out


def _f64(x) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(x, dtype=np.float64))


def propagate_end(coef: StepCoefficients, q0, a, w, k: float, *, s0=(0.0, 0.0),
                  dscale: float = 1.0) -> tuple[np.ndarray, np.ndarray, float]:
    """End state ``q_N`` and its sensitivity for input ``u = a - k w`` (module docstring).

    Parameters
    ----------
    coef : one-step coefficients for this ``k`` and step
    q0 : (2,) initial state
    a, w : (N,) input arrays on the grid
    k : the coefficient in ``u = a - k w``
    s0 : (2,) initial sensitivity (zero: the initial conditions do not depend on ``k``)
    dscale : ``du/dk = -dscale w`` (1 for the own coefficient)

    Returns
    -------
    q_N, sigma_N : (2,) arrays
    misfit : RMS over the grid of ``q[:, 0] - w`` (for the vertical axis: ``y - h`` [m])
    """
    out = _run_end(*coef.packed(), _f64(q0), _f64(s0), _f64(a), _f64(w), float(k), float(dscale))
    return out[:2], out[2:4], float(out[4])


def propagate_end_many(kind: str, ks, dt: float, q0, a, w, *,
                       hold: str = "linear") -> tuple[np.ndarray, np.ndarray]:
    """End states and misfits for many ``k`` at once (the root scan; no sensitivities).

    Parameters
    ----------
    kind : ``"horizontal"`` or ``"vertical"`` (:func:`horizontal_step` / :func:`vertical_step`)
    ks : (K,) coefficients; lane ``j`` has input ``u = a - ks[j] w``
    dt : step [s]
    q0 : (2,) initial state
    a, w : (N,) input arrays on the grid
    hold : ``"linear"`` or ``"zero"``

    Returns
    -------
    q_N : (K, 2) end states, bit-identical to :func:`propagate_end` with the same ``k``
    misfit : (K,) RMS of ``q[:, 0] - w``, bit-identical to :func:`propagate_end`'s
    """
    _check_hold(hold)
    if kind not in ("horizontal", "vertical"):
        raise ValidationError(f"kind must be 'horizontal' or 'vertical', got {kind!r}")
    ks = _f64(ks).reshape(-1)
    if ks.size == 0:
        return np.empty((0, 2)), np.empty(0)
    C = _step_rows(kind == "vertical", ks, float(dt), hold == "linear")
    out = _run_end_batch(C, _f64(q0), _f64(a), _f64(w), ks)
    return out[:, :2], out[:, 2]


def propagate_path(coef: StepCoefficients, q0, a, w, k: float, *, s0=(0.0, 0.0),
                   dscale: float = 1.0) -> tuple[np.ndarray, np.ndarray]:
    """Whole path: states (N, 2) and sensitivities (N, 2); arguments as :func:`propagate_end`."""
    return _run_path(*coef.packed(), _f64(q0), _f64(s0), _f64(a), _f64(w), float(k),
                     float(dscale))


# --------------------------------------------------------------------------------------------
# Grid and end-point functions F(k) with exact derivative
# --------------------------------------------------------------------------------------------
def check_grid(t) -> float:
    """Validate a uniform, strictly increasing time grid and return its step [s].

    Raises
    ------
    ValidationError
        Fewer than 2 samples, non-finite or non-increasing times, or a non-uniform step
        (any step off the mean step by more than 1e-6 of it: the exact discretisation uses one
        ``Phi`` for all steps).
    """
    t = np.asarray(t, dtype=np.float64)
    if t.ndim != 1 or t.size < 2:
        raise ValidationError("the Sabziev fusion needs a 1-D time grid of at least 2 samples")
    if not np.all(np.isfinite(t)):
        raise ValidationError("time grid has non-finite values", column="t_s")
    d = np.diff(t)
    if np.any(d <= 0):
        raise ValidationError("time grid not strictly increasing", column="t_s",
                              rows=(np.flatnonzero(d <= 0) + 2).tolist())
    dt = (t[-1] - t[0]) / (t.size - 1)
    bad = np.abs(d - dt) > 1e-6 * dt
    if np.any(bad):
        raise ValidationError(f"time grid not uniform (step {dt:g} s): the exact discretisation "
                              "needs one step; resample first", column="t_s",
                              rows=(np.flatnonzero(bad) + 2).tolist())
    return float(dt)


def vertical_end_point(k2: float, dt: float, a_y, h, y0: float,
                       hold: str = "linear") -> tuple[float, float]:
    """Discrete end point ``y_N(k2)`` and its exact derivative ``d y_N / d k2``.

    ``y'' - k2 y = a_y - k2 h``, ``y(0) = 0``, ``y'(0) = y0`` (METHODS.md section 1).
    """
    q, s, _ = propagate_end(vertical_step(k2, dt, hold), (0.0, y0), a_y, h, k2)
    return float(q[0]), float(s[0])


def horizontal_end_point(k: float, dt: float, a, v, s0: float,
                         hold: str = "linear") -> tuple[float, float]:
    """Discrete end point ``x_N(k)`` and its exact derivative ``d x_N / d k``.

    ``x'' - k x' = a - k v``, ``x(0) = 0``, ``x'(0) = s0`` (METHODS.md section 1).
    """
    q, s, _ = propagate_end(horizontal_step(k, dt, hold), (0.0, s0), a, v, k)
    return float(q[0]), float(s[0])


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



# --------------------------------------------------------------------------------------------
# Library API: one axis, and the three-axis fusion
# --------------------------------------------------------------------------------------------
KT_MAX = 25.0
"""Overflow guard: positive-branch coefficients are limited to ``k T <= KT_MAX`` (horizontal)
and ``sqrt(k2) T <= KT_MAX`` (vertical).  Beyond that the solution weights the lift-off data by
more than e^25 ~ 7e10 and rounding alone moves a 100 km end point by metres: such a "root"
cannot be resolved (found on simulated flights at k T ~ 44: residual 8e6 m)."""

POINTS_PER_DECADE = 12
"""Scan density of the root search in |k| (:mod:`flightrecon.fusion.newton`, step 3)."""


@dataclass(frozen=True)
class AxisSolution:
    """Solution of one Sabziev axis on the grid.

    Attributes
    ----------
    k : the coefficient used (NaN if the boundary-value problem has no root)
    position_m, velocity_mps : (N,) track and rate along the axis (NaN if no root)
    dposition_dk, dvelocity_dk : (N,) exact sensitivities of the discrete track to ``k``
    report : root-finder report (``None`` in the initial-value mode, ``k`` given)
    """

    k: float
    position_m: np.ndarray
    velocity_mps: np.ndarray
    dposition_dk: np.ndarray
    dvelocity_dk: np.ndarray
    report: RootReport | None = None


def _arr(name: str, x, n: int) -> np.ndarray:
    a = np.ascontiguousarray(np.asarray(x, dtype=np.float64))
    if a.shape != (n,):
        raise ValidationError(f"{name} must have shape ({n},), got {a.shape}")
    if not np.all(np.isfinite(a)):
        bad = np.flatnonzero(~np.isfinite(a))
        raise ValidationError(f"{name} has non-finite values (first at sample {bad[0]}): fill or "
                              "cut gaps before the fusion")
    return a


def _solve_axis(kind: str, t, a, w, v0: float, s_T: float | None, k: float | None,
                k0: float | None, hold: str, tol_m: float, max_iter: int, parametrisation: str,
                kt_max: float, strict: bool, axis: str, rule: str = "slowest") -> AxisSolution:
    dt = check_grid(t)
    n = len(t)
    a = _arr(f"{axis} acceleration", a, n)
    w = _arr(f"{axis} reference", w, n)
    _check_hold(hold)
    step = vertical_step if kind == "vertical" else horizontal_step
    T = dt * (n - 1)
    report = None
    if k is None:
        if s_T is None or not np.isfinite(s_T):
            raise ValidationError(f"{axis} axis: give the end point or the coefficient k")

        def fun(kk: float) -> tuple[float, float, float]:
            q, s, misfit = propagate_end(step(kk, dt, hold), (0.0, v0), a, w, kk)
            return float(q[0]) - s_T, float(s[0]), misfit

        def fun_many(kks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            # the scan: same F and misfit as fun, all k in one pass over the data
            q, misfit = propagate_end_many(kind, kks, dt, (0.0, v0), a, w, hold=hold)
            return q[:, 0] - s_T, misfit

        if kind == "vertical":
            k_ref, k_pos, k_neg = T**-2, (kt_max / T) ** 2, (0.5 / dt) ** 2
        else:
            k_ref, k_pos, k_neg = 1.0 / T, kt_max / T, 1.0 / dt
        report = find_coefficient(fun, k_ref=k_ref, k_max_pos=k_pos, k_max_neg=k_neg, k0=k0,
                                  tol_m=tol_m, max_iter=max_iter,
                                  points_per_decade=POINTS_PER_DECADE, fun_many=fun_many,
                                  parametrisation=parametrisation, strict=strict, axis=axis,
                                  rule=rule if kind == "vertical" else "slowest")
        if not report.converged:
            nan = np.full(n, np.nan)
            return AxisSolution(float("nan"), nan, nan.copy(), nan.copy(), nan.copy(), report)
        k = report.root
    k = float(k)
    if not np.isfinite(k):
        raise ValidationError(f"{axis} axis: coefficient k must be finite")
    Q, S = propagate_path(step(k, dt, hold), (0.0, v0), a, w, k)
    return AxisSolution(k, Q[:, 0], Q[:, 1], S[:, 0], S[:, 1], report)


def solve_axis_y(t, a_y, h, y0: float, y_T: float | None = None, *, k: float | None = None,
                 k0: float | None = None, hold: str = "linear", tol_m: float = 1e-3,
                 max_iter: int = 60, parametrisation: str = "k", kt_max: float = KT_MAX,
                 strict: bool = False, rule: str = "baro") -> AxisSolution:
    """Vertical axis: ``y'' - k2 y = a_y - k2 h``, ``y(0) = 0``, ``y'(0) = y0``, ``y(T) = y_T``.

    METHODS.md section 1; seed 001 equations (1)-(4).  Either ``y_T`` (boundary-value mode:
    ``k2`` by :func:`flightrecon.fusion.newton.find_coefficient`) or ``k`` (initial-value mode).

    Parameters
    ----------
    t : (N,) uniform time grid [s], from lift-off (only differences matter)
    a_y : (N,) vertical (up) kinematic acceleration [m/s^2]
    h : (N,) baro(-inertial) height relative to the lift-off point [m]
    y0 : vertical velocity at lift-off [m/s]
    y_T : end height relative to the lift-off point [m]
    k : k2 [1/s^2] for the initial-value mode
    k0 : start value of the iteration (``alpha`` for ``parametrisation="alpha"``)
    hold : input hold between samples, ``"linear"`` or ``"zero"``
    tol_m : end-point tolerance [m]
    max_iter : iteration cap per phase
    parametrisation : ``"k"`` or the paper's ``"alpha"``
    kt_max : overflow guard (:data:`KT_MAX`)
    strict : raise ConvergenceError when no root is found
    rule : root selection on the oscillatory negative branch: ``"baro"`` (default; the root
        whose track stays closest to ``h`` in RMS) or ``"slowest"`` (smallest ``w``);
        :mod:`flightrecon.fusion.newton`, step 4
    """
    return _solve_axis("vertical", t, a_y, h, float(y0), y_T, k, k0, hold, tol_m, max_iter,
                       parametrisation, kt_max, strict, "y (vertical)", rule)


def solve_axis_horizontal(t, a, v_air, v0: float, s_T: float | None = None, *,
                          k: float | None = None, k0: float | None = None,
                          hold: str = "linear", tol_m: float = 1e-3, max_iter: int = 60,
                          kt_max: float = KT_MAX, strict: bool = False,
                          axis: str = "horizontal") -> AxisSolution:
    """Horizontal axis: ``s'' - k s' = a - k v_air``, ``s(0) = 0``, ``s'(0) = v0``, ``s(T) = s_T``.

    METHODS.md section 1; seed 001 section IV (x with k1, z with k3).

    Parameters
    ----------
    t : (N,) uniform time grid [s]
    a : (N,) kinematic acceleration along the axis [m/s^2]
    v_air : (N,) air-derived velocity along the axis (wind added where known) [m/s]
    v0 : velocity along the axis at lift-off [m/s]
    s_T : end coordinate relative to the lift-off point [m]
    k : coefficient [1/s] for the initial-value mode
    k0, hold, tol_m, max_iter, kt_max, strict : as :func:`solve_axis_y`
    axis : name for messages
    """
    return _solve_axis("horizontal", t, a, v_air, float(v0), s_T, k, k0, hold, tol_m, max_iter,
                       "k", kt_max, strict, axis)


@dataclass(frozen=True)
class SabzievSolution:
    """The fused track in the Sabziev frame (x north, y up, z east; origin at lift-off).

    Attributes
    ----------
    t_s : (N,) grid
    xyz_m : (N, 3) position [x north, y up, z east] relative to the lift-off point [m]
    vxyz_mps : (N, 3) velocity, same axes [m/s]
    k : (k1, k2, k3)
    axes : ``{"x": AxisSolution, "y": ..., "z": ...}``
    cross_dk2_m : (N, 2) the cross terms ``d x / d k2``, ``d z / d k2`` through ``y'`` in the
        air-derived velocity (NaN where an axis has no root)
    cross_dk2_mps : (N, 2) the same for the velocities
    end_residual_m : (3,) end point minus target (NaN where no target was given)
    wind_modelled : whether a wind was added to the air-derived velocity
    warnings : what the caller should show the analyst

    The full Jacobians ``dxyz_dk`` and ``dvxyz_dk`` (N, 3, 3) are assembled on first use (two
    arrays of 72 bytes a sample: 83 MB on a 10-hour 16 Hz flight, needed only for ``k_sd``).
    """

    t_s: np.ndarray
    xyz_m: np.ndarray
    vxyz_mps: np.ndarray
    k: tuple[float, float, float]
    axes: dict
    cross_dk2_m: np.ndarray
    cross_dk2_mps: np.ndarray
    end_residual_m: np.ndarray
    wind_modelled: bool
    warnings: tuple[str, ...] = ()

    def _jacobian(self, own: str, cross: np.ndarray) -> np.ndarray:
        n = len(self.t_s)
        d = np.zeros((n, 3, 3))
        for i, name in enumerate(("x", "y", "z")):
            d[:, i, i] = getattr(self.axes[name], own)
        d[:, 0, 1] = cross[:, 0]
        d[:, 2, 1] = cross[:, 1]
        return d

    @cached_property
    def dxyz_dk(self) -> np.ndarray:
        """(N, 3, 3) ``d xyz[:, i] / d k[j]`` (``k = (k1, k2, k3)``): own-axis terms from the
        sensitivity recursion, and the cross terms ``d x / d k2``, ``d z / d k2`` through
        ``y'`` in the air-derived velocity; ``d y / d k1 = d y / d k3 = 0``."""
        return self._jacobian("dposition_dk", self.cross_dk2_m)

    @cached_property
    def dvxyz_dk(self) -> np.ndarray:
        """(N, 3, 3) as :attr:`dxyz_dk` for the velocity."""
        return self._jacobian("dvelocity_dk", self.cross_dk2_mps)

    @property
    def converged(self) -> bool:
        """All three axes found a root (True in the initial-value mode)."""
        return all(a.report is None or a.report.converged for a in self.axes.values())

    @property
    def north_m(self) -> np.ndarray:
        return self.xyz_m[:, 0]

    @property
    def up_m(self) -> np.ndarray:
        return self.xyz_m[:, 1]

    @property
    def east_m(self) -> np.ndarray:
        return self.xyz_m[:, 2]

    def position_sd_m(self, k_sd) -> np.ndarray:
        """First-order standard deviation (N, 3) of the track for independent ``k`` spreads.

        ``var(xyz_i) = sum_j (d xyz_i / d k_j)^2 k_sd_j^2`` (linearisation; on the oscillatory
        vertical branch it holds only while ``k_sd`` is small against the root spacing).
        """
        sd = np.asarray(k_sd, dtype=np.float64)
        if sd.shape != (3,) or np.any(sd < 0) or not np.all(np.isfinite(sd)):
            raise ValidationError("k_sd must be three finite non-negative numbers")
        return np.sqrt(np.einsum("nij,j->ni", self.dxyz_dk**2, sd**2))

    def velocity_sd_mps(self, k_sd) -> np.ndarray:
        """As :meth:`position_sd_m` for the velocity."""
        sd = np.asarray(k_sd, dtype=np.float64)
        if sd.shape != (3,) or np.any(sd < 0) or not np.all(np.isfinite(sd)):
            raise ValidationError("k_sd must be three finite non-negative numbers")
        return np.sqrt(np.einsum("nij,j->ni", self.dvxyz_dk**2, sd**2))


def air_velocity(tas, heading_rad, climb_rate, wind_ne=None) -> tuple[np.ndarray, np.ndarray]:
    """Air-derived horizontal velocity (north, east) of METHODS.md section 1.

    ``v_x = sqrt(max(v^2 - y'^2, 0)) cos(psi) + W_N``, ``v_z = sqrt(max(v^2 - y'^2, 0)) sin(psi)
    + W_E`` with the wind (north, east components of where it blows *to*) when given.
    """
    v_h = np.sqrt(np.maximum(np.asarray(tas) ** 2 - np.asarray(climb_rate) ** 2, 0.0))
    vn = v_h * np.cos(heading_rad)
    ve = v_h * np.sin(heading_rad)
    if wind_ne is not None:
        vn = vn + wind_ne[:, 0]
        ve = ve + wind_ne[:, 1]
    return vn, ve


def fuse(t, a_ned, tas, heading_rad, h_rel, v0_ned, end_ned=None, wind_ne=None, k=None, *,
         k0=None, hold: str = "linear", tol_m: float = 1e-3, max_iter: int = 60,
         parametrisation: str = "k", kt_max: float = KT_MAX, strict: bool = False,
         vertical_rule: str = "baro") -> SabzievSolution:
    """Sabziev boundary-value fusion of loads, airspeed, heading and baro height (METHODS.md 1).

    Solves the vertical axis first (k2), then north (k1) and east (k3), which need ``y'``.

    Parameters
    ----------
    t : (N,) uniform grid [s] from lift-off to the arrival
    a_ned : (N, 3) kinematic acceleration north, east, down [m/s^2]
        (``a_x = a_N``, ``a_y = -a_D``, ``a_z = a_E``)
    tas : (N,) true airspeed [m/s]
    heading_rad : (N,) true heading [rad] (unwrapped is fine)
    h_rel : (N,) baro height relative to the lift-off point [m]
    v0_ned : (3,) ground velocity at lift-off, north, east, down [m/s]
    end_ned : (3,) arrival point relative to the lift-off point, north, east, down [m];
        required unless ``k`` is given
    wind_ne : (N, 2) wind velocity (where it blows *to*) north, east [m/s], or None
        (then the result warns "wind unmodelled")
    k : (k1, k2, k3) for the initial-value mode (no end point needed)
    k0 : start values (k1, k2, k3) of the iterations, or None for the defaults
    hold, tol_m, max_iter, parametrisation, kt_max, strict : as :func:`solve_axis_y`
        (``parametrisation`` applies to k2 only, like the paper)
    vertical_rule : root selection for k2 (``rule`` of :func:`solve_axis_y`)

    Returns
    -------
    SabzievSolution
    """
    t = np.asarray(t, dtype=np.float64)
    dt = check_grid(t)
    n = len(t)
    a_ned = np.asarray(a_ned, dtype=np.float64)
    if a_ned.shape != (n, 3):
        raise ValidationError(f"a_ned must have shape ({n}, 3), got {a_ned.shape}")
    tas = _arr("tas", tas, n)
    psi = _arr("heading", heading_rad, n)
    h_rel = _arr("baro height", h_rel, n)
    v0 = np.asarray(v0_ned, dtype=np.float64)
    if v0.shape != (3,) or not np.all(np.isfinite(v0)):
        raise ValidationError("v0_ned must be three finite numbers")
    warn: list[str] = []
    if wind_ne is not None:
        wind_ne = np.asarray(wind_ne, dtype=np.float64)
        if wind_ne.shape != (n, 2) or not np.all(np.isfinite(wind_ne)):
            raise ValidationError(f"wind_ne must be finite with shape ({n}, 2)")
    else:
        warn.append("wind unmodelled: no wind channel, the air-derived velocity is used as "
                    "ground velocity and k1, k3 absorb the drift")
    if k is None:
        if end_ned is None:
            raise ValidationError("give the arrival point (end_ned) or the coefficients k")
        end = np.asarray(end_ned, dtype=np.float64)
        if end.shape != (3,) or not np.all(np.isfinite(end)):
            raise ValidationError("end_ned must be three finite numbers")
        targets = (end[0], -end[2], end[1])
        ks = (None, None, None)
    else:
        ks = tuple(float(x) for x in k)
        if len(ks) != 3 or not all(np.isfinite(ks)):
            raise ValidationError("k must be three finite numbers (k1, k2, k3)")
        targets = (None, None, None)
        end = None if end_ned is None else np.asarray(end_ned, dtype=np.float64)
    starts = (None, None, None) if k0 is None else tuple(k0)
    common = {"hold": hold, "tol_m": tol_m, "max_iter": max_iter, "kt_max": kt_max, "strict": strict}
    ax_y = solve_axis_y(t, -a_ned[:, 2], h_rel, -v0[2], targets[1], k=ks[1], k0=starts[1],
                        parametrisation=parametrisation, rule=vertical_rule, **common)
    if np.all(np.isfinite(ax_y.velocity_mps)):
        climb = ax_y.velocity_mps
        dclimb = ax_y.dvelocity_dk
    else:
        climb = np.gradient(h_rel, dt)
        dclimb = np.zeros(n)
        warn.append("vertical axis has no root: the climb rate in the air-derived velocity is "
                    "taken from the baro height instead")
    vn, ve = air_velocity(tas, psi, climb, wind_ne)
    ax_x = solve_axis_horizontal(t, a_ned[:, 0], vn, v0[0], targets[0], k=ks[0], k0=starts[0],
                                 axis="x (north)", **common)
    ax_z = solve_axis_horizontal(t, a_ned[:, 1], ve, v0[1], targets[2], k=ks[2], k0=starts[2],
                                 axis="z (east)", **common)
    # cross sensitivities d(x, z)/d k2 through y' in sqrt(v^2 - y'^2)
    v_h2 = tas**2 - climb**2
    with np.errstate(divide="ignore", invalid="ignore"):
        dvh = np.where(v_h2 > 0, -climb * dclimb / np.sqrt(np.where(v_h2 > 0, v_h2, 1.0)), 0.0)
    xyz = np.column_stack([ax_x.position_m, ax_y.position_m, ax_z.position_m])
    vxyz = np.column_stack([ax_x.velocity_mps, ax_y.velocity_mps, ax_z.velocity_mps])
    cross = np.zeros((n, 2))
    dcross = np.zeros((n, 2))
    for i, ax, a_col, v_col, trig in ((0, ax_x, 0, vn, np.cos(psi)), (1, ax_z, 1, ve, np.sin(psi))):
        if not (np.isfinite(ax.k) and np.isfinite(ax_y.k)):
            cross[:, i] = np.nan
            dcross[:, i] = np.nan
            continue
        c = horizontal_step(ax.k, dt, hold)
        zero = StepCoefficients(c.Phi, np.zeros((2, 2)), c.G0, np.zeros(2), c.G1, np.zeros(2))
        u = a_ned[:, a_col] - ax.k * v_col
        _, S = propagate_path(zero, (0.0, v0[a_col]), u, dvh * trig, 0.0, dscale=ax.k)
        cross[:, i] = S[:, 0]
        dcross[:, i] = S[:, 1]
    res = np.full(3, np.nan)
    if end is not None:
        res = xyz[-1] - np.array([end[0], -end[2], end[1]])
    return SabzievSolution(t, xyz, vxyz, (ax_x.k, ax_y.k, ax_z.k), {"x": ax_x, "y": ax_y,
                           "z": ax_z}, cross, dcross, res, wind_ne is not None, tuple(warn))
