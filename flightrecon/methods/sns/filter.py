"""The SNS filter and smoother as a model of the estimation core (docs/sns.md, "Filter",
"Smoother"; docs/estimation.md, "One forward loop", "One backward loop").

:class:`SnsModel` holds the filter's inputs (:class:`KernelSteps`, :class:`KernelFixes`,
:class:`KernelNoise`) and the buffers of its run; the functions registered below for it with
:func:`~flightrecon.estimation.model.implements` are what the core's
:func:`~flightrecon.estimation.filtering.forward_pass` and
:func:`~flightrecon.estimation.smoothing.backward_pass` call at each step:

* ``update_into`` (step k): the fixes of the step stacked, ``S = H P- H^T + D D^T + G G^T``,
  ``K = P- H^T S^+`` with the pseudo-inverse (:func:`~flightrecon.estimation.updates.gain_into`),
  the Joseph form, ``x+ = x- (+) K nu`` on the ellipsoid;
* ``predict_into`` (step k from k-1): ``f(x+)``, ``Phi``, ``B`` of step k-1; the consistent form
  adds the correlated-noise terms of the update of step k-1 (gain ``L = Phi K + B G^T S^+``,
  :func:`~flightrecon.estimation.updates.correlated_noise_predict_into`), the seed form
  ``Phi P+ Phi^T + B B^T``.  The core runs the prediction of step k before the update of step k,
  so the update's ``P-``, ``H``, ``G``, ``K``, ``S^+``, ``nu`` and ``D D^T`` stay in the
  workspace (:class:`SnsWorkspace`) until the prediction that follows;
* the cross-covariance ``cross[k] = Cov(x_k, x_{k+1} | Y_0..k) = P+_k Phi^T - K G B^T``
  (``P+_k Phi^T`` for the seed form and for steps without fixes) is kept by the prediction for
  the smoother, whose geometry is latitude/longitude with the step heights, Cholesky pivot
  tolerance 1e-14.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from flightrecon.estimation.filtering import FilterRun, forward_pass, keep_dense_into
from flightrecon.estimation.linalg import mdmt_acc_into, mmt_into, sym_into
from flightrecon.estimation.manifold import LATLON, boxminus, boxplus
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
    workspace,
)
from flightrecon.estimation.predict import predict_cov_into
from flightrecon.estimation.smoothing import SmoothedRun, backward_pass
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
    FixReadings,
    SnsNoise,
    StepInputs,
    StepReadings,
    fill_single_sample,
    observation_rows_into,
    per_fix_sd,
    step_matrices_into,
)

#: Cholesky pivot tolerance of the smoother's predicted covariances (relative to the diagonal)
RTS_REL_TOL = 1e-14


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


class SnsModel(NamedTuple):
    """The SNS filter as a model of the estimation core (module docstring).

    ``kind`` ``MODEL_AIRSPEED`` / ``MODEL_DOPPLER``, ``form`` ``FORM_CONSISTENT`` /
    ``FORM_SEED``, ``geometry`` the state's geometry (``LATLON``; ``EUCLIDEAN`` only for the
    reference test of the smoother), ``m_max`` the most measurement rows of a step (at least
    1); the inputs; the buffers of the run: predicted ``x_p``, ``P_p`` and filtered ``x_f``,
    ``P_f`` (N, 5) / (N, 5, 5) (lat/lon radians first; covariances in north/east metres),
    ``cross`` (N, 5, 5) ``Cov(x_k, x_{k+1} | Y_0..k)`` (row N-1 zero), ``nis`` (N,) (NaN
    without fixes), ``rank`` (N,) its degrees of freedom, and the smoothed covariances ``P_s``
    (N, 5, 5) (empty (0, 5, 5) in a forward run).
    """

    kind: int
    form: int
    geometry: int
    m_max: int
    steps: KernelSteps
    fixes: KernelFixes
    noise: KernelNoise
    x_p: np.ndarray
    P_p: np.ndarray
    x_f: np.ndarray
    P_f: np.ndarray
    cross: np.ndarray
    nis: np.ndarray
    rank: np.ndarray
    P_s: np.ndarray


class SnsWorkspace(NamedTuple):
    """Scratch of one run, in preallocated buffers (the small-matrix algebra runs in loop
    products, :func:`~flightrecon.estimation.linalg.mm_into` etc., without per-step heap
    allocations).  The first block is what the update of step k leaves for the prediction of
    step k+1: the rows ``m[0]`` of its stacked observation (0 without fixes), ``H``, ``G``,
    ``D D^T`` (``Rd``), ``nu``, ``K``, ``S^+`` (``Sp``) and the predicted covariance ``Pm`` it
    started from."""

    m: np.ndarray
    Hb: np.ndarray
    Gb: np.ndarray
    Rd: np.ndarray
    nub: np.ndarray
    Kb: np.ndarray
    Spb: np.ndarray
    Pm: np.ndarray
    Rtb: np.ndarray
    Sb: np.ndarray
    Ab: np.ndarray
    Vb: np.ndarray
    PHtb: np.ndarray
    T5m: np.ndarray
    BGb: np.ndarray
    BGSb: np.ndarray
    Lgb: np.ndarray
    Spnu: np.ndarray
    hh: np.ndarray
    Hi: np.ndarray
    Gi: np.ndarray
    d: np.ndarray
    d2: np.ndarray
    Jw: np.ndarray
    Gw: np.ndarray
    Lw: np.ndarray
    Phi: np.ndarray
    B: np.ndarray
    KH: np.ndarray
    T55: np.ndarray
    Pn: np.ndarray
    T5e: np.ndarray
    ones_e: np.ndarray
    minus_m: np.ndarray
    dxb: np.ndarray
    c: np.ndarray


@implements(workspace, SnsModel)
def _workspace(model):
    mmax = model.m_max
    n = N_STATE
    ne = N_EPS1
    return SnsWorkspace(
        np.zeros(1, dtype=np.int64), np.zeros((mmax, n)), np.zeros((mmax, ne)), np.zeros(mmax),
        np.zeros(mmax), np.zeros((n, mmax)), np.zeros((mmax, mmax)), np.zeros((n, n)),
        np.zeros((mmax, mmax)), np.zeros((mmax, mmax)), np.zeros((mmax, mmax)),
        np.zeros((mmax, mmax)), np.zeros((n, mmax)), np.zeros((n, mmax)), np.zeros((n, mmax)),
        np.zeros((n, mmax)), np.zeros((n, mmax)), np.zeros(mmax), np.zeros(4), np.zeros((4, n)),
        np.zeros((4, ne)), np.zeros(2), np.zeros(2), np.zeros((2, 3)), np.zeros((2, 4)),
        np.zeros((2, 2)), np.zeros((n, n)), np.zeros((n, ne)), np.zeros((n, n)),
        np.zeros((n, n)), np.zeros((n, n)), np.zeros((n, ne)), np.ones(ne), -np.ones(mmax),
        np.zeros(n), np.zeros(3))


@implements(predict_into, SnsModel, refcounted=False)
def _predict(model, k, x, P, ws):
    """Step k-1 to k from the filtered ``x``, ``P`` of step k-1 (docs/sns.md, "Filter"):
    ``x_k = f(x+) (+ B G^T S^+ nu)``, ``P_k`` by the consistent or the seed form; keeps
    ``cross[k-1] = P+ Phi^T (- K G B^T)``."""
    st = model.steps
    kp = k - 1
    m = ws.m[0]
    c = ws.c
    for j in range(3):
        c[j] = x[2 + j]
    tau = st.t[k] - st.t[kp]
    step = StepReadings(st.A[kp], st.U[kp], st.W[kp], tau, st.star[kp], st.dt_star[kp],
                        st.Qb[kp], st.Qa[kp])
    step_matrices_into(model.kind, c, step, model.noise.sig, model.noise.q,
                       (ws.d, ws.Phi, ws.B), (ws.Jw, ws.Gw, ws.d2, ws.Lw))
    dn = ws.d[0]
    de = ws.d[1]
    ck = model.cross[kp]
    mmt_into(P, ws.Phi, ck)  # smoother numerator P+ Phi^T (- K G B^T when correlated)
    Pn = ws.Pn
    if m > 0 and model.form == FORM_CONSISTENT:
        BGS = ws.BGSb[:, :m]
        nu = ws.nub[:m]
        correlated_noise_predict_into(ws.Pm, ws.Phi, ws.B, ws.Kb[:, :m], ws.Hb[:m], ws.Gb[:m],
                                      ws.Spb[:m, :m], ws.Rd[:m], Pn, ck, BGS,
                                      (ws.Lgb[:, :m], ws.BGb[:, :m], ws.KH, ws.T55, ws.T5e,
                                       ws.ones_e, ws.minus_m[:m]))
        for j in range(m):  # state correction B G^T S^+ nu (position rows only: the
            dn += BGS[0, j] * nu[j]  # random-walk columns of B have no G counterpart)
            de += BGS[1, j] * nu[j]
    else:
        predict_cov_into(P, ws.Phi, Pn, ws.T55)  # Phi P+ Phi^T + B B^T
        mdmt_acc_into(ws.B, ws.ones_e, ws.B, Pn)
    lat, lon = boxplus(x[0], x[1], dn, de, st.hgt[kp])
    x[0] = lat
    x[1] = lon
    sym_into(Pn, P)


@implements(keep_predicted, SnsModel, refcounted=False)
def _keep_predicted(model, k, x, P):
    keep_dense_into(model.x_p, model.P_p, k, x, P)


@implements(update_into, SnsModel, refcounted=False)
def _update(model, k, x, P, ws):
    """The fixes of step k, stacked (docs/sns.md, "Filter"): ``K = P- H^T S^+``, Joseph form,
    ``x+ = x- (+) K nu``; records ``nis[k]``, ``rank[k]``."""
    fx = model.fixes
    nz = model.noise
    hgt = model.steps.hgt[k]
    n = N_STATE
    ne = N_EPS1
    m = 0
    for i in range(fx.start[k], fx.end[k]):
        m += 2
        for j in range(2):
            if not np.isnan(fx.v[i, j]):
                m += 1
    ws.m[0] = m
    if m == 0:
        return
    c = ws.c
    for j in range(3):
        c[j] = x[2 + j]
    Hs = ws.Hb[:m]
    Gs = ws.Gb[:m]
    nu = ws.nub[:m]
    K = ws.Kb[:, :m]
    Rt = ws.Rtb[:m, :m]
    S = ws.Sb[:m, :m]
    Sp = ws.Spb[:m, :m]
    PHt = ws.PHtb[:, :m]
    Rd = ws.Rd
    Hi = ws.Hi
    Gi = ws.Gi
    hh = ws.hh
    r = 0
    for i in range(fx.start[k], fx.end[k]):
        fix = FixReadings(fx.PA[i], fx.PU[i], fx.PW[i], fx.tau[i], fx.a[i], fx.u[i], fx.w[i],
                          fx.tau_in[i])
        observation_rows_into(model.kind, c, fix, nz.sig, model.steps.Qb[k], (hh, Hi, Gi),
                              (ws.d, ws.Jw, ws.Gw, ws.Lw))
        dn, de = boxminus(fx.lat[i], fx.lon[i], x[0], x[1], hgt)
        for j in range(4):
            if j >= 2 and np.isnan(fx.v[i, j - 2]):
                continue
            for l in range(n):
                Hs[r, l] = Hi[j, l]
            for l in range(ne):
                Gs[r, l] = Gi[j, l]
            if j == 0:
                nu[r] = dn - hh[0]
                Rd[r] = nz.pos_sd[i] * nz.pos_sd[i]
            elif j == 1:
                nu[r] = de - hh[1]
                Rd[r] = nz.pos_sd[i] * nz.pos_sd[i]
            else:
                nu[r] = fx.v[i, j - 2] - hh[j]
                Rd[r] = nz.vel_sd[i] * nz.vel_sd[i]
            r += 1
    mmt_into(Gs, Gs, Rt)  # Rt = D D^T + G G^T
    for r in range(m):
        Rt[r, r] += Rd[r]
    Pm = ws.Pm  # P- kept for the correlated-noise prediction of step k+1
    for i in range(n):
        for j in range(n):
            Pm[i, j] = P[i, j]
    # the core's update: K = P- H^T S^+, Joseph form, x+ = x- (+) K nu on the ellipsoid
    rk = gain_into(Pm, Hs, Rt, nz.rcond, PHt, S, Sp, K, ws.Ab[:m, :m], ws.Vb[:m, :m])
    joseph_cov_into(Pm, K, Hs, Rt, P, ws.KH, ws.T55, ws.T5m[:, :m], ws.Pn)
    model.nis[k] = normalised_innovation(Sp, nu, ws.Spnu[:m])
    model.rank[k] = rk
    state_correction_into(LATLON, x, K, nu, hgt, ws.dxb, x)


@implements(keep_filtered, SnsModel, refcounted=False)
def _keep_filtered(model, k, x, P):
    keep_dense_into(model.x_f, model.P_f, k, x, P)


@implements(smoothing_covariances, SnsModel)
def _smoothing_covariances(model, k, ws):
    return model.P_f[k], model.P_p[k + 1]


@implements(cross_transposed_into, SnsModel, refcounted=False)
def _cross_transposed(model, k, CT, ws):
    n = CT.shape[0]
    for i in range(n):
        for j in range(n):
            CT[i, j] = model.cross[k, j, i]


@implements(cross_times_into, SnsModel, refcounted=False)
def _cross_times(model, k, y, out, ws):
    n = out.shape[0]
    for i in range(n):
        v = 0.0
        for j in range(n):
            v += model.cross[k, i, j] * y[j]
        out[i] = v


@implements(rts_frame, SnsModel)
def _rts_frame(model, k):
    return model.geometry, model.steps.hgt[k], model.steps.hgt[k + 1], RTS_REL_TOL


@implements(keep_smoothed, SnsModel, refcounted=False)
def _keep_smoothed(model, k, x, P, with_cov, ws):
    if with_cov:
        n = P.shape[0]
        for i in range(n):
            for j in range(n):
                model.P_s[k, i, j] = P[i, j]


def _f64(a, dtype=np.float64) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a, dtype=dtype))


def _rows_per_step(start: np.ndarray, end: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Measurement rows of each step: two per fix and one per velocity component present."""
    per_fix = 2 + np.count_nonzero(~np.isnan(v), axis=1)
    cum = np.concatenate([[0], np.cumsum(per_fix)])
    return cum[end] - cum[start]


