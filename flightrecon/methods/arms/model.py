"""The ADS/ARMS track filter as a model of the estimation core (:class:`ArmsTrackModel`): its
prediction by the exact transitions (:mod:`flightrecon.methods.arms.transition`) and its update
by the radar plot's rows (:mod:`flightrecon.methods.arms.measurement`) and the air data's, run
by :func:`flightrecon.estimation.filtering.forward_pass`."""

from __future__ import annotations

from typing import NamedTuple

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
from flightrecon.estimation.predict import add_noise_symmetrised_into, predict_cov_into
from flightrecon.estimation.updates import joseph_update
from flightrecon.methods.arms.measurement import radar_rows_into


class ArmsTrackModel(NamedTuple):
    """The CV (n = 4, ``[x, Vx, y, Vy]``) or joint (n = 6, ``[x, Vx, y, Vy, dVx, dVy]``) track
    filter as a model of the estimation core (:mod:`flightrecon.estimation.model`), run by
    :func:`flightrecon.estimation.filtering.forward_pass`.

    Inputs: ``F``, ``Q`` (N, n, n) the exact transitions and process noises
    (:func:`cv_transition` / :func:`joint_transition`); ``radar`` (N, 2) ``[rho*, theta*]``
    (NaN: no plot at that step); ``radar_sd`` (N, 2) ``[sigma_rho, sigma_theta]``; ``air``
    (N, 2) ``V* = [V*x, V*y]`` (NaN: none; used only when n = 6) with noise ``Rv`` (2, 2);
    ``lin`` the radar linearisation (:func:`linearisation_code`).

    Outputs (filled by the run): ``x_f``, ``P_f`` the filtered, ``x_p``, ``P_p`` the predicted
    estimates; ``nu`` (N, 4) the innovations (columns 0-1 the radar's: range/azimuth for the
    EKF, x/y for the converted form; 2-3 the air data's; NaN where none) and ``S`` (N, 4, 4)
    their covariances; ``nis`` and ``n_meas`` per step; ``radar_used``, ``air_used`` (N,) the
    steps whose plot / air-data sample was used.

    The transition is linear, so its backward pass is the linear model's
    (:func:`flightrecon.estimation.kalman.rts_smooth`: ``C^T = F_{k+1} P_f[k]``).
    """

    F: np.ndarray
    Q: np.ndarray
    radar: np.ndarray
    radar_sd: np.ndarray
    air: np.ndarray
    Rv: np.ndarray
    lin: int
    x_f: np.ndarray
    P_f: np.ndarray
    x_p: np.ndarray
    P_p: np.ndarray
    nu: np.ndarray
    S: np.ndarray
    nis: np.ndarray
    n_meas: np.ndarray
    radar_used: np.ndarray
    air_used: np.ndarray


def arms_track_model(F: np.ndarray, Q: np.ndarray, radar: np.ndarray, radar_sd: np.ndarray,
                     air: np.ndarray, Rv: np.ndarray, lin: int) -> ArmsTrackModel:
    """An :class:`ArmsTrackModel` on these inputs with its output buffers (NaN innovations,
    no measurement used)."""
    N, n = F.shape[0], F.shape[1]
    c = np.ascontiguousarray
    return ArmsTrackModel(c(F), c(Q), c(radar), c(radar_sd), c(air), c(Rv), int(lin),
                          np.empty((N, n)), np.empty((N, n, n)), np.empty((N, n)),
                          np.empty((N, n, n)), np.full((N, 4), np.nan),
                          np.full((N, 4, 4), np.nan), np.full(N, np.nan),
                          np.zeros(N, dtype=np.int64), np.zeros(N, dtype=np.bool_),
                          np.zeros(N, dtype=np.bool_))


