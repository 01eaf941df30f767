"""SNS forward filter (compiled kernel and its wrapper) and RTS smoother."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numba as nb
import numpy as np

from flightrecon.estimation.linalg import mdmt_acc_into, mmt_into, sym_into
from flightrecon.estimation.manifold import LATLON, boxminus, boxplus
from flightrecon.estimation.predict import predict_cov_into
from flightrecon.estimation.rts import rts_step, rts_step_work
from flightrecon.estimation.updates import (
    correlated_noise_predict_into,
    gain_into,
    joseph_cov_into,
    normalised_innovation,
    state_correction_into,
)
from flightrecon.methods.sns.model import (
    FORM_CONSISTENT,
    FORM_SEED,
    MODEL_AIRSPEED,
    MODEL_DOPPLER,
    N_EPS1,
    N_STATE,
    SnsNoise,
    StepInputs,
    _observation_rows_into,
    _step_matrices_into,
    fill_single_sample,
    per_fix_sd,
)


@dataclass(frozen=True)
class SnsRun:
    """A forward run of the SNS filter (time-major; position in lat/lon radians).

    Attributes
    ----------
    x_pred, x : (N, 5) predicted / filtered states ``[lat_rad, lon_rad, c1, c2, c3]``
    P_pred, P : (N, 5, 5) covariances in the local-level frame (north/east metres first)
    cross : (N, 5, 5) ``Cov(x_k, x_{k+1} | Y_0..k)`` (smoother numerator; row ``N-1`` zero)
    nis : (N,) normalised innovation squared (NaN without fixes), ``rank`` its degrees of freedom
    h : (N,) heights used for the radii
    model, form : as passed
    """

    x_pred: np.ndarray
    x: np.ndarray
    P_pred: np.ndarray
    P: np.ndarray
    cross: np.ndarray
    nis: np.ndarray
    rank: np.ndarray
    h: np.ndarray
    model: int
    form: int


@dataclass(frozen=True)
class SnsSmoothed:
    """Smoothed states ``x`` (N, 5) (lat/lon radians first) and covariances ``P`` (N, 5, 5).

    ``cholesky_fallbacks``: steps whose predicted covariance failed its Cholesky factorisation
    (not positive definite to rounding), where the gain came from a general solve; reported by
    the adapter, never silent.
    """

    x: np.ndarray
    P: np.ndarray
    cholesky_fallbacks: int = 0


class KernelSteps(NamedTuple):
    """The filter steps' inputs across the compiled boundary (see :class:`StepInputs`)."""

    t: np.ndarray        # (N,) step times [s]
    hgt: np.ndarray      # (N,) heights [m]
    A: np.ndarray        # (N, 2) integrated measured velocity over each step
    U: np.ndarray        # (N, 2) its unit-vector integral
    W: np.ndarray        # (N, 2) integrated wind reading
    star: np.ndarray     # (N, 3, 2) the readings of the sample that straddles a step end
    dt_star: np.ndarray  # (N,) its hold
    Qb: np.ndarray       # (N, 7) noise integrals of the step (whole samples)
    Qa: np.ndarray       # (N, 7) and of the straddling part


class KernelFixes(NamedTuple):
    """The SNS fixes, grouped per step (``start``/``end`` index the fixes of each step)."""

    start: np.ndarray    # (N,)
    end: np.ndarray      # (N,)
    lat: np.ndarray      # (F,) [rad]
    lon: np.ndarray      # (F,) [rad]
    v: np.ndarray        # (F, 2) velocity north/east [m/s]
    tau: np.ndarray      # (F,) fix time minus step time [s]
    PA: np.ndarray       # (F, 2) reading integrals from the step to the fix
    PU: np.ndarray       # (F, 2)
    PW: np.ndarray       # (F, 2)
    a: np.ndarray        # (F, 2) readings at the fix
    u: np.ndarray        # (F, 2)
    w: np.ndarray        # (F, 2)
    tau_in: np.ndarray   # (F,) fix time minus its recorder sample's time [s]


