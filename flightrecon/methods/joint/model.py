"""The joint smoother's compiled model (state layout and types in
:mod:`~flightrecon.methods.joint.layout`; docs/joint.md, "Filter, smoother, iterations";
docs/estimation.md, "The joint model"): the transition and process noise, the scalar measurement
functions, the model protocol of the estimation core and the MAP cost.

The transition is the identity plus a few blocks (:func:`transition_into`); the passes predict with
it row-compressed through the core (:func:`flightrecon.estimation.predict.predict_sparse`) and add
the process noise touching only its nonzero entries (:func:`add_process_noise`: the
constant-velocity and Gauss-Markov blocks from :mod:`flightrecon.estimation.discretise`).

:class:`JointModel` holds one pass's inputs (the :class:`~flightrecon.methods.joint.layout.
Dynamics`, :class:`~flightrecon.methods.joint.layout.Scalars` and
:class:`~flightrecon.methods.joint.layout.Geometry` layouts, the innovation gate and the
linearisation point ``xlin``) and the buffers its outputs go to; the functions registered with
``implements`` are the model protocol (:mod:`flightrecon.estimation.model`) for it, compiled into
the core's :func:`~flightrecon.estimation.filtering.forward_pass` and
:func:`~flightrecon.estimation.smoothing.backward_pass` (a step's prediction, scalar updates,
smoothing covariances: their docstrings).  None of them loops over the time steps.

The MAP cost (:func:`map_cost`; docs/joint.md, "MAP cost") of a state trajectory X on the state
grid, the negative log posterior up to a constant::

    J(X) = 1/2 (x_0 - m_0)^T P_0^{-1} (x_0 - m_0)                         (prior)
         + 1/2 sum_k e_k^T Q_k^{-1} e_k,   e_k = x_k - f_k(x_{k-1})       (process)
         + sum_j rho(u_j),                 u_j = (z_j - h_j(x_{k(j)})) / sqrt(R_j)   (data)

with the transition f_k and the measurement functions h_j of the models built about X itself (the
linearisation terms vanish: the nonlinear model's cost) and the robust loss (Huber with threshold
``c``, constant beyond ``c_rej``; u^2/2 without ``robust``)::

    rho(u) = u^2 / 2                      |u| <= c
           = c |u| - c^2 / 2              c < |u| <= c_rej
           = c c_rej - c^2 / 2            |u| > c_rej

concave in s = u^2 with derivative w/2, w = min(1, c/|u|) (0 beyond c_rej): the IRLS step with those
weights is a majorise-minimise step on J (Lange, Hunter & Yang 2000).  States without process noise
(Q_k,ii = 0, or below rounding of the state, (64 eps |x|)^2) are constants of the model, kept
constant exactly by the RTS smoother: no process term, their largest step change returned as a
check.
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from flightrecon.estimation import model as em
from flightrecon.estimation.discretise import gauss_markov_step, white_acceleration_q
from flightrecon.estimation.linalg import cholesky_factor, pack_sym, unpack_sym
from flightrecon.estimation.manifold import EUCLIDEAN
from flightrecon.estimation.predict import (
    predict_cov_sparse,
    predict_sparse,
    sparse_left_product,
    sparse_matvec,
    sparse_rmatvec,
    sparse_rows,
)
from flightrecon.estimation.updates import scalar_update_short
from flightrecon.methods.joint.layout import (
    AZIMUTH,
    DOPPLER,
    ELEVATION,
    G0,
    HEADING,
    IATT,
    IBA,
    IBH,
    IC,
    IDC,
    IDW,
    IG,
    IGU,
    IKS,
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
    Dynamics,
    Geometry,
    Scalars,
)


@nb.njit(cache=True, nogil=True, inline="always")
def wrap_pi(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


@nb.njit(cache=True, nogil=True)
def transition_into(F, k, dt, Cen, Cnb, Csf, Jatt, acc, tau_ba, dz, ga):
    """Fill ``F`` (n, n) with the transition matrix F_k from step k-1 to step k (k >= 1).

    ``Csf[k]`` is the step mean of C_nb diag(f_body) (the Jacobian of the acceleration in the
    accelerometer scale errors), ``Jatt[k]`` (3, 2) that of dC/dphi f and dC/dtheta f (roll and
    pitch biases), ``dz[k]`` the nominal's height change over the step (the wind moves along its
    gradient with height), ``ga[k]`` the gust's decay over the step.  Only the position, velocity,
    wind, accelerometer-bias and gust rows differ from the identity.

    Over one state step of length dt (inputs held between input samples)::

        p+ = p + C_en (v dt + dP_meas + J_p [dpsi, b_a])
        v+ = v + dV_meas + J_v [dpsi, b_a]
        w+ = w + g dz + noise (random walk in time and in altitude)
        g+ = g + noise (random walk in time)
        u+ = a u + noise,  a = exp(-V dt / L), var sigma_u^2 (1 - a^2)   (V: the recorded airspeed)
        b_a+ = exp(-dt/tau) b_a + noise

    dP_meas, dV_meas the increments of the measured kinematic acceleration over the step (exact
    for held inputs; plus the Coriolis and transport-rate acceleration at the nominal velocity:
    :func:`~flightrecon.methods.joint.linearisation.models_at`), dz the nominal's climb, with
    J_v = [[a_E, -a_N, 0]^T dt, -g0 C_nb dt, -g0 C_nb diag(f) dt, -g0 dC/dphi f dt,
    -g0 dC/dtheta f dt] and J_p = J_v dt / 2: the heading bias rotates the measured horizontal
    acceleration, the accelerometer bias and scale errors add through the attitude (f: measured
    specific force in body axes, in g), and the roll and pitch biases tilt it:
    dC/dphi f = C_nb (e_x x f) and dC/dtheta f = C_nb (u x f), u = (0, cos phi, -sin phi)
    (C_nb = R_z R_y R_x; R_x^T e_y = u), both as step means over the held inputs.  C_en
    (NED -> ECEF) is evaluated on the nominal trajectory (refreshed each iteration).
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
    e, _ = gauss_markov_step(1.0 / tau_ba, 0.0, h)  # accelerometer bias: Gauss-Markov
    for j in range(3):
        F[IBA + j, IBA + j] = e
    F[IW, IG] = dz[k]
    F[IW + 1, IG + 1] = dz[k]
    F[IGU, IGU] = ga[k]
    F[IGU + 1, IGU + 1] = ga[k]