@implements(workspace, ArmsTrackModel)
def _workspace(model):
    n = model.F.shape[1]
    # the step's stacked innovation, Jacobian, noise and innovation slots (radar 0-1, air 2-3),
    # then the prediction's buffers (x^-, F P F^T, F P)
    return (np.zeros(4), np.zeros((4, n)), np.zeros((4, 4)), np.empty(4, dtype=np.int64),
            np.empty(n), np.empty((n, n)), np.empty((n, n)))


@implements(predict_into, ArmsTrackModel, refcounted=False)
def _predict(model, k, x, P, ws):
    """``x <- F_k x``, ``P <- F_k P F_k^T + Q_k`` symmetrised (exact CV / Gauss-Markov
    discretisation): :func:`~flightrecon.estimation.predict.predict`'s operations in the
    workspace's buffers (no allocation)."""
    xn, FPFt, T = ws[4], ws[5], ws[6]
    F = model.F[k]
    Q = model.Q[k]
    n = x.shape[0]
    for i in range(n):
        acc = 0.0
        for j in range(n):
            acc += F[i, j] * x[j]
        xn[i] = acc
    predict_cov_into(P, F, FPFt, T)
    add_noise_symmetrised_into(FPFt, Q, P)
    for i in range(n):
        x[i] = xn[i]


@implements(keep_predicted, ArmsTrackModel, refcounted=False)
def _keep_predicted(model, k, x, P):
    keep_dense_into(model.x_p, model.P_p, k, x, P)


@implements(update_into, ArmsTrackModel)
def _update(model, k, x, P, ws):
    """The step's plot and air-data sample in one block Joseph update (docs/arms.md).

    Radar: :func:`radar_rows_into` (EKF or converted, ``model.lin``).  Air data (n = 6):
    ``V* = [Vx + dVx, Vy + dVy] + e``, ``e ~ N(0, Rv)``, rows ``H = [0 1 0 0 1 0; 0 0 0 1 0 1]``.
    Innovations are kept in slots 0-1 (radar) and 2-3 (air data) of ``model.nu`` / ``model.S``.
    """
    nu, Hk, Rk, slot = ws[0], ws[1], ws[2], ws[3]
    n = x.shape[0]
    radar = model.radar
    air = model.air
    nu[:] = 0.0
    Hk[:, :] = 0.0
    Rk[:, :] = 0.0
    c = 0
    if not (np.isnan(radar[k, 0]) or np.isnan(radar[k, 1])):
        radar_sd = model.radar_sd
        if radar_rows_into(model.lin, radar[k, 0], radar[k, 1], radar_sd[k, 0] ** 2,
                           radar_sd[k, 1] ** 2, x, nu, Hk, Rk):
            slot[0] = 0
            slot[1] = 1
            c = 2
            model.radar_used[k] = True
    if n == 6 and not (np.isnan(air[k, 0]) or np.isnan(air[k, 1])):
        nu[c] = air[k, 0] - (x[1] + x[4])
        nu[c + 1] = air[k, 1] - (x[3] + x[5])
        Hk[c, 1] = 1.0
        Hk[c, 4] = 1.0
        Hk[c + 1, 3] = 1.0
        Hk[c + 1, 5] = 1.0
        Rv = model.Rv
        for a in range(2):
            for b in range(2):
                Rk[c + a, c + b] = Rv[a, b]
        slot[c] = 2
        slot[c + 1] = 3
        c += 2
        model.air_used[k] = True
    if c > 0:
        v = nu[:c].copy()
        xu, Pu, S, model.nis[k] = joseph_update(x, P, v, Hk[:c].copy(), Rk[:c, :c].copy())
        x[:] = xu
        P[:, :] = Pu
        model.n_meas[k] = c
        nu_k = model.nu[k]
        S_k = model.S[k]
        for a in range(c):
            nu_k[slot[a]] = v[a]
            for b in range(c):
                S_k[slot[a], slot[b]] = S[a, b]


@implements(keep_filtered, ArmsTrackModel, refcounted=False)
def _keep_filtered(model, k, x, P):
    keep_dense_into(model.x_f, model.P_f, k, x, P)
