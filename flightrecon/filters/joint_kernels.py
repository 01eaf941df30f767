"""Compiled kernels of the joint post-flight smoother (see :mod:`flightrecon.filters.joint`).

State (n = 15), SI units::

    0:3   p      position, ECEF [m]
    3:6   v      ground velocity, local north-east-down at the nominal position [m/s]
    6:8   w      horizontal wind velocity (where the air moves to), north, east [m/s]
    8:11  b_a    accelerometer bias, body axes, as load factor [g]   (measured - true)
    11    dpsi   heading bias [rad]                                    (measured - true)
    12    s      airspeed scale error: TAS_measured = (1 + s) TAS_true
    13    b_h    pressure-altitude offset [m]
    14    c      pressure-altitude scale: h_p - h_p,field = (1 + c)(h - h_field) + b_h
    15    k_W    Doppler ground-speed scale error: W_measured = (1 + k_W) |v_horizontal|
    16    dc     drift-angle bias [rad] (measured - true)
    17:20 s_a    accelerometer scale errors, body axes: f_measured = (1 + s_a) f_true + b_a

Propagation over one state step of length dt (inputs held between input samples)::

    p+ = p + C_en (v dt + dP_meas + J_p [dpsi, b_a])        dP_meas, dV_meas: increments of the
    v+ = v + dV_meas + J_v [dpsi, b_a]                       measured kinematic acceleration
    w+ = w + noise (random walk in time and in altitude)     over the step (exact for held inputs)
    b_a+ = exp(-dt/tau) b_a + noise

with J_v = [[a_E, -a_N, 0]^T dt, -g0 C_nb dt, -g0 C_nb diag(f) dt] and J_p = J_v dt / 2: the
heading bias rotates the measured horizontal acceleration, the accelerometer bias and scale
errors add through the attitude (f: measured specific force in body axes, in g).  C_en (NED -> ECEF) is
evaluated on the nominal trajectory (Gauss-Newton linearisation, refreshed each iteration).

Measurements are scalars processed one at a time at their own step, with ``tau`` = their time
minus the step's time (the state is carried to the measurement time by the velocity):

* ``LINEAR``: z = H x + d (GNSS position / velocity components, end points, ground constraints)
* ``RANGE``, ``AZIMUTH``, ``ELEVATION``: radar slant range and angles from the station
* ``TAS``: (1 + s) |v - w| (three-dimensional air velocity, vertical wind neglected)
* ``HEADING``: atan2(v_E - w_E, v_N - w_N) + dpsi (innovation wrapped to (-pi, pi])
* ``BARO``: (1 + c) (h_nom + up . (p - p_nom) - v_D tau) + b_h
* ``DOPPLER``: (1 + k_W) |v_horizontal|
* ``TRACK``: heading + drift as recorded = atan2(v_E, v_N) + dpsi + dc (innovation wrapped)
"""

from __future__ import annotations

import numba as nb
import numpy as np

N_STATE = 20
IP, IV, IW, IBA, IPSI, IS, IBH, IC, IDW, IDC, IKS = 0, 3, 6, 8, 11, 12, 13, 14, 15, 16, 17
G0 = 9.80665

LINEAR, RANGE, AZIMUTH, ELEVATION, TAS, HEADING, BARO, DOPPLER, TRACK = 0, 1, 2, 3, 4, 5, 6, 7, 8
ANGLE_TYPES = (AZIMUTH, ELEVATION, HEADING, TRACK)


