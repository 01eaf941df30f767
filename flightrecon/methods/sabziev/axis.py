"""One Sabziev axis: the coefficient by root search (or given) and the axis's track with its
exact sensitivity to the coefficient (docs/sabziev.md; seed 001 equations (1)-(4) for the
vertical axis, section IV for the horizontal ones), under the ``paper`` or the ``stable``
policy (:data:`POLICIES`).  The three-axis fusion that calls it is :mod:`.solve`'s."""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.methods.sabziev.discrete import (
    check_grid,
    check_hold,
    horizontal_step,
    propagate_end,
    propagate_end_many,
    propagate_path,
    vertical_step,
)
from flightrecon.methods.sabziev.nearest import find_root_near
from flightrecon.methods.sabziev.newton import find_coefficient
from flightrecon.methods.sabziev.roots import RootReport

KT_MAX = 25.0
"""Overflow guard: positive-branch coefficients are limited to ``k T <= KT_MAX`` (horizontal)
and ``sqrt(k2) T <= KT_MAX`` (vertical).  Beyond that the solution weights the lift-off data by
more than e^25 ~ 7e10 and rounding alone moves a 100 km end point by metres: such a "root"
cannot be resolved (found on simulated flights at k T ~ 44: residual 8e6 m)."""

POINTS_PER_DECADE = 12
"""Scan density of the root search in |k| (:mod:`flightrecon.methods.sabziev.newton`, step 3)."""

POLICIES = ("stable", "paper")
"""How a coefficient is chosen (docs/sabziev.md, "Root finding"): ``stable`` searches the
stable range only (k1, k3 < 0; k2 < 0 by the ``nearest`` rule) and, where ``F`` has no root
there, takes a fixed stable coefficient and removes the remaining end miss linearly in time;
``paper`` searches both branches and leaves an axis without a root NaN."""

TAU_FALLBACK_S = 10.0
"""Time constant [s] of the horizontal complementary filter (``k = -1/TAU_FALLBACK_S``) taken
when ``F`` has no root on the stable branch (policy ``stable``): short enough that attitude
errors in high-g manoeuvres (spiral dives) do not accumulate into velocity errors (``b tau``),
long enough to smooth the air data with the accelerometers.  Measured on the corpus and JSBSim
flights (docs/sabziev.md): with 10 s the worst flight was 1.23 times dead reckoning with a
linear end correction, with 30 s 1.67 (a spiral dive)."""

TAU_MAX_S = 100.0
"""Slowest horizontal time constant [s] accepted as a root (policy ``stable``): the velocity
error a constant accelerometer error ``b`` leaves in the complementary filter is ``b tau``,
2 m/s for 2 mg at 100 s, the size of the air-data velocity errors (1 % of 200 m/s); a slower
root makes the track mostly inertial (measured, docs/sabziev.md: roots of 170-800 s gave 1.8
to 2.7 times the error of dead reckoning with a linear end correction)."""

W_LIMITS = (0.05, 0.5)
"""Bounds [rad/s] of the target loop frequency of the vertical axis (:func:`vertical_target_w`)."""

ACC_BIAS_NOMINAL = 0.02
"""Nominal vertical accelerometer error [m/s^2] (2 mg) of :func:`vertical_target_w`."""

BARO_NOISE_NOMINAL_M = 1.0
"""Nominal noise of the pressure height [m], correlated over :data:`BARO_NOISE_TIME_S`."""

BARO_NOISE_TIME_S = 0.2
"""Correlation time [s] of the pressure height noise (a 5 Hz channel's sample interval)."""


def vertical_target_w(T: float) -> float:
    """Target frequency [rad/s] of the undamped baro-inertial loop (policy ``stable``).

    Error of the loop ``e'' + w^2 e = b + w^2 n`` over a flight of length ``T``: a constant
    accelerometer error ``b`` gives ``|e| <= 2 b / w^2``; white pressure-height noise of
    standard deviation ``sigma`` and correlation time ``tau`` excites the undamped loop at its
    own frequency, ``rms(e) ~ w sigma sqrt(tau T / 2)``.  The sum is smallest at
    ``w* = (4 b / (sigma sqrt(tau T / 2)))^(1/3)``; with the nominal ``b``
    (:data:`ACC_BIAS_NOMINAL`), ``sigma``, ``tau`` that is 0.20 rad/s at ``T`` = 900 s and
    0.11 rad/s at 10 h, clipped to :data:`W_LIMITS`.

    Parameters
    ----------
    T : duration of the fusion interval [s]
    """
    noise = BARO_NOISE_NOMINAL_M * np.sqrt(BARO_NOISE_TIME_S * max(T, 1.0) / 2.0)
    w = (4.0 * ACC_BIAS_NOMINAL / noise) ** (1.0 / 3.0)
    return float(np.clip(w, *W_LIMITS))


