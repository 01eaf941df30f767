"""Compiled forward filter and RTS backward passes of the joint smoother.

Built on the estimation core: the sparse prediction (:func:`~flightrecon.estimation.predict.
predict_sparse`), the scalar short-form update (:func:`~flightrecon.estimation.updates.
scalar_update_short`) and the RTS step (:func:`~flightrecon.estimation.rts.rts_step`,
:func:`~flightrecon.estimation.rts.rts_mean_solve`), each fed with the row-compressed transition
(docs/estimation.md).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flightrecon.estimation.linalg import pack_sym, packed_size, unpack_sym
from flightrecon.estimation.manifold import EUCLIDEAN, state_plus_into
from flightrecon.estimation.predict import (
    predict_cov_sparse,
    predict_sparse,
    sparse_left_product,
    sparse_rmatvec,
    sparse_rows,
)
from flightrecon.estimation.rts import rts_mean_solve, rts_step, rts_step_work
from flightrecon.estimation.updates import scalar_update_short
from flightrecon.methods.joint.dynamics import (
    add_process_noise,
    transition_into,
    wrap_pi,
)
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
)
from flightrecon.methods.joint.observation import measure_into


def filter_buffers(N: int, store_predicted: bool = True) -> tuple[np.ndarray, ...]:
    """Outputs of :func:`forward` for N steps: ``xf`` (N, n), ``Pf`` (N, n (n + 1) / 2),
    ``xp``, ``Pp`` (the covariances as packed lower triangles, :func:`~flightrecon.estimation.
    linalg.pack_sym`: half the memory, 190 MB less on a 10-hour flight at 1 Hz; an empty ``Pp``
    without ``store_predicted``: recomputed backward, bit-identical, 0.2-0.3 s more per pass on
    that flight)."""
    n = N_STATE
    L = packed_size(n)
    return (np.empty((N, n)), np.empty((N, L)), np.empty((N, n)),
            np.empty((N if store_predicted else 0, L)))


@nb.njit(cache=True, nogil=True)
def forward(xf, Pf, xp, Pp, x0, P0, dyn, meas, geo, gate, xlin):
    """Forward extended Kalman filter with sequential scalar updates.

    ``dyn``, ``meas``, ``geo``: the :class:`~flightrecon.methods.joint.layout.Dynamics`,
    :class:`~flightrecon.methods.joint.layout.Scalars` and
    :class:`~flightrecon.methods.joint.layout.Geometry` layouts.

    With ``xlin`` (N, n) the measurements are linearised about it (the smoothed states of the
    last pass: h(x) ~ h(xlin_k) + H(xlin_k)(x - xlin_k), which makes the iterations Gauss-Newton
    on the whole record, an iterated extended Kalman smoother); with an empty ``xlin`` (0, n)
    about the filter's own prediction (an extended Kalman filter: the first pass).

    ``mstart`` (N+1,) indexes the measurements of each step (sorted by step).  A measurement
    whose normalised innovation exceeds ``gate`` (0: off) has its variance inflated so that it
    equals ``gate`` (a Huber-type robust update: a jump is followed only slowly, never trusted).
    Fills the filtered and predicted states/covariances ``xf``, ``Pf``, ``xp``, ``Pp``
    (:func:`filter_buffers`: covariances as packed lower triangles; given, so that the
    Gauss-Newton iterations reuse them; an empty ``Pp`` is not filled: the backward passes then
    recompute each predicted covariance from ``Pf``, bit for bit the same, which saves its
    memory) and returns, per measurement, the innovation, its variance (before inflation) and
    the inflation factor.

    Allocation-free per step: the prediction uses the row-compressed F_k (P <- F P F^T + Q in
    O(n nnz)), the update the nonzero entries of each measurement's gradient.
    """
    dt, Cen, Cnb, Csf, Jatt, acc, dP, dV, dz, qv_extra, q, ga = dyn
    mstart, mtype, mz, mr, mw, mtau, mH, mrow, md = meas
    pnom, hnom, pst, Cst = geo
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
            _transition_rows(F, cols, vals, cnt, k, dt, Cen, Cnb, Csf, Jatt, acc, q[4], dz, ga)
            predict_sparse(x, P, cols, vals, cnt, xn, B)  # x <- F x, P <- F P F^T
            for i in range(3):  # + the control input (the recorded increments) and Q_k
                for m in range(3):
                    x[IP + i] += Cen[k - 1, i, m] * dP[k, m]
                x[IV + i] += dV[k, i]
            add_process_noise(P, k, dt, Cen, dz, qv_extra, q, ga)
        for i in range(n):  # element loop, not xp[k] = x: no shape-check path to compile
            xp[k, i] = x[i]
        if Pp.shape[0] > 0:
            pack_sym(P, Pp[k])
        for j in range(mstart[k], mstart[k + 1]):
            if mw[j] <= 0.0:
                continue
            t = mtype[j]
            if xlin.shape[0] > 0:
                hx = measure_into(H, j, k, xlin[k], mtype, mz, mtau, mH, mrow, md, Cen, pnom,
                                  hnom, pst, Cst)
                nu = mz[j] - hx
                if t == AZIMUTH or t == ELEVATION or t == HEADING or t == TRACK:
                    nu = wrap_pi(nu)
                for i in range(n):
                    if H[i] != 0.0:
                        nu -= H[i] * (x[i] - xlin[k, i])
            else:
                hx = measure_into(H, j, k, x, mtype, mz, mtau, mH, mrow, md, Cen, pnom, hnom,
                                  pst, Cst)
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
            # scalar update with K = PH / S, in place, O(n^2): the short form P - PH PH^T / S
            # (not the Joseph form, which it equals only at this optimal gain, to rounding)
            scalar_update_short(x, P, PH, nu, S)
        for i in range(n):
            xf[k, i] = x[i]
        pack_sym(P, Pf[k])
    return nu_out, s_out, infl


@nb.njit(cache=True, nogil=True)
def _transition_rows(F, cols, vals, cnt, k, dt, Cen, Cnb, Csf, Jatt, acc, tau_ba, dz, ga):
    """F_k into ``F`` and its row-compressed copy (:func:`transition_into`,
    :func:`~flightrecon.estimation.predict.sparse_rows`)."""
    transition_into(F, k, dt, Cen, Cnb, Csf, Jatt, acc, tau_ba, dz, ga)
    sparse_rows(F, cols, vals, cnt)


@nb.njit(cache=True, nogil=True)
def _predicted_at(k, Pf, Pp, cols, vals, cnt, B, dt, Cen, dz, qv_extra, q, ga, buf):
    """P_p[k] into ``buf``: the stored one if the forward pass kept them, else recomputed."""
    if Pp.shape[0] > 0:
        unpack_sym(Pp[k], buf)
        return buf
    _predicted_cov(k, Pf, Pp, cols, vals, cnt, B, dt, Cen, dz, qv_extra, q, ga, buf)
    return buf


@nb.njit(cache=True, nogil=True)
def _predicted_cov(k, Pf, Pp, cols, vals, cnt, B, dt, Cen, dz, qv_extra, q, ga, out):
    """P_p[k] = F_k P_f[k-1] F_k^T + Q_k into ``out``, recomputed with the same operations as
    :func:`forward` (``cols``/``vals``/``cnt``: F_k row-compressed), for a forward pass that
    did not store it (its lower triangle, as the stored one)."""
    n = out.shape[0]
    unpack_sym(Pf[k - 1], out)
    predict_cov_sparse(out, cols, vals, cnt, B)
    add_process_noise(out, k, dt, Cen, dz, qv_extra, q, ga)
    for i in range(n):
        for j in range(i):
            out[j, i] = out[i, j]


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
            e = wrap_pi(e)
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
def backward_mean(xf, Pf, xp, Pp, dyn, meas, geo):
    """RTS backward pass for the smoothed states only (no covariances), and the residuals.

    x_s[k] = x_f[k] + P_f[k] F_{k+1}^T P_p[k+1]^{-1} (x_s[k+1] - x_p[k+1]): the same smoothed
    mean as :func:`backward` (Rauch, Tung & Striebel 1965) at O(n^3 / 6) per step (one Cholesky
    solve with a vector) instead of O(n^3) products; used in the Gauss-Newton iterations, which
    need the trajectory and the residuals but not the smoothed covariances.

    Returns smoothed states, normalised residuals, raw residuals and rates (as :func:`backward`)
    and the number of steps whose predicted covariance failed its Cholesky factorisation (not
    positive definite to rounding: the gain then comes from a general solve, which raises
    LinAlgError only if the matrix is singular; the caller reports the count).
    """
    dt, Cen, Cnb, Csf, Jatt, acc, dP, dV, dz, qv_extra, q, ga = dyn
    mstart, mtype, mz, mr, mw, mtau, mH, mrow, md = meas
    pnom, hnom, pst, Cst = geo
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
    dx = np.empty(n)
    H = np.empty(n)
    B = np.empty((n, n))
    Pbuf = np.empty((n, n))
    Pfk = np.empty((n, n))
    no_P = np.empty((0, 0))
    no_hph = np.empty(0)
    n_fallback = 0
    for k in range(N - 1, -1, -1):
        if k < N - 1:
            _transition_rows(F, cols, vals, cnt, k + 1, dt, Cen, Cnb, Csf, Jatt, acc, q[4], dz,
                             ga)
            Pk1 = _predicted_at(k + 1, Pf, Pp, cols, vals, cnt, B, dt, Cen, dz, qv_extra, q,
                                ga, Pbuf)
            # y = P_p^-1 (x_s[k+1] - x_p[k+1]), then x_s[k] = x_f[k] + P_f[k] (F^T y)
            if not rts_mean_solve(EUCLIDEAN, xp[k + 1], Pk1, xs[k + 1], 0.0, 0.0, L, d, y):
                n_fallback += 1
            sparse_rmatvec(cols, vals, cnt, y, z)
            unpack_sym(Pf[k], Pfk)
            for a in range(n):
                v = 0.0
                for b in range(n):
                    v += Pfk[a, b] * z[b]
                dx[a] = v
            state_plus_into(EUCLIDEAN, xf[k], dx, 0.0, xs[k])
        _residuals_at(k, xs[k], mstart, mtype, mz, mr, mtau, mH, mrow, md, Cen, pnom, hnom, pst,
                      Cst, H, res, res_n, rate, no_P, no_hph)
    return xs, res_n, res, rate, n_fallback


@nb.njit(cache=True, nogil=True)
def backward(xf, Pf, xp, Pp, dyn, meas, geo, residuals):
    """RTS backward pass with covariances; also the smoothed residuals (see
    :func:`backward_mean`, which gives the same states without the covariances).

    Returns smoothed states, the smoothed position-velocity covariance block (N, 6, 6), the
    smoothed state variances (N, n), normalised residuals, raw residuals, rates and, per
    measurement, H P_s H^T (the smoothed variance of the predicted measurement), and the number
    of Cholesky failures (as :func:`backward_mean`).  With
    ``residuals`` False the residual outputs stay NaN (the covariances do not need them: this
    pass can then run beside :func:`backward_mean` on another thread).
    """
    dt, Cen, Cnb, Csf, Jatt, acc, dP, dV, dz, qv_extra, q, ga = dyn
    mstart, mtype, mz, mr, mw, mtau, mH, mrow, md = meas
    pnom, hnom, pst, Cst = geo
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
    CT = np.empty((n, n))
    B = np.empty((n, n))
    Pbuf = np.empty((n, n))
    Pfk = np.empty((n, n))
    work = rts_step_work(n)
    H = np.empty(n)
    Ps = np.empty((n, n))
    unpack_sym(Pf[N - 1], Ps)
    n_fallback = 0
    for k in range(N - 1, -1, -1):
        if k < N - 1:
            _transition_rows(F, cols, vals, cnt, k + 1, dt, Cen, Cnb, Csf, Jatt, acc, q[4], dz,
                             ga)
            unpack_sym(Pf[k], Pfk)
            sparse_left_product(cols, vals, cnt, Pfk, CT)  # C^T = F P_f[k]
            Pk1 = _predicted_at(k + 1, Pf, Pp, cols, vals, cnt, B, dt, Cen, dz, qv_extra, q,
                                ga, Pbuf)
            # the core's step, in place on Ps (P_s[k+1] -> P_s[k])
            if not rts_step(EUCLIDEAN, (xf[k], Pfk), (xp[k + 1], Pk1), (xs[k + 1], Ps), CT,
                            (0.0, 0.0), 0.0, (xs[k], Ps), work):
                n_fallback += 1
        for i in range(6):
            for j in range(6):
                Pblk[k, i, j] = Ps[i, j]
        for i in range(n):
            var[k, i] = Ps[i, i]
        if residuals:
            _residuals_at(k, xs[k], mstart, mtype, mz, mr, mtau, mH, mrow, md, Cen, pnom, hnom,
                          pst, Cst, H, res, res_n, rate, Ps, hph)
    return xs, Pblk, var, res_n, res, rate, hph, n_fallback