@nb.njit(cache=True)
def _wrap(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


@nb.njit(cache=True)
def transition(k, dt, Cen, Cnb, Csf, acc, tau_ba):
    """Transition matrix F_k from step k-1 to step k (k >= 1).  ``Csf[k]`` is the step mean of
    C_nb diag(f_body) (the Jacobian of the acceleration in the accelerometer scale errors)."""
    n = N_STATE
    F = np.eye(n)
    h = dt[k]
    C = Cen[k - 1]
    for i in range(3):
        for j in range(3):
            F[IP + i, IV + j] = C[i, j] * h
    gpsi = np.array([acc[k, 1], -acc[k, 0], 0.0])
    Jb = -G0 * Cnb[k]
    for i in range(3):
        F[IV + i, IPSI] = gpsi[i] * h
        for j in range(3):
            F[IV + i, IBA + j] = Jb[i, j] * h
    Js = -G0 * Csf[k]
    for i in range(3):
        for j in range(3):
            F[IV + i, IKS + j] = Js[i, j] * h
    # position: C_en times the velocity terms times dt/2
    for i in range(3):
        for j in range(3):
            s_ks = 0.0
            for m in range(3):
                s_ks += C[i, m] * Js[m, j]
            F[IP + i, IKS + j] = s_ks * h * h / 2.0
        s_psi = 0.0
        for m in range(3):
            s_psi += C[i, m] * gpsi[m]
        F[IP + i, IPSI] = s_psi * h * h / 2.0
        for j in range(3):
            s = 0.0
            for m in range(3):
                s += C[i, m] * Jb[m, j]
            F[IP + i, IBA + j] = s * h * h / 2.0
    e = np.exp(-h / tau_ba)
    for j in range(3):
        F[IBA + j, IBA + j] = e
    return F


@nb.njit(cache=True)
def process_noise(k, dt, Cen, climb, qv_extra, q):
    """Process-noise covariance Q_k.  q = [q_acc, q_wind_t, q_wind_h, var_ba, tau_ba,
    q_psi, q_bh] (see JointNoise); ``climb[k]`` is |height change| over the step (wind varies
    with altitude), ``qv_extra[k]`` extra acceleration PSD where the load factors are missing."""
    n = N_STATE
    Q = np.zeros((n, n))
    h = dt[k]
    qa = q[0] + qv_extra[k]
    C = Cen[k - 1]
    for i in range(3):
        Q[IP + i, IP + i] = qa * h ** 3 / 3.0
        Q[IV + i, IV + i] = qa * h
        for j in range(3):
            Q[IP + i, IV + j] = qa * h * h / 2.0 * C[i, j]
            Q[IV + j, IP + i] = Q[IP + i, IV + j]
    qw = q[1] * h + q[2] * climb[k]
    Q[IW, IW] = qw
    Q[IW + 1, IW + 1] = qw
    gm = q[3] * (1.0 - np.exp(-2.0 * h / q[4]))
    for j in range(3):
        Q[IBA + j, IBA + j] = gm
    Q[IPSI, IPSI] = q[5] * h
    Q[IBH, IBH] = q[6] * h
    return Q


@nb.njit(cache=True)
def measure(j, k, x, mtype, mz, mtau, mH, md, Cen, pnom, hnom, pst, Cst):
    """h(x) and its gradient for scalar measurement j at step k (state x at the step)."""
    n = N_STATE
    H = np.zeros(n)
    t = mtype[j]
    tau = mtau[j]
    C = Cen[k]
    if t == LINEAR:
        hx = md[j]
        for i in range(n):
            H[i] = mH[j, i]
            hx += mH[j, i] * x[i]
        return hx, H
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
        return hx, H
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
        return f * va, H
    if t == HEADING:
        an = x[IV] - x[IW]
        ae = x[IV + 1] - x[IW + 1]
        v2 = an * an + ae * ae
        H[IV] = -ae / v2
        H[IV + 1] = an / v2
        H[IW] = ae / v2
        H[IW + 1] = -an / v2
        H[IPSI] = 1.0
        return np.arctan2(ae, an) + x[IPSI], H
    if t == DOPPLER:
        vn = x[IV]
        ve = x[IV + 1]
        w = np.sqrt(vn * vn + ve * ve)
        f = 1.0 + x[IDW]
        H[IV] = f * vn / w
        H[IV + 1] = f * ve / w
        H[IDW] = w
        return f * w, H
    if t == TRACK:
        vn = x[IV]
        ve = x[IV + 1]
        v2 = vn * vn + ve * ve
        H[IV] = -ve / v2
        H[IV + 1] = vn / v2
        H[IPSI] = 1.0
        H[IDC] = 1.0
        return np.arctan2(ve, vn) + x[IPSI] + x[IDC], H
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
    return f * base + x[IBH], H


@nb.njit(cache=True)
def forward(x0, P0, dt, Cen, Cnb, Csf, acc, dP, dV, climb, qv_extra, q, mstart, mtype, mz, mr, mw, mtau, mH,
            md, pnom, hnom, pst, Cst, gate):
    """Forward extended Kalman filter with sequential scalar updates (Joseph form).

    ``mstart`` (N+1,) indexes the measurements of each step (sorted by step).  A measurement
    whose normalised innovation exceeds ``gate`` (0: off) has its variance inflated so that it
    equals ``gate`` (a Huber-type robust update: a jump is followed only slowly, never trusted).
    Returns filtered and predicted states/covariances and, per measurement, the innovation, its
    variance (before inflation) and the inflation factor applied.
    """
    N = dt.shape[0]
    n = N_STATE
    M = mtype.shape[0]
    xf = np.empty((N, n))
    Pf = np.empty((N, n, n))
    xp = np.empty((N, n))
    Pp = np.empty((N, n, n))
    nu_out = np.full(M, np.nan)
    s_out = np.full(M, np.nan)
    infl = np.ones(M)
    x = x0.copy()
    P = P0.copy()
    for k in range(N):
        if k > 0:
            F = transition(k, dt, Cen, Cnb, Csf, acc, q[4])
            Q = process_noise(k, dt, Cen, climb, qv_extra, q)
            x = F @ x
            for i in range(3):
                for m in range(3):
                    x[IP + i] += Cen[k - 1, i, m] * dP[k, m]
                x[IV + i] += dV[k, i]
            P = F @ P @ F.T + Q
            P = 0.5 * (P + P.T)
        xp[k] = x
        Pp[k] = P
        for j in range(mstart[k], mstart[k + 1]):
            if mw[j] <= 0.0:
                continue
            hx, H = measure(j, k, x, mtype, mz, mtau, mH, md, Cen, pnom, hnom, pst, Cst)
            nu = mz[j] - hx
            t = mtype[j]
            if t == AZIMUTH or t == ELEVATION or t == HEADING or t == TRACK:
                nu = _wrap(nu)
            PH = P @ H
            r = mr[j] / mw[j]
            HPH = H @ PH
            S = HPH + r
            nu_out[j] = nu
            s_out[j] = S
            if gate > 0.0 and nu * nu > gate * gate * S:
                r_new = nu * nu / (gate * gate) - HPH
                infl[j] = r_new / r
                r = r_new
                S = HPH + r
            # Joseph form for a scalar update, O(n^2), in place (no temporaries):
            # P <- P - K PH^T - PH K^T + S K K^T with K = PH / S (symmetric by construction)
            for a in range(n):
                ka = PH[a] / S
                for b in range(a, n):
                    kb = PH[b] / S
                    v = P[a, b] - ka * PH[b] - PH[a] * kb + S * ka * kb
                    P[a, b] = v
                    P[b, a] = v
                x[a] += ka * nu
        xf[k] = x
        Pf[k] = P
    return xf, Pf, xp, Pp, nu_out, s_out, infl


@nb.njit(cache=True)
def backward(xf, Pf, xp, Pp, dt, Cen, Cnb, Csf, acc, q, mstart, mtype, mz, mr, mtau, mH, md, pnom,
             hnom, pst, Cst):
    """RTS backward pass; also the smoothed residual of every measurement (raw, and in units of
    its own standard deviation sqrt(R)), and its rate dh/dtau (for clock-offset estimation).

    Returns smoothed states, the smoothed position-velocity covariance block (N, 6, 6), the
    smoothed state variances (N, n), normalised residuals, raw residuals and rates.
    """
    N, n = xf.shape
    M = mtype.shape[0]
    xs = xf.copy()
    Pblk = np.empty((N, 6, 6))
    var = np.empty((N, n))
    res_n = np.full(M, np.nan)
    res = np.full(M, np.nan)
    rate = np.full(M, np.nan)
    Ps_next = Pf[N - 1].copy()
    for k in range(N - 1, -1, -1):
        if k < N - 1:
            F = transition(k + 1, dt, Cen, Cnb, Csf, acc, q[4])
            A = F @ Pf[k]
            C = np.linalg.solve(Pp[k + 1], A).T
            xs[k] = xf[k] + C @ (xs[k + 1] - xp[k + 1])
            Pk = Pf[k] + C @ (Ps_next - Pp[k + 1]) @ C.T
            Pk = 0.5 * (Pk + Pk.T)
        else:
            Pk = Pf[k].copy()
        Ps_next = Pk
        Pblk[k] = Pk[0:6, 0:6]
        for i in range(n):
            var[k, i] = Pk[i, i]
        x = xs[k]
        for j in range(mstart[k], mstart[k + 1]):
            hx, H = measure(j, k, x, mtype, mz, mtau, mH, md, Cen, pnom, hnom, pst, Cst)
            e = mz[j] - hx
            t = mtype[j]
            if t == AZIMUTH or t == ELEVATION or t == HEADING or t == TRACK:
                e = _wrap(e)
            res[j] = e
            res_n[j] = e / np.sqrt(mr[j])
            # rate of the predicted measurement with the measurement time: dh/dtau
            if t == LINEAR:
                rd = 0.0
                for m in range(3):
                    s = 0.0
                    for i in range(3):
                        s += mH[j, IP + i] * Cen[k, i, m]
                    rd += s * x[IV + m]
                rate[j] = rd
            elif t == TAS or t == HEADING or t == DOPPLER or t == TRACK:
                rate[j] = 0.0
            else:
                rd = 0.0
                for m in range(3):
                    s = 0.0
                    for i in range(3):
                        s += H[IP + i] * Cen[k, i, m]
                    rd += s * x[IV + m]
                rate[j] = rd
    return xs, Pblk, var, res_n, res, rate