@nb.njit(cache=True, nogil=True)
def add_process_noise(P, k, dt, Cen, dz, qv_extra, q, ga):
    """P += Q_k in place, touching only the nonzero entries of Q_k. q = [q_acc, q_wind_t, q_wind_h,
    var_ba, tau_ba, q_psi, q_bh, q_grad, var_gust, dq_n, dq_e, dq_d] (see JointNoise and
    :func:`flightrecon.methods.joint.linearisation.q_vector`); ``|dz[k]|`` is the height change over
    the step (wind varies with altitude), ``qv_extra[k]`` extra acceleration PSD where the load
    factors are missing, ``ga[k]`` the gust's decay over the step (exact discretisation of the
    first-order Gauss-Markov gust: var_gust (1 - ga^2)).

    Position-velocity block: white acceleration along each NED axis a of PSD q_a = q_acc +
    qv_extra[k] + dq_a (dq_a the sampling part of a low-rate load record, docs/joint.md, "1 Hz
    records"), position in ECEF through C = C_en (NED -> ECEF) at step k - 1, exact for a constant C
    over the step (Bar-Shalom et al. 2001, eq. 6.2.2-12, axis by axis):

        Q_pp = h^3/3 C diag(q) C^T,   Q_pv = h^2/2 C diag(q),   Q_vv = h diag(q);

    with dq = 0 this is the isotropic q_acc (h^3/3, h^2/2 C, h) of one white acceleration."""
    h = dt[k]
    base = q[0] + qv_extra[k]
    qa = (base + q[9], base + q[10], base + q[11])   # a tuple: no allocation per step
    qpp, qpv, qvv = white_acceleration_q(1.0, h)
    C = Cen[k - 1]
    for i in range(3):
        for m in range(3):
            s = 0.0
            for a in range(3):
                s += C[i, a] * qa[a] * C[m, a]
            P[IP + i, IP + m] += qpp * s
        P[IV + i, IV + i] += qvv * qa[i]
        for j in range(3):
            v = qpv * C[i, j] * qa[j]
            P[IP + i, IV + j] += v
            P[IV + j, IP + i] += v
    qw = q[1] * h + q[2] * abs(dz[k])
    P[IW, IW] += qw
    P[IW + 1, IW + 1] += qw
    _, gm = gauss_markov_step(1.0 / q[4], q[3], h)
    for j in range(3):
        P[IBA + j, IBA + j] += gm
    P[IPSI, IPSI] += q[5] * h
    P[IBH, IBH] += q[6] * h
    P[IG, IG] += q[7] * h
    P[IG + 1, IG + 1] += q[7] * h
    qg = q[8] * (1.0 - ga[k] * ga[k])
    P[IGU, IGU] += qg
    P[IGU + 1, IGU + 1] += qg


