"""The joint smoother's iterations, in one place: a built problem
(:class:`~flightrecon.methods.joint.problem.JointProblem`) solved by forward filter, RTS backward
pass and Gauss-Newton relinearisation with robust re-weighting and clock-offset steps, damped by a
backtracking line search on the MAP cost (:func:`smooth_joint`; docs/joint.md, "Filter, smoother,
iterations").

The iterations are an iterated extended Kalman smoother with a line search (Sarkka & Svensson 2020,
"Levenberg-Marquardt and line-search extended Kalman smoothers", ICASSP, section 4): each pass
linearises about the current iterate X and smooths, which gives the Gauss-Newton point X_GN; the
next iterate is X + alpha (X_GN - X) with alpha = 1, 1/2, 1/4, ... the first that does not raise the
MAP cost J (:func:`~flightrecon.methods.joint.model.map_cost`; :func:`line_search`), or where none
does a Levenberg-Marquardt step (algorithm 2: :func:`lm_step`).  The robust weights, the clock
offsets (their Gauss-Newton step jointly with the track, from each pass's forward filter:
:func:`clock_step`), the take-off roll, the gust sd (:func:`gust_round`) and the noise factors are
updated between the passes (:func:`_accepted`) and held fixed within one (the cost is compared under
the same ones).  The passes' front ends (:func:`forward`, :func:`backward`) run the compiled model
(:class:`~flightrecon.methods.joint.model.JointModel`) on the estimation core's loops, the
covariance pass on a second thread beside the mean pass (docs/joint.md, "Filter, smoother,
iterations", item 1).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, replace
from typing import Any, NamedTuple

import numba as nb
import numpy as np

from flightrecon.estimation.filtering import forward_pass
from flightrecon.estimation.linalg import packed_size, unpack_sym
from flightrecon.estimation.smoothing import backward_pass
from flightrecon.geo.frames import ecef_to_geodetic
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.inputs import EndPoint, TakeoffRoll, refined_roll
from flightrecon.methods.joint.layout import (
    N_STATE,
    Cost,
    Dynamics,
    Geometry,
    Measurements,
    Scalars,
)
from flightrecon.methods.joint.linearisation import (
    Nominal,
    PassModels,
    SmootherFlight,
    initial_estimate,
    models_about,
    models_at,
    nominal_states,
    pass_cost,
    q_vector,
)
from flightrecon.methods.joint.measurements import NOISE_GROUPS
from flightrecon.methods.joint.model import JointModel, joint_model
from flightrecon.methods.joint.problem import JointProblem
from flightrecon.methods.joint.settings import SOURCES, JointSettings


def filter_buffers(N: int, store_predicted: bool = True) -> tuple[np.ndarray, ...]:
    """Outputs of :func:`forward` for N steps: ``xf`` (N, n), ``Pf`` (N, n (n + 1) / 2), ``xp``,
    ``Pp`` (the covariances as packed lower triangles,
    :func:`~flightrecon.estimation.linalg.pack_sym`: half the memory, 190 MB less on a 10-hour
    flight at 1 Hz; an empty ``Pp`` without ``store_predicted``: recomputed backward, bit-identical,
    0.2-0.3 s more per pass on that flight)."""
    n = N_STATE
    L = packed_size(n)
    return (np.empty((N, n)), np.empty((N, L)), np.empty((N, n)),
            np.empty((N if store_predicted else 0, L)))


def forward(bufs: tuple[np.ndarray, ...], x0: np.ndarray, P0: np.ndarray, dyn: Dynamics,
            meas: Scalars, geo: Geometry, gate: float, xlin: np.ndarray | None,
            clock: tuple[np.ndarray, np.ndarray] | None = None) -> JointModel:
    """Forward extended Kalman filter with sequential scalar updates (the model's ``predict_into``
    and ``update_into``, :mod:`~flightrecon.methods.joint.model`) into the filter buffers ``bufs``
    (:func:`filter_buffers`; an empty ``Pp`` is not filled: the backward passes then recompute each
    predicted covariance, bit for bit the same).

    With ``xlin`` (N, n) the measurements are linearised about it (the smoothed states of the last
    pass: an iterated extended Kalman smoother, Gauss-Newton on the whole record); with None (or an
    empty (0, n)) about the filter's own prediction (the first pass).  ``gate`` and ``clock`` as
    in :func:`~flightrecon.methods.joint.model.joint_model`.  Returns the pass's
    :class:`~flightrecon.methods.joint.model.JointModel`: its innovations, their variances and
    inflations (``nu``, ``S``, ``infl``) and the clock offsets' outputs (``cnorm``, ``cxf``,
    ``cxp``).
    """
    model = joint_model(bufs, dyn, meas, geo, gate, xlin, forward=True, clock=clock)
    forward_pass(model, x0, P0, bufs[0].shape[0])
    return model


class Smoothed(NamedTuple):
    """A backward pass: the smoothed states ``x`` (N, n), its ``model``
    (:class:`~flightrecon.methods.joint.model.JointModel`: the residuals ``res_n``, ``res``,
    ``rate``, ``hph`` and the covariance blocks ``Pblk``, ``var`` it computed) and the number of
    ``cholesky_fallbacks``."""

    x: np.ndarray
    model: JointModel
    cholesky_fallbacks: int


def backward(bufs: tuple[np.ndarray, ...], dyn: Dynamics, meas: Scalars, geo: Geometry,
             with_cov: bool, residuals: bool = True) -> Smoothed:
    """RTS backward pass (Rauch, Tung & Striebel 1965) on the filter buffers ``bufs``, with the
    smoothed covariances (``with_cov``) or the mean only: x_s[k] = x_f[k] + P_f[k] F_{k+1}^T
    P_p[k+1]^{-1} (x_s[k+1] - x_p[k+1]), the same smoothed mean at O(n^3 / 6) per step (one Cholesky
    solve with a vector) instead of O(n^3) products; the Gauss-Newton iterations need the trajectory
    and the residuals but not the covariances.  Without ``residuals`` the covariance pass can run
    beside the mean pass on another thread.  Counts the steps whose predicted covariance failed its
    Cholesky factorisation (not positive definite to rounding: the gain then comes from the
    eigen-decomposition solve; the caller reports the count)."""
    xf, Pf, xp, Pp = bufs
    N, n = xf.shape
    model = joint_model(bufs, dyn, meas, geo, residuals=residuals, covariances=with_cov)
    xs = np.empty((N, n))
    P_last = np.empty((n, n))
    unpack_sym(Pf[N - 1], P_last)
    n_fallback = backward_pass(model, xf, xp, xs, P_last if with_cov else np.empty((0, 0)))
    return Smoothed(xs, model, int(n_fallback))


def smoothed_columns(cxf: np.ndarray, cxp: np.ndarray, Pf: np.ndarray, Pp: np.ndarray,
                     dyn: Dynamics, meas: Scalars, geo: Geometry) -> np.ndarray:
    """The clock offsets' smoothed columns X_s,g (2, N, n) from their filtered and predicted ones
    (:func:`forward`'s, the same pass's ``Pf``, ``Pp``): the mean-only RTS recursion
    x_s[k] = x_f[k] + C (x_s[k+1] - x_p[k+1]) is linear in (x_f, x_p) with no input of its own, so
    on the columns it gives d x_s / d c up to sign: the track moved by an offset error dc is
    x_s - X_s,g dc, and an offset of covariance Sigma adds X_s,g Sigma X_s,g^T to the track's (the
    marginal covariance of the state augmented by the constant offsets)."""
    out = np.empty_like(cxf)
    for c in range(cxf.shape[0]):
        out[c] = backward((cxf[c], Pf, cxp[c], Pp), dyn, meas, geo, False, False).x
    return out


class BackgroundCovariances(threading.Thread):
    """The RTS covariance pass (:func:`backward`, without the residuals) of the filter
    buffers ``bufs`` = (xf, Pf, xp, Pp) and the pass's layouts, started on a second thread to
    run beside the mean pass and whatever follows it until the covariances or the buffers are
    needed; :meth:`result` waits for it."""

    def __init__(self, bufs: tuple[np.ndarray, ...], dyn: Dynamics, meas: Scalars,
                 geo: Geometry) -> None:
        super().__init__(name="joint-covariances")
        self.job = (bufs, dyn, meas, geo)
        self.out: Smoothed | None = None
        self.error: BaseException | None = None
        self.start()

    def run(self) -> None:
        try:
            self.out = backward(*self.job, True, False)
        except BaseException as exc:  # re-raised on the thread that waits for it
            self.error = exc

    def result(self) -> Smoothed:
        """The covariance pass, once the thread has finished."""
        self.join()
        if self.error is not None:
            raise self.error
        assert self.out is not None
        return self.out


@dataclass
class PassResult:
    """Outputs of one forward filter and backward smoother pass."""

    xs: np.ndarray
    res: np.ndarray
    rate: np.ndarray
    hph: np.ndarray | None
    infl: np.ndarray
    innov: np.ndarray
    innov_var: np.ndarray
    Pblk: np.ndarray | None
    var: np.ndarray | None
    n_fallback: int
    kern_args: tuple[Dynamics, Scalars, Geometry]
    scalars: jl.Scalars
    pending: BackgroundCovariances | None = None  # its covariance pass, still on its thread
    #                                               (Pblk and var None until joined)
    info: dict[str, Any] | None = None   # the pass's entry in the iterations
    # the clock columns and rates of its forward pass, and the offsets' outputs of it (normal
    # equations, filter columns after and before each step's updates: :func:`forward`)
    clock: tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, ...]] | None = None


def robust_weights(res_n: np.ndarray, weights: np.ndarray, settings: JointSettings) -> np.ndarray:
    """IRLS weights of the robust loss from the normalised residuals of the iterate: 1 up to
    ``huber_c``, huber_c/|u| beyond (Huber), 1e-8 beyond ``reject_c`` (set aside: a jumped source
    cannot pull the track at all); unchanged without ``robust``."""
    if not settings.robust:
        return weights
    a = np.abs(res_n)
    w = np.where(a > settings.huber_c, settings.huber_c / np.maximum(a, 1e-12), 1.0)
    w = np.where(a > settings.reject_c, 1e-8, w)
    w[~np.isfinite(w)] = 1.0
    return w


CLOCK_SOURCES = (("gnss", ("gnss_pos",)), ("gnss_velocity", ("gnss_vel",)),
                 ("radar", ("radar",)))
"""The clock offsets estimated, in the order of the forward pass's clock columns
(:data:`~flightrecon.methods.joint.model.N_CLOCK`), and the sources each shifts.  The GNSS
velocities have their own: on the real G1000 exports the ground speed and track lag the
positions (docs/joint.md, "Filter, smoother, iterations", item 4).  The radar last: a flight
without one carries two columns, not three
(:func:`~flightrecon.methods.joint.model.joint_model`)."""

CLOCK_MIN_MEASUREMENTS = 10
"""Fewer measurements of a source than this: its offset is not estimated."""

CLOCK_DETECT_SD = 3.0
"""An offset still at zero is taken once its step exceeds this many of its sd (detected); below,
the source's stamps are kept: estimating an offset that is not there costs accuracy (docs/joint.md,
item 4: the simulated radar approaches)."""

CLOCK_STILL_SD = 0.1
"""A clock step of at most this fraction of the offset's sd is not taken (the offset stands
still for the convergence test): it would move the track by at most a tenth of the share of
the track's uncertainty the offset's own uncertainty carries."""


def clock_columns(meas: Measurements, settings: JointSettings
                  ) -> tuple[np.ndarray, np.ndarray] | None:
    """Each measurement's clock column for the forward pass (:data:`CLOCK_SOURCES`' index; -1 for
    the measurements no offset shifts) and the rate of its prediction with its time that the
    kernel's gradient does not give (``Measurements.rate``); None when no source has
    :data:`CLOCK_MIN_MEASUREMENTS`.  With a derived ``n_long_g`` (``settings.long_load_derived``)
    the GNSS positions' offset is held at the cleaning's (it would absorb the airspeed's lag, which
    the along-track acceleration then has: docs/joint.md, item 4); the velocities' is estimated."""
    cols = np.full(len(meas.z), -1, dtype=np.int64)
    for c, (name, src) in enumerate(CLOCK_SOURCES):
        if name == "gnss" and settings.long_load_derived:
            continue
        sel = np.isin(meas.source, [SOURCES.index(x) for x in src])
        if sel.sum() >= CLOCK_MIN_MEASUREMENTS:
            cols[sel] = c
    if not np.any(cols >= 0):
        return None
    return cols, np.zeros(len(cols)) if meas.rate is None else meas.rate


