"""The Sabziev adapter's result (docs/sabziev.md, "The adapter"): the coefficients it resolves,
its self-check, the track on the grid with its sd, and the summary."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from flightrecon.methods.baselines import (
    DR_WALK_MPS_SQRT_S,
    corrected_track_sd_m,
)
from flightrecon.methods.sabziev import SabzievSolution
from flightrecon.methods.sabziev.heights import SCALE_BAND


def self_check(sol: SabzievSolution, t: np.ndarray, h_pressure: np.ndarray, tas: np.ndarray,
               reference: dict[str, Any]) -> list[str]:
    """The fusion's own health (docs/sabziev.md, "Health"): what makes its track impossible.

    * a non-finite position or velocity;
    * a vertical speed above the highest recorded true airspeed plus 30 m/s (the envelope's
      rule, docs/output.md; from the exact velocity of the recursion);
    * a height more than 300 m + 15 % of the pressure height from the recorded pressure height
      (relative to lift-off) for 30 s or more;
    * an end point that the pressure height misses by more than 300 m + 15 % of the end height
      (a wrong arrival elevation, QNH or altitude unit: the vertical then cannot be right);
    * a pressure height that changes faster or slower than the vertical accelerometer says
      (:func:`baro_accelerometer_scale` outside :data:`SCALE_BAND`, when the fit is informative:
      R^2 >= 0.5 and a spread of at least 5 m): an altitude unit error, which the end-point
      check misses on a flight that lands where it took off.

    Returns the problems in words (empty: healthy).
    """
    out: list[str] = []
    if not (np.all(np.isfinite(sol.xyz_m)) and np.all(np.isfinite(sol.vxyz_mps))):
        out.append("non-finite track")
        return out
    vs = float(np.max(np.abs(sol.vxyz_mps[:, 1])))
    vs_lim = float(np.nanmax(tas)) + 30.0
    if vs > vs_lim:
        out.append(f"vertical speed {vs:.0f} m/s beyond the envelope's {vs_lim:.0f}")
    dt = float(t[1] - t[0])
    dev = np.abs(sol.xyz_m[:, 1] - h_pressure)
    bad = dev > 300.0 + 0.15 * np.abs(h_pressure)
    if bad.sum() * dt >= 30.0:
        out.append(f"height up to {float(np.max(dev[bad])):.0f} m from the recorded pressure "
                   f"height for {bad.sum() * dt:.0f} s (tolerance 300 m + 15 %)")
    scale, r2 = reference.get("baro_vs_accelerometer"), reference.get("baro_vs_accelerometer_r2")
    if (scale is not None and r2 is not None and np.isfinite(scale) and r2 >= 0.5
            and reference.get("baro_vs_accelerometer_spread_m", 0.0) >= 5.0
            and not SCALE_BAND[0] <= scale <= SCALE_BAND[1]):
        out.append(f"the pressure height changes {scale:.2f} times as fast as the vertical "
                   "accelerometer says (an altitude unit error: feet read as metres is 3.28)")
    D = reference.get("end_mismatch_m")
    if D is not None and abs(D) > 300.0 + 0.15 * abs(float(sol.xyz_m[-1, 1])):
        out.append(f"the recorded pressure height ends {D:+.0f} m from the end point's height: "
                   "a wrong arrival elevation, QNH or altitude unit")
    return out



K_SD_END_M = 50.0
"""End-point uncertainty [m] behind a fit's conditioning ``k_sd = K_SD_END_M / |dF/dk|``
(summary ``axes.<x|y|z>.k_sd``): the spread of a root that 50 m of end-point uncertainty alone
gives (docs/sabziev.md, "Is k an aircraft property?"); the store weights fleet means by it."""


FIXED_K_REL_SD = 0.5
"""Nominal relative sd given to a fixed stable coefficient taken for an axis without a fleet
coefficient (:func:`resolve_coefficients`), for the track's sd columns: not measured (no fit
of the aircraft says anything about that axis); time constant 10 s +- 5 s."""


def resolve_coefficients(k: tuple[float, float, float] | None, duration_s: float
                         ) -> tuple[tuple[float, float, float] | None, list[str]]:
    """Coefficients for the initial-value mode with a missing (NaN) axis replaced by the stable
    policy's fixed coefficient: ``-1/TAU_FALLBACK_S`` for k1, k3 and ``-w*(T)^2`` for k2
    (:func:`flightrecon.methods.sabziev.axis.vertical_target_w`).

    Parameters
    ----------
    k : (k1, k2, k3), NaN on an axis without a usable fleet coefficient; ``None`` for the
        boundary-value mode (returned unchanged)
    duration_s : length T of the fusion interval [s]

    Returns
    -------
    k, defaulted
        the coefficients to use and the names (``"k1"``...) of the axes replaced
    """
    if k is None:
        return None, []
    from flightrecon.methods.sabziev.axis import TAU_FALLBACK_S, vertical_target_w

    default = (-1.0 / TAU_FALLBACK_S, -vertical_target_w(duration_s) ** 2,
               -1.0 / TAU_FALLBACK_S)
    out, names = [], []
    for i, x in enumerate(k):
        x = float(x)
        if np.isnan(x):
            out.append(default[i])
            names.append(f"k{i + 1}")
        else:
            out.append(x)
    return (out[0], out[1], out[2]), names


def add_conditioning(sol: SabzievSolution, axes: dict[str, Any]) -> None:
    """Add to each axis with a root its end-point sensitivity ``dF_dk`` (exact, the diagonal of
    the sensitivity recursion at the end) and ``k_sd = K_SD_END_M / |dF/dk|``."""
    for name in ("x", "y", "z"):
        ax = sol.axes[name]
        if ax.report is None or not ax.report.converged or ax.fallback:
            continue
        d = float(np.asarray(ax.dposition_dk)[-1])
        axes[name]["dF_dk"] = finite_or_none(d)
        axes[name]["k_sd"] = finite_or_none(K_SD_END_M / abs(d)) if d != 0.0 else None


LIFTOFF_SD_M = 1000.0
"""Horizontal sd [m] of the lift-off point when it is not given (the departure airfield's
reference point stands for it: 1-3 km from the real lift-off point on airfields, 800 m in the
simulator), added in quadrature to the spread from ``k_sd`` in the ``*_sd_m`` columns: without
it the sd is zero at lift-off, which the pipeline's health check rightly refuses."""

