"""SNS output: the smoothed track densified onto the input grid, and the integration
of sensor readings between filter steps."""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from flightrecon.estimation.manifold import boxplus, radii
from flightrecon.geo.ellipsoid import radii_from_sin
from flightrecon.methods.sns.model import (
    MODEL_AIRSPEED,
    increment_cs_into,
    scale_angle,
)


class ReadingIntegrals(NamedTuple):
    """Cumulative integrals of the held readings at a set of times, each (M, 2)
    (:func:`integrate_readings`): measured velocity ``A``, its unit vector ``U``, wind ``W``."""

    A: np.ndarray
    U: np.ndarray
    W: np.ndarray


class HeldReadings(NamedTuple):
    """The readings held at a set of times, each (M, 2): measured velocity ``a``, its unit
    vector ``u``, wind (toward) ``w``."""

    a: np.ndarray
    u: np.ndarray
    w: np.ndarray


def _c(a, dtype=np.float64) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a, dtype=dtype))


@nb.njit(cache=True, nogil=True)
def _inc_pos(model, s, ct, st, c0, c1, A0, A1, W0, W1, tau):
    """North/east increment ``s R(theta) A + Wv + dw tau`` of :func:`increment` (scalars)."""
    ra0 = ct * A0 - st * A1
    ra1 = st * A0 + ct * A1
    if model == MODEL_AIRSPEED:
        return ra0 + W0 + c0 * tau, ra1 + W1 + c1 * tau
    return s * ra0, s * ra1


@nb.njit(cache=True, nogil=True)
def _boxplus_pre(lat: float, lon: float, slat: float, clat: float, mr: float, nr: float,
                 dn: float, de: float, h: float) -> tuple[float, float]:
    """:func:`boxplus` from a point whose ``sin``/``cos`` of latitude and height-free radii
    ``mr, nr`` (``radii(lat, 0)``) are known.

    The mid-latitude ``lat + dl`` (``dl = dn / (2 (M + h))``) enters through the angle-addition
    formulas with ``sin dl = dl - dl^3/6`` and ``cos dl = 1 - dl^2/2 + dl^4/24``, whose
    truncation (``dl^5/120``, ``dl^6/720``) is below 1e-17 for ``|dl| <= 1e-3`` rad (6 km);
    larger moves take :func:`boxplus` itself.  Same result to round-off, without the three
    trigonometric calls per move.
    """
    mh = mr + h
    dl = 0.5 * dn / mh
    if abs(dl) > 1e-3:
        return boxplus(lat, lon, dn, de, h)
    d2 = dl * dl
    sd = dl * (1.0 - d2 / 6.0)
    cd = 1.0 - 0.5 * d2 + d2 * d2 / 24.0
    sm = slat * cd + clat * sd
    cm = clat * cd - slat * sd
    m, n = radii_from_sin(sm)
    return lat + dn / (m + h), lon + de / ((n + h) * cm)