def clock_covariance(cols: np.ndarray, normal: np.ndarray
                     ) -> tuple[list[int], np.ndarray, np.ndarray] | None:
    """The clock columns estimated (those with :data:`CLOCK_MIN_MEASUREMENTS` and a positive normal
    equation), the offsets' covariance A^-1 and their Gauss-Newton step A^-1 b from the forward
    pass's normal equations ``normal`` = [A b] (C, C + 1) (:func:`clock_step`); None when none is
    estimated or A is singular."""
    nc = normal.shape[0]
    act = [c for c in range(nc)
           if np.sum(cols == c) >= CLOCK_MIN_MEASUREMENTS and normal[c, c] > 0.0]
    if not act:
        return None
    A = normal[:, :nc][np.ix_(act, act)]
    try:
        cov = np.linalg.inv(A)
    except np.linalg.LinAlgError:
        return None
    if not np.all(np.isfinite(cov)) or np.any(np.diag(cov) <= 0.0):
        return None
    return act, cov, cov @ normal[act, nc]


def clock_step(clock_cols: tuple[np.ndarray, np.ndarray], outputs: tuple[np.ndarray, ...],
               alpha: float, clock: dict[str, float], clock_sd: dict[str, float],
               info: dict[str, Any]) -> tuple[dict[str, float], dict[str, float]]:
    """The clock offsets' Gauss-Newton step jointly with the track (the new offsets and sd
    returned, the step written to ``info``), in seconds added to each source's time stamps (the
    convention of `clean --gnss-clock-offset / --radar-clock-offset`; docs/joint.md, "Filter,
    smoother, iterations", item 4): dc = A^-1 b of the normal equations [A b] the pass's forward
    filter accumulated with the offsets as regression parameters (``outputs``' first;
    :func:`clock_covariance`), A^-1 their covariance.  The step is scaled by the line search's
    ``alpha`` (0 after a Levenberg-Marquardt step: the offsets stay) and taken when it exceeds
    :data:`CLOCK_STILL_SD` of its sd, by an offset still at zero only beyond
    :data:`CLOCK_DETECT_SD` of it."""
    est = clock_covariance(clock_cols[0], outputs[0])
    if est is None:
        return clock, clock_sd
    act, cov, d = est
    clock, clock_sd = dict(clock), dict(clock_sd)
    for i, c in enumerate(act):
        name = CLOCK_SOURCES[c][0]
        sd = float(np.sqrt(cov[i, i]))
        if not np.isfinite(d[i]):
            continue
        clock_sd[name] = sd
        step = float(alpha * d[i])
        detected = clock[name] != 0.0 or abs(step) > CLOCK_DETECT_SD * sd
        if detected and abs(step) > CLOCK_STILL_SD * sd:
            clock[name] += step
        info[f"clock_{name}_s"] = clock[name]
        info[f"clock_{name}_step_s"] = step
    return clock, clock_sd