class KernelNoise(NamedTuple):
    """Noise of the filter (see :class:`SnsNoise`)."""

    sig: np.ndarray      # (4,) sensor noise per sample
    q: np.ndarray        # random-walk densities of the corrections
    pos_sd: np.ndarray   # (F,) per-fix SNS position sd [m]
    vel_sd: np.ndarray   # (F,) per-fix SNS velocity sd [m/s]
    rcond: float         # pseudo-inverse tolerance


@nb.njit(cache=True, nogil=True)
def _filter_kernel(model, form, x0, P0, steps, fixes, noise):
    t, hgt, A, U, W, star, dt_star, Qb, Qa = steps
    fs, fe, flat, flon, fv, ftau, fPA, fPU, fPW, fa, fu, fw, ftau_in = fixes
    sig, q, pos_sd, vel_sd, rcond = noise
    # All small-matrix algebra runs in preallocated buffers with loop products (mm_into, mmt_into):
    # the same operations as the matrix expressions in the module docstring, without the
    # per-step heap allocations and BLAS calls that dominated the run time.
    N = t.shape[0]
    n = N_STATE
    ne = N_EPS1
    xp = np.empty((N, n))
    xs = np.empty((N, n))
    Pp = np.empty((N, n, n))
    Ps = np.empty((N, n, n))
    cross = np.zeros((N, n, n))
    nis = np.full(N, np.nan)
    rank = np.zeros(N, dtype=np.int64)
    mmax = 1
    for k in range(N):
        m = 0
        for i in range(fs[k], fe[k]):
            m += 2
            for j in range(2):
                if not np.isnan(fv[i, j]):
                    m += 1
        mmax = max(mmax, m)
    # buffers
    Hb = np.zeros((mmax, n))
    Gb = np.zeros((mmax, ne))
    Rd = np.zeros(mmax)
    nub = np.zeros(mmax)
    Rtb = np.zeros((mmax, mmax))
    Sb = np.zeros((mmax, mmax))
    Spb = np.zeros((mmax, mmax))
    Ab = np.zeros((mmax, mmax))
    Vb = np.zeros((mmax, mmax))
    PHtb = np.zeros((n, mmax))
    Kb = np.zeros((n, mmax))
    T5m = np.zeros((n, mmax))
    BGb = np.zeros((n, mmax))
    BGSb = np.zeros((n, mmax))
    Lgb = np.zeros((n, mmax))
    Spnu = np.zeros(mmax)
    hh = np.zeros(4)
    Hi = np.zeros((4, n))
    Gi = np.zeros((4, ne))
    d = np.zeros(2)
    d2 = np.zeros(2)
    Jw = np.zeros((2, 3))
    Gw = np.zeros((2, 4))
    Lw = np.zeros((2, 2))
    Phi = np.zeros((n, n))
    B = np.zeros((n, ne))
    KH = np.zeros((n, n))
    T55 = np.zeros((n, n))
    Pn = np.zeros((n, n))
    Pplus = np.zeros((n, n))
    T5e = np.zeros((n, ne))
    ones_e = np.ones(ne)
    minus_m = -np.ones(mmax)
    x = x0.copy()
    P = P0.copy()
    xplus = np.zeros(n)
    dxb = np.zeros(n)
    c = np.zeros(3)
    for k in range(N):
        for i in range(n):  # element loops, not xp[k] = x: no shape-check path to compile
            xp[k, i] = x[i]
            for j in range(n):
                Pp[k, i, j] = P[i, j]
        for j in range(3):
            c[j] = x[2 + j]
        # ---- fixes taken during step k: stacked observation
        m = 0
        for i in range(fs[k], fe[k]):
            m += 2
            for j in range(2):
                if not np.isnan(fv[i, j]):
                    m += 1
        have = m > 0
        Hs = Hb[:m]
        Gs = Gb[:m]
        nu = nub[:m]
        K = Kb[:, :m]
        Rt = Rtb[:m, :m]
        S = Sb[:m, :m]
        Sp = Spb[:m, :m]
        PHt = PHtb[:, :m]
        if have:
            r = 0
            for i in range(fs[k], fe[k]):
                _observation_rows_into(model, c, fPA[i], fPU[i], fPW[i], ftau[i], fa[i], fu[i],
                                       fw[i], sig, ftau_in[i], Qb[k], hh, Hi, Gi, d, Jw, Gw, Lw)
                dn, de = boxminus(flat[i], flon[i], x[0], x[1], hgt[k])
                for j in range(4):
                    if j >= 2 and np.isnan(fv[i, j - 2]):
                        continue
                    for l in range(n):
                        Hs[r, l] = Hi[j, l]
                    for l in range(ne):
                        Gs[r, l] = Gi[j, l]
                    if j == 0:
                        nu[r] = dn - hh[0]
                        Rd[r] = pos_sd[i] * pos_sd[i]
                    elif j == 1:
                        nu[r] = de - hh[1]
                        Rd[r] = pos_sd[i] * pos_sd[i]
                    else:
                        nu[r] = fv[i, j - 2] - hh[j]
                        Rd[r] = vel_sd[i] * vel_sd[i]
                    r += 1
            mmt_into(Gs, Gs, Rt)  # Rt = D D^T + G G^T
            for r in range(m):
                Rt[r, r] += Rd[r]
            # the core's update: K = P- H^T S^+, Joseph form, x+ = x- (+) K nu on the ellipsoid
            rk = gain_into(P, Hs, Rt, rcond, PHt, S, Sp, K, Ab[:m, :m], Vb[:m, :m])
            joseph_cov_into(P, K, Hs, Rt, Pplus, KH, T55, T5m[:, :m], Pn)
            nis[k] = normalised_innovation(Sp, nu, Spnu[:m])
            rank[k] = rk
            state_correction_into(LATLON, x, K, nu, hgt[k], dxb, xplus)
        else:
            for i in range(n):
                xplus[i] = x[i]
                for j in range(n):
                    Pplus[i, j] = P[i, j]
        for i in range(n):
            xs[k, i] = xplus[i]
            for j in range(n):
                Ps[k, i, j] = Pplus[i, j]
        if k == N - 1:
            break
        # ---- prediction to k+1 with the corrected readings of step k
        for j in range(3):
            c[j] = xplus[2 + j]
        tau = t[k + 1] - t[k]
        _step_matrices_into(model, c, A[k], U[k], W[k], tau, sig, q, star[k], dt_star[k],
                            Qb[k], Qa[k], d, Phi, B, Jw, Gw, d2, Lw)
        dn = d[0]
        de = d[1]
        ck = cross[k]
        mmt_into(Pplus, Phi, ck)  # smoother numerator P+ Phi^T (- K G B^T when correlated)
        if have and form == FORM_CONSISTENT:
            BGS = BGSb[:, :m]
            correlated_noise_predict_into(P, Phi, B, K, Hs, Gs, Sp, Rd[:m], Pn, ck, BGS,
                                          (Lgb[:, :m], BGb[:, :m], KH, T55, T5e, ones_e,
                                           minus_m[:m]))
            for j in range(m):  # state correction B G^T S^+ nu (position rows only: the
                dn += BGS[0, j] * nu[j]  # random-walk columns of B have no G counterpart)
                de += BGS[1, j] * nu[j]
        else:
            predict_cov_into(Pplus, Phi, Pn, T55)  # Phi P+ Phi^T + B B^T
            mdmt_acc_into(B, ones_e, B, Pn)
        lat, lon = boxplus(xplus[0], xplus[1], dn, de, hgt[k])
        x[0] = lat
        x[1] = lon
        for i in range(2, n):
            x[i] = xplus[i]
        sym_into(Pn, P)
    return xp, xs, Pp, Ps, cross, nis, rank