@dataclass(frozen=True)
class AxisSolution:
    """Solution of one Sabziev axis on the grid.

    Attributes
    ----------
    k : the coefficient used (NaN if the boundary-value problem has no root)
    position_m, velocity_mps : (N,) track and rate along the axis (NaN if no root)
    dposition_dk, dvelocity_dk : (N,) exact sensitivities of the discrete track to ``k``
    report : root-finder report (``None`` in the initial-value mode, ``k`` given)
    correction_m : end miss [m] of the track with ``k`` removed linearly in time (policy
        ``stable`` when ``F`` has no root in the stable range; 0 otherwise): the track is
        ``s(k, t) - correction_m (t - t_0)/T``
    """

    k: float
    position_m: np.ndarray
    velocity_mps: np.ndarray
    dposition_dk: np.ndarray
    dvelocity_dk: np.ndarray
    report: RootReport | None = None
    correction_m: float = 0.0

    fallback: bool = False

    @property
    def end_met(self) -> bool:
        """A finite track (meeting the end point when one was given: a root, or the linear
        correction of the policy ``stable``)."""
        return bool(np.isfinite(self.k) and np.all(np.isfinite(self.position_m)))


def checked_samples(name: str, x, n: int) -> np.ndarray:
    a = np.ascontiguousarray(np.asarray(x, dtype=np.float64))
    if a.shape != (n,):
        raise ValidationError(f"{name} must have shape ({n},), got {a.shape}")
    if not np.all(np.isfinite(a)):
        bad = np.flatnonzero(~np.isfinite(a))
        raise ValidationError(f"{name} has non-finite values (first at sample {bad[0]}): fill or "
                              "cut gaps before the fusion")
    return a


class _AxisOptions(NamedTuple):
    """Numerical options of one axis (:func:`solve_axis_y` documents each)."""

    hold: str
    tol_m: float
    max_iter: int
    parametrisation: str
    kt_max: float
    strict: bool
    rule: str = "slowest"
    policy: str = "paper"