def stop_reason_of(history: list[dict[str, Any]], settings: JointSettings) -> str:
    """Why the iterations stopped without converging: the line search failed, the cost rose from one
    pass to the next (through the updates between the passes: weights' residuals, clock offsets,
    take-off roll, noise factors), or the cap on the passes was reached."""
    last = history[-1]
    if last.get("line_search_failed"):
        lm = (f", nor a Levenberg-Marquardt step with damping up to {settings.lm_lambda_max:g}"
              if settings.levenberg_marquardt else "")
        return (f"line search failed: no step size down to 1/{2 ** settings.line_search_halvings}"
                f" of the Gauss-Newton step{lm} lowered the MAP cost (the full step moved the "
                f"track by {last['gauss_newton_position_change_m']:.0f} m)")
    if (len(history) > 1 and last.get("parameters_changed")
            and last["cost"] > history[-2]["cost"] * (1.0 + settings.cost_tol)):
        return (f"cost rising: {history[-2]['cost']:.6g} -> {last['cost']:.6g} over the last "
                "pass (the updates between the passes, of the take-off roll, the clock "
                "offsets or the noise factors, raised it)")
    return (f"max passes reached ({len(history)}): the last moved the track by "
            f"{last['max_position_change_m']:.1f} m, the cost by "
            f"{last.get('cost_relative_change', float('nan')):.2g} (relative)")


def innovation_loglik(innov: np.ndarray, innov_var: np.ndarray, sel: np.ndarray) -> float:
    """Log-likelihood of the data by the prediction-error decomposition,
    ``-1/2 sum_j (nu_j^2 / S_j + ln(2 pi S_j))`` over the selected scalar innovations ``nu`` with
    their variances ``S`` (the exact likelihood of the linearised model for the given noise; Harvey
    1989, section 3.4)."""
    ok = sel & np.isfinite(innov) & np.isfinite(innov_var) & (innov_var > 0)
    if not ok.any():
        return float("nan")
    s = innov_var[ok]
    return float(-0.5 * np.sum(innov[ok] ** 2 / s + np.log(2.0 * np.pi * s)))


def _em_noise_scales(groups, res, hph, r0, use, min_count: int = 30) -> dict[int, float]:
    """M-step of expectation-maximisation for one variance factor c per group.

    With z_j = h_j(x) + v_j, v_j ~ N(0, c R0_j), the expected complete-data log-likelihood under the
    smoothed posterior is maximised by c = mean_j[(e_j^2 + H_j P_s H_j^T) / R0_j] over the group's
    measurements (e: smoothed residual; Shumway & Stoffer 1982, eq. 12 for a scalar factor;
    linearised at the smoothed trajectory).  Groups with fewer than ``min_count`` measurements keep
    their factor.
    """
    out = {}
    for gi in np.unique(groups[groups >= 0]):
        sel = (groups == gi) & use & np.isfinite(res) & np.isfinite(hph)
        if sel.sum() >= min_count:
            out[int(gi)] = float(np.mean((res[sel] ** 2 + hph[sel]) / r0[sel]))
    return out


def noise_update(groups: np.ndarray, hph: np.ndarray, r0: np.ndarray, res: np.ndarray,
                  use: np.ndarray, scale: np.ndarray, settings: JointSettings,
                  info: dict[str, Any]) -> tuple[np.ndarray, bool]:
    """EM step of the noise factors (:func:`_em_noise_scales`) on the measurements taken at face
    value (``use``), bounded by ``noise_factor_bounds``; the new factors into ``info``. Returns them
    and whether any moved by more than ``noise_tol``."""
    new_scale = scale.copy()
    lo_b, hi_b = settings.noise_factor_bounds
    for gi, c in _em_noise_scales(groups, res, hph, r0, use).items():
        new_scale[gi] = min(max(c, lo_b), hi_b)   # bounded: no runaway factor
    moved = bool(np.any(np.abs(new_scale / scale - 1.0) > settings.noise_tol))
    info["noise_scale"] = {name: float(new_scale[i]) for i, name in enumerate(NOISE_GROUPS.values())
                           if np.any(groups == i)}
    return new_scale, moved


def gust_sd_estimate(xs: np.ndarray, var: np.ndarray, airborne: np.ndarray) -> float | None:
    """sqrt(mean(u_hat^2 + P_uu)) of the smoothed states ``xs`` and variances ``var`` (N, n) over
    the steps ``airborne`` (N,) (whose air data the smoother uses) and both gust axes; None without
    such a step or with a non-finite value.  The gust is stationary first-order Gauss-Markov of
    variance sigma_u^2 per axis, so E[u_hat^2 + var(u | data)] = sigma_u^2 (law of total variance)
    and sigma_u^2 <- this mean has its fixed point at the flight's own gust variance (the moment
    form of the EM update of a stationary variance; docs/joint.md, "Wind and turbulence")."""
    if not airborne.any():
        return None
    m = float(np.mean(xs[airborne, jl.S_GUST] ** 2 + var[airborne, jl.S_GUST]))
    return float(np.sqrt(m)) if np.isfinite(m) and m > 0 else None


def _covariances(out: PassResult | None) -> None:
    """Wait for the smoothed covariances of ``out`` (a pass whose covariance recursion ran on a
    second thread) and put them in it; its fallback count becomes the larger of the two passes' (and
    so does its entry's in the iterations, ``out.info``)."""
    if out is None or out.pending is None:
        return
    cov = out.pending.result()
    out.pending = None
    out.Pblk, out.var = cov.model.Pblk, cov.model.var
    out.n_fallback = max(out.n_fallback, cov.cholesky_fallbacks)
    if out.info is not None:
        out.info["cholesky_fallbacks"] = out.n_fallback