def _outputs(N: int, n_smoothed: int) -> tuple[np.ndarray, ...]:
    n = N_STATE
    return (np.empty((N, n)), np.empty((N, n, n)), np.empty((N, n)), np.empty((N, n, n)),
            np.zeros((N, n, n)), np.full(N, np.nan), np.zeros(N, dtype=np.int64),
            np.empty((n_smoothed, n, n)))


def sns_filter(inputs: StepInputs, x0: np.ndarray, P0: np.ndarray, noise: SnsNoise, *,
               model: int, form: int = FORM_CONSISTENT) -> FilterRun:
    """Run the nonlinear SNS filter forward (module docstring; docs/sns.md).

    Parameters
    ----------
    inputs : :class:`StepInputs`
    x0 : (5,) initial state ``[lat_rad, lon_rad, c1, c2, c3]`` at ``inputs.t[0]``
    P0 : (5, 5) its covariance (north/east metres, correction units)
    noise : :class:`SnsNoise`
    model : ``MODEL_AIRSPEED`` or ``MODEL_DOPPLER``
    form : ``FORM_CONSISTENT`` (correlated-noise terms) or ``FORM_SEED`` (seed 003 as printed)

    Returns
    -------
    FilterRun
        The core's run: ``x_pred``, ``x`` (N, 5) predicted / filtered states (lat/lon radians
        first), ``P_pred``, ``P`` (N, 5, 5) in the local-level frame (north/east metres first);
        diagnostics ``cross`` (N, 5, 5) ``Cov(x_k, x_{k+1} | Y_0..k)`` (row N-1 zero), ``nis``
        (N,) (NaN without fixes), ``rank`` its degrees of freedom, ``h`` (N,) the heights of
        the radii, ``model`` and ``form`` as passed; ``run.model`` the :class:`SnsModel`
        (its ``kind`` and ``form``), which :func:`sns_smooth` takes.
    """
    if model not in (MODEL_AIRSPEED, MODEL_DOPPLER):
        raise ValueError(f"unknown model {model}")
    if form not in (FORM_CONSISTENT, FORM_SEED):
        raise ValueError(f"unknown form {form}")
    t = _f64(inputs.t)
    if t.ndim != 1 or t.size < 2 or not np.all(np.diff(t) > 0):
        raise ValueError("filter times must be strictly increasing, at least two")
    P0 = _f64(P0)
    if P0.shape != (N_STATE, N_STATE):
        raise ValueError(f"P0 must be (5, 5), got {P0.shape}")
    inputs = fill_single_sample(inputs)
    N = t.shape[0]
    steps = KernelSteps(t, _f64(inputs.h), _f64(inputs.A), _f64(inputs.U), _f64(inputs.W),
                        _f64(inputs.star).reshape(-1, 3, 2), _f64(inputs.dt_star),
                        _f64(inputs.Qb).reshape(-1, 7), _f64(inputs.Qa).reshape(-1, 7))
    fixes = KernelFixes(_f64(inputs.fix_start, np.int64), _f64(inputs.fix_end, np.int64),
                        _f64(inputs.fix_lat), _f64(inputs.fix_lon),
                        _f64(inputs.fix_v).reshape(-1, 2), _f64(inputs.fix_tau),
                        _f64(inputs.fix_PA).reshape(-1, 2), _f64(inputs.fix_PU).reshape(-1, 2),
                        _f64(inputs.fix_PW).reshape(-1, 2), _f64(inputs.fix_a).reshape(-1, 2),
                        _f64(inputs.fix_u).reshape(-1, 2), _f64(inputs.fix_w).reshape(-1, 2),
                        _f64(inputs.fix_tau_in))
    kn = KernelNoise(_f64(noise.sensor_sd), _f64(noise.rw_q),
                     per_fix_sd(inputs.fix_pos_sd, noise.pos_sd_m, len(inputs.fix_lat)),
                     per_fix_sd(inputs.fix_vel_sd, noise.vel_sd_mps, len(inputs.fix_lat)),
                     float(noise.rcond))
    rows = _rows_per_step(fixes.start, fixes.end, fixes.v)
    m_max = max(1, int(rows.max()))
    sm = SnsModel(int(model), int(form), LATLON, m_max, steps, fixes, kn, *_outputs(N, 0))
    forward_pass(sm, _f64(x0), P0, N)
    diagnostics = {"cross": sm.cross, "nis": sm.nis, "rank": sm.rank, "h": steps.hgt.copy(),
                   "model": np.asarray(int(model)), "form": np.asarray(int(form))}
    return FilterRun(sm.x_f, sm.P_f, sm.x_p, sm.P_p, diagnostics, sm)