LIFTOFF_GIVEN_SD_M = 10.0
"""The same when the lift-off point is given (``liftoff=``)."""


def sabziev_track(t_all, sl, sol: SabzievSolution, k_sd, origin: np.ndarray,
                  origin_sd_m: float = 0.0, plane: Any = None,
                  bridge_sd_m: np.ndarray | None = None) -> pd.DataFrame:
    """The output columns through the one builder (:class:`flightrecon.tracks.TrackColumns`):
    north, east in the output plane, the fusion's height above the departure airfield
    (``sabziev_height_m``) and from it the plane's up, latitude, longitude and ellipsoidal
    height (``plane``: the output plane; without it, no ``up``/``lat``/``lon``/``alt``),
    the velocities; with ``k_sd`` the sd columns, the horizontal ones with ``origin_sd_m`` in
    quadrature; without ``k_sd``, ``bridge_sd_m`` (the covered rows, :func:`bridge_sd`), if
    given, as the north and east sd, after the velocities."""
    from flightrecon.tracks import TrackColumns

    out = TrackColumns("sabziev", t_all, sl)
    # Sabziev order: north (0), up (1), east (2); ``origin`` is (north, east, up)
    offset = (origin[0], origin[2], origin[1])
    pos = [sol.xyz_m[:, j] + offset[j] for j in range(3)]
    psd = vsd = None
    if k_sd is not None:
        psd, vsd = sol.position_sd_m(k_sd), sol.velocity_sd_mps(k_sd)
    for name, j in (("north", 0), ("east", 2)):
        out.add(name, "m", pos[j], None if psd is None else np.hypot(psd[:, j], origin_sd_m))
    if plane is not None:
        out.add_place(plane, pos[2], pos[0], height=pos[1],
                      up_sd=None if psd is None else psd[:, 1])
    for name, j in (("vn", 0), ("ve", 2), ("vu", 1)):
        out.add(name, "mps", sol.vxyz_mps[:, j], None if vsd is None else vsd[:, j])
    if bridge_sd_m is not None and psd is None:
        out.add_sd("north", "m", bridge_sd_m)
        out.add_sd("east", "m", bridge_sd_m)
    return out.frame()


def bridge_sd(t: np.ndarray, start_sd_m: float, end_sd_m: float
              ) -> tuple[np.ndarray, dict[str, Any]]:
    """The horizontal sd [m] at the times ``t`` of a boundary-value track without a fleet
    spread of ``k`` (:func:`sabziev_track` writes it as ``sabziev_north_sd_m`` and
    ``sabziev_east_sd_m``): the stable track is in effect a dead reckoning corrected to both
    ends, and its sd that of :func:`flightrecon.methods.baselines.corrected_track_sd_m` (the
    lift-off point's sd, the end point's, the wind's random walk between them).  Returns the sd
    and the model's summary entry."""
    sd = corrected_track_sd_m(t, float(t[0]), float(t[-1]), start_sd_m, end_sd_m)
    return sd, {"model": "dead reckoning corrected to both ends (fusion.baselines."
                     "corrected_track_sd_m)", "start_sd_m": start_sd_m, "end_sd_m": end_sd_m,
            "wind_walk_mps_sqrt_s": DR_WALK_MPS_SQRT_S, "largest_sd_m": float(np.max(sd))}


def finite_or_none(x: float) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None


def sabziev_summary(sol: SabzievSolution, k, k_sd, t, v0, end_info, warn, hold, rule) -> dict:
    axes = {}
    history = {}
    for name, ax in sol.axes.items():
        if ax.report is None:
            axes[name] = {"converged": True, "k": finite_or_none(ax.k), "mode": "initial-value"}
            continue
        d = ax.report.as_dict()
        history[name] = d.pop("history")
        d["k_used"] = finite_or_none(ax.k)
        d["fallback"] = bool(ax.fallback)
        d["end_correction_m"] = finite_or_none(ax.correction_m)
        axes[name] = d
    res = sol.end_residual_m
    return {
        # the boundary-value problem is solved: each axis has a root, or (policy stable) a
        # finite track whose end miss was removed linearly; roots_found says which
        "converged": all(a.report is None or a.report.converged or (a.fallback and a.end_met)
                         for a in sol.axes.values()),
        "roots_found": bool(sol.converged),
        "fallback_axes": [n for n, a in sol.axes.items() if a.fallback],
        "mode": "initial-value" if k is not None else "boundary-value",
        "k1": finite_or_none(sol.k[0]), "k2": finite_or_none(sol.k[1]),
        "k3": finite_or_none(sol.k[2]),
        "k_sd": None if k_sd is None else [float(x) for x in k_sd],
        "axes": axes,
        "history": history,
        "end_point": end_info,
        "end_residual_m": {"north": finite_or_none(res[0]), "up": finite_or_none(res[1]),
                           "east": finite_or_none(res[2])},
        "interval_s": [float(t[0]), float(t[-1])],
        "liftoff_velocity_ned_mps": [float(x) for x in v0],
        "wind_modelled": bool(sol.wind_modelled),
        "hold": hold,
        "vertical_rule": rule,
        "warnings": warn,
    }