@nb.njit(cache=True, nogil=True)
def _densify_kernel(model, xs, Ps, kidx, tq, tf, at_q, at_filter, hq, held, sig):
    # Scalar form of the per-sample work (no allocation): the increments of :func:`increment`
    # (only ``d`` is needed for the positions; the velocity uses ``d``, ``J`` and ``Gs`` at
    # ``tau = 1``), blended as described in :func:`densify`.
    IA, IU, IW = at_q
    FA, FU, FW = at_filter
    a, u, w = held
    M = tq.shape[0]
    lat = np.empty(M)
    lon = np.empty(M)
    Pn = np.empty((M, 2, 2))
    v = np.empty((M, 2))
    Pv = np.empty((M, 2, 2))
    nlast = xs.shape[0] - 1
    J = np.zeros((2, 3))
    Gs = np.zeros((2, 4))
    d = np.zeros(2)
    c = np.zeros(3)
    JP = np.zeros((2, 3))
    kprev = -1
    s = 1.0
    ct = 1.0
    st = 0.0
    # sin/cos of latitude and height-free radii of the states x_k and x_{k+1} (_boxplus_pre)
    s0 = c0 = m0 = n0 = s1 = c1 = m1 = n1 = 0.0
    for j in range(M):
        k = kidx[j]
        k1 = min(k + 1, nlast)
        if k != kprev:
            for i in range(3):
                c[i] = xs[k, 2 + i]
            s, th = scale_angle(model, c)
            ct = np.cos(th)
            st = np.sin(th)
            kprev = k
            s0 = np.sin(xs[k, 0])
            c0 = np.cos(xs[k, 0])
            m0, n0 = radii(xs[k, 0], 0.0)
            s1 = np.sin(xs[k1, 0])
            c1 = np.cos(xs[k1, 0])
            m1, n1 = radii(xs[k1, 0], 0.0)
        tk = tf[k]
        tk1 = tf[k1]
        # forward from x_k over [t_k, t_j]
        d10, d11 = _inc_pos(model, s, ct, st, c[0], c[1], IA[j, 0] - FA[k, 0],
                            IA[j, 1] - FA[k, 1], IW[j, 0] - FW[k, 0], IW[j, 1] - FW[k, 1],
                            tq[j] - tk)
        la1, lo1 = _boxplus_pre(xs[k, 0], xs[k, 1], s0, c0, m0, n0, d10, d11, hq[j])
        if k < nlast and tk1 > tk:
            wgt = (tq[j] - tk) / (tk1 - tk)
            # backward from x_{k+1} over [t_j, t_{k+1}]
            d20, d21 = _inc_pos(model, s, ct, st, c[0], c[1], FA[k1, 0] - IA[j, 0],
                                FA[k1, 1] - IA[j, 1], FW[k1, 0] - IW[j, 0],
                                FW[k1, 1] - IW[j, 1], tk1 - tq[j])
            la2, lo2 = _boxplus_pre(xs[k1, 0], xs[k1, 1], s1, c1, m1, n1, -d20, -d21, hq[j])
            # linear blend in latitude/longitude: the two dead-reckoned positions differ by
            # the step's smoothed process noise (millimetres to centimetres), over which the
            # radii change by 1e-9 relative, so this equals the blend of the north/east
            # difference (la1 (+) wgt (la2 (-) la1)) to far below a micrometre
            la = la1 + wgt * (la2 - la1)
            lo = lo1 + wgt * (lo2 - lo1)
            for r in range(2):
                for q in range(2):
                    Pn[j, r, q] = (1.0 - wgt) * Ps[k, r, q] + wgt * Ps[k1, r, q]
        else:
            la = la1
            lo = lo1
            for r in range(2):
                for q in range(2):
                    Pn[j, r, q] = Ps[k, r, q]
        lat[j] = la
        lon[j] = lo
        increment_cs_into(model, s, ct, st, c, a[j, 0], a[j, 1], u[j, 0], u[j, 1], w[j, 0],
                           w[j, 1], 1.0, sig, d, J, Gs)
        v[j, 0] = d[0]
        v[j, 1] = d[1]
        # Pv = J P_c J^T + Gs Gs^T
        for r in range(2):
            for q in range(3):
                acc = 0.0
                for l in range(3):
                    acc += J[r, l] * Ps[k, 2 + l, 2 + q]
                JP[r, q] = acc
        for r in range(2):
            for q in range(2):
                acc = 0.0
                for l in range(3):
                    acc += JP[r, l] * J[q, l]
                for l in range(4):
                    acc += Gs[r, l] * Gs[q, l]
                Pv[j, r, q] = acc
    return lat, lon, Pn, v, Pv