def rts_smooth_cross(x_pred: np.ndarray, x: np.ndarray, P_pred: np.ndarray, P: np.ndarray,
                     cross: np.ndarray, h: np.ndarray, geometry: int = LATLON) -> SmoothedRun:
    """RTS backward pass of a run given as arrays, with its cross-covariances ``cross[k] =
    Cov(x_k, x_{k+1} | Y_0..k)`` (the correlated-noise term of the consistent form included),
    in the state geometry ``geometry`` (latitude/longitude with the heights ``h``; Euclidean
    for the reference test), on the core's :func:`~flightrecon.estimation.smoothing.backward_pass`.

    Returns the core's :class:`~flightrecon.estimation.smoothing.SmoothedRun` (``x``, ``P``,
    ``cholesky_fallbacks``: steps whose predicted covariance failed its Cholesky factorisation
    and were solved through its eigen-decomposition; reported, never silent).
    """
    x_pred, x, P_pred, P, cross, h = (_f64(a) for a in (x_pred, x, P_pred, P, cross, h))
    N, n = x.shape
    e1 = np.empty(0)
    e2 = np.empty((0, 2))
    ei = np.empty(0, dtype=np.int64)
    steps = KernelSteps(e1, h, e2, e2, e2, np.empty((0, 3, 2)), e1, np.empty((0, 7)),
                        np.empty((0, 7)))
    fixes = KernelFixes(ei, ei, e1, e1, e2, e1, e2, e2, e2, e2, e2, e2, e1)
    noise = KernelNoise(e1, e1, e1, e1, 0.0)
    sm = SnsModel(-1, -1, int(geometry), 1, steps, fixes, noise, x_pred, P_pred, x, P, cross,
                  e1, ei, np.empty((N, n, n)))
    xs = np.empty((N, n))
    n_fallback = backward_pass(sm, x, x_pred, xs, P[N - 1])
    return SmoothedRun(xs, sm.P_s, int(n_fallback))


def sns_smooth(run: FilterRun) -> SmoothedRun:
    """Backward pass of :func:`sns_filter`'s run with the gain matching the filter's form
    (its cross-covariances; module docstring, "Smoother")."""
    sm = run.model
    N, n = sm.x_f.shape
    sm = sm._replace(P_s=np.empty((N, n, n)))
    xs = np.empty((N, n))
    n_fallback = backward_pass(sm, sm.x_f, sm.x_p, xs, sm.P_f[N - 1])
    return SmoothedRun(xs, sm.P_s, int(n_fallback))