@nb.njit(cache=True, nogil=True, inline="always")
def _moved(x, C, tau, i):
    """ECEF coordinate ``i`` of the position moved by the velocity over ``tau``: p_i + sum_m C[i, m]
    v_m tau (summed in that order).  Inlined at numba's IR level into :func:`measure_into` (called
    there with the constants 0, 1, 2: three compilations of their own otherwise, 1.5 s on a cold
    cache)."""
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


N_CLOCK = 3
"""Clock offsets the forward pass can carry as filter columns (GNSS positions, radar, GNSS
velocities: :data:`~flightrecon.methods.joint.solve.CLOCK_SOURCES`)."""


@em.with_mean_only_pass
class JointModel(NamedTuple):
    """One pass of the joint smoother as a model of the estimation core (module docstring).

    Inputs: ``dyn``, ``meas``, ``geo`` (the layouts), ``gate`` (the normalised innovation beyond
    which a measurement's variance is inflated; 0: off), ``xlin`` (N, n) the linearisation point of
    the measurements ((0, n): the filter's own prediction).

    Filter buffers: ``xf``, ``xp`` (N, n), ``Pf``, ``Pp`` (N, n (n + 1) / 2) packed lower triangles
    (``Pp`` (0, ...): not kept); per measurement the innovation ``nu``, its variance ``S`` (before
    inflation) and the inflation factor ``infl`` ((0,) in a backward pass).

    Smoother buffers: per measurement the residuals ``res`` (z - h(x_s)), ``res_n`` (in units of
    sqrt(R)), the ``rate`` dh/dtau and ``hph`` (H P_s H^T, in the covariance pass only) ((0,): not
    computed); per step ``Pblk`` (N, 6, 6) the position-velocity block of P_s and ``var`` (N, n) its
    diagonal ((0, ...): the mean-only pass).

    Clock offsets (forward pass; (0,): not estimated): ``ccol`` (M,) the clock column of each
    measurement (0 GNSS, 1 radar, -1 none), ``crate`` (M,) the rate of the prediction with the
    measurement's time where its gradient does not give it (GNSS velocities: the nominal's
    acceleration; 0 elsewhere), ``cnorm`` (C, C + 1) the normal equations [A b] of the offsets'
    Gauss-Newton step accumulated over the pass (:func:`_clock_column_update`; (0, 0): not
    estimated), ``cxf``, ``cxp`` (C, N, n) the offsets' filter columns after and before each step's
    updates (C = 3: GNSS positions, radar, GNSS velocities).
    """


    dyn: Dynamics
    meas: Scalars
    geo: Geometry
    gate: float
    xlin: np.ndarray
    xf: np.ndarray
    Pf: np.ndarray
    xp: np.ndarray
    Pp: np.ndarray
    nu: np.ndarray
    S: np.ndarray
    infl: np.ndarray
    res_n: np.ndarray
    res: np.ndarray
    rate: np.ndarray
    hph: np.ndarray
    Pblk: np.ndarray
    var: np.ndarray
    ccol: np.ndarray
    crate: np.ndarray
    cnorm: np.ndarray
    cxf: np.ndarray
    cxp: np.ndarray


