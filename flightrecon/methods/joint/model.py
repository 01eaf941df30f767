"""The joint smoother's model on the estimation core's loops (docs/joint.md, "Filter, smoother,
iterations"; docs/estimation.md, "The joint model").

:class:`JointModel` holds one pass's inputs (the :class:`~flightrecon.methods.joint.layout.
Dynamics`, :class:`~flightrecon.methods.joint.layout.Scalars` and
:class:`~flightrecon.methods.joint.layout.Geometry` layouts, the innovation gate and the
linearisation point ``xlin``) and the buffers its outputs go to; the functions below are the
model protocol (:mod:`flightrecon.estimation.model`) for it, compiled into the core's
:func:`~flightrecon.estimation.filtering.forward_pass` and
:func:`~flightrecon.estimation.smoothing.backward_pass`.  None of them loops over the time
steps.

Forward, at step k:

* prediction: x <- F_k x + the recorded increments (the control input), P <- F_k P F_k^T + Q_k,
  with F_k row-compressed (:func:`~flightrecon.estimation.predict.predict_sparse`, O(n nnz))
  and Q_k added on its nonzero entries (:func:`~flightrecon.methods.joint.dynamics.
  add_process_noise`);
* the predicted and filtered covariances kept as packed lower triangles
  (:func:`~flightrecon.estimation.linalg.pack_sym`); an empty ``Pp`` keeps no predicted
  covariance (the backward pass recomputes it, bit for bit the same);
* the step's scalar measurements one after the other, each with the short-form update
  (:func:`~flightrecon.estimation.updates.scalar_update_short`), linearised about ``xlin[k]``
  (an iterated extended Kalman smoother) or, with an empty ``xlin``, about the prediction (an
  extended Kalman filter), with a Huber-type innovation gate.

Backward, at step k: ``C^T = F_{k+1} P_f[k]`` (:func:`~flightrecon.estimation.predict.
sparse_left_product`), ``C y = P_f[k] (F_{k+1}^T y)`` in the mean-only pass, and at the smoothed
state the residuals of the step's measurements (with H P_s H^T in the covariance pass), the
position-velocity block of P_s and its diagonal.
"""

from __future__ import annotations

from typing import NamedTuple

import numba as nb
import numpy as np

from flightrecon.estimation.linalg import pack_sym, unpack_sym
from flightrecon.estimation.manifold import EUCLIDEAN
from flightrecon.estimation.model import (
    cross_times_into,
    cross_transposed_into,
    implements,
    keep_filtered,
    keep_predicted,
    keep_smoothed,
    predict_into,
    rts_frame,
    smoothing_covariances,
    update_into,
    with_mean_only_pass,
    workspace,
)
from flightrecon.estimation.predict import (
    predict_cov_sparse,
    predict_sparse,
    sparse_left_product,
    sparse_matvec,
    sparse_rmatvec,
    sparse_rows,
)
from flightrecon.estimation.updates import scalar_update_short
from flightrecon.methods.joint.dynamics import add_process_noise, transition_into, wrap_pi
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
    Dynamics,
    Geometry,
    Scalars,
)
from flightrecon.methods.joint.observation import measure_into

__all__ = ["N_CLOCK", "JointModel", "joint_model"]

N_CLOCK = 3
"""Clock offsets the forward pass can carry as filter columns (GNSS positions, radar, GNSS
velocities: :data:`~flightrecon.methods.joint.updates.CLOCK_SOURCES`)."""


