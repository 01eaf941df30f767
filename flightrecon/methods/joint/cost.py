"""MAP cost of a joint-smoother trajectory (docs/joint.md, "Filter, smoother, iterations").

For a state trajectory X = (x_0, ..., x_{N-1}) on the state grid the negative log posterior,
up to a constant, is

    J(X) = 1/2 (x_0 - m_0)^T P_0^{-1} (x_0 - m_0)                         (prior)
         + 1/2 sum_k e_k^T Q_k^{-1} e_k,   e_k = x_k - f_k(x_{k-1})       (process)
         + sum_j rho(u_j),                 u_j = (z_j - h_j(x_{k(j)})) / sqrt(R_j)   (data)

with f_k the transition of :mod:`~flightrecon.methods.joint.dynamics` (F_k x + the measured
increments) and h_j the measurement functions of
:mod:`~flightrecon.methods.joint.observation`, both evaluated with the models built about X
itself (nominal = X), so that the linearisation terms vanish and J is the nonlinear model's
cost.  ``rho`` is the robust loss whose iteratively reweighted least squares weights the
smoother uses (Huber with threshold ``c``, constant beyond ``c_rej``)::

    rho(u) = u^2 / 2                      |u| <= c
           = c |u| - c^2 / 2              c < |u| <= c_rej
           = c c_rej - c^2 / 2            |u| > c_rej

As a function of s = u^2 it is concave with derivative w/2, w = min(1, c/|u|) (0 beyond
c_rej): the weighted quadratic w u^2/2 + const is a tangent majoriser, so an IRLS step with
those weights is a majorise-minimise step on J (Lange, Hunter & Yang 2000); with
``robust`` False rho(u) = u^2/2.

States without process noise (the scale errors, the roll and pitch biases, the Doppler and
drift errors: Q_k,ii = 0) are constants of the model: the RTS smoother keeps them constant
exactly (its gain row of such a state is the unit row), they carry no process term, and the
largest step change of them is returned as a check (it is rounding, not a penalty).  The same
holds for a state whose Q_k,ii is below rounding of the state itself
((64 eps |x|)^2: the term could not be told from rounding).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flightrecon.estimation.linalg import cholesky_factor
from flightrecon.estimation.predict import sparse_matvec, sparse_rows
from flightrecon.methods.joint.dynamics import (
    add_process_noise,
    transition_into,
    wrap_pi,
)
from flightrecon.methods.joint.layout import (
    AZIMUTH,
    DOPPLER,
    ELEVATION,
    HEADING,
    IP,
    IV,
    N_STATE,
    TAS,
    TRACK,
)
from flightrecon.methods.joint.observation import measure_into

_EPS64 = 64.0 * np.finfo(float).eps


@nb.njit(cache=True, nogil=True)
def robust_loss(u, huber_c, reject_c, robust):
    """rho(u) of the module docstring (the loss whose IRLS weights the smoother uses)."""
    a = abs(u)
    if not robust or a <= huber_c:
        return 0.5 * u * u
    if a <= reject_c:
        return huber_c * a - 0.5 * huber_c * huber_c
    return huber_c * reject_c - 0.5 * huber_c * huber_c


@nb.njit(cache=True, nogil=True)
def _process_term(X, dyn, F, cols, vals, cnt, Q, xn, e):
    """1/2 sum_k e_k^T Q_k^-1 e_k over the steps, and the largest |e_k,i| of the states that
    carry no process noise (module docstring); returns (term, max_constant_change, failures)."""
    dt, Cen, Cnb, Csf, Jatt, acc, dP, dV, dz, qv_extra, q, ga = dyn
    N, n = X.shape
    total = 0.0
    const_max = 0.0
    n_fail = 0
    act = np.empty(n, dtype=np.int64)
    for k in range(1, N):
        transition_into(F, k, dt, Cen, Cnb, Csf, Jatt, acc, q[4], dz, ga)
        sparse_rows(F, cols, vals, cnt)
        sparse_matvec(cols, vals, cnt, X[k - 1], xn)
        for i in range(3):
            for m in range(3):
                xn[IP + i] += Cen[k - 1, i, m] * dP[k, m]
            xn[IV + i] += dV[k, i]
        for i in range(n):
            e[i] = X[k, i] - xn[i]
            for j in range(n):
                Q[i, j] = 0.0
        add_process_noise(Q, k, dt, Cen, dz, qv_extra, q, ga)
        m = 0
        for i in range(n):
            tol = _EPS64 * (abs(X[k, i]) + abs(xn[i]))
            if Q[i, i] > tol * tol and Q[i, i] > 0.0:
                act[m] = i
                m += 1
            elif abs(e[i]) > const_max:
                const_max = abs(e[i])
        if m == 0:
            continue
        Qa = np.empty((m, m))
        La = np.empty((m, m))
        for a in range(m):
            for b in range(m):
                Qa[a, b] = Q[act[a], act[b]]
        if not cholesky_factor(Qa, La, 0.0):
            n_fail += 1
            continue
        # e^T Q^-1 e = |L^-1 e|^2 (forward substitution)
        y = np.empty(m)
        s = 0.0
        for a in range(m):
            v = e[act[a]]
            for b in range(a):
                v -= La[a, b] * y[b]
            y[a] = v / La[a, a]
            s += y[a] * y[a]
        total += 0.5 * s
    return total, const_max, n_fail


@nb.njit(cache=True, nogil=True)
def map_cost(X, x0, P0inv, dyn, meas, geo, huber_c, reject_c, robust):
    """MAP cost J(X) of the module docstring and its parts.

    Parameters
    ----------
    X : (N, n) state trajectory on the state grid.
    x0, P0inv : prior mean (n,) and inverse prior covariance (n, n) of x_0.
    dyn, meas, geo : the :class:`~flightrecon.methods.joint.layout.Dynamics`,
        :class:`~flightrecon.methods.joint.layout.Scalars` and
        :class:`~flightrecon.methods.joint.layout.Geometry` built about X; ``meas.r`` holds
        the nominal variances (with the noise scale factors, without the robust weights or
        the forward pass's inflation); a measurement with ``meas.w <= 0`` is left out (as the
        forward filter does).
    huber_c, reject_c, robust : the robust loss (:func:`robust_loss`).

    Returns
    -------
    prior, process, data : the three terms of J.
    const_change : largest step change of the states without process noise (rounding).
    res, rate : (M,) residual z - h(x) (angles wrapped) and the rate dh/dtau of each predicted
        measurement (for the clock-offset fit; 0 for air data), as
        :func:`~flightrecon.methods.joint.passes.backward_mean` gives them.
    n_fail : steps whose Q_k (active part) failed its Cholesky factorisation (left out).
    """
    mstart, mtype, mz, mr, mw, mtau, mH, mrow, md = meas
    pnom, hnom, pst, Cst = geo
    Cen = dyn[1]
    N, n = X.shape
    M = mtype.shape[0]
    # prior
    d = X[0] - x0
    prior = 0.0
    for i in range(n):
        for j in range(n):
            prior += d[i] * P0inv[i, j] * d[j]
    prior *= 0.5
    F = np.empty((n, n))
    cols = np.empty((n, n), dtype=np.int64)
    vals = np.empty((n, n))
    cnt = np.empty(n, dtype=np.int64)
    Q = np.empty((n, n))
    xn = np.empty(n)
    e = np.empty(n)
    process, const_change, n_fail = _process_term(X, dyn, F, cols, vals, cnt, Q, xn, e)
    # data
    H = np.empty(N_STATE)
    res = np.full(M, np.nan)
    rate = np.full(M, np.nan)
    data = 0.0
    for k in range(N):
        for j in range(mstart[k], mstart[k + 1]):
            hx = measure_into(H, j, k, X[k], mtype, mz, mtau, mH, mrow, md, Cen, pnom, hnom,
                              pst, Cst)
            t = mtype[j]
            r = mz[j] - hx
            if t == AZIMUTH or t == ELEVATION or t == HEADING or t == TRACK:
                r = wrap_pi(r)
            res[j] = r
            if t == TAS or t == HEADING or t == DOPPLER or t == TRACK:
                rate[j] = 0.0
            else:
                rd = 0.0
                for m in range(3):
                    s = 0.0
                    for i in range(3):
                        s += H[IP + i] * Cen[k, i, m]
                    rd += s * X[k, IV + m]
                rate[j] = rd
            if mw[j] <= 0.0:
                continue
            data += robust_loss(r / np.sqrt(mr[j]), huber_c, reject_c, robust)
    return prior, process, data, const_change, res, rate, n_fail