def joint_model(bufs: tuple[np.ndarray, ...], dyn: Dynamics, meas: Scalars, geo: Geometry,
                gate: float = 0.0, xlin: np.ndarray | None = None, forward: bool = False,
                residuals: bool = False, covariances: bool = False,
                clock: tuple[np.ndarray, np.ndarray] | None = None) -> JointModel:
    """A :class:`JointModel` on the filter buffers ``bufs`` = (xf, Pf, xp, Pp), with the output
    buffers of a ``forward`` pass (innovations NaN, inflations 1) or of a backward pass: the
    ``residuals`` (and H P_s H^T; NaN until computed) and the smoothed ``covariances`` blocks.
    ``clock`` (a forward pass; None: no clock offsets) the clock column of each measurement (-1
    none) and its ``crate``: the pass then accumulates the offsets' normal equations in
    ``cnorm``."""
    xf, Pf, xp, Pp = bufs
    N, n = xf.shape
    M = len(meas.mtype)
    none = np.empty(0)
    m_res = M if residuals else 0
    # the clock columns up to the last one a measurement uses (a 10-hour flight's three
    # (N, n) columns before and after the update are 45 MB: the radar's, last, only with radar)
    nc = 0 if clock is None else int(max(np.max(clock[0], initial=-1) + 1, 1))
    return JointModel(dyn, meas, geo, float(gate), np.zeros((0, n)) if xlin is None else xlin, xf,
                      Pf, xp, Pp, np.full(M, np.nan) if forward else none,
                      np.full(M, np.nan) if forward else none, np.ones(M) if forward else none,
                      np.full(m_res, np.nan), np.full(m_res, np.nan), np.full(m_res, np.nan),
                      np.full(m_res, np.nan), np.empty((N if covariances else 0, 6, 6)),
                      np.empty((N if covariances else 0, n)),
                      np.empty(0, dtype=np.int64) if clock is None else clock[0].astype(np.int64),
                      np.empty(0) if clock is None else np.asarray(clock[1], float),
                      np.zeros((0, 0)) if clock is None else np.zeros((nc, nc + 1)),
                      np.zeros((nc, 0 if clock is None else N, n)),
                      np.zeros((nc, 0 if clock is None else N, n)))


# ---- helpers at one step ----

@nb.njit(cache=True, nogil=True)
def _transition_rows(F, cols, vals, cnt, k, dyn):
    """F_k into ``F`` and its row-compressed copy (:func:`transition_into`,
    :func:`~flightrecon.estimation.predict.sparse_rows`)."""
    transition_into(F, k, dyn.dt, dyn.Cen, dyn.Cnb, dyn.Csf, dyn.Jatt, dyn.acc, dyn.q[4], dyn.dz,
                    dyn.ga)
    sparse_rows(F, cols, vals, cnt)


@nb.njit(cache=True, nogil=True)
def _predicted_cov(k, Pf, cols, vals, cnt, B, dyn, out):
    """P_p[k] = F_k P_f[k-1] F_k^T + Q_k into ``out``, recomputed with the same operations as the
    forward prediction (``cols``/``vals``/``cnt``: F_k row-compressed), for a forward pass that did
    not keep it (its lower triangle mirrored, as the kept one)."""
    dt, Cen, Cnb, Csf, Jatt, acc, dP, dV, dz, qv_extra, q, ga = dyn
    n = out.shape[0]
    unpack_sym(Pf[k - 1], out)
    predict_cov_sparse(out, cols, vals, cnt, B)
    add_process_noise(out, k, dt, Cen, dz, qv_extra, q, ga)
    for i in range(n):
        for j in range(i):
            out[j, i] = out[i, j]


@nb.njit(cache=True, nogil=True)
def _residuals_at(k, x, meas, geo, Cen, H, res, res_n, rate, P, hph):
    """Residuals z - h(x) of step k's measurements at the smoothed state ``x``: raw, in units of
    sqrt(R), and the rate dh/dtau of each predicted measurement (for the clock offsets); with a
    smoothed covariance ``P`` (n, n) (an empty array: skipped) also H P H^T into ``hph``."""
    mstart, mtype, mz, mr, mw, mtau, mH, mrow, md = meas
    pnom, hnom, pst, Cst = geo
    n = N_STATE
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
            e = wrap_pi(e)
        res[j] = e
        res_n[j] = e / np.sqrt(mr[j])
        # rate of the predicted measurement with the measurement time: dh/dtau
        if t == TAS or t == HEADING or t == DOPPLER or t == TRACK:
            rate[j] = 0.0
            continue
        rate[j] = _position_rate(H, Cen, k, x)