def _settled(it: int, step: PassStep, cost0: float | None, psi_moved: float, w_change: float,
             params_still: bool, settings: JointSettings, info: dict[str, Any]) -> bool:
    """Convergence test (docs/joint.md): the MAP cost changed by less than ``cost_tol`` (relative),
    the track by less than ``converge_m`` and the heading bias by less than 1e-4 rad (1 m at 10 km)
    in the last pass, no robust weight by more than ``converge_weight``, and the clock offsets and
    noise factors stand still.  A pass whose line search found no lower cost counts as settled only
    if its full Gauss-Newton step was that small too."""
    if it == 0 or cost0 is None:
        return False
    shift = step.gn_shift_m if not step.ok else info["max_position_change_m"]
    new = step.gn_cost if not step.ok else step.cost["cost"]
    rel = abs(cost0 - new) / max(abs(new), 1.0)
    info["cost_relative_change"] = float(rel)
    return bool(rel < settings.cost_tol and shift < settings.converge_m and psi_moved < 1e-4
                and w_change <= settings.converge_weight and params_still)


@dataclass(frozen=True)
class Iterate:
    """What one damped Gauss-Newton pass hands the next, replaced by each pass and never changed:
    the ``nominal`` of the next pass, the clock offsets [s] (added to the stamps) and their sd, the
    noise factor per group (EM), the accepted trajectory ``X`` (None before the first pass), the
    ``models`` built about it and its ``cost`` under them (with the noise factors it was computed
    with: the next pass's start while nothing changed), the IRLS ``weights``, the last accepted
    Levenberg-Marquardt damping / 10, ``refit`` (the models' noise changed: a new cost), the gust sd
    estimates and the take-off rolls of the passes so far (the last pass's last: a roll once left is
    not taken again)."""

    nominal: Nominal
    clock: dict[str, float]
    clock_sd: dict[str, float]
    scale: np.ndarray
    X: np.ndarray | None = None
    models: PassModels | None = None
    cost: tuple[Cost, np.ndarray] | None = None
    weights: np.ndarray | None = None
    lm_lambda: float = 0.0
    refit: bool = False
    gust_rounds: tuple[dict[str, Any], ...] = ()
    rolls_seen: tuple[TakeoffRoll, ...] = ()


@dataclass
class Buffers:
    """The passes' filter buffers (allocated and paged in once, written by every pass), the
    Levenberg-Marquardt pass's own, and the pass whose covariance thread still reads ``bufs``."""

    bufs: tuple[np.ndarray, ...]
    lm: tuple[np.ndarray, ...] | None = None
    running: PassResult | None = None


class Pass(NamedTuple):
    """One pass: its models, smoothing outputs, accepted step and entry in the iterations."""

    models: PassModels
    out: PassResult
    step: PassStep
    info: dict[str, Any]


def _pass_models(fl: SmootherFlight, it: Iterate) -> PassModels:
    """The models of the next pass: about the iterate, with the current clock offsets and the
    take-off roll refined on the iterate (those of the line search's last candidate when they are
    the same).  A refined roll or a clock offset changes the cost function itself, so costs are
    compared across passes only where neither changed (``parameters_changed``).  A roll back at one
    an earlier pass had (a cycle that never settles) is not taken: the last pass's stays
    (docs/joint.md, "Filter, smoother, iterations", "Damping")."""
    nom = it.nominal
    roll = refined_roll(fl.inp, fl.T, nom.vnom, nom.ba_hat)
    if it.rolls_seen and any(roll.same_as(r) for r in it.rolls_seen[:-1]):
        roll = it.rolls_seen[-1]
    if it.models is not None and it.models.clock == it.clock and it.models.roll.same_as(roll):
        return it.models
    return models_at(fl, nom, it.clock, roll)


def _smoothing_pass(fl: SmootherFlight, X: np.ndarray | None, ws: Buffers, mdl: PassModels,
                    r: np.ndarray, weights: np.ndarray, k: int) -> PassResult:
    """Pass ``k``'s forward filter (linearised about the iterate ``X``; None: about its own
    prediction) and RTS backward pass on the buffers, once the last pass's covariance thread, which
    reads them, has finished.  The smoothed covariances: in the backward pass itself where the noise
    estimation needs the smoothed H P H^T (every pass), otherwise from the second pass on (the first
    is far from the solution) on a second thread beside the mean pass, joined when its outputs are
    needed or the buffers are written again (:func:`_covariances`)."""
    s, em = fl.settings, fl.settings.estimate_noise
    assert fl.x0 is not None and fl.P0 is not None
    _covariances(ws.running)
    ws.running = None   # (the last pass's outputs go before this pass's are built)
    scalars = mdl.scalars._replace(r=r, w=weights)
    # the gate in the first pass only (gate_damped off): later IRLS weights, the MAP majoriser
    gate = s.innovation_gate if s.robust and (s.first_gate or k > 0) else 0.0
    if k > 0 and s.line_search and not s.gate_damped:
        gate = 0.0
    cols = clock_columns(mdl.meas, s) if s.estimate_clock else None
    fw = forward(ws.bufs, fl.x0, fl.P0, mdl.dyn, scalars, mdl.geo, gate, X, cols)
    kern_args = (mdl.dyn, scalars._replace(r=r * fw.infl), mdl.geo)
    pending = BackgroundCovariances(ws.bufs, *kern_args) if k > 0 and not em else None
    b = backward(ws.bufs, *kern_args, em)
    m = b.model
    out = PassResult(b.x, m.res, m.rate, m.hph if em else None, fw.infl, fw.nu, fw.S,
                     m.Pblk if em else None, m.var if em else None, b.cholesky_fallbacks,
                     kern_args, scalars, pending,
                     clock=None if cols is None else (cols, (fw.cnorm, fw.cxf, fw.cxp)))
    ws.running = out if pending is not None else None
    return out