def densify(model: int, xs: np.ndarray, Ps: np.ndarray, kidx: np.ndarray, tq: np.ndarray,
            t_filter: np.ndarray, I_at_q: tuple[np.ndarray, np.ndarray, np.ndarray],
            I_at_filter: tuple[np.ndarray, np.ndarray, np.ndarray], hq: np.ndarray,
            readings: tuple[np.ndarray, np.ndarray, np.ndarray], sig: np.ndarray):
    """Smoothed position and velocity at every recorder-grid time from the filter-grid states.

    Between filter points ``t_k <= t < t_{k+1}`` the position is dead-reckoned exactly (held
    readings, corrections of step k) forward from ``x_k`` and backward from ``x_{k+1}`` and the
    two are blended linearly in time, in latitude/longitude (they differ only by the smoothed
    process noise of the step, millimetres, over which this equals a blend of the north/east
    difference to 1e-9 relative); the position covariance is interpolated linearly.  The
    velocity is the corrected reading, with covariance ``Jv P_c Jv^T + Gv Gv^T`` (corrections'
    covariance plus the reading's own noise).

    Parameters
    ----------
    xs, Ps : smoothed (or filtered) states and covariances on the filter grid
    kidx : (M,) filter step of each query time
    tq : (M,) query times [s]; ``t_filter`` the filter times
    I_at_q, I_at_filter : cumulative integrals ``(IA, IU, IW)`` of the held readings at the query
        times (each (M, 2)) and at the filter times (each (N, 2))
    hq : (M,) heights [m]; ``readings`` ``(a, u, w)`` held at the query times, each (M, 2)

    Returns
    -------
    lat, lon [rad] (M,), P_ne (M, 2, 2), v_ne (M, 2) [m/s], P_v (M, 2, 2)
    """
    at_q = ReadingIntegrals(*(_c(x) for x in I_at_q))
    at_filter = ReadingIntegrals(*(_c(x) for x in I_at_filter))
    held = HeldReadings(*(_c(x) for x in readings))
    return _densify_kernel(int(model), _c(xs), _c(Ps), _c(kidx, np.int64), _c(tq),
                           _c(t_filter), at_q, at_filter, _c(hq), held, _c(sig))


@nb.njit(cache=True, nogil=True)
def _integrate_kernel(t, a, u, w):
    M = t.shape[0]
    IA = np.empty((M, 2))
    IU = np.empty((M, 2))
    IW = np.empty((M, 2))
    CQ = np.empty((M + 1, 7))
    for i in range(2):
        IA[0, i] = 0.0
        IU[0, i] = 0.0
        IW[0, i] = 0.0
    for i in range(7):
        CQ[0, i] = 0.0
    for j in range(M):
        dt = t[j + 1] - t[j] if j < M - 1 else 0.0
        if j < M - 1:
            for i in range(2):
                IA[j + 1, i] = IA[j, i] + a[j, i] * dt
                IU[j + 1, i] = IU[j, i] + u[j, i] * dt
                IW[j + 1, i] = IW[j, i] + w[j, i] * dt
        dt2 = dt * dt
        ja0 = -a[j, 1]
        ja1 = a[j, 0]
        CQ[j + 1, 0] = CQ[j, 0] + dt2 * (u[j, 0] * u[j, 0])
        CQ[j + 1, 1] = CQ[j, 1] + dt2 * (u[j, 0] * u[j, 1])
        CQ[j + 1, 2] = CQ[j, 2] + dt2 * (u[j, 1] * u[j, 1])
        CQ[j + 1, 3] = CQ[j, 3] + dt2 * (ja0 * ja0)
        CQ[j + 1, 4] = CQ[j, 4] + dt2 * (ja0 * ja1)
        CQ[j + 1, 5] = CQ[j, 5] + dt2 * (ja1 * ja1)
        CQ[j + 1, 6] = CQ[j, 6] + dt2
    return IA, IU, IW, CQ


def integrate_readings(t: np.ndarray, a: np.ndarray, u: np.ndarray, w: np.ndarray):
    """Cumulative integrals of the held readings and the cumulative per-sample noise sums.

    Parameters
    ----------
    t : (M,) recorder times [s], strictly increasing
    a, u, w : (M, 2) measured velocity vector, its unit vector, measured wind (toward), each
        held from its sample to the next (left zero-order hold)

    Returns
    -------
    IA, IU, IW : (M, 2) integrals from ``t[0]`` to ``t[j]`` of the held series
    CQ : (M + 1, 7) ``CQ[j]`` = sum over samples ``i < j`` of ``dt_i^2 [u u^T (xx, xy, yy),
        (Ja)(Ja)^T (xx, xy, yy), 1]`` with ``Ja = [-a_e, a_n]`` and ``dt_i = t[i+1] - t[i]``
        (0 for the last sample): the sums :func:`segment_factor` takes, for any run of samples
        as a difference of two rows.

    One sequential pass (the same additions, in the same order, as ``np.cumsum``).
    """
    return _integrate_kernel(_c(t), _c(a), _c(u), _c(w))