@with_mean_only_pass
class JointModel(NamedTuple):
    """One pass of the joint smoother as a model of the estimation core (module docstring).

    Inputs: ``dyn``, ``meas``, ``geo`` (the layouts), ``gate`` (the normalised innovation
    beyond which a measurement's variance is inflated; 0: off), ``xlin`` (N, n) the
    linearisation point of the measurements ((0, n): the filter's own prediction).

    Filter buffers: ``xf``, ``xp`` (N, n), ``Pf``, ``Pp`` (N, n (n + 1) / 2) packed lower
    triangles (``Pp`` (0, ...): not kept); per measurement the innovation ``nu``, its variance
    ``S`` (before inflation) and the inflation factor ``infl`` ((0,) in a backward pass).

    Smoother buffers: per measurement the residuals ``res`` (z - h(x_s)), ``res_n`` (in units
    of sqrt(R)), the ``rate`` dh/dtau and ``hph`` (H P_s H^T, in the covariance pass only)
    ((0,): not computed); per step ``Pblk`` (N, 6, 6) the position-velocity block of P_s and
    ``var`` (N, n) its diagonal ((0, ...): the mean-only pass).

    Clock offsets (forward pass; (0,): not estimated): ``ccol`` (M,) the clock column of each
    measurement (0 GNSS, 1 radar, -1 none), ``crate`` (M,) the rate of the prediction with the
    measurement's time where its gradient does not give it (GNSS velocities: the nominal's
    acceleration; 0 elsewhere), ``cnorm`` (C, C + 1) the normal equations [A b] of the
    offsets' Gauss-Newton step accumulated over the pass (:func:`_clock_column_update`; (0, 0):
    not estimated), ``cxf``, ``cxp`` (C, N, n) the offsets' filter columns after and before
    each step's updates (C = 3: GNSS positions, radar, GNSS velocities).
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
    ``residuals`` (and H P_s H^T; NaN until computed) and the smoothed ``covariances``
    blocks.  ``clock`` (a forward pass; None: no clock offsets) the clock column of each
    measurement (-1 none) and its ``crate``: the pass then accumulates the offsets' normal
    equations in ``cnorm``."""
    xf, Pf, xp, Pp = bufs
    N, n = xf.shape
    M = len(meas.mtype)
    none = np.empty(0)
    m_res = M if residuals else 0
    # the clock columns up to the last one a measurement uses (a 10-hour flight's three
    # (N, n) columns before and after the update are 45 MB: the radar's, last, only with radar)
    nc = 0 if clock is None else int(max(np.max(clock[0], initial=-1) + 1, 1))
    return JointModel(
        dyn, meas, geo, float(gate),
        np.zeros((0, n)) if xlin is None else xlin,
        xf, Pf, xp, Pp,
        np.full(M, np.nan) if forward else none,
        np.full(M, np.nan) if forward else none,
        np.ones(M) if forward else none,
        np.full(m_res, np.nan), np.full(m_res, np.nan), np.full(m_res, np.nan),
        np.full(m_res, np.nan),
        np.empty((N if covariances else 0, 6, 6)), np.empty((N if covariances else 0, n)),
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
    """P_p[k] = F_k P_f[k-1] F_k^T + Q_k into ``out``, recomputed with the same operations as
    the forward prediction (``cols``/``vals``/``cnt``: F_k row-compressed), for a forward pass
    that did not keep it (its lower triangle mirrored, as the kept one)."""
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
    """dh/dtau of a measurement of the position with gradient ``H`` (for ``LINEAR``, its row
    of mH) at state ``x``: (dh/dp) C_en[k] v, the change of the predicted measurement with
    its time."""
    rd = 0.0
    for m in range(3):
        s = 0.0
        for i in range(3):
            s += H[IP + i] * Cen[k, i, m]
        rd += s * x[IV + m]
    return rd


@nb.njit(cache=True, nogil=True)
def _clock_column_update(j, k, g, nu, S, H, hnz, nh, PH, xg, ccol, cnorm, ng):
    """The clock offsets' columns of the augmented filter at scalar measurement j
    (docs/joint.md, "Filter, smoother, iterations", item 4).

    A measurement stamped t_m and used at t_m + c + dc predicts h + g dc, g = dh/dtau its
    rate at the linearisation point (of a position, :func:`_position_rate`, plus ``crate``).
    With the offsets' step dc (one per column: :data:`~flightrecon.methods.joint.updates.
    CLOCK_SOURCES`) as constant regression parameters of the
    pass's linearised model, the filtered state is x(dc) = x(0) - X_g dc and the innovations
    nu(dc) = nu - nu_g . dc, where the columns X_g (``xg[:, k]``, (C, n) at step k) are the
    same filter run on the data g_c = g [column of j is c] from zero, with no control input:
    nu_g,c = g_c - H X_g,c, X_g,c <- X_g,c + K nu_g,c (K = P H^T / S,
    the gain of this update) and X_g,c <- F_k X_g,c between the steps (the augmented Kalman
    filter: de Jong 1991, "The diffuse Kalman filter", Ann. Stat. 19, 1073-1083; Durbin &
    Koopman 2012, "Time series analysis by state space methods", 6.2.2).  The pass's MAP cost
    profiled over the track is then sum_j (nu_j - nu_g,j . dc)^2 / S_j + const, so the
    Gauss-Newton step of the offsets jointly with the track solves A dc = b with
    A = sum nu_g nu_g^T / S and b = sum nu_g nu / S; ``cnorm`` (C, C + 1) accumulates [A b],
    and A^-1 is the offsets' covariance.  ``ng`` (C,) scratch."""
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

@implements(workspace, JointModel, forceinline=True)
def _workspace(model):
    """Scratch of both passes: F_k dense and row-compressed, the products' buffers, a
    measurement's gradient and its nonzero indices, P_p[k+1] and P_f[k] unpacked."""
    n = N_STATE
    return (np.empty((n, n)), np.empty((n, n), dtype=np.int64), np.empty((n, n)),
            np.empty(n, dtype=np.int64), np.empty((n, n)), np.empty(n), np.empty(n),
            np.empty(n), np.empty(n, dtype=np.int64), np.empty((n, n)), np.empty((n, n)),
            np.empty(n), np.empty(N_CLOCK))


@implements(predict_into, JointModel, refcounted=False, forceinline=True)
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


@implements(keep_predicted, JointModel, refcounted=False, forceinline=True)
def _keep_predicted(model, k, x, P):
    xp = model.xp
    for i in range(N_STATE):  # element loop, not xp[k] = x: no shape-check path to compile
        xp[k, i] = x[i]
    if model.Pp.shape[0] > 0:
        pack_sym(P, model.Pp[k])


@implements(update_into, JointModel, refcounted=False, forceinline=True)
def _update(model, k, x, P, ws):
    """The step's scalar measurements in turn (docs/joint.md, "Filter, smoother, iterations").

    With a linearisation point ``xlin`` the innovation is z - h(xlin_k) - H (x - xlin_k)
    (Gauss-Newton on the whole record), else z - h(x).  A measurement whose normalised
    innovation exceeds ``gate`` (0: off) has its variance inflated so that it equals ``gate``
    (a Huber-type robust update).  Each update is the short form K = P H^T / S,
    P <- P - P H^T H P / S over the gradient's nonzero entries, O(n^2)
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
            hx = measure_into(H, j, k, x, mtype, mz, mtau, mH, mrow, md, Cen, pnom, hnom,
                              pst, Cst)
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


@implements(keep_filtered, JointModel, refcounted=False, forceinline=True)
def _keep_filtered(model, k, x, P):
    xf = model.xf
    for i in range(N_STATE):
        xf[k, i] = x[i]
    pack_sym(P, model.Pf[k])


@implements(smoothing_covariances, JointModel, forceinline=True)
def _smoothing_covariances(model, k, ws):
    """P_f[k] unpacked and P_p[k+1] (unpacked, or recomputed when the forward pass did not keep
    it); F_{k+1} row-compressed in ``ws`` for the cross-covariance that follows."""
    F, cols, vals, cnt, B = ws[0], ws[1], ws[2], ws[3], ws[4]
    Pbuf, Pfk = ws[9], ws[10]
    _transition_rows(F, cols, vals, cnt, k + 1, model.dyn)
    unpack_sym(model.Pf[k], Pfk)
    if model.Pp.shape[0] > 0:
        unpack_sym(model.Pp[k + 1], Pbuf)
    else:
        _predicted_cov(k + 1, model.Pf, cols, vals, cnt, B, model.dyn, Pbuf)
    return Pfk, Pbuf


@implements(cross_transposed_into, JointModel, refcounted=False, forceinline=True)
def _cross_transposed(model, k, CT, ws):
    sparse_left_product(ws[1], ws[2], ws[3], ws[10], CT)  # C^T = F_{k+1} P_f[k]


@implements(cross_times_into, JointModel, refcounted=False, forceinline=True)
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


@implements(rts_frame, JointModel, forceinline=True)
def _rts_frame(model, k):
    return EUCLIDEAN, 0.0, 0.0, 0.0


@implements(keep_smoothed, JointModel, refcounted=False, forceinline=True)
def _keep_smoothed(model, k, x, P, with_cov, ws):
    """The position-velocity block and the diagonal of P_s (covariance pass); the residuals at
    the smoothed state where the model has their buffers (with H P_s H^T in the covariance
    pass: an empty ``P`` in the mean-only one)."""
    if with_cov and model.Pblk.shape[0] > 0:
        for i in range(6):
            for j in range(6):
                model.Pblk[k, i, j] = P[i, j]
        for i in range(N_STATE):
            model.var[k, i] = P[i, i]
    if model.res.shape[0] > 0:
        _residuals_at(k, x, model.meas, model.geo, model.dyn.Cen, ws[6], model.res,
                      model.res_n, model.rate, P, model.hph)