def _one_pass(fl: SmootherFlight, it: Iterate, ws: Buffers, k: int
              ) -> tuple[SmootherFlight, Iterate, Pass, bool]:
    """One damped Gauss-Newton pass: models about the iterate, its cost, the smoothing pass, the
    line search (a Levenberg-Marquardt step where it fails), then the updates (:func:`_accepted`).
    Returns the flight (with the prior of x_0 once known, the gust sd changed), the next iterate,
    the pass and whether the iterations settled."""
    s = fl.settings
    mdl = _pass_models(fl, it)
    if fl.x0 is None:
        x0, P0 = initial_estimate(fl.inp, mdl.geo.pnom, s.noise, s.min_airspeed_mps, s.priors)
        fl = replace(fl, x0=x0, P0=P0, P0inv=np.linalg.inv(P0))
    if it.X is None and s.first_pass == "nominal":
        it = replace(it, X=nominal_states(fl, mdl))
    # the nominal variances with the noise factors of their groups
    r = mdl.meas.r * np.where(mdl.groups >= 0, it.scale[np.maximum(mdl.groups, 0)], 1.0)
    weights = it.weights
    reset = weights is None or len(weights) != len(mdl.meas.z)
    weights = np.ones(len(mdl.meas.z)) if weights is None or reset else weights
    # the iterate's cost under the pass's models (None before the first pass; the last accepted
    # one where the models and noise factors are the same); after a reset (a new measurement set:
    # a refined take-off roll) the IRLS weights at the iterate, so that the pass is again a
    # majorise-minimise step (with all weights 1 its Gauss-Newton step need not lower the cost)
    start = None
    if it.X is not None:
        start = (it.cost[0] if mdl is it.models and it.cost is not None
                 and np.array_equal(it.scale, it.cost[1]) else pass_cost(fl, mdl, it.X, r, weights))
        if reset:
            weights = robust_weights(start.res / np.sqrt(r), weights, s)
    cost0 = None if start is None else start.terms["cost"]
    out = _smoothing_pass(fl, it.X, ws, mdl, r, weights, k)
    step = line_search(fl, mdl, it.X, start, out, r, weights)
    lm_lambda = it.lm_lambda
    if not step.ok and s.levenberg_marquardt and start is not None and it.X is not None:
        lm, lm_lambda = lm_step(fl, it.X, ws, mdl, start, r, weights, lm_lambda)
        if lm is not None:
            step = replace(lm, evaluations=step.evaluations + lm.evaluations,
                           gn_shift_m=step.gn_shift_m, gn_cost=step.gn_cost)
    shift = float(np.max(np.abs(step.X[:, jl.S_POS] - mdl.geo.pnom))) if step.ok else 0.0
    changed = it.refit or (it.models is not None and it.cost is not None and (
        it.models.clock != mdl.clock or not it.models.roll.same_as(mdl.roll)
        or not np.array_equal(it.scale, it.cost[1])))
    it = replace(it, weights=weights, lm_lambda=lm_lambda, refit=False)
    info: dict[str, Any] = {"iteration": k, "max_position_change_m": shift,
                            "parameters_changed": bool(changed),
                            "roll_start_t_s": mdl.roll.start_t,
                            "cholesky_fallbacks": out.n_fallback, **step.cost,
                            "cost_start": cost0,
                            "step_size": step.alpha, "lm_lambda": step.lm_lambda,
                            "line_search_evaluations": step.evaluations,
                            "gauss_newton_position_change_m": step.gn_shift_m}
    out.info = info
    psi_from = 0.0 if it.nominal.psi_hat is None else it.nominal.psi_hat
    psi_new = np.ascontiguousarray((step.X if step.ok else out.xs)[:, jl.IPSI])
    psi_moved = float(np.max(np.abs(psi_new - psi_from)))
    info["max_heading_bias_change_deg"] = float(np.degrees(psi_moved))
    info["heading_bias_deg"] = float(np.degrees(step.X[len(fl.T) // 2, jl.IPSI]))
    p = Pass(mdl, out, step, info)
    if not step.ok:
        info["line_search_failed"] = True
        info["gauss_newton_cost"] = step.gn_cost
        return fl, it, p, _settled(k, step, cost0, psi_moved, 0.0, True, s, info)
    return _accepted(fl, it, p, r, cost0, psi_new, psi_moved, shift)


def _accepted(fl: SmootherFlight, it: Iterate, p: Pass, r: np.ndarray, cost0: float | None,
              psi_new: np.ndarray, psi_moved: float, shift: float
              ) -> tuple[SmootherFlight, Iterate, Pass, bool]:
    """After a pass that lowered the cost: the IRLS weights at its residuals, the clock offsets'
    step, the noise factors' EM step, the next iterate about the accepted trajectory, the
    convergence test (:func:`_settled`) and, while not settled and the pass still moved the track
    (or the noise is estimated), the gust sd's round (:func:`gust_round`)."""
    s = fl.settings
    mdl, out, step, info = p
    k = info["iteration"]
    assert it.weights is not None
    w_before = it.weights.copy()
    weights = robust_weights(step.res / np.sqrt(r), it.weights, s)
    clock, clock_sd = it.clock, it.clock_sd
    if out.clock is not None:
        # the offsets' Gauss-Newton step of this pass (a Levenberg-Marquardt step is not it)
        clock, clock_sd = clock_step(*out.clock, step.alpha if step.lm_lambda == 0.0 else 0.0,
                                     clock, clock_sd, info)
    scale, noise_moved = it.scale, False
    if s.estimate_noise:
        # measurements taken at face value in this pass: full weight, not gated
        use = (weights >= 1.0) & (w_before >= 1.0) & (out.infl <= 1.0)
        assert out.hph is not None
        scale, noise_moved = noise_update(mdl.groups, out.hph, mdl.meas.r, step.res, use,
                                          it.scale, s, info)
    X = step.X
    rolls = it.rolls_seen
    if not any(mdl.roll.same_as(r) for r in rolls):
        rolls = (*rolls, mdl.roll)
    m = step.models
    nxt = replace(it, nominal=Nominal(m.lat, m.lon, m.h, X[:, jl.S_VEL], psi_new,
                                      X[:, jl.S_ACC_BIAS]),
                  clock=clock, clock_sd=clock_sd, scale=scale, X=X, models=m,
                  cost=(Cost(step.cost, step.res, step.rate), it.scale), weights=weights,
                  rolls_seen=rolls)
    settled = _settled(k, step, cost0, psi_moved,
                       float(np.max(np.abs(weights - w_before), initial=0.0)),
                       clock == it.clock and not noise_moved, s, info)
    if not settled and (s.estimate_noise or shift > 10.0 * s.converge_m):
        _covariances(out)
        fl, nxt = gust_round(fl, nxt, out, out.xs if full_step(step) else X, k)
    return fl, nxt, p, settled


def _flight_of(problem: JointProblem) -> SmootherFlight:
    """The problem's flight, which must be of its inputs and settings (an adjusted problem is built
    by :func:`~flightrecon.methods.joint.problem.adjusted`, not by replacing a field)."""
    fl = problem.flight
    if fl is None or fl.inp is not problem.inputs or fl.settings is not problem.settings:
        raise ValueError("the joint problem's flight is not that of its inputs and settings "
                         "(build adjusted problems with problem.adjusted)")
    return fl


def smooth_joint(problem: JointProblem) -> JointRun:
    """Solve ``problem``: forward EKF and RTS passes, iterated as damped Gauss-Newton on the MAP
    cost with IRLS weights from the flight's nominal (docs/joint.md, "Filter, smoother,
    iterations").

    The result is the last accepted iterate, the lowest-cost one (each pass's cost does not exceed
    the cost of its start under the same clock offsets, roll and noise factors);
    ``JointRun.converged`` is the test of :func:`_settled` and ``stop_reason`` says why the
    iterations stopped."""
    fl = _flight_of(problem)
    s = fl.settings
    it = Iterate(fl.nominal, {name: 0.0 for name, _ in CLOCK_SOURCES},
                 {name: np.nan for name, _ in CLOCK_SOURCES}, np.ones(len(NOISE_GROUPS)))
    n_iter = max(1, s.iterations, s.noise_iterations if s.estimate_noise else 1)
    return _passes(fl, it, range(n_iter))


def smooth_joint_from(problem: JointProblem, start: JointRun, passes: int = 1,
                      enough_m: float = 0.0) -> JointRun:
    """Solve ``problem`` from a converged run ``start`` of the same flight (its iterate, nominal,
    clock offsets, noise factors and step-0 prior) in at most ``passes`` damped Gauss-Newton passes
    (fewer when they settle, or once a pass moved the track by at most ``enough_m`` [m]: the next
    step is of second order in it): the held-out smoothing of the gap calibration, ``problem`` the
    flight with stretches of GNSS withheld and ``start``'s gust sd held (docs/joint.md, "GNSS gaps",
    item 3).  Each pass is one of :func:`smooth_joint`'s later passes (no innovation gate; IRLS
    weights at the iterate; the line search on the MAP cost), so the result is
    :func:`smooth_joint`'s as far as one Gauss-Newton step from ``start`` reaches."""
    fl = _flight_of(problem)
    if start.prior is not None:
        fl = replace(fl, x0=start.prior[0], P0=start.prior[1], P0inv=np.linalg.inv(start.prior[1]))
    v, psi, ba = (np.ascontiguousarray(start.x[:, c]) for c in (jl.S_VEL, jl.IPSI, jl.S_ACC_BIAS))
    it = Iterate(Nominal(start.lat_deg.copy(), start.lon_deg.copy(), start.h_m.copy(), v, psi, ba),
                 {k: o[0] for k, o in start.clock_offsets_s.items()},
                 {k: o[1] for k, o in start.clock_offsets_s.items()},
                 np.array([start.noise_scale[name] for name in NOISE_GROUPS.values()]), X=start.x,
                 rolls_seen=(start.roll,))
    return _passes(fl, it, range(1, 1 + max(1, passes)), enough_m, warm=True)


def _passes(fl: SmootherFlight, it: Iterate, its: range, enough_m: float = -1.0,
            warm: bool = False) -> JointRun:
    """The damped Gauss-Newton passes numbered ``its`` until they settle (or a pass failed, or one
    moved the track by at most ``enough_m``), then the result of the last."""
    ws = Buffers(filter_buffers(len(fl.T)))
    history: list[dict[str, Any]] = []
    last, converged = None, False
    for k in its:
        last = None   # the last pass's models and outputs go before the next pass builds its own
        fl, it, last, settled = _one_pass(fl, it, ws, k)
        history.append(last.info)
        if settled:
            last.info["converged"] = converged = True
            break
        if not last.step.ok or last.info["max_position_change_m"] <= enough_m:
            break
    reason = ("converged" if converged else
              f"warm start: {len(history)} pass(es) from the converged run" if warm
              else stop_reason_of(history, fl.settings))
    assert last is not None
    return _finish(fl, it, ws, last, history, converged, reason)


def _finish(fl: SmootherFlight, it: Iterate, ws: Buffers, last: Pass,
            history: list[dict[str, Any]], converged: bool, reason: str) -> JointRun:
    """The result of the last pass: its iterate (the pass's own smoothed states after a full step),
    the smoothed covariances of its linearisation with the clock offsets' uncertainty, the noise
    check (the pass redone with the default noise where it fails) and the gust sd used."""
    mdl, out, step, _ = last
    assert it.weights is not None
    _covariances(out)
    ws.running = None
    full = full_step(step)
    fin = out if full else replace(out, xs=step.X, res=step.res)
    if fin.Pblk is None or fin.var is None:
        # smoothed covariances of the last pass (its states equal those of the mean-only pass
        # to round-off: same gains, same linearisation)
        cov = backward(ws.bufs, *out.kern_args, True, False)
        fin = replace(fin, xs=cov.x if full else fin.xs, Pblk=cov.model.Pblk, var=cov.model.var,
                      n_fallback=max(fin.n_fallback, cov.cholesky_fallbacks))
    lat, lon, h = step.models.lat, step.models.lon, step.models.h
    scale, noise_check = it.scale, None
    if fl.settings.estimate_noise:
        noise_check, redo = _noise_check(fl, mdl, out, it, ws)
        if redo is not None:
            fin, scale = redo, np.ones(len(NOISE_GROUPS))
            lat, lon, h = ecef_to_geodetic(fin.xs[:, 0], fin.xs[:, 1], fin.xs[:, 2])
    assert fin.Pblk is not None and fin.var is not None
    # (after a redone pass too: the last pass's columns, as the offsets are the same)
    Pblk, var = _with_clock_uncertainty(out, ws.bufs[1], ws.bufs[3], fin.Pblk, fin.var, it.clock)
    history[-1]["stop_reason"] = reason
    shift = (None if converged or not step.ok else
             np.linalg.norm(step.X[:, jl.S_POS] - mdl.geo.pnom, axis=1))
    return JointRun(t=fl.T, x=fin.xs, P_pv=Pblk, var=var, lat_deg=lat, lon_deg=lon, h_m=h,
                    Cen=mdl.dyn.Cen, meas=mdl.meas, weights=it.weights,
                    resid_norm=fin.res / np.sqrt(fin.scalars.r), innov=fin.innov,
                    innov_var=fin.innov_var,
                    clock_offsets_s={k: (it.clock[k], it.clock_sd[k]) for k in it.clock},
                    noise_scale={name: float(scale[i]) for i, name in
                                 enumerate(NOISE_GROUPS.values())},
                    iterations=history, end_points=mdl.ends,
                    roll=mdl.roll, noise_check=noise_check, cholesky_fallbacks=int(fin.n_fallback),
                    converged=converged, stop_reason=reason,
                    gust={"sd_mps": fl.settings.noise.gust_mps, "rounds": list(it.gust_rounds)},
                    prior=None if fl.x0 is None or fl.P0 is None else (fl.x0, fl.P0),
                    last_shift_m=shift)


def _with_clock_uncertainty(out: PassResult, Pf: np.ndarray, Pp: np.ndarray, Pblk: np.ndarray,
                            var: np.ndarray, clock: dict[str, float]
                            ) -> tuple[np.ndarray, np.ndarray]:
    """The smoothed covariances of the last pass ``out`` (``Pblk`` (N, 6, 6), ``var`` (N, n)) with
    the clock offsets' uncertainty added: the pass smoothed the track given the offsets; with the
    offsets as constant states of covariance Sigma (A^-1 of their normal equations,
    :func:`clock_covariance`) the track's marginal covariance is P_s + X_s,g Sigma X_s,g^T, X_s,g
    the offsets' smoothed filter columns (:func:`smoothed_columns`), over the offsets taken (nonzero
    in ``clock``; an offset held at zero, not detected, is the model's zero: with it the simulated
    GNSS circuits' NEES fell to 0.45 / 0.57, below the 95 % band of 40 runs).  Unchanged without
    such offsets.  (An offset's sd of 5 ms moves a track at 55 m/s by 0.3 m: on a simulated circuit
    with 2 m GNSS fixes that is about the track's own sd.)"""
    if out.clock is None:
        return Pblk, var
    est = clock_covariance(out.clock[0][0], out.clock[1][0])
    if est is None:
        return Pblk, var
    act, cov, _ = est
    keep = [i for i, c in enumerate(act) if clock.get(CLOCK_SOURCES[c][0], 0.0) != 0.0]
    if not keep:
        return Pblk, var
    act, cov = [act[i] for i in keep], cov[np.ix_(keep, keep)]
    _, cxf, cxp = out.clock[1]
    cols = smoothed_columns(cxf[act], cxp[act], Pf, Pp, *out.kern_args)   # (a, N, n)
    # X Sigma X^T per step: its diagonal, and its position-velocity block
    xsig = np.einsum("aki,ab->bki", cols, cov)
    var = var + np.einsum("aki,aki->ki", xsig, cols)
    Pblk = Pblk + np.einsum("aki,akj->kij", xsig[:, :, :6], cols[:, :, :6])
    return Pblk, var


def _noise_check(fl: SmootherFlight, mdl: PassModels, out: PassResult, it: Iterate,
                 ws: Buffers) -> tuple[dict[str, Any], PassResult | None]:
    """The estimated noise must raise the likelihood of the data: the innovations' log-likelihood
    (prediction-error decomposition) of the last pass against a forward pass with the default
    variances at the same linearisation, weights and clock offsets; otherwise the defaults are kept
    and the last pass is redone with them (docs/joint.md, "Noise estimation").  Returns the check
    and, when rejected, the redone pass's outputs."""
    s = fl.settings
    assert fl.x0 is not None and fl.P0 is not None
    lo_b, hi_b = s.noise_factor_bounds
    bufs1 = tuple(np.empty_like(b) for b in ws.bufs)
    # the default variances with the weights the last forward pass ran with
    scalars1 = out.scalars._replace(r=mdl.meas.r.copy())
    fw = forward(bufs1, fl.x0, fl.P0, mdl.dyn, scalars1, mdl.geo,
                 s.innovation_gate if s.robust else 0.0, it.X)
    sel = (scalars1.w >= 1.0) & (out.infl <= 1.0) & (fw.infl <= 1.0)
    ll_est = innovation_loglik(out.innov, out.innov_var, sel)
    ll_def = innovation_loglik(fw.nu, fw.S, sel)
    at_bound = [name for i, name in enumerate(NOISE_GROUPS.values())
                if np.any(mdl.groups == i) and (it.scale[i] <= lo_b or it.scale[i] >= hi_b)]
    accepted = bool(np.isfinite(ll_est) and ll_est > ll_def)
    check = {"loglik_estimated": ll_est, "loglik_default": ll_def, "measurements": int(sel.sum()),
             "accepted": accepted, "factors_at_bound": at_bound, "bounds": [lo_b, hi_b]}
    if accepted:
        return check, None
    kern_args = (mdl.dyn, scalars1._replace(r=scalars1.r * fw.infl), mdl.geo)
    b = backward(bufs1, *kern_args, True)
    m = b.model
    return check, PassResult(b.x, m.res, m.rate, m.hph, fw.infl, fw.nu, fw.S, m.Pblk, m.var,
                             b.cholesky_fallbacks, kern_args, scalars1)


def line_search(fl: SmootherFlight, mdl: PassModels, X: np.ndarray | None, start: Cost | None,
                out: PassResult, r: np.ndarray, weights: np.ndarray) -> PassStep:
    """Backtracking line search along the Gauss-Newton step (Sarkka & Svensson 2020, alg. 3): X +
    alpha (X_GN - X), alpha = 1, 1/2, ... (``line_search_halvings`` times), the first whose MAP cost
    does not exceed the cost of X (``start``; every cost under this pass's clock offsets, roll,
    noise factors).  The first pass (no iterate yet) takes the full step; so does every pass with
    ``line_search`` off (the cost is still evaluated and reported)."""
    s = fl.settings
    X_gn = out.xs
    gn_shift = float(np.max(np.abs(X_gn[:, jl.S_POS] - mdl.geo.pnom)))
    alpha, evals, gn_cost = 1.0, 0, np.nan
    while True:
        Xc = X_gn if alpha == 1.0 or X is None else X + alpha * (X_gn - X)
        mc, Xc, (cost, res, rate) = models_about(fl, Xc, mdl, r, weights)
        evals += 1
        if alpha == 1.0:   # the backward pass's residuals: the undamped iterations unchanged
            res, rate = out.res, out.rate
            gn_cost = cost["cost"]
        step = PassStep(Xc, alpha, cost, mc, res, rate, evals, True, gn_shift, gn_cost)
        if (X is None or start is None or not s.line_search
                or (np.isfinite(cost["cost"]) and cost["cost"] <= start.terms["cost"])):
            return step
        if evals > s.line_search_halvings:
            # no step size lowered the cost: the iterate stays (the lowest-cost one)
            return PassStep(X, 0.0, start.terms, mdl, start.res, start.rate, evals, False,
                            gn_shift, gn_cost)
        del step, mc   # the rejected candidate's models go before the next one's are built
        alpha *= 0.5


def with_pseudo(sc: Scalars, X: np.ndarray, sd: np.ndarray, lam: float) -> Scalars:
    """``sc`` with the Levenberg-Marquardt pseudo-measurements x_k,i = X_k,i of variance sd_i^2 /
    lam appended to every step's measurements (Sarkka & Svensson 2020, section 3: the smoother then
    minimises the linearised cost plus lam/2 sum_k |x_k - X_k|^2_D, D = diag(1/sd^2), the states
    scaled by their prior sd)."""
    N, n = X.shape
    M = len(sc.z)
    step = np.repeat(np.arange(N), np.diff(sc.start))
    start = sc.start + n * np.arange(N + 1)
    pos = np.arange(M) + n * step
    pseudo = ((start[1:] - n)[:, None] + np.arange(n)[None, :]).ravel()

    def put(orig: np.ndarray, extra: np.ndarray | float) -> np.ndarray:
        out = np.empty(M + N * n, dtype=orig.dtype)
        out[pos] = orig
        out[pseudo] = np.broadcast_to(extra, (N, n)).ravel()
        return out

    K = sc.H.shape[0]
    return Scalars(start, put(sc.mtype, jl.LINEAR), put(sc.z, X), put(sc.r, sd ** 2 / lam),
                      put(sc.w, 1.0), put(sc.tau, 0.0), np.vstack([sc.H, np.eye(n)]),
                      put(sc.row, K + np.arange(n)), put(sc.d, 0.0))


def lm_step(fl: SmootherFlight, X: np.ndarray, ws: Buffers, mdl: PassModels, start: Cost,
            r: np.ndarray, weights: np.ndarray, lm_lambda: float) -> tuple[PassStep | None, float]:
    """Levenberg-Marquardt step when the line search failed (Sarkka & Svensson 2020, alg. 2): the
    smoothing pass with the pseudo-measurements of :func:`with_pseudo` about the iterate ``X``,
    lambda from ``lm_lambda0`` (or ten times the last one, ``lm_lambda``) multiplied by 10 until the
    cost does not exceed the iterate's, at most up to ``lm_lambda_max``.  Returns the step (None if
    none did) and the damping to remember (lambda / 10 of the step taken)."""
    s = fl.settings
    if ws.lm is None:  # its own buffers: the plain pass's filter outputs are kept
        ws.lm = tuple(np.empty_like(b) for b in ws.bufs)
    assert fl.x0 is not None and fl.P0 is not None
    sd = np.sqrt(np.diag(fl.P0))
    lam, evals = max(10.0 * lm_lambda, s.lm_lambda0), 0
    while lam <= s.lm_lambda_max:
        sc = with_pseudo(mdl.scalars._replace(r=r, w=weights), X, sd, lam)
        forward(ws.lm, fl.x0, fl.P0, mdl.dyn, sc, mdl.geo, 0.0, X)
        xs = backward(ws.lm, mdl.dyn, sc, mdl.geo, False).x
        mc, Xc, (cost, res, rate) = models_about(fl, xs, mdl, r, weights)
        evals += 1
        if np.isfinite(cost["cost"]) and cost["cost"] <= start.terms["cost"]:
            return PassStep(Xc, 1.0, cost, mc, res, rate, evals, True, np.nan, np.nan,
                            lam), lam / 10.0
        lam *= 10.0
    return None, lm_lambda


def full_step(step: PassStep) -> bool:
    """Whether the accepted iterate is the pass's own smoothed states."""
    return step.ok and step.alpha == 1.0 and step.lm_lambda == 0.0


def with_gust_sd(fl: SmootherFlight, sd_mps: float) -> SmootherFlight:
    """``fl`` with the gust sd ``sd_mps``: in the settings, the process noise and the prior of x_0
    (the rest of the prior, its mean included, unchanged)."""
    noise = replace(fl.settings.noise, gust_mps=float(sd_mps))
    fl = replace(fl, settings=replace(fl.settings, noise=noise), q=q_vector(noise))
    if fl.P0 is None:
        return fl
    P0 = fl.P0.copy()
    P0[jl.S_GUST, jl.S_GUST] = np.eye(2) * float(sd_mps) ** 2
    return replace(fl, P0=P0, P0inv=np.linalg.inv(P0))


def gust_round(fl: SmootherFlight, it: Iterate, out: PassResult, X: np.ndarray, k: int
               ) -> tuple[SmootherFlight, Iterate]:
    """The gust sd re-estimated from the pass's smoothed track ``X`` (``estimate_gust``;
    :func:`gust_sd_estimate`) after a pass that is not the last and moved the
    track by more than 10 ``converge_m`` or estimates the noise factors too (none of its own where
    the GNSS pins the track), recorded in the iterate's ``gust_rounds``; where it moved by more than
    ``gust_tol`` the flight's models take it (:func:`with_gust_sd`) and the next pass starts with
    new models and a new cost (``parameters_changed``).  At most ``gust_rounds`` changes."""
    s = fl.settings
    changes = sum(r["changed"] for r in it.gust_rounds)
    if not s.estimate_gust or out.var is None or changes >= s.gust_rounds:
        return fl, it
    tas = fl.inp.tas[fl.idx]
    est = gust_sd_estimate(X, out.var, np.isfinite(tas) & (tas >= s.min_airspeed_mps))
    if est is None:
        return fl, it
    used = s.noise.gust_mps
    moved = abs(est / used - 1.0) > s.gust_tol
    # over-relaxed in log space (twice the EM step: sd^2 / used): the plain update converges
    # linearly at a rate of 0.55-0.75 here (7 rounds from 2 to 0.54 m/s on the 10-hour
    # benchmark flight); twice the step converges for any rate in (0, 1), at |2 rate - 1|
    nxt = float(np.clip(est * est / used, *s.gust_bounds_mps))
    it = replace(it, gust_rounds=(*it.gust_rounds, {
        "pass": k, "gust_mps": used, "estimate_mps": est, "next_mps": nxt,
        "changed": bool(moved)}))
    if not moved:
        return fl, it
    return with_gust_sd(fl, nxt), replace(it, models=None, cost=None, refit=True)


@dataclass(frozen=True)
class PassStep:
    """The accepted iterate of one pass (after the line search)."""

    X: np.ndarray
    alpha: float
    cost: dict[str, float]
    models: PassModels           # built about X with the pass's clock offsets and roll
    res: np.ndarray
    rate: np.ndarray
    evaluations: int
    ok: bool                  # False: no step lowered the cost (X is the pass's start)
    gn_shift_m: float         # largest position change of the full Gauss-Newton step
    gn_cost: float            # cost at the full Gauss-Newton step
    lm_lambda: float = 0.0    # > 0: a Levenberg-Marquardt step with this damping


def hermite_positions(t_out: np.ndarray, T: np.ndarray, p: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Cubic Hermite interpolation of positions ``p`` (N, 3) with their velocities ``v`` (N, 3) from
    the state times ``T`` (sorted) to ``t_out`` (any order; clamped to the span): error O(dt^4)
    instead of the a dt^2 / 8 of linear interpolation, 0.6 m in a 25-degree turn at a 1 s state
    step."""
    if len(T) < 2:
        return np.repeat(np.asarray(p, float)[:1], len(t_out), axis=0)
    return hermite_kernel(np.asarray(t_out, float), np.asarray(T, float),
                          np.ascontiguousarray(p, dtype=float),
                          np.ascontiguousarray(v, dtype=float))


@nb.njit(cache=True, nogil=True)
def hermite_kernel(t_out, T, p, v):
    """:func:`hermite_positions`' loop, one pass over sorted ``t_out`` (searched again from the
    start where it goes back); numpy's searchsorted and temporaries take ten times as long on a
    10-hour 16 Hz grid."""
    out = np.empty((t_out.shape[0], 3))
    N = T.shape[0]
    k = 0
    for i in range(t_out.shape[0]):
        t = t_out[i]
        if k > 0 and t < T[k]:
            k = 0
        while k < N - 2 and T[k + 1] <= t:
            k += 1
        h = T[k + 1] - T[k]
        s = min(max((t - T[k]) / h if h > 0 else 0.0, 0.0), 1.0)
        s2 = s * s
        s3 = s2 * s
        h00, h10 = 2 * s3 - 3 * s2 + 1, (s3 - 2 * s2 + s) * h
        h01, h11 = -2 * s3 + 3 * s2, (s3 - s2) * h
        for j in range(3):
            out[i, j] = h00 * p[k, j] + h10 * v[k, j] + h01 * p[k + 1, j] + h11 * v[k + 1, j]
    return out


@dataclass(frozen=True)
class JointRun:
    """Result of :func:`smooth_joint` on the state grid."""

    t: np.ndarray
    x: np.ndarray            # smoothed states (N, n)
    P_pv: np.ndarray         # smoothed position-velocity covariance block (ECEF p, NED v)
    var: np.ndarray          # smoothed state variances (N, n)
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    h_m: np.ndarray          # ellipsoidal height
    Cen: np.ndarray
    meas: Measurements
    weights: np.ndarray
    resid_norm: np.ndarray
    innov: np.ndarray
    innov_var: np.ndarray
    clock_offsets_s: dict[str, tuple[float, float]]  # (value, sd): seconds added to the stamps
    noise_scale: dict[str, float]
    iterations: list[dict[str, Any]]
    end_points: tuple[EndPoint, ...]   # as used in the last pass (end_points_at)
    roll: TakeoffRoll                  # the take-off roll of the last pass (refined_roll)
    noise_check: dict[str, Any] | None = None   # estimate_noise: the likelihood check
    cholesky_fallbacks: int = 0  # last pass's steps whose Cholesky failed (general solve)
    # convergence: the test of docs/joint.md ("Filter, smoother, iterations"), and why not
    converged: bool = False
    stop_reason: str = ""
    gust: dict[str, Any] | None = None   # gust sd of the last pass, its estimates (turbulence)
    prior: tuple[np.ndarray, np.ndarray] | None = None   # (x0, P0): the prior of step 0 used
    # the last pass's position change per state [m] when the passes stopped unconverged
    # (settling.settling); None when they converged
    last_shift_m: np.ndarray | None = None

    def positions_ecef(self, t_s: np.ndarray) -> np.ndarray:
        """The smoothed ECEF positions (K, 3) [m] at the times ``t_s``: the states' positions and
        their velocities (NED, rotated to ECEF) interpolated by :func:`hermite_positions`."""
        return hermite_positions(t_s, self.t, self.x[:, jl.S_POS],
                                 np.einsum("kij,kj->ki", self.Cen, self.x[:, jl.S_VEL]))
