"""The discrete Sabziev recursion: exact step coefficients for a held input, the end point and
the path with their exact sensitivities to the coefficient, and the batched scan over k."""

from __future__ import annotations

from dataclasses import dataclass

import numba as nb
import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.methods.sabziev.functions import HOLDS, phi_functions, psi_functions


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


def check_hold(hold: str) -> None:
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
    check_hold(hold)
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
    check_hold(hold)
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
    check_hold(hold)
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

    ``y'' - k2 y = a_y - k2 h``, ``y(0) = 0``, ``y'(0) = y0`` (docs/sabziev.md).
    """
    q, s, _ = propagate_end(vertical_step(k2, dt, hold), (0.0, y0), a_y, h, k2)
    return float(q[0]), float(s[0])


def horizontal_end_point(k: float, dt: float, a, v, s0: float,
                         hold: str = "linear") -> tuple[float, float]:
    """Discrete end point ``x_N(k)`` and its exact derivative ``d x_N / d k``.

    ``x'' - k x' = a - k v``, ``x(0) = 0``, ``x'(0) = s0`` (docs/sabziev.md).
    """
    q, s, _ = propagate_end(horizontal_step(k, dt, hold), (0.0, s0), a, v, k)
    return float(q[0]), float(s[0])
