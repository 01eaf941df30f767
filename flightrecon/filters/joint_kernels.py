"""Compiled kernels of the joint post-flight smoother (see :mod:`flightrecon.filters.joint`).

State (n = 24), SI units::

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
    20    dphi   roll bias [rad] (measured - true)
    21    dtheta pitch bias [rad] (measured - true)
    22:24 g      wind gradient with height, north, east [(m/s)/m]

Propagation over one state step of length dt (inputs held between input samples)::

    p+ = p + C_en (v dt + dP_meas + J_p [dpsi, b_a])        dP_meas, dV_meas: increments of the
    v+ = v + dV_meas + J_v [dpsi, b_a]                       measured kinematic acceleration
    w+ = w + g dz + noise (random walk in time and in altitude)  over the step (exact for held
    g+ = g + noise (random walk in time)                     inputs; dz: the nominal's climb)
    b_a+ = exp(-dt/tau) b_a + noise

with J_v = [[a_E, -a_N, 0]^T dt, -g0 C_nb dt, -g0 C_nb diag(f) dt, -g0 dC/dphi f dt,
-g0 dC/dtheta f dt] and J_p = J_v dt / 2: the heading bias rotates the measured horizontal
acceleration, the accelerometer bias and scale errors add through the attitude (f: measured
specific force in body axes, in g), and the roll and pitch biases tilt it:
dC/dphi f = C_nb (e_x x f) and dC/dtheta f = C_nb (u x f), u = (0, cos phi, -sin phi)
(C_nb = R_z R_y R_x; R_x^T e_y = u), both as step means over the held inputs.  C_en (NED -> ECEF) is
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

from flightrecon.filters.smallmat import cholesky_factor, cholesky_solve_columns

N_STATE = 24
IP, IV, IW, IBA, IPSI, IS, IBH, IC, IDW, IDC, IKS, IATT, IG = (0, 3, 6, 8, 11, 12, 13, 14, 15, 16,
                                                                17, 20, 22)
G0 = 9.80665

LINEAR, RANGE, AZIMUTH, ELEVATION, TAS, HEADING, BARO, DOPPLER, TRACK = 0, 1, 2, 3, 4, 5, 6, 7, 8
ANGLE_TYPES = (AZIMUTH, ELEVATION, HEADING, TRACK)


@nb.njit(cache=True, nogil=True)
def _wrap(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


@nb.njit(cache=True, nogil=True)
def transition_into(F, k, dt, Cen, Cnb, Csf, Jatt, acc, tau_ba, dz):
    """Fill ``F`` (n, n) with the transition matrix F_k from step k-1 to step k (k >= 1).

    ``Csf[k]`` is the step mean of C_nb diag(f_body) (the Jacobian of the acceleration in the
    accelerometer scale errors), ``Jatt[k]`` (3, 2) that of dC/dphi f and dC/dtheta f (roll and
    pitch biases), ``dz[k]`` the nominal's height change over the step (the wind moves along
    its gradient with height).  Only the position, velocity, wind and accelerometer-bias rows
    differ from the identity (see the module docstring).
    """
    n = N_STATE
    for i in range(n):
        for j in range(n):
            F[i, j] = 0.0
        F[i, i] = 1.0
    h = dt[k]
    for i in range(3):
        for j in range(3):
            F[IP + i, IV + j] = Cen[k - 1, i, j] * h
    g0 = acc[k, 1]
    g1 = -acc[k, 0]
    F[IV, IPSI] = g0 * h
    F[IV + 1, IPSI] = g1 * h
    for i in range(3):
        for j in range(3):
            F[IV + i, IBA + j] = -G0 * Cnb[k, i, j] * h
            F[IV + i, IKS + j] = -G0 * Csf[k, i, j] * h
        for j in range(2):
            F[IV + i, IATT + j] = -G0 * Jatt[k, i, j] * h
    # position: C_en times the velocity terms times dt/2
    hh = h * h / 2.0
    for i in range(3):
        c0, c1, c2 = Cen[k - 1, i, 0], Cen[k - 1, i, 1], Cen[k - 1, i, 2]
        F[IP + i, IPSI] = (c0 * g0 + c1 * g1) * hh
        for j in range(3):
            F[IP + i, IKS + j] = -G0 * (c0 * Csf[k, 0, j] + c1 * Csf[k, 1, j]
                                        + c2 * Csf[k, 2, j]) * hh
            F[IP + i, IBA + j] = -G0 * (c0 * Cnb[k, 0, j] + c1 * Cnb[k, 1, j]
                                        + c2 * Cnb[k, 2, j]) * hh
        for j in range(2):
            F[IP + i, IATT + j] = -G0 * (c0 * Jatt[k, 0, j] + c1 * Jatt[k, 1, j]
                                         + c2 * Jatt[k, 2, j]) * hh
    e = np.exp(-h / tau_ba)
    for j in range(3):
        F[IBA + j, IBA + j] = e
    F[IW, IG] = dz[k]
    F[IW + 1, IG + 1] = dz[k]


@nb.njit(cache=True, nogil=True)
def transition(k, dt, Cen, Cnb, Csf, Jatt, acc, tau_ba, dz):
    """Transition matrix F_k from step k-1 to step k (k >= 1); see :func:`transition_into`."""
    F = np.empty((N_STATE, N_STATE))
    transition_into(F, k, dt, Cen, Cnb, Csf, Jatt, acc, tau_ba, dz)
    return F


@nb.njit(cache=True, nogil=True)
def _sparse_rows(F, cols, vals, cnt):
    """Row-compressed copy of ``F``: row i has ``cnt[i]`` nonzeros ``vals[i, :cnt[i]]`` in the
    columns ``cols[i, :cnt[i]]`` (F_k is the identity plus a few blocks: 11 nonzeros at most
    per row, so products with it cost O(n nnz) instead of O(n^3))."""
    n = F.shape[0]
    for i in range(n):
        c = 0
        for m in range(n):
            if F[i, m] != 0.0:
                cols[i, c] = m
                vals[i, c] = F[i, m]
                c += 1
        cnt[i] = c


@nb.njit(cache=True, nogil=True)
def _predict_cov(P, cols, vals, cnt, B):
    """P <- F P F^T in place with the row-compressed F (:func:`_sparse_rows`); B is scratch.

    B = P F^T (B[a, i] = sum_m P[a, m] F[i, m]), then P = F B, symmetrised.
    """
    n = P.shape[0]
    for i in range(n):
        for a in range(n):
            s = 0.0
            for c in range(cnt[i]):
                s += P[a, cols[i, c]] * vals[i, c]
            B[a, i] = s
    for i in range(n):
        for j in range(i, n):
            s = 0.0
            for c in range(cnt[i]):
                s += vals[i, c] * B[cols[i, c], j]
            P[i, j] = s
    for i in range(n):
        for j in range(i):
            P[i, j] = P[j, i]


@nb.njit(cache=True, nogil=True)
def _sparse_matvec(cols, vals, cnt, x, out):
    """out = F x with the row-compressed F."""
    for i in range(x.shape[0]):
        s = 0.0
        for c in range(cnt[i]):
            s += vals[i, c] * x[cols[i, c]]
        out[i] = s


@nb.njit(cache=True, nogil=True)
def _sparse_rmatvec(cols, vals, cnt, y, out):
    """out = F^T y with the row-compressed F."""
    n = y.shape[0]
    for m in range(n):
        out[m] = 0.0
    for i in range(n):
        for c in range(cnt[i]):
            out[cols[i, c]] += vals[i, c] * y[i]


@nb.njit(cache=True, nogil=True)
def _cholesky_solve(A, b, L, y):
    """y = A^{-1} b for a symmetric positive-definite A by Cholesky (L is scratch).

    Returns False (and leaves y undefined) if A is not numerically positive definite.
    """
    if not cholesky_factor(A, L, 0.0):
        return False
    cholesky_solve_columns(L, b.reshape((-1, 1)), y.reshape((-1, 1)))
    return True


@nb.njit(cache=True, nogil=True)
def add_process_noise(P, k, dt, Cen, dz, qv_extra, q):
    """P += Q_k in place, touching only the nonzero entries of Q_k.  q = [q_acc, q_wind_t,
    q_wind_h, var_ba, tau_ba, q_psi, q_bh, q_grad] (see JointNoise); ``|dz[k]|`` is the height
    change over the step (wind varies with altitude), ``qv_extra[k]`` extra acceleration PSD
    where the load factors are missing.  Position-velocity block: white acceleration of PSD q_a
    (Q_pp = q_a h^3/3, Q_vv = q_a h, Q_pv = q_a h^2/2 C_en)."""
    h = dt[k]
    qa = q[0] + qv_extra[k]
    for i in range(3):
        P[IP + i, IP + i] += qa * h ** 3 / 3.0
        P[IV + i, IV + i] += qa * h
        for j in range(3):
            v = qa * h * h / 2.0 * Cen[k - 1, i, j]
            P[IP + i, IV + j] += v
            P[IV + j, IP + i] += v
    qw = q[1] * h + q[2] * abs(dz[k])
    P[IW, IW] += qw
    P[IW + 1, IW + 1] += qw
    gm = q[3] * (1.0 - np.exp(-2.0 * h / q[4]))
    for j in range(3):
        P[IBA + j, IBA + j] += gm
    P[IPSI, IPSI] += q[5] * h
    P[IBH, IBH] += q[6] * h
    P[IG, IG] += q[7] * h
    P[IG + 1, IG + 1] += q[7] * h


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
        return f * va
    if t == HEADING:
        an = x[IV] - x[IW]
        ae = x[IV + 1] - x[IW + 1]
        v2 = an * an + ae * ae
        H[IV] = -ae / v2
        H[IV + 1] = an / v2
        H[IW] = ae / v2
        H[IW + 1] = -an / v2
        H[IPSI] = 1.0
        return np.arctan2(ae, an) + x[IPSI]
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
def forward(xf, Pf, xp, Pp, x0, P0, dt, Cen, Cnb, Csf, Jatt, acc, dP, dV, dz, qv_extra, q, mstart, mtype, mz, mr, mw,
            mtau, mH, mrow, md, pnom, hnom, pst, Cst, gate, xlin):
    """Forward extended Kalman filter with sequential scalar updates.

    With ``xlin`` (N, n) the measurements are linearised about it (the smoothed states of the
    last pass: h(x) ~ h(xlin_k) + H(xlin_k)(x - xlin_k), which makes the iterations Gauss-Newton
    on the whole record, an iterated extended Kalman smoother); with an empty ``xlin`` (0, n)
    about the filter's own prediction (an extended Kalman filter: the first pass).

    ``mstart`` (N+1,) indexes the measurements of each step (sorted by step).  A measurement
    whose normalised innovation exceeds ``gate`` (0: off) has its variance inflated so that it
    equals ``gate`` (a Huber-type robust update: a jump is followed only slowly, never trusted).
    Fills the filtered and predicted states/covariances ``xf``, ``Pf`` (N, n[, n]), ``xp``,
    ``Pp`` (given, so that the Gauss-Newton iterations reuse them; an empty ``Pp`` is not
    filled: the backward passes then recompute each predicted covariance from ``Pf``, bit for
    bit the same, which saves its memory) and returns, per
    measurement, the innovation, its variance (before inflation) and the inflation factor.

    Allocation-free per step: the prediction uses the row-compressed F_k (P <- F P F^T + Q in
    O(n nnz)), the update the nonzero entries of each measurement's gradient.
    """
    N = dt.shape[0]
    n = N_STATE
    M = mtype.shape[0]
    nu_out = np.full(M, np.nan)
    s_out = np.full(M, np.nan)
    infl = np.ones(M)
    x = x0.copy()
    P = P0.copy()
    F = np.empty((n, n))
    B = np.empty((n, n))
    cols = np.empty((n, n), dtype=np.int64)
    vals = np.empty((n, n))
    cnt = np.empty(n, dtype=np.int64)
    xn = np.empty(n)
    H = np.empty(n)
    PH = np.empty(n)
    hnz = np.empty(n, dtype=np.int64)
    for k in range(N):
        if k > 0:
            _transition_rows(F, cols, vals, cnt, k, dt, Cen, Cnb, Csf, Jatt, acc, q[4], dz)
            _sparse_matvec(cols, vals, cnt, x, xn)
            for i in range(n):
                x[i] = xn[i]
            for i in range(3):
                for m in range(3):
                    x[IP + i] += Cen[k - 1, i, m] * dP[k, m]
                x[IV + i] += dV[k, i]
            _predict_cov(P, cols, vals, cnt, B)
            add_process_noise(P, k, dt, Cen, dz, qv_extra, q)
        xp[k] = x
        if Pp.shape[0] > 0:
            Pp[k] = P
        for j in range(mstart[k], mstart[k + 1]):
            if mw[j] <= 0.0:
                continue
            t = mtype[j]
            if xlin.shape[0] > 0:
                hx = measure_into(H, j, k, xlin[k], mtype, mz, mtau, mH, mrow, md, Cen, pnom,
                                  hnom, pst, Cst)
                nu = mz[j] - hx
                if t == AZIMUTH or t == ELEVATION or t == HEADING or t == TRACK:
                    nu = _wrap(nu)
                for i in range(n):
                    if H[i] != 0.0:
                        nu -= H[i] * (x[i] - xlin[k, i])
            else:
                hx = measure_into(H, j, k, x, mtype, mz, mtau, mH, mrow, md, Cen, pnom, hnom,
                                  pst, Cst)
                nu = mz[j] - hx
                if t == AZIMUTH or t == ELEVATION or t == HEADING or t == TRACK:
                    nu = _wrap(nu)
            nh = 0
            for i in range(n):
                if H[i] != 0.0:
                    hnz[nh] = i
                    nh += 1
            HPH = 0.0
            for a in range(n):
                v = 0.0
                for c in range(nh):
                    v += P[a, hnz[c]] * H[hnz[c]]
                PH[a] = v
            for c in range(nh):
                HPH += H[hnz[c]] * PH[hnz[c]]
            r = mr[j] / mw[j]
            S = HPH + r
            nu_out[j] = nu
            s_out[j] = S
            if gate > 0.0 and nu * nu > gate * gate * S:
                r_new = nu * nu / (gate * gate) - HPH
                infl[j] = r_new / r
                r = r_new
                S = HPH + r
            # scalar update with K = PH / S, in place, O(n^2): the Joseph form
            # (I - K H) P (I - K H)^T + K r K^T expanded for the optimal gain is
            # P - K PH^T - PH K^T + S K K^T = P - PH PH^T / S; (PH_a PH_b) / S is bitwise
            # symmetric, so P stays exactly symmetric
            inv_s = 1.0 / S
            for a in range(n):
                pa = PH[a]
                for b in range(n):
                    P[a, b] -= (pa * PH[b]) * inv_s
                x[a] += pa * inv_s * nu
        xf[k] = x
        Pf[k] = P
    return nu_out, s_out, infl


@nb.njit(cache=True, nogil=True)
def _transition_rows(F, cols, vals, cnt, k, dt, Cen, Cnb, Csf, Jatt, acc, tau_ba, dz):
    """F_k into ``F`` and its row-compressed copy (:func:`transition_into`, :func:`_sparse_rows`)."""
    transition_into(F, k, dt, Cen, Cnb, Csf, Jatt, acc, tau_ba, dz)
    _sparse_rows(F, cols, vals, cnt)


@nb.njit(cache=True, nogil=True)
def _predicted_at(k, Pf, Pp, cols, vals, cnt, B, dt, Cen, dz, qv_extra, q, buf):
    """P_p[k]: the stored one if the forward pass kept them, else recomputed into ``buf``."""
    if Pp.shape[0] > 0:
        return Pp[k]
    _predicted_cov(k, Pf, Pp, cols, vals, cnt, B, dt, Cen, dz, qv_extra, q, buf)
    return buf


@nb.njit(cache=True, nogil=True)
def _predicted_cov(k, Pf, Pp, cols, vals, cnt, B, dt, Cen, dz, qv_extra, q, out):
    """P_p[k] = F_k P_f[k-1] F_k^T + Q_k into ``out``, recomputed with the same operations as
    :func:`forward` (``cols``/``vals``/``cnt``: F_k row-compressed), for a forward pass that
    did not store it."""
    n = out.shape[0]
    for i in range(n):
        for j in range(n):
            out[i, j] = Pf[k - 1, i, j]
    _predict_cov(out, cols, vals, cnt, B)
    add_process_noise(out, k, dt, Cen, dz, qv_extra, q)


@nb.njit(cache=True, nogil=True)
def _residuals_at(k, x, mstart, mtype, mz, mr, mtau, mH, mrow, md, Cen, pnom, hnom, pst, Cst,
                  H, res, res_n, rate, P, hph):
    """Residuals z - h(x) of step k's measurements at the smoothed state ``x``: raw, in units of
    sqrt(R), and the rate dh/dtau of each predicted measurement (for the clock offsets); with a
    smoothed covariance ``P`` (n, n) (an empty array: skipped) also H P H^T into ``hph``."""
    n = x.shape[0]
    for j in range(mstart[k], mstart[k + 1]):
        hx = measure_into(H, j, k, x, mtype, mz, mtau, mH, mrow, md, Cen, pnom, hnom, pst, Cst)
        if P.shape[0] == n:
            v = 0.0
            for a in range(n):
                if H[a] != 0.0:
                    for b in range(n):
                        v += H[a] * P[a, b] * H[b]
            hph[j] = v
        e = mz[j] - hx
        t = mtype[j]
        if t == AZIMUTH or t == ELEVATION or t == HEADING or t == TRACK:
            e = _wrap(e)
        res[j] = e
        res_n[j] = e / np.sqrt(mr[j])
        # rate of the predicted measurement with the measurement time: dh/dtau
        if t == TAS or t == HEADING or t == DOPPLER or t == TRACK:
            rate[j] = 0.0
            continue
        rd = 0.0  # H holds the gradient (for LINEAR, the measurement's row of mH)
        for m in range(3):
            s = 0.0
            for i in range(3):
                s += H[IP + i] * Cen[k, i, m]
            rd += s * x[IV + m]
        rate[j] = rd


@nb.njit(cache=True, nogil=True)
def backward_mean(xf, Pf, xp, Pp, dt, Cen, Cnb, Csf, Jatt, acc, q, mstart, mtype, mz, mr, mtau, mH,
                  mrow, md, pnom, hnom, pst, Cst, dz, qv_extra):
    """RTS backward pass for the smoothed states only (no covariances), and the residuals.

    x_s[k] = x_f[k] + P_f[k] F_{k+1}^T P_p[k+1]^{-1} (x_s[k+1] - x_p[k+1]): the same smoothed
    mean as :func:`backward` (Rauch, Tung & Striebel 1965) at O(n^3 / 6) per step (one Cholesky
    solve with a vector) instead of O(n^3) products; used in the Gauss-Newton iterations, which
    need the trajectory and the residuals but not the smoothed covariances.

    Returns smoothed states, normalised residuals, raw residuals and rates (as :func:`backward`).
    """
    N, n = xf.shape
    M = mtype.shape[0]
    xs = xf.copy()
    res_n = np.full(M, np.nan)
    res = np.full(M, np.nan)
    rate = np.full(M, np.nan)
    F = np.empty((n, n))
    cols = np.empty((n, n), dtype=np.int64)
    vals = np.empty((n, n))
    cnt = np.empty(n, dtype=np.int64)
    L = np.empty((n, n))
    d = np.empty(n)
    y = np.empty(n)
    z = np.empty(n)
    H = np.empty(n)
    B = np.empty((n, n))
    Pbuf = np.empty((n, n))
    no_P = np.empty((0, 0))
    no_hph = np.empty(0)
    for k in range(N - 1, -1, -1):
        if k < N - 1:
            _transition_rows(F, cols, vals, cnt, k + 1, dt, Cen, Cnb, Csf, Jatt, acc, q[4], dz)
            Pk1 = _predicted_at(k + 1, Pf, Pp, cols, vals, cnt, B, dt, Cen, dz, qv_extra, q,
                                Pbuf)
            for i in range(n):
                d[i] = xs[k + 1, i] - xp[k + 1, i]
            if not _cholesky_solve(Pk1, d, L, y):
                y[:] = np.linalg.solve(Pk1, d)
            _sparse_rmatvec(cols, vals, cnt, y, z)
            for a in range(n):
                v = xf[k, a]
                for b in range(n):
                    v += Pf[k, a, b] * z[b]
                xs[k, a] = v
        _residuals_at(k, xs[k], mstart, mtype, mz, mr, mtau, mH, mrow, md, Cen, pnom, hnom, pst,
                      Cst, H, res, res_n, rate, no_P, no_hph)
    return xs, res_n, res, rate


@nb.njit(cache=True, nogil=True)
def backward(xf, Pf, xp, Pp, dt, Cen, Cnb, Csf, Jatt, acc, q, mstart, mtype, mz, mr, mtau, mH, mrow,
             md, pnom, hnom, pst, Cst, dz, qv_extra, residuals):
    """RTS backward pass with covariances; also the smoothed residuals (see
    :func:`backward_mean`, which gives the same states without the covariances).

    Returns smoothed states, the smoothed position-velocity covariance block (N, 6, 6), the
    smoothed state variances (N, n), normalised residuals, raw residuals, rates and, per
    measurement, H P_s H^T (the smoothed variance of the predicted measurement).  With
    ``residuals`` False the residual outputs stay NaN (the covariances do not need them: this
    pass can then run beside :func:`backward_mean` on another thread).
    """
    N, n = xf.shape
    M = mtype.shape[0]
    xs = xf.copy()
    Pblk = np.empty((N, 6, 6))
    var = np.empty((N, n))
    res_n = np.full(M, np.nan)
    res = np.full(M, np.nan)
    rate = np.full(M, np.nan)
    hph = np.full(M, np.nan)
    F = np.empty((n, n))
    cols = np.empty((n, n), dtype=np.int64)
    vals = np.empty((n, n))
    cnt = np.empty(n, dtype=np.int64)
    A = np.empty((n, n))
    B = np.empty((n, n))
    Pbuf = np.empty((n, n))
    G = np.empty((n, n))
    GT = np.empty((n, n))
    L = np.empty((n, n))
    D = np.empty((n, n))
    E = np.empty((n, n))
    d = np.empty(n)
    H = np.empty(n)
    Ps = Pf[N - 1].copy()
    for k in range(N - 1, -1, -1):
        if k < N - 1:
            _transition_rows(F, cols, vals, cnt, k + 1, dt, Cen, Cnb, Csf, Jatt, acc, q[4], dz)
            # A = F P_f[k] (row-compressed F); the gain G = P_f F^T P_p^-1, i.e. G^T = P_p^-1 A
            for i in range(n):
                for b in range(n):
                    v = 0.0
                    for c in range(cnt[i]):
                        v += vals[i, c] * Pf[k, cols[i, c], b]
                    A[i, b] = v
            Pk1 = _predicted_at(k + 1, Pf, Pp, cols, vals, cnt, B, dt, Cen, dz, qv_extra, q,
                                Pbuf)
            if cholesky_factor(Pk1, L, 0.0):
                cholesky_solve_columns(L, A, GT)      # GT = P_p^-1 A = G^T
            else:
                GT[:, :] = np.linalg.solve(Pk1, A)
            for i in range(n):
                for j in range(n):
                    G[i, j] = GT[j, i]
            # x_s[k] = x_f[k] + G (x_s[k+1] - x_p[k+1])
            for i in range(n):
                d[i] = xs[k + 1, i] - xp[k + 1, i]
            for i in range(n):
                v = xf[k, i]
                for j in range(n):
                    v += G[i, j] * d[j]
                xs[k, i] = v
            # P_s[k] = P_f[k] + G (P_s[k+1] - P_p[k+1]) G^T (BLAS products into buffers)
            for i in range(n):
                for j in range(n):
                    D[i, j] = Ps[i, j] - Pk1[i, j]
            np.dot(G, D, E)
            np.dot(E, GT, Ps)
            for i in range(n):
                for j in range(i, n):
                    Ps[i, j] += Pf[k, i, j]
            for i in range(n):           # the upper triangle mirrored: exactly symmetric
                for j in range(i):
                    Ps[i, j] = Ps[j, i]
        for i in range(6):
            for j in range(6):
                Pblk[k, i, j] = Ps[i, j]
        for i in range(n):
            var[k, i] = Ps[i, i]
        if residuals:
            _residuals_at(k, xs[k], mstart, mtype, mz, mr, mtau, mH, mrow, md, Cen, pnom, hnom,
                          pst, Cst, H, res, res_n, rate, Ps, hph)
    return xs, Pblk, var, res_n, res, rate, hph
