"""Compiled scalar measurement models of the joint smoother (types in
:mod:`flightrecon.methods.joint.layout`)."""

from __future__ import annotations

import numba as nb
import numpy as np

from flightrecon.methods.joint.layout import (
    AZIMUTH,
    DOPPLER,
    ELEVATION,
    HEADING,
    IBH,
    IC,
    IDC,
    IDW,
    IGU,
    IP,
    IPSI,
    IS,
    IV,
    IW,
    LINEAR,
    N_STATE,
    NED_POS,
    RANGE,
    STATE,
    TAS,
    TRACK,
)


@nb.njit(cache=True, nogil=True)
def measure(j, k, x, mtype, mz, mtau, mH, mrow, md, Cen, pnom, hnom, pst, Cst):
    """h(x) and its gradient for scalar measurement j at step k (state x at the step).

    See :func:`measure_into` (this form allocates the gradient; for tests and analysis)."""
    H = np.empty(N_STATE)
    hx = measure_into(H, j, k, x, mtype, mz, mtau, mH, mrow, md, Cen, pnom, hnom, pst, Cst)
    return hx, H


@nb.njit(cache=True, nogil=True, inline="always")
def _moved(x, C, tau, i):
    """ECEF coordinate ``i`` of the position moved by the velocity over ``tau``:
    p_i + sum_m C[i, m] v_m tau (summed in that order).  Inlined at numba's IR level into
    :func:`measure_into` (called there with the constants 0, 1, 2: three compilations of
    their own otherwise, 1.5 s on a cold cache)."""
    s = x[IP + i]
    for m in range(3):
        s += C[i, m] * x[IV + m] * tau
    return s


@nb.njit(cache=True, nogil=True)
def measure_into(H, j, k, x, mtype, mz, mtau, mH, mrow, md, Cen, pnom, hnom, pst, Cst):
    """h(x) of scalar measurement j at step k (state x at the step); its gradient into ``H``.

    ``LINEAR`` measurements have their row of H in ``mH[mrow[j]]`` (only those rows are stored);
    ``NED_POS`` and ``STATE`` have an axis or a state index in ``mrow[j]`` and no stored row.
    """
    n = N_STATE
    for i in range(n):
        H[i] = 0.0
    t = mtype[j]
    tau = mtau[j]
    C = Cen[k]
    if t == LINEAR:
        hx = md[j]
        row = mrow[j]
        for i in range(n):
            H[i] = mH[row, i]
            hx += mH[row, i] * x[i]
        return hx
    if t == STATE:
        H[mrow[j]] = 1.0
        return x[mrow[j]] + md[j]
    if t == NED_POS:   # c_i . p + v_i tau, c_i the NED axis i in ECEF at the step
        a = mrow[j]
        hx = md[j] + x[IV + a] * tau
        for i in range(3):
            H[IP + i] = C[i, a]
            hx += C[i, a] * x[IP + i]
        H[IV + a] = tau
        return hx
    if t == RANGE or t == AZIMUTH or t == ELEVATION:
        # (scalars and tuples, no arrays: the step's functions allocate nothing)
        pos = (_moved(x, C, tau, 0) - pst[0], _moved(x, C, tau, 1) - pst[1],
               _moved(x, C, tau, 2) - pst[2])
        # ENU at the station: Cst has the E, N, U unit vectors as columns
        e = Cst[0, 0] * pos[0] + Cst[1, 0] * pos[1] + Cst[2, 0] * pos[2]
        nn = Cst[0, 1] * pos[0] + Cst[1, 1] * pos[1] + Cst[2, 1] * pos[2]
        u = Cst[0, 2] * pos[0] + Cst[1, 2] * pos[1] + Cst[2, 2] * pos[2]
        dh2 = e * e + nn * nn
        dh = np.sqrt(dh2)
        r2 = dh2 + u * u
        r = np.sqrt(r2)
        g0 = g1 = g2 = 0.0
        if t == RANGE:
            hx = r
            g0, g1, g2 = e / r, nn / r, u / r
        elif t == AZIMUTH:
            hx = np.arctan2(e, nn)
            g0, g1 = nn / dh2, -e / dh2
        else:
            hx = np.arctan2(u, dh)
            g0, g1, g2 = -u * e / (dh * r2), -u * nn / (dh * r2), dh / r2
        # d h / d pos_ecef = g^T Cst^T
        gp = (Cst[0, 0] * g0 + Cst[0, 1] * g1 + Cst[0, 2] * g2,
              Cst[1, 0] * g0 + Cst[1, 1] * g1 + Cst[1, 2] * g2,
              Cst[2, 0] * g0 + Cst[2, 1] * g1 + Cst[2, 2] * g2)
        for i in range(3):
            H[IP + i] = gp[i]
        for m in range(3):
            s = 0.0
            for i in range(3):
                s += gp[i] * C[i, m]
            H[IV + m] = s * tau
        return hx
    if t == TAS:
        an = x[IV] - x[IW]
        ae = x[IV + 1] - x[IW + 1]
        ad = x[IV + 2]
        va = np.sqrt(an * an + ae * ae + ad * ad)
        f = 1.0 + x[IS]
        H[IV] = f * an / va
        H[IV + 1] = f * ae / va
        H[IV + 2] = f * ad / va
        H[IW] = -H[IV]
        H[IW + 1] = -H[IV + 1]
        H[IS] = va
        H[IGU] = 1.0
        return f * va + x[IGU]
    if t == HEADING:
        an = x[IV] - x[IW]
        ae = x[IV + 1] - x[IW + 1]
        v2 = an * an + ae * ae
        H[IV] = -ae / v2
        H[IV + 1] = an / v2
        H[IW] = ae / v2
        H[IW + 1] = -an / v2
        H[IPSI] = 1.0
        H[IGU + 1] = 1.0 / md[j]   # md[j]: the recorded airspeed (a known scale, not a state)
        return np.arctan2(ae, an) + x[IPSI] + x[IGU + 1] / md[j]
    if t == DOPPLER:
        vn = x[IV]
        ve = x[IV + 1]
        w = np.sqrt(vn * vn + ve * ve)
        f = 1.0 + x[IDW]
        H[IV] = f * vn / w
        H[IV + 1] = f * ve / w
        H[IDW] = w
        return f * w
    if t == TRACK:
        vn = x[IV]
        ve = x[IV + 1]
        v2 = vn * vn + ve * ve
        H[IV] = -ve / v2
        H[IV + 1] = vn / v2
        H[IPSI] = 1.0
        H[IDC] = 1.0
        return np.arctan2(ve, vn) + x[IPSI] + x[IDC]
    # BARO
    base = hnom[k] - x[IV + 2] * tau
    for i in range(3):
        base += -C[i, 2] * (x[IP + i] - pnom[k, i])
    f = 1.0 + x[IC]
    for i in range(3):
        H[IP + i] = -f * C[i, 2]
    H[IV + 2] = -f * tau
    H[IC] = base
    H[IBH] = 1.0
    return f * base + x[IBH]
