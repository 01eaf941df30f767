"""Compiled state transition and process noise of the joint smoother (state layout in
:mod:`flightrecon.methods.joint.layout`).

The transition is the identity plus a few blocks; the passes predict with it row-compressed
through the estimation core (:func:`flightrecon.estimation.predict.predict_sparse`) and add the
process noise here, touching only its nonzero entries (:func:`add_process_noise`: the
constant-velocity and Gauss-Markov blocks from :mod:`flightrecon.estimation.discretise`).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flightrecon.estimation.discretise import gauss_markov_step, white_acceleration_q
from flightrecon.methods.joint.layout import (
    G0,
    IATT,
    IBA,
    IBH,
    IG,
    IGU,
    IKS,
    IP,
    IPSI,
    IV,
    IW,
    N_STATE,
)


@nb.njit(cache=True, nogil=True, inline="always")
def wrap_pi(a):
    return (a + np.pi) % (2.0 * np.pi) - np.pi


@nb.njit(cache=True, nogil=True)
def transition_into(F, k, dt, Cen, Cnb, Csf, Jatt, acc, tau_ba, dz, ga):
    """Fill ``F`` (n, n) with the transition matrix F_k from step k-1 to step k (k >= 1).

    ``Csf[k]`` is the step mean of C_nb diag(f_body) (the Jacobian of the acceleration in the
    accelerometer scale errors), ``Jatt[k]`` (3, 2) that of dC/dphi f and dC/dtheta f (roll and
    pitch biases), ``dz[k]`` the nominal's height change over the step (the wind moves along
    its gradient with height), ``ga[k]`` the gust's decay over the step.  Only the position,
    velocity, wind, accelerometer-bias and gust rows differ from the identity (see the module
    docstring of :mod:`~flightrecon.methods.joint.layout`).
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
def transition(k, dt, Cen, Cnb, Csf, Jatt, acc, tau_ba, dz, ga):
    """Transition matrix F_k from step k-1 to step k (k >= 1); see :func:`transition_into`."""
    F = np.empty((N_STATE, N_STATE))
    transition_into(F, k, dt, Cen, Cnb, Csf, Jatt, acc, tau_ba, dz, ga)
    return F


@nb.njit(cache=True, nogil=True)
def add_process_noise(P, k, dt, Cen, dz, qv_extra, q, ga):
    """P += Q_k in place, touching only the nonzero entries of Q_k. q = [q_acc, q_wind_t,
    q_wind_h, var_ba, tau_ba, q_psi, q_bh, q_grad, var_gust, dq_n, dq_e, dq_d] (see
    JointNoise and :func:`flightrecon.methods.joint.nominal.q_vector`); ``|dz[k]|`` is
    the height change over the step (wind varies with altitude), ``qv_extra[k]`` extra
    acceleration PSD where the load factors are missing, ``ga[k]`` the gust's decay over the
    step (exact discretisation of the first-order Gauss-Markov gust: var_gust (1 - ga^2)).

    Position-velocity block: white acceleration along each NED axis a of PSD
    q_a = q_acc + qv_extra[k] + dq_a (dq_a the sampling part of a low-rate load record,
    docs/joint.md, "1 Hz records"), position in ECEF through C = C_en (NED -> ECEF) at step
    k - 1, exact for a constant C over the step (Bar-Shalom et al. 2001, eq. 6.2.2-12, axis by
    axis):

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