@nb.njit(cache=True, nogil=True)
def _position_rate(H, Cen, k, x):
    """dh/dtau of a measurement of the position with gradient ``H`` (for ``LINEAR``, its row of mH)
    at state ``x``: (dh/dp) C_en[k] v, the change of the predicted measurement with its time."""
    rd = 0.0
    for m in range(3):
        s = 0.0
        for i in range(3):
            s += H[IP + i] * Cen[k, i, m]
        rd += s * x[IV + m]
    return rd


@nb.njit(cache=True, nogil=True)
def _clock_column_update(j, k, g, nu, S, H, hnz, nh, PH, xg, ccol, cnorm, ng):
    """The clock offsets' columns of the augmented filter at scalar measurement j (docs/joint.md,
    "Filter, smoother, iterations", item 4).

    A measurement stamped t_m and used at t_m + c + dc predicts h + g dc, g = dh/dtau its rate at
    the linearisation point (of a position, :func:`_position_rate`, plus ``crate``). With the
    offsets' step dc (one per column: :data:`~flightrecon.methods.joint.solve.CLOCK_SOURCES`) as
    constant regression parameters of the pass's linearised model, the filtered state is x(dc) =
    x(0) - X_g dc and the innovations nu(dc) = nu - nu_g . dc, where the columns X_g (``xg[:, k]``,
    (C, n) at step k) are the same filter run on the data g_c = g [column of j is c] from zero, with
    no control input: nu_g,c = g_c - H X_g,c, X_g,c <- X_g,c + K nu_g,c (K = P H^T / S, the gain of
    this update) and X_g,c <- F_k X_g,c between the steps (the augmented Kalman filter: de Jong
    1991, "The diffuse Kalman filter", Ann. Stat. 19, 1073-1083; Durbin & Koopman 2012, "Time series
    analysis by state space methods", 6.2.2).  The pass's MAP cost profiled over the track is then
    sum_j (nu_j - nu_g,j . dc)^2 / S_j + const, so the Gauss-Newton step of the offsets jointly with
    the track solves A dc = b with A = sum nu_g nu_g^T / S and b = sum nu_g nu / S; ``cnorm``
    (C, C + 1) accumulates [A b], and A^-1 is the offsets' covariance.  ``ng`` (C,) scratch."""
    nc = xg.shape[0]
    for c in range(nc):
        ng[c] = g if ccol[j] == c else 0.0
        for a in range(nh):
            ng[c] -= H[hnz[a]] * xg[c, k, hnz[a]]
    inv_s = 1.0 / S
    for c in range(nc):
        for d in range(nc):
            cnorm[c, d] += ng[c] * ng[d] * inv_s
        cnorm[c, nc] += ng[c] * nu * inv_s
    for a in range(xg.shape[2]):
        ka = PH[a] * inv_s
        for c in range(nc):
            xg[c, k, a] += ka * ng[c]


# ---- the model protocol (estimation.model) ----

@em.implements(em.workspace, JointModel, forceinline=True)
def _workspace(model):
    """Scratch of both passes: F_k dense and row-compressed, the products' buffers, a measurement's
    gradient and its nonzero indices, P_p[k+1] and P_f[k] unpacked."""
    n = N_STATE
    return (np.empty((n, n)), np.empty((n, n), dtype=np.int64), np.empty((n, n)),
            np.empty(n, dtype=np.int64), np.empty((n, n)), np.empty(n), np.empty(n),
            np.empty(n), np.empty(n, dtype=np.int64), np.empty((n, n)), np.empty((n, n)),
            np.empty(n), np.empty(N_CLOCK))


