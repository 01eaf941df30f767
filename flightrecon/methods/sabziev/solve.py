"""Solving the Sabziev fusion: one axis by root search and Newton-Raphson, and the three-axis
fusion :func:`fuse`."""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from typing import Any, NamedTuple

import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.methods.sabziev.discrete import (
    StepCoefficients,
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

# --------------------------------------------------------------------------------------------
# Library API: one axis, and the three-axis fusion
# --------------------------------------------------------------------------------------------
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


def _arr(name: str, x, n: int) -> np.ndarray:
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
    a = _arr(f"{axis} acceleration", a, n)
    w = _arr(f"{axis} reference", w, n)
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


@dataclass(frozen=True)
class SabzievSolution:
    """The fused track in the Sabziev frame (x north, y up, z east; origin at lift-off).

    Attributes
    ----------
    t_s : (N,) grid
    xyz_m : (N, 3) position [x north, y up, z east] relative to the lift-off point [m]
    vxyz_mps : (N, 3) velocity, same axes [m/s]
    k : (k1, k2, k3)
    axes : ``{"x": AxisSolution, "y": ..., "z": ...}``
    cross_dk2_m : (N, 2) the cross terms ``d x / d k2``, ``d z / d k2`` through ``y'`` in the
        air-derived velocity (NaN where an axis has no root)
    cross_dk2_mps : (N, 2) the same for the velocities
    end_residual_m : (3,) end point minus target (NaN where no target was given)
    wind_modelled : whether a wind was added to the air-derived velocity
    warnings : what the caller should show the analyst

    The full Jacobians ``dxyz_dk`` and ``dvxyz_dk`` (N, 3, 3) are assembled on first use (two
    arrays of 72 bytes a sample: 83 MB on a 10-hour 16 Hz flight, needed only for ``k_sd``).
    """

    t_s: np.ndarray
    xyz_m: np.ndarray
    vxyz_mps: np.ndarray
    k: tuple[float, float, float]
    axes: dict
    cross_dk2_m: np.ndarray
    cross_dk2_mps: np.ndarray
    end_residual_m: np.ndarray
    wind_modelled: bool
    warnings: tuple[str, ...] = ()

    def _jacobian(self, own: str, cross: np.ndarray) -> np.ndarray:
        n = len(self.t_s)
        d = np.zeros((n, 3, 3))
        for i, name in enumerate(("x", "y", "z")):
            d[:, i, i] = getattr(self.axes[name], own)
        d[:, 0, 1] = cross[:, 0]
        d[:, 2, 1] = cross[:, 1]
        return d

    @cached_property
    def dxyz_dk(self) -> np.ndarray:
        """(N, 3, 3) ``d xyz[:, i] / d k[j]`` (``k = (k1, k2, k3)``): own-axis terms from the
        sensitivity recursion, and the cross terms ``d x / d k2``, ``d z / d k2`` through
        ``y'`` in the air-derived velocity; ``d y / d k1 = d y / d k3 = 0``."""
        return self._jacobian("dposition_dk", self.cross_dk2_m)

    @cached_property
    def dvxyz_dk(self) -> np.ndarray:
        """(N, 3, 3) as :attr:`dxyz_dk` for the velocity."""
        return self._jacobian("dvelocity_dk", self.cross_dk2_mps)

    @property
    def converged(self) -> bool:
        """All three axes found a root (True in the initial-value mode)."""
        return all(a.report is None or a.report.converged for a in self.axes.values())

    @property
    def end_met(self) -> bool:
        """All three axes have a finite track meeting the end point (a root, or the linear
        correction of the policy ``stable``; :attr:`AxisSolution.end_met`)."""
        return all(a.end_met for a in self.axes.values())

    @property
    def north_m(self) -> np.ndarray:
        return self.xyz_m[:, 0]

    @property
    def up_m(self) -> np.ndarray:
        return self.xyz_m[:, 1]

    @property
    def east_m(self) -> np.ndarray:
        return self.xyz_m[:, 2]

    def position_sd_m(self, k_sd) -> np.ndarray:
        """First-order standard deviation (N, 3) of the track for independent ``k`` spreads.

        ``var(xyz_i) = sum_j (d xyz_i / d k_j)^2 k_sd_j^2`` (linearisation; on the oscillatory
        vertical branch it holds only while ``k_sd`` is small against the root spacing).
        """
        sd = np.asarray(k_sd, dtype=np.float64)
        if sd.shape != (3,) or np.any(sd < 0) or not np.all(np.isfinite(sd)):
            raise ValidationError("k_sd must be three finite non-negative numbers")
        return np.sqrt(np.einsum("nij,j->ni", self.dxyz_dk**2, sd**2))

    def velocity_sd_mps(self, k_sd) -> np.ndarray:
        """As :meth:`position_sd_m` for the velocity."""
        sd = np.asarray(k_sd, dtype=np.float64)
        if sd.shape != (3,) or np.any(sd < 0) or not np.all(np.isfinite(sd)):
            raise ValidationError("k_sd must be three finite non-negative numbers")
        return np.sqrt(np.einsum("nij,j->ni", self.dvxyz_dk**2, sd**2))


def air_velocity(tas, heading_rad, climb_rate, wind_ne=None) -> tuple[np.ndarray, np.ndarray]:
    """Air-derived horizontal velocity (north, east) of docs/sabziev.md.

    ``v_x = sqrt(max(v^2 - y'^2, 0)) cos(psi) + W_N``, ``v_z = sqrt(max(v^2 - y'^2, 0)) sin(psi)
    + W_E`` with the wind (north, east components of where it blows *to*) when given.
    """
    v_h = np.sqrt(np.maximum(np.asarray(tas) ** 2 - np.asarray(climb_rate) ** 2, 0.0))
    vn = v_h * np.cos(heading_rad)
    ve = v_h * np.sin(heading_rad)
    if wind_ne is not None:
        vn = vn + wind_ne[:, 0]
        ve = ve + wind_ne[:, 1]
    return vn, ve


def fuse(t, a_ned, tas, heading_rad, h_rel, v0_ned, end_ned=None, wind_ne=None, k=None, *,
         k0=None, hold: str = "linear", tol_m: float = 1e-3, max_iter: int = 60,
         parametrisation: str = "k", kt_max: float = KT_MAX, strict: bool = False,
         vertical_rule: str = "baro", policy: str = "paper") -> SabzievSolution:
    """Sabziev boundary-value fusion of loads, airspeed, heading and baro height (docs/sabziev.md).

    Solves the vertical axis first (k2), then north (k1) and east (k3), which need ``y'``.

    Parameters
    ----------
    t : (N,) uniform grid [s] from lift-off to the arrival
    a_ned : (N, 3) kinematic acceleration north, east, down [m/s^2]
        (``a_x = a_N``, ``a_y = -a_D``, ``a_z = a_E``)
    tas : (N,) true airspeed [m/s]
    heading_rad : (N,) true heading [rad] (unwrapped is fine)
    h_rel : (N,) baro height relative to the lift-off point [m]
    v0_ned : (3,) ground velocity at lift-off, north, east, down [m/s]
    end_ned : (3,) arrival point relative to the lift-off point, north, east, down [m];
        required unless ``k`` is given
    wind_ne : (N, 2) wind velocity (where it blows *to*) north, east [m/s], or None
        (then the result warns "wind unmodelled")
    k : (k1, k2, k3) for the initial-value mode (no end point needed)
    k0 : start values (k1, k2, k3) of the iterations, or None for the defaults
    hold, tol_m, max_iter, parametrisation, kt_max, strict : as :func:`solve_axis_y`
        (``parametrisation`` applies to k2 only, like the paper)
    vertical_rule : root selection for k2 (``rule`` of :func:`solve_axis_y`, policy ``paper``)
    policy : :data:`POLICIES` (``paper`` here for the library; the adapter uses ``stable``)

    Returns
    -------
    SabzievSolution
    """
    t = np.asarray(t, dtype=np.float64)
    dt = check_grid(t)
    n = len(t)
    a_ned, tas, psi, h_rel, v0, wind_ne, warn = _fuse_inputs(t, a_ned, tas, heading_rad, h_rel,
                                                             v0_ned, wind_ne)
    targets, ks, end = _end_or_coefficients(end_ned, k)
    starts = (None, None, None) if k0 is None else tuple(k0)
    common: dict[str, Any] = {"hold": hold, "tol_m": tol_m, "max_iter": max_iter,
                              "kt_max": kt_max, "strict": strict, "policy": policy}
    ax_y = solve_axis_y(t, -a_ned[:, 2], h_rel, -v0[2], targets[1], k=ks[1], k0=starts[1],
                        parametrisation=parametrisation, rule=vertical_rule, **common)
    if np.all(np.isfinite(ax_y.velocity_mps)):
        climb = ax_y.velocity_mps
        dclimb = ax_y.dvelocity_dk
    else:
        climb = np.gradient(h_rel, dt)
        dclimb = np.zeros(n)
        warn.append("vertical axis has no root: the climb rate in the air-derived velocity is "
                    "taken from the baro height instead")
    vn, ve = air_velocity(tas, psi, climb, wind_ne)
    ax_x = solve_axis_horizontal(t, a_ned[:, 0], vn, v0[0], targets[0], k=ks[0], k0=starts[0],
                                 axis="x (north)", **common)
    ax_z = solve_axis_horizontal(t, a_ned[:, 1], ve, v0[1], targets[2], k=ks[2], k0=starts[2],
                                 axis="z (east)", **common)
    cross, dcross = _cross_sensitivities(dt, hold, a_ned, tas, psi, v0, climb, dclimb,
                                         (ax_x, ax_y, ax_z), (vn, ve))
    xyz = np.column_stack([ax_x.position_m, ax_y.position_m, ax_z.position_m])
    vxyz = np.column_stack([ax_x.velocity_mps, ax_y.velocity_mps, ax_z.velocity_mps])
    res = np.full(3, np.nan)
    if end is not None:
        res = xyz[-1] - np.array([end[0], -end[2], end[1]])
    return SabzievSolution(t, xyz, vxyz, (ax_x.k, ax_y.k, ax_z.k), {"x": ax_x, "y": ax_y,
                           "z": ax_z}, cross, dcross, res, wind_ne is not None, tuple(warn))


def _fuse_inputs(t, a_ned, tas, heading_rad, h_rel, v0_ned, wind_ne):
    """:func:`fuse`'s inputs checked and as float arrays; the warning when there is no wind."""
    n = len(t)
    a_ned = np.asarray(a_ned, dtype=np.float64)
    if a_ned.shape != (n, 3):
        raise ValidationError(f"a_ned must have shape ({n}, 3), got {a_ned.shape}")
    tas = _arr("tas", tas, n)
    psi = _arr("heading", heading_rad, n)
    h_rel = _arr("baro height", h_rel, n)
    v0 = np.asarray(v0_ned, dtype=np.float64)
    if v0.shape != (3,) or not np.all(np.isfinite(v0)):
        raise ValidationError("v0_ned must be three finite numbers")
    warn: list[str] = []
    if wind_ne is not None:
        wind_ne = np.asarray(wind_ne, dtype=np.float64)
        if wind_ne.shape != (n, 2) or not np.all(np.isfinite(wind_ne)):
            raise ValidationError(f"wind_ne must be finite with shape ({n}, 2)")
    else:
        warn.append("wind unmodelled: no wind channel, the air-derived velocity is used as "
                    "ground velocity and k1, k3 absorb the drift")
    return a_ned, tas, psi, h_rel, v0, wind_ne, warn


def _end_or_coefficients(end_ned, k):
    """Boundary-value mode (the end point's (x, y, z) targets) or initial-value mode (the
    coefficients); returns ``(targets, ks, end)``, each axis ``None`` where not given."""
    if k is None:
        if end_ned is None:
            raise ValidationError("give the arrival point (end_ned) or the coefficients k")
        end = np.asarray(end_ned, dtype=np.float64)
        if end.shape != (3,) or not np.all(np.isfinite(end)):
            raise ValidationError("end_ned must be three finite numbers")
        return (end[0], -end[2], end[1]), (None, None, None), end
    ks = tuple(float(x) for x in k)
    if len(ks) != 3 or not all(np.isfinite(ks)):
        raise ValidationError("k must be three finite numbers (k1, k2, k3)")
    return (None, None, None), ks, None if end_ned is None else np.asarray(end_ned,
                                                                         dtype=np.float64)


def _cross_sensitivities(dt, hold, a_ned, tas, psi, v0, climb, dclimb, axes, air_ne):
    """Cross sensitivities d(x, z)/d k2 through y' in ``sqrt(v^2 - y'^2)`` and their
    derivatives (NaN where an axis has no coefficient); each (N, 2) for (x, z).  ``axes``:
    the x, y, z :class:`AxisSolution`; ``air_ne``: the air-derived north and east velocity."""
    ax_x, ax_y, ax_z = axes
    vn, ve = air_ne
    n = len(tas)
    v_h2 = tas**2 - climb**2
    with np.errstate(divide="ignore", invalid="ignore"):
        dvh = np.where(v_h2 > 0, -climb * dclimb / np.sqrt(np.where(v_h2 > 0, v_h2, 1.0)), 0.0)
    cross = np.zeros((n, 2))
    dcross = np.zeros((n, 2))
    for i, ax, a_col, v_col, trig in ((0, ax_x, 0, vn, np.cos(psi)), (1, ax_z, 1, ve, np.sin(psi))):
        if not (np.isfinite(ax.k) and np.isfinite(ax_y.k)):
            cross[:, i] = np.nan
            dcross[:, i] = np.nan
            continue
        c = horizontal_step(ax.k, dt, hold)
        zero = StepCoefficients(c.Phi, np.zeros((2, 2)), c.G0, np.zeros(2), c.G1, np.zeros(2))
        u = a_ned[:, a_col] - ax.k * v_col
        _, S = propagate_path(zero, (0.0, v0[a_col]), u, dvh * trig, 0.0, dscale=ax.k)
        cross[:, i] = S[:, 0]
        dcross[:, i] = S[:, 1]
        if ax.fallback:  # the linear end correction removes the end value's sensitivity too
            frac = np.arange(n) / (n - 1)
            cross[:, i] -= frac * S[-1, 0]
            dcross[:, i] -= S[-1, 0] / ((n - 1) * dt)
    return cross, dcross