def _c(a, dtype=np.float64) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a, dtype=dtype))


def sns_filter(inputs: StepInputs, x0: np.ndarray, P0: np.ndarray, noise: SnsNoise, *,
               model: int, form: int = FORM_CONSISTENT) -> SnsRun:
    """Run the nonlinear SNS filter forward (module docstring; docs/sns.md).

    Parameters
    ----------
    inputs : :class:`StepInputs`
    x0 : (5,) initial state ``[lat_rad, lon_rad, c1, c2, c3]`` at ``inputs.t[0]``
    P0 : (5, 5) its covariance (north/east metres, correction units)
    noise : :class:`SnsNoise`
    model : ``MODEL_AIRSPEED`` or ``MODEL_DOPPLER``
    form : ``FORM_CONSISTENT`` (correlated-noise terms) or ``FORM_SEED`` (seed 003 as printed)
    """
    if model not in (MODEL_AIRSPEED, MODEL_DOPPLER):
        raise ValueError(f"unknown model {model}")
    if form not in (FORM_CONSISTENT, FORM_SEED):
        raise ValueError(f"unknown form {form}")
    t = _c(inputs.t)
    if t.ndim != 1 or t.size < 2 or not np.all(np.diff(t) > 0):
        raise ValueError("filter times must be strictly increasing, at least two")
    P0 = _c(P0)
    if P0.shape != (N_STATE, N_STATE):
        raise ValueError(f"P0 must be (5, 5), got {P0.shape}")
    inputs = fill_single_sample(inputs)
    steps = KernelSteps(t, _c(inputs.h), _c(inputs.A), _c(inputs.U), _c(inputs.W),
                        _c(inputs.star).reshape(-1, 3, 2), _c(inputs.dt_star),
                        _c(inputs.Qb).reshape(-1, 7), _c(inputs.Qa).reshape(-1, 7))
    fixes = KernelFixes(_c(inputs.fix_start, np.int64), _c(inputs.fix_end, np.int64),
                        _c(inputs.fix_lat), _c(inputs.fix_lon), _c(inputs.fix_v).reshape(-1, 2),
                        _c(inputs.fix_tau), _c(inputs.fix_PA).reshape(-1, 2),
                        _c(inputs.fix_PU).reshape(-1, 2), _c(inputs.fix_PW).reshape(-1, 2),
                        _c(inputs.fix_a).reshape(-1, 2), _c(inputs.fix_u).reshape(-1, 2),
                        _c(inputs.fix_w).reshape(-1, 2), _c(inputs.fix_tau_in))
    kn = KernelNoise(_c(noise.sensor_sd), _c(noise.rw_q),
                     per_fix_sd(inputs.fix_pos_sd, noise.pos_sd_m, len(inputs.fix_lat)),
                     per_fix_sd(inputs.fix_vel_sd, noise.vel_sd_mps, len(inputs.fix_lat)),
                     float(noise.rcond))
    out = _filter_kernel(int(model), int(form), _c(x0), P0, steps, fixes, kn)
    xp, xs, Pp, Ps, cross, nis, rank = out
    return SnsRun(xp, xs, Pp, Ps, cross, nis, rank, _c(inputs.h).copy(), int(model),
                  int(form))


