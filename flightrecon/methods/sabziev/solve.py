"""The three-axis Sabziev fusion :func:`fuse` (docs/sabziev.md): the vertical axis first, then
north and east with the climb rate in their air-derived velocity, and the cross sensitivities
through it; each axis by :mod:`.axis`."""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from typing import Any

import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.methods.sabziev.axis import (
    KT_MAX,
    checked_samples,
    solve_axis_horizontal,
    solve_axis_y,
)
from flightrecon.methods.sabziev.discrete import (
    StepCoefficients,
    check_grid,
    horizontal_step,
    propagate_path,
)


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
        correction of the policy ``stable``; :attr:`.axis.AxisSolution.end_met`)."""
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
    tas = checked_samples("tas", tas, n)
    psi = checked_samples("heading", heading_rad, n)
    h_rel = checked_samples("baro height", h_rel, n)
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
    the x, y, z :class:`.axis.AxisSolution`; ``air_ne``: the air-derived north and east velocity."""
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