@em.implements(em.predict_into, JointModel, refcounted=False, forceinline=True)
def _predict(model, k, x, P, ws):
    """x <- F_k x + C_en[k-1] dP_k (position) + dV_k (velocity), P <- F_k P F_k^T + Q_k
    (docs/joint.md, "State and dynamics"), with F_k row-compressed: O(n nnz)."""
    dyn = model.dyn
    F, cols, vals, cnt, B, xn = ws[0], ws[1], ws[2], ws[3], ws[4], ws[5]
    _transition_rows(F, cols, vals, cnt, k, dyn)
    predict_sparse(x, P, cols, vals, cnt, xn, B)  # x <- F x, P <- F P F^T
    if model.cnorm.shape[0] > 0:  # the clock offsets' columns: X_g <- F_k X_g
        for c in range(model.cxf.shape[0]):
            sparse_matvec(cols, vals, cnt, model.cxf[c, k - 1], xn)
            for i in range(N_STATE):
                model.cxp[c, k, i] = xn[i]
    Cen, dP, dV = dyn.Cen, dyn.dP, dyn.dV
    for i in range(3):  # + the control input (the recorded increments) and Q_k
        for m in range(3):
            x[IP + i] += Cen[k - 1, i, m] * dP[k, m]
        x[IV + i] += dV[k, i]
    add_process_noise(P, k, dyn.dt, Cen, dyn.dz, dyn.qv_extra, dyn.q, dyn.ga)


@em.implements(em.keep_predicted, JointModel, refcounted=False, forceinline=True)
def _keep_predicted(model, k, x, P):
    xp = model.xp
    for i in range(N_STATE):  # element loop, not xp[k] = x: no shape-check path to compile
        xp[k, i] = x[i]
    if model.Pp.shape[0] > 0:
        pack_sym(P, model.Pp[k])


@em.implements(em.update_into, JointModel, refcounted=False, forceinline=True)
def _update(model, k, x, P, ws):
    """The step's scalar measurements in turn (docs/joint.md, "Filter, smoother, iterations").

    With a linearisation point ``xlin`` the innovation is z - h(xlin_k) - H (x - xlin_k)
    (Gauss-Newton on the whole record), else z - h(x).  A measurement whose normalised innovation
    exceeds ``gate`` (0: off) has its variance inflated so that it equals ``gate`` (a Huber-type
    robust update).  Each update is the short form K = P H^T / S, P <- P - P H^T H P / S over the
    gradient's nonzero entries, O(n^2)
    (:func:`~flightrecon.estimation.updates.scalar_update_short`).
    """
    H, PH, hnz = ws[6], ws[7], ws[8]
    mstart, mtype, mz, mr, mw, mtau, mH, mrow, md = model.meas
    pnom, hnom, pst, Cst = model.geo
    Cen = model.dyn.Cen
    xlin = model.xlin
    gate = model.gate
    nu_out, s_out, infl = model.nu, model.S, model.infl
    clocks = model.cnorm.shape[0] > 0
    n = N_STATE  # a constant: the loops below unroll (as in the filter before the core)
    if clocks:  # the clock offsets' columns enter the step as predicted (0 at step 0)
        for c in range(model.cxf.shape[0]):
            for i in range(n):
                model.cxf[c, k, i] = model.cxp[c, k, i]
    for j in range(mstart[k], mstart[k + 1]):
        if mw[j] <= 0.0:
            continue
        t = mtype[j]
        if xlin.shape[0] > 0:
            hx = measure_into(H, j, k, xlin[k], mtype, mz, mtau, mH, mrow, md, Cen, pnom,
                              hnom, pst, Cst)
            g = (_position_rate(H, Cen, k, xlin[k]) + model.crate[j]
                 if clocks and model.ccol[j] >= 0 else 0.0)
            nu = mz[j] - hx
            if t == AZIMUTH or t == ELEVATION or t == HEADING or t == TRACK:
                nu = wrap_pi(nu)
            for i in range(n):
                if H[i] != 0.0:
                    nu -= H[i] * (x[i] - xlin[k, i])
        else:
            hx = measure_into(H, j, k, x, mtype, mz, mtau, mH, mrow, md, Cen, pnom, hnom, pst, Cst)
            g = (_position_rate(H, Cen, k, x) + model.crate[j]
                 if clocks and model.ccol[j] >= 0 else 0.0)
            nu = mz[j] - hx
            if t == AZIMUTH or t == ELEVATION or t == HEADING or t == TRACK:
                nu = wrap_pi(nu)
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
        if clocks:
            _clock_column_update(j, k, g, nu, S, H, hnz, nh, PH, model.cxf, model.ccol,
                                 model.cnorm, ws[12])
        # the short form P - PH PH^T / S (not the Joseph form, which it equals only at this
        # optimal gain, to rounding)
        scalar_update_short(x, P, PH, nu, S)