@nb.njit(cache=True, nogil=True)
def _smoother_kernel(xp, xf, Pp, Pf, cross, hgt, geom=LATLON):
    """RTS backward pass on the core's step (:func:`~flightrecon.estimation.rts.rts_step`) with
    the filter's cross-covariances (``C = cross[k]``, which holds the correlated-noise term of
    the consistent form) in the geometry ``geom`` (latitude/longitude; Euclidean only for the
    reference test); returns ``xs``, ``Ps`` and the number of predicted covariances that failed
    their Cholesky factorisation."""
    N, n = xf.shape
    xs = xf.copy()
    Ps = Pf.copy()
    CT = np.zeros((n, n))
    work = rts_step_work(n)
    n_fallback = 0
    for k in range(N - 2, -1, -1):
        for i in range(n):
            for j in range(n):
                CT[i, j] = cross[k, j, i]
        if not rts_step(geom, (xf[k], Pf[k]), (xp[k + 1], Pp[k + 1]), (xs[k + 1], Ps[k + 1]),
                        CT, (hgt[k], hgt[k + 1]), 1e-14, (xs[k], Ps[k]), work):
            n_fallback += 1
    return xs, Ps, n_fallback


def sns_smooth(run: SnsRun) -> SnsSmoothed:
    """Backward pass with the gain matching the filter's form (module docstring, "Smoother")."""
    xs, Ps, n_fallback = _smoother_kernel(_c(run.x_pred), _c(run.x), _c(run.P_pred), _c(run.P),
                                          _c(run.cross), _c(run.h))
    return SnsSmoothed(xs, Ps, int(n_fallback))