def _solve_axis(kind: str, t, a, w, v0: float, s_T: float | None, k: float | None,
                k0: float | None, opts: _AxisOptions, axis: str) -> AxisSolution:
    hold, tol_m, max_iter, parametrisation, kt_max, strict, rule, policy = opts
    if policy not in POLICIES:
        raise ValidationError(f"policy must be one of {POLICIES}, got {policy!r}")
    dt = check_grid(t)
    n = len(t)
    a = checked_samples(f"{axis} acceleration", a, n)
    w = checked_samples(f"{axis} reference", w, n)
    check_hold(hold)
    step = vertical_step if kind == "vertical" else horizontal_step
    T = dt * (n - 1)
    report = None
    if k is None:
        if s_T is None or not np.isfinite(s_T):
            raise ValidationError(f"{axis} axis: give the end point or the coefficient k")

        def fun(kk: float) -> tuple[float, float, float]:
            q, s, misfit = propagate_end(step(kk, dt, hold), (0.0, v0), a, w, kk)
            return float(q[0]) - s_T, float(s[0]), misfit

        def fun_many(kks: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
            # the scan: same F and misfit as fun, all k in one pass over the data
            q, misfit = propagate_end_many(kind, kks, dt, (0.0, v0), a, w, hold=hold)
            return q[:, 0] - s_T, misfit

        if kind == "vertical":
            k_ref, k_pos, k_neg = T**-2, (kt_max / T) ** 2, (0.5 / dt) ** 2
        else:
            k_ref, k_pos, k_neg = 1.0 / T, kt_max / T, 1.0 / dt
        if policy == "stable":
            return _solve_stable(kind, t, a, w, v0, s_T, fun, fun_many, opts, axis,
                                 (k_ref, k_neg))
        report = find_coefficient(fun, k_ref=k_ref, k_max_pos=k_pos, k_max_neg=k_neg, k0=k0,
                                  tol_m=tol_m, max_iter=max_iter,
                                  points_per_decade=POINTS_PER_DECADE, fun_many=fun_many,
                                  parametrisation=parametrisation, strict=strict, axis=axis,
                                  rule=rule if kind == "vertical" else "slowest")
        if not report.converged:
            nan = np.full(n, np.nan)
            return AxisSolution(float("nan"), nan, nan.copy(), nan.copy(), nan.copy(), report)
        k = report.root
    k = float(k)
    if not np.isfinite(k):
        raise ValidationError(f"{axis} axis: coefficient k must be finite")
    Q, S = propagate_path(step(k, dt, hold), (0.0, v0), a, w, k)
    return AxisSolution(k, Q[:, 0], Q[:, 1], S[:, 0], S[:, 1], report)


def _solve_stable(kind: str, t, a, w, v0: float, s_T: float, fun, fun_many,
                  opts: _AxisOptions, axis: str, scales: tuple[float, float]) -> AxisSolution:
    """Policy ``stable`` (docs/sabziev.md, "Root finding"): a root in the stable range, else a
    fixed stable coefficient with its end miss removed linearly in time.

    Horizontal: the slowest root on the negative branch (:func:`find_coefficient` with
    ``branches=("negative",)``); none: ``k = -1/TAU_FALLBACK_S``.  Vertical: the root nearest
    the target loop frequency :func:`vertical_target_w` (:func:`find_root_near`, scanned in
    quarter root spacings ``pi/(4T)``); none: ``k2 = -w*^2``.  The corrected track
    ``s(k, t) - r (t - t_0)/T`` (``r`` the end miss) meets the end point exactly; its
    sensitivity to ``k`` is ``ds/dk - (t - t_0)/T ds_N/dk``.
    """
    hold, tol_m, max_iter, _p, _kt, _strict, _rule, _policy = opts
    dt = float(t[1] - t[0])
    T = float(t[-1] - t[0])
    k_ref, k_neg = scales
    span_lo = max(1e-2, 1.0 / (TAU_MAX_S * k_ref))
    if kind == "vertical":
        w_t = vertical_target_w(T)
        w_hi = min(3.0 * w_t, 0.5 / dt)
        report = find_root_near(fun, w_target=min(w_t, w_hi), w_step=np.pi / (4.0 * T),
                                w_lo=w_t / 3.0, w_hi=w_hi, tol_m=tol_m, max_iter=max_iter,
                                fun_many=fun_many, axis=axis)
        k_fb = -min(w_t, w_hi) ** 2
    else:
        report = find_coefficient(fun, k_ref=k_ref, k_max_pos=k_ref, k_max_neg=k_neg,
                                  tol_m=tol_m, max_iter=max_iter, span_lo=span_lo,
                                  k0=-3.0 * max(k_ref, 1.0 / TAU_MAX_S),
                                  points_per_decade=POINTS_PER_DECADE, fun_many=fun_many,
                                  axis=axis, branches=("negative",))
        if report.converged and abs(report.root) * TAU_MAX_S < 1.0:
            report = replace(report, converged=False, branch="none", reason=(
                f"no root taken: the only root, k = {report.root:.4g} 1/s (time constant "
                f"{-1.0 / report.root:.0f} s), is slower than the {TAU_MAX_S:.0f} s limit: "
                "not taken"))
        k_fb = -1.0 / TAU_FALLBACK_S
    k = report.root if report.converged else k_fb
    coef = vertical_step(k, dt, hold) if kind == "vertical" else horizontal_step(k, dt, hold)
    Q, S = propagate_path(coef, (0.0, v0), a, w, k)
    if report.converged:
        return AxisSolution(k, Q[:, 0], Q[:, 1], S[:, 0], S[:, 1], report)
    # no root taken is not a failure of this policy (the track meets the end point and says
    # how): ``strict`` does not raise here, it raises where the paper policy leaves no track
    miss = float(Q[-1, 0] - s_T)
    frac = (t - t[0]) / T
    pos = Q[:, 0] - miss * frac
    vel = Q[:, 1] - miss / T
    dpos = S[:, 0] - frac * S[-1, 0]
    dvel = S[:, 1] - S[-1, 0] / T
    return AxisSolution(k, pos, vel, dpos, dvel, report, miss, True)


def solve_axis_y(t, a_y, h, y0: float, y_T: float | None = None, *, k: float | None = None,
                 k0: float | None = None, hold: str = "linear", tol_m: float = 1e-3,
                 max_iter: int = 60, parametrisation: str = "k", kt_max: float = KT_MAX,
                 strict: bool = False, rule: str = "baro",
                 policy: str = "paper") -> AxisSolution:
    """Vertical axis: ``y'' - k2 y = a_y - k2 h``, ``y(0) = 0``, ``y'(0) = y0``, ``y(T) = y_T``.

    docs/sabziev.md; seed 001 equations (1)-(4).  Either ``y_T`` (boundary-value mode:
    ``k2`` by :func:`flightrecon.methods.sabziev.newton.find_coefficient`) or ``k``
    (initial-value mode).

    Parameters
    ----------
    t : (N,) uniform time grid [s], from lift-off (only differences matter)
    a_y : (N,) vertical (up) kinematic acceleration [m/s^2]
    h : (N,) baro(-inertial) height relative to the lift-off point [m]
    y0 : vertical velocity at lift-off [m/s]
    y_T : end height relative to the lift-off point [m]
    k : k2 [1/s^2] for the initial-value mode
    k0 : start value of the iteration (``alpha`` for ``parametrisation="alpha"``)
    hold : input hold between samples, ``"linear"`` or ``"zero"``
    tol_m : end-point tolerance [m]
    max_iter : iteration cap per phase
    parametrisation : ``"k"`` or the paper's ``"alpha"``
    kt_max : overflow guard (:data:`KT_MAX`)
    strict : raise ConvergenceError when no root is found
    rule : root selection on the oscillatory negative branch: ``"baro"`` (default; the root
        whose track stays closest to ``h`` in RMS) or ``"slowest"`` (smallest ``w``);
        :mod:`flightrecon.methods.sabziev.newton`, step 4 (policy ``paper``)
    policy : ``"paper"`` (both branches; NaN without a root) or ``"stable"`` (the root nearest
        :func:`vertical_target_w` on the stable branch, else ``k2 = -w*^2`` with the end miss
        removed linearly in time; :data:`POLICIES`, :func:`_solve_stable`)
    """
    opts = _AxisOptions(hold, tol_m, max_iter, parametrisation, kt_max, strict, rule, policy)
    return _solve_axis("vertical", t, a_y, h, float(y0), y_T, k, k0, opts, "y (vertical)")


def solve_axis_horizontal(t, a, v_air, v0: float, s_T: float | None = None, *,
                          k: float | None = None, k0: float | None = None,
                          hold: str = "linear", tol_m: float = 1e-3, max_iter: int = 60,
                          kt_max: float = KT_MAX, strict: bool = False,
                          axis: str = "horizontal", policy: str = "paper") -> AxisSolution:
    """Horizontal axis: ``s'' - k s' = a - k v_air``, ``s(0) = 0``, ``s'(0) = v0``, ``s(T) = s_T``.

    docs/sabziev.md; seed 001 section IV (x with k1, z with k3).

    Parameters
    ----------
    t : (N,) uniform time grid [s]
    a : (N,) kinematic acceleration along the axis [m/s^2]
    v_air : (N,) air-derived velocity along the axis (wind added where known) [m/s]
    v0 : velocity along the axis at lift-off [m/s]
    s_T : end coordinate relative to the lift-off point [m]
    k : coefficient [1/s] for the initial-value mode
    k0, hold, tol_m, max_iter, kt_max, strict, policy : as :func:`solve_axis_y` (policy
        ``stable``: the slowest negative root, else ``k = -1/TAU_FALLBACK_S`` corrected)
    axis : name for messages
    """
    opts = _AxisOptions(hold, tol_m, max_iter, "k", kt_max, strict, "slowest", policy)
    return _solve_axis("horizontal", t, a, v_air, float(v0), s_T, k, k0, opts, axis)