@em.implements(em.keep_filtered, JointModel, refcounted=False, forceinline=True)
def _keep_filtered(model, k, x, P):
    xf = model.xf
    for i in range(N_STATE):
        xf[k, i] = x[i]
    pack_sym(P, model.Pf[k])


@em.implements(em.smoothing_covariances, JointModel, forceinline=True)
def _smoothing_covariances(model, k, ws):
    """P_f[k] unpacked and P_p[k+1] (unpacked, or recomputed when the forward pass did not keep it);
    F_{k+1} row-compressed in ``ws`` for the cross-covariance that follows."""
    F, cols, vals, cnt, B = ws[0], ws[1], ws[2], ws[3], ws[4]
    Pbuf, Pfk = ws[9], ws[10]
    _transition_rows(F, cols, vals, cnt, k + 1, model.dyn)
    unpack_sym(model.Pf[k], Pfk)
    if model.Pp.shape[0] > 0:
        unpack_sym(model.Pp[k + 1], Pbuf)
    else:
        _predicted_cov(k + 1, model.Pf, cols, vals, cnt, B, model.dyn, Pbuf)
    return Pfk, Pbuf


@em.implements(em.cross_transposed_into, JointModel, refcounted=False, forceinline=True)
def _cross_transposed(model, k, CT, ws):
    sparse_left_product(ws[1], ws[2], ws[3], ws[10], CT)  # C^T = F_{k+1} P_f[k]


@em.implements(em.cross_times_into, JointModel, refcounted=False, forceinline=True)
def _cross_times(model, k, y, out, ws):
    """C y = P_f[k] (F_{k+1}^T y): the sparse product first, O(nnz + n^2)."""
    z, Pfk = ws[11], ws[10]
    sparse_rmatvec(ws[1], ws[2], ws[3], y, z)
    n = N_STATE
    # out = sum_b z[b] P_f[b, :] (P_f symmetric): each element the sum over b in order, as
    # sum_b P_f[a, b] z[b], along contiguous rows (vectorised)
    for a in range(n):
        out[a] = 0.0
    for b in range(n):
        zb = z[b]
        for a in range(n):
            out[a] += Pfk[b, a] * zb


@em.implements(em.rts_frame, JointModel, forceinline=True)
def _rts_frame(model, k):
    return EUCLIDEAN, 0.0, 0.0, 0.0


@em.implements(em.keep_smoothed, JointModel, refcounted=False, forceinline=True)
def _keep_smoothed(model, k, x, P, with_cov, ws):
    """The position-velocity block and the diagonal of P_s (covariance pass); the residuals at the
    smoothed state where the model has their buffers (with H P_s H^T in the covariance pass: an
    empty ``P`` in the mean-only one)."""
    if with_cov and model.Pblk.shape[0] > 0:
        for i in range(6):
            for j in range(6):
                model.Pblk[k, i, j] = P[i, j]
        for i in range(N_STATE):
            model.var[k, i] = P[i, i]
    if model.res.shape[0] > 0:
        _residuals_at(k, x, model.meas, model.geo, model.dyn.Cen, ws[6], model.res,
                      model.res_n, model.rate, P, model.hph)


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
    """1/2 sum_k e_k^T Q_k^-1 e_k over the steps, and the largest |e_k,i| of the states that carry
    no process noise (module docstring); returns (term, max_constant_change, failures)."""
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
        :func:`~flightrecon.methods.joint.solve.backward` gives them.
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
            rate[j] = (0.0 if t == TAS or t == HEADING or t == DOPPLER or t == TRACK
                       else _position_rate(H, Cen, k, X[k]))
            if mw[j] <= 0.0:
                continue
            data += robust_loss(r / np.sqrt(mr[j]), huber_c, reject_c, robust)
    return prior, process, data, const_change, res, rate, n_fail
