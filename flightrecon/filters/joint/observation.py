"""Compiled scalar measurement models of the joint smoother (types in
:mod:`flightrecon.filters.joint.layout`)."""

from __future__ import annotations

import numba as nb
import numpy as np

from flightrecon.filters.joint.layout import (
    AZIMUTH,
    DOPPLER,
    ELEVATION,
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
    RANGE,
    SIDESLIP,
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


@nb.njit(cache=True, nogil=True)
def measure_into(H, j, k, x, mtype, mz, mtau, mH, mrow, md, Cen, pnom, hnom, pst, Cst):
    """h(x) of scalar measurement j at step k (state x at the step); its gradient into ``H``.

    ``LINEAR`` measurements have their row of H in ``mH[mrow[j]]`` (only those rows are stored).
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
    if t == RANGE or t == AZIMUTH or t == ELEVATION:
        pos = np.empty(3)
        for i in range(3):
            s = x[IP + i]
            for m in range(3):
                s += C[i, m] * x[IV + m] * tau
            pos[i] = s - pst[i]
        d = np.empty(3)  # ENU at the station: Cst has the E, N, U unit vectors as columns
        for i in range(3):
            d[i] = Cst[0, i] * pos[0] + Cst[1, i] * pos[1] + Cst[2, i] * pos[2]
        e, nn, u = d[0], d[1], d[2]
        dh2 = e * e + nn * nn
        dh = np.sqrt(dh2)
        r2 = dh2 + u * u
        r = np.sqrt(r2)
        g = np.zeros(3)
        if t == RANGE:
            hx = r
            g[0], g[1], g[2] = e / r, nn / r, u / r
        elif t == AZIMUTH:
            hx = np.arctan2(e, nn)
            g[0], g[1] = nn / dh2, -e / dh2
        else:
            hx = np.arctan2(u, dh)
            g[0], g[1], g[2] = -u * e / (dh * r2), -u * nn / (dh * r2), dh / r2
        # d h / d pos_ecef = g^T Cst^T
        gp = np.empty(3)
        for i in range(3):
            gp[i] = Cst[i, 0] * g[0] + Cst[i, 1] * g[1] + Cst[i, 2] * g[2]
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
    if t == SIDESLIP:
        return _sideslip(H, x, mH[mrow[j]])
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


@nb.njit(cache=True, nogil=True)
def _sideslip(H, x, row):
    """The zero-sideslip measurement: h = b_y / |a| + u_c / V and its gradient into ``H``.

    ``a`` = (v_N - w_N, v_E - w_E, v_D) is the air velocity in NED and b_y = c_y . a its
    component along the body's right wing, c_y = C e_y, C = R_z(psi) R_y(theta) R_x(phi) at the
    recorded attitude with the heading less its bias (psi = psi_rec - dpsi); u_c is the
    cross-track gust and V the recorded airspeed.  ``row`` holds psi_rec, theta_rec, phi_rec
    [rad] and V [m/s] (docs/joint.md, "Air data").  dC/dpsi e_y = e_z x c_y.

    The roll and pitch biases are left out: their effect here (dtheta sin(phi), dphi sin(alpha))
    has the size and the pattern of a real aircraft's sideslip in turns (JSBSim's jet: 0.2 deg
    with the sign of the roll), which the pitch bias then absorbed (0.18 deg against a truth of
    0, the accelerometer x bias moved by g dtheta); they are observed by the loads.
    """
    psi = row[0] - x[IPSI]
    th = row[1]
    ph = row[2]
    V = row[3]
    cps, sps = np.cos(psi), np.sin(psi)
    cth, sth = np.cos(th), np.sin(th)
    cph, sph = np.cos(ph), np.sin(ph)
    an = x[IV] - x[IW]
    ae = x[IV + 1] - x[IW + 1]
    ad = x[IV + 2]
    A = np.sqrt(an * an + ae * ae + ad * ad)
    cyn = cps * sth * sph - sps * cph
    cye = sps * sth * sph + cps * cph
    cyd = cth * sph
    by = cyn * an + cye * ae + cyd * ad
    k = by / (A * A * A)
    H[IV] = cyn / A - k * an
    H[IV + 1] = cye / A - k * ae
    H[IV + 2] = cyd / A - k * ad
    H[IW] = -H[IV]
    H[IW + 1] = -H[IV + 1]
    H[IPSI] = (cye * an - cyn * ae) / A
    H[IGU + 1] = 1.0 / V
    return by / A + x[IGU + 1] / V
