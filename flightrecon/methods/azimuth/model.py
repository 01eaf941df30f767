"""The azimuth channel's filter as a model of the estimation core (docs/azimuth.md).

:class:`AzimuthModel` supplies the prediction and the two measurement updates of one event to
the core's forward loop (:func:`flightrecon.estimation.filtering.forward_pass`); its transition
is linear (Singer or random-walk matrices), so its backward pass is the linear model's
(:func:`flightrecon.estimation.kalman.rts_smooth`, ``C^T = F_{k+1} P_f[k]``).
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from flightrecon.estimation.filtering import keep_dense_into
from flightrecon.estimation.model import (
    implements,
    keep_filtered,
    keep_predicted,
    predict_into,
    update_into,
    workspace,
)
from flightrecon.estimation.predict import predict_in_place
from flightrecon.estimation.updates import joseph_update

__all__ = ["AzimuthModel", "azimuth_model"]


@nb.njit(cache=True, nogil=True)
def _wrap(x):
    return np.pi - np.mod(np.pi - x, 2.0 * np.pi)


class AzimuthModel(NamedTuple):
    """The azimuth filter of state ``[eps, omega, a]`` on the event times.

    Inputs: ``F``, ``Q`` (N, 3, 3) the transitions and process noises (Singer, eqs. (1)-(4), or
    the aided model's random walk, eqs. (5)-(8)); ``eps_meas`` (N,) the radar azimuth (NaN: no
    plot) with variances ``eps_var``; ``a_ne`` (N, 2) the on-board horizontal acceleration (NaN
    rows: no on-board observation) with the covariances of its white (``Sa``) and slowly
    varying (``Sb``) errors; ``r``, ``rdot`` (N,) the tracked range and range rate with their
    covariance ``Pr`` (N, 2, 2); ``n_corr`` the inflation of the correlated error variances.

    Outputs (filled by the run): ``x_f``, ``P_f``, ``x_p``, ``P_p``; ``nu_eps``, ``s_eps`` (N,)
    the azimuth innovations (wrapped) and their variances, ``nu_z``, ``s_z``, ``r_z`` (N,) the
    transverse-acceleration innovations, their variances and the observation variance ``R_z``
    (NaN where no such measurement).
    """

    F: np.ndarray
    Q: np.ndarray
    eps_meas: np.ndarray
    eps_var: np.ndarray
    a_ne: np.ndarray
    Sa: np.ndarray
    Sb: np.ndarray
    r: np.ndarray
    rdot: np.ndarray
    Pr: np.ndarray
    n_corr: float
    x_f: np.ndarray
    P_f: np.ndarray
    x_p: np.ndarray
    P_p: np.ndarray
    nu_eps: np.ndarray
    s_eps: np.ndarray
    nu_z: np.ndarray
    s_z: np.ndarray
    r_z: np.ndarray


def azimuth_model(F, Q, eps_meas, eps_var, a_ne, Sa, Sb, r, rdot, Pr,
                  n_corr: float) -> AzimuthModel:
    """An :class:`AzimuthModel` on these inputs (contiguous float arrays) with its output
    buffers (NaN innovations)."""
    N = F.shape[0]
    c = np.ascontiguousarray
    return AzimuthModel(c(F), c(Q), c(eps_meas), c(eps_var), c(a_ne), c(Sa), c(Sb), c(r),
                        c(rdot), c(Pr), float(n_corr), np.empty((N, 3)), np.empty((N, 3, 3)),
                        np.empty((N, 3)), np.empty((N, 3, 3)), np.full(N, np.nan),
                        np.full(N, np.nan), np.full(N, np.nan), np.full(N, np.nan),
                        np.full(N, np.nan))


@implements(workspace, AzimuthModel)
def _workspace(model):
    # the radar row H = [1, 0, 0], and the 1x1 noise and innovation of a scalar update
    return np.array([[1.0, 0.0, 0.0]]), np.empty((1, 1)), np.empty(1)


@implements(predict_into, AzimuthModel)
def _predict(model, k, x, P, ws):
    """``x <- F_k x``, ``P <- F_k P F_k^T + Q_k`` symmetrised (Singer or random-walk matrices;
    :func:`~flightrecon.estimation.predict.predict`: ``F x`` through BLAS, whose summation
    order an element loop does not reproduce for n = 3, hence counted)."""
    predict_in_place(x, P, model.F[k], model.Q[k])


@implements(keep_predicted, AzimuthModel, refcounted=False)
def _keep_predicted(model, k, x, P):
    keep_dense_into(model.x_p, model.P_p, k, x, P)


@implements(update_into, AzimuthModel)
def _update(model, k, x, P, ws):
    """Radar update with the wrapped azimuth innovation, then the on-board update linearised
    at the current estimate (docs/azimuth.md "Observations"): ``H = [-dz/deps, 2 r_dot, r]``,
    ``R_z = u Sa u^T + n_corr (u Sb u^T + [a, 2 omega] Pr [a, 2 omega]^T)``, ``u = [-sin eps,
    cos eps]``; each a scalar Joseph update."""
    h_eps, r1, nu1 = ws[0], ws[1], ws[2]
    if not np.isnan(model.eps_meas[k]):
        nu1[0] = _wrap(model.eps_meas[k] - x[0])
        r1[0, 0] = model.eps_var[k]
        xu, Pu, S1, _ = joseph_update(x, P, nu1, h_eps, r1)
        x[:] = xu
        P[:, :] = Pu
        model.nu_eps[k] = nu1[0]
        model.s_eps[k] = S1[0, 0]
    a_ne = model.a_ne
    if not np.isnan(a_ne[k, 0]):
        Sa = model.Sa
        Sb = model.Sb
        Pr = model.Pr
        rdot = model.rdot[k]
        rk = model.r[k]
        e, om, a = x[0], x[1], x[2]
        s, c = np.sin(e), np.cos(e)
        zacc = a_ne[k, 1] * c - a_ne[k, 0] * s
        dz = -(a_ne[k, 1] * s + a_ne[k, 0] * c)
        h = np.empty((1, 3))
        h[0, 0], h[0, 1], h[0, 2] = -dz, 2.0 * rdot, rk
        u0, u1 = -s, c
        rs = (u0 * u0 * Sa[k, 0, 0] + 2.0 * u0 * u1 * Sa[k, 0, 1] + u1 * u1 * Sa[k, 1, 1])
        rb = (u0 * u0 * Sb[k, 0, 0] + 2.0 * u0 * u1 * Sb[k, 0, 1] + u1 * u1 * Sb[k, 1, 1])
        g0_, g1_ = a, 2.0 * om  # dz_model / d(r, r_dot)
        rr = g0_ * g0_ * Pr[k, 0, 0] + 2.0 * g0_ * g1_ * Pr[k, 0, 1] + g1_ * g1_ * Pr[k, 1, 1]
        R = rs + model.n_corr * (rb + rr)
        nu1[0] = zacc - 2.0 * rdot * om - rk * a
        r1[0, 0] = R
        xu, Pu, S1, _ = joseph_update(x, P, nu1, h, r1)
        x[:] = xu
        P[:, :] = Pu
        model.nu_z[k] = nu1[0]
        model.s_z[k] = S1[0, 0]
        model.r_z[k] = R


@implements(keep_filtered, AzimuthModel, refcounted=False)
def _keep_filtered(model, k, x, P):
    keep_dense_into(model.x_f, model.P_f, k, x, P)
