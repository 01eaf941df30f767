"""Method adapter: the Sabziev boundary-value fusion on a cleaned flight.

:func:`run_sabziev` takes a :class:`flightrecon.types.CleanFlight`, builds the inputs of
:func:`flightrecon.methods.sabziev.fuse` (docs/sabziev.md) and returns a
:class:`flightrecon.types.MethodResult` with ``sabziev_``-prefixed columns.  The practical
choices the paper leaves open are documented in docs/sabziev.md, "The adapter":

* Interval: lift-off to touchdown from ``clean.phases``; a record cut in the air starts (ends)
  at its first (last) sample, and the departure (arrival) position is then taken as the given
  point.  The lift-off point is the departure position (origin of the output tangent plane)
  unless given (``liftoff``); the arrival point can be overridden (``arrival``: the touchdown
  point rather than the airfield reference point, 1-3 km apart).
* Horizontal end point: the arrival position in the output tangent plane
  (:func:`flightrecon.geo.frames.output_plane`, east-north-up at the departure airfield).
* Vertical, in pressure terms: the pressure altitude of an airfield of elevation ``E`` under
  sea-level pressure ``QNH`` is ``H_p(E, QNH) = pressure_altitude(p_ISA(E) * QNH / 1013.25)``
  (the ISA profile scaled to the QNH; about ``E - 8.3 m/hPa * (QNH - 1013.25)`` near sea
  level).  ``h = baro_alt_m - H_p(dep)`` and ``y_T = H_p(arr) - H_p(dep)``; the output
  ``sabziev_height_m`` is this pressure-consistent height above the departure airfield (the
  same datum as the pipeline's baro fallback), and ``sabziev_up_m`` the same point's up in
  the output tangent plane, as for every prefix (:mod:`flightrecon.tracks`).
* Lift-off velocity: ``clean.phases.liftoff_velocity_ned_mps``; when unknown (record starts in
  the air), the air-derived velocity (plus wind) and the baro climb rate at the first sample.
* Wind: from ``wind_speed_mps`` / ``wind_from_deg`` (meteorological, blowing from) when the
  grid has them; else the winds-aloft table (``--wind``) at the recorded altitude
  (:func:`flightrecon.ingest.priors.wind_aloft_on_grid`, docs/wind.md); otherwise the summary
  warns "wind unmodelled".  ``wind_source`` in the summary says which.
* Known positions (``--fix``): without an arrival position, a fix within
  :data:`END_FIX_TOLERANCE_S` of the interval's end (the last sample of a record that ends in
  the air) is the end point (:func:`end_fix`); the boundary-value problem has no place for
  positions inside the interval, so the other fixes are not used (the summary says so).
* Gaps (NaN) inside the interval are bridged linearly and reported (the fusion integrates
  every sample; a long bridged gap is a defect the analyst must see).
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.errors import (
    FlightReconWarning,
)
from flightrecon.geo.atmosphere import field_pressure_altitude_m
from flightrecon.methods.baselines import (
    ARRIVAL_POINT_SD_M,
)
from flightrecon.methods.sabziev import KT_MAX, SabzievSolution, fuse
from flightrecon.methods.sabziev.flight_inputs import (
    REQUIRED_CHANNELS,
    acceleration_on_interval,
    end_point_ned,
    end_sources,
    flight_interval,
    grid_column,
    heading_reference,
    liftoff_origin,
    liftoff_velocity,
    wind_on_interval,
)
from flightrecon.methods.sabziev.heights import (
    baro_accelerometer_scale,
    end_consistent_height,
    liftoff_datum,
)
from flightrecon.methods.sabziev.result import (
    FIXED_K_REL_SD,
    LIFTOFF_GIVEN_SD_M,
    LIFTOFF_SD_M,
    add_conditioning,
    bridge_sd,
    finite_or_none,
    resolve_coefficients,
    sabziev_summary,
    sabziev_track,
    self_check,
)
from flightrecon.methods.sabziev.surface import surface_fit
from flightrecon.types import CleanFlight, MethodResult, Position, PositionFix

__all__ = ["run_sabziev"]


@dataclass
class _Inputs:
    """What :func:`run_sabziev` prepares from the cleaned flight for the fusion."""

    plane: Any
    arr: Position | None
    fix_end: PositionFix | None
    t_all: np.ndarray
    sl: slice
    t: np.ndarray
    cols: dict[str, np.ndarray]
    a_ned: np.ndarray
    origin: np.ndarray
    psi: np.ndarray
    wind: np.ndarray | None
    wind_source: str
    notes: list[str]
    reference: dict[str, Any]
    h_rel: np.ndarray
    h_pressure: np.ndarray
    v0: np.ndarray
    end_ned: np.ndarray | None
    end_info: dict[str, Any]


def _prepare(clean: CleanFlight, arrival: Position | None, k: Any, liftoff: Position | None,
             liftoff_velocity_ned: Any, acceleration_ned: np.ndarray | None,
             policy: str) -> _Inputs:
    """The fusion's inputs on the flight's interval (docs/sabziev.md, "The adapter"): the
    channels, the kinematic acceleration, the lift-off origin and its height datum, the
    wind, the lift-off velocity and the end point, with the notes for the summary."""
    from flightrecon.geo.frames import output_plane

    meta = clean.meta
    plane = output_plane(meta)  # raises MetadataError without a departure
    grid = clean.grid
    arr, fix_end = end_sources(clean, arrival, k)
    t_all = grid["t_s"].to_numpy(dtype=np.float64)
    i0, i1, notes = flight_interval(clean, t_all)
    sl = slice(i0, i1 + 1)
    t = t_all[sl]
    cols = {c: grid_column(grid, c, sl, notes) for c in REQUIRED_CHANNELS}
    a_ned = acceleration_on_interval(clean, cols, sl, len(t_all), acceleration_ned)
    hp_dep = field_pressure_altitude_m(meta.departure.elev_m, meta.qnh_departure_hpa)
    origin = liftoff_origin(meta, plane, liftoff, hp_dep)
    h_rel = cols["baro_alt_m"] - hp_dep - origin[2]
    psi = np.radians(cols["heading_deg"])
    wind, wind_source = wind_on_interval(grid, meta, sl, notes)
    n_unused = len(meta.fixes) - (1 if fix_end is not None else 0) if meta.fixes else 0
    if n_unused > 0:
        notes.append(f"{n_unused} known position(s) (--fix) inside the interval not used: the "
                     "boundary-value fusion has no place for them (the joint smoother uses them)")
    reference: dict[str, Any] = {"datum": "field pressure altitude under QNH"}
    if policy == "stable":
        h_rel, reference = liftoff_datum(clean, t_all, sl, cols["baro_alt_m"])
        if clean.phases is None or clean.phases.starts_airborne:
            # the first sample is in the air: the track starts at the aircraft's pressure
            # height above the departure field (under its QNH), not at the field
            up0 = reference["liftoff_pressure_alt_m"] - hp_dep if liftoff is None else 0.0
            reference["start_height_m"] = up0
            origin = origin + np.array([0.0, 0.0, up0])
    h_pressure = h_rel
    v0 = liftoff_velocity(clean, t, h_rel, cols, psi, wind, notes, liftoff_velocity_ned)
    end_ned, end_info = end_point_ned(meta, plane, arr, fix_end, hp_dep, origin, h_rel,
                                   geometric=policy == "stable")
    if policy == "stable" and end_ned is not None:
        h_rel, corr = end_consistent_height(t, h_rel, -float(end_ned[2]))
        reference.update(corr)
    return _Inputs(plane, arr, fix_end, t_all, sl, t, cols, a_ned, origin, psi, wind,
                   wind_source, notes, reference, h_rel, h_pressure, v0, end_ned, end_info)


def _solve(clean: CleanFlight, p: _Inputs, k: Any, k0: Any, opts: dict[str, Any],
           surface: bool) -> tuple[SabzievSolution, dict[str, Any]]:
    """The fusion in the flat frame, then (stable policy, an end point, no given k, a true
    heading) its fit in the curvilinear frame (:func:`surface_fit`); with the frame's note."""
    sol = fuse(p.t, p.a_ned, p.cols["tas_mps"], p.psi, p.h_rel, p.v0, p.end_ned, p.wind, k,
               k0=k0, **opts)
    frame: dict[str, Any] = {"frame": "flat (tangent plane at the departure airfield)"}
    grid_heading = heading_reference(clean) == "grid"
    if grid_heading:
        frame["why"] = ("the heading propagated from the body rates is a grid heading (north of "
                        "the departure's tangent plane), whose frame is flat")
    if (opts["policy"] == "stable" and surface and not grid_heading and p.end_ned is not None
            and k is None):
        sol, frame = surface_fit(sol, p.plane, clean.meta, p.origin, p.end_ned, dict(
            t=p.t, a_ned=p.a_ned, tas=p.cols["tas_mps"], heading_rad=p.psi, h_rel=p.h_rel,
            v0_ned=p.v0, wind_ne=p.wind), dict(opts))
    return sol, frame


def _summary_of(p: _Inputs, sol: SabzievSolution, frame: dict[str, Any], k: Any, k_sd: Any,
                k_defaults: list[str], origin_sd: float, warn: list[str], hold: str,
                vertical_rule: str, policy: str) -> tuple[pd.DataFrame, dict[str, Any]]:
    """The track on the grid and the summary, with the bridge sd, the conditioning, the
    vertical reference's checks and the self-check's problems (``health_problems``)."""
    t, sl = p.t, p.sl
    sd_m, sd_entry = None, None
    if k_sd is None and p.end_ned is not None and policy == "stable":
        end_sd = (p.fix_end.sd_m if p.arr is None and p.fix_end is not None
                  else ARRIVAL_POINT_SD_M)
        sd_m, sd_entry = bridge_sd(t, origin_sd, end_sd)
    track = sabziev_track(p.t_all, sl, sol, k_sd, p.origin, origin_sd, p.plane, sd_m)
    summary = sabziev_summary(sol, k, k_sd, t, p.v0, p.end_info, warn, hold, vertical_rule)
    if sd_entry is not None:
        summary["track_sd"] = sd_entry
    summary["wind_source"] = p.wind_source
    summary["policy"] = policy
    summary["k_defaults"] = k_defaults
    if k_sd is not None:
        summary["liftoff_sd_m"] = origin_sd
    if summary["mode"] == "boundary-value":
        add_conditioning(sol, summary["axes"])
    summary["frame"] = frame
    reference = p.reference
    summary["vertical_reference"] = reference
    sc, r2, spread = baro_accelerometer_scale(t, -p.a_ned[:, 2], p.cols["baro_alt_m"])
    reference.update({"baro_vs_accelerometer": finite_or_none(sc),
                      "baro_vs_accelerometer_r2": finite_or_none(r2),
                      "baro_vs_accelerometer_spread_m": finite_or_none(spread)})
    problems = self_check(sol, t, p.h_pressure, p.cols["tas_mps"], reference)
    summary["healthy"] = not problems
    summary["health_problems"] = problems
    return track, summary


def _nominal_k_sd(k: Any, k_sd: Any, k_defaults: list[str], notes: list[str]) -> Any:
    """A defaulted axis has no fleet spread: a nominal one (:data:`FIXED_K_REL_SD` of the
    fixed coefficient) where its sd is not finite, said in ``notes``."""
    if k_sd is None or not k_defaults:
        return k_sd
    assert k is not None
    k_sd = tuple(FIXED_K_REL_SD * abs(k[i]) if (f"k{i + 1}" in k_defaults
                                                and not np.isfinite(x)) else float(x)
                 for i, x in enumerate(k_sd))
    notes.append(f"track sd of {', '.join(k_defaults)}: a nominal {FIXED_K_REL_SD:.0%} "
                 "of the fixed coefficient, not a measured spread")
    return k_sd


def run_sabziev(clean: CleanFlight, *, k: tuple[float, float, float] | None = None,
                k_sd: tuple[float, float, float] | None = None,
                arrival: Position | None = None, liftoff: Position | None = None,
                liftoff_velocity_ned: tuple[float, float, float] | None = None,
                k0: tuple[float, float, float] | None = None,
                hold: str = "linear", tol_m: float = 1e-3, max_iter: int = 60,
                vertical_rule: str = "baro", kt_max: float = KT_MAX, strict: bool = False,
                acceleration_ned: np.ndarray | None = None,
                policy: str = "stable", surface: bool = True) -> MethodResult:
    """Run the Sabziev fusion on a cleaned flight (docs/sabziev.md; module docstring).

    Parameters
    ----------
    clean : cleaned flight (grid, phases, meta with the departure position)
    k : (k1, k2, k3) for the initial-value mode (arrival not needed)
    k_sd : standard deviations of ``k`` (fleet spread): adds ``sabziev_*_sd_*`` columns by
        first-order propagation through the exact sensitivities
    arrival : arrival position overriding ``clean.meta.arrival`` (e.g. the touchdown point
        instead of the airfield reference point: they are 1-3 km apart)
    liftoff : lift-off point, when known (default: the departure position); the track is
        still output relative to the departure airfield
    liftoff_velocity_ned : ground velocity at lift-off [m/s], when known better than from the
        ground roll (``clean.phases``), e.g. from GNSS
    k0 : start values of the iterations
    hold, tol_m, max_iter, vertical_rule, kt_max, strict : see
        :func:`flightrecon.methods.sabziev.fuse`
    acceleration_ned : (N, 3) kinematic acceleration on the whole grid, if already computed
        (default: :func:`flightrecon.geo.kinematics.kinematic_acceleration_ned` of the loads)
    policy : ``stable`` (default) or ``paper``
        (:data:`flightrecon.methods.sabziev.axis.POLICIES`; docs/sabziev.md "Root finding" and
        "The adapter"): with ``stable`` the vertical reference is the pressure height relative
        to its recorded value at lift-off, made consistent with the end points
        (:func:`end_consistent_height`)
    surface : with policy ``stable`` and an end point, fit in the curvilinear frame
        (:func:`surface_fit`: distances along the surface, then the tangent plane); False
        keeps the paper's flat frame

    Returns
    -------
    MethodResult
        ``track`` on the grid times: ``sabziev_north_m``, ``sabziev_east_m``, ``sabziev_up_m``
        (tangent plane at the departure airfield), ``sabziev_height_m`` (the
        pressure-consistent height above it), ``sabziev_lat_deg``, ``sabziev_lon_deg``,
        ``sabziev_alt_m``, ``sabziev_vn_mps``, ``sabziev_ve_mps``, ``sabziev_vu_mps``, NaN outside
        lift-off..touchdown, plus ``*_sd_*`` columns when ``k_sd`` is given.  ``summary``:
        ``converged``, ``k1..k3``, ``axes`` (per-axis report), ``history`` (Newton ``[k, F]``
        per axis), ``wind_modelled``, ``warnings``.

    Raises
    ------
    MetadataError
        No departure position; neither an arrival position nor ``k``.
    SchemaError
        A required channel is missing from the grid.
    ConvergenceError
        ``strict`` and an axis found no root.
    """
    p = _prepare(clean, arrival, k, liftoff, liftoff_velocity_ned, acceleration_ned, policy)
    k, k_defaults = resolve_coefficients(k, float(p.t[-1] - p.t[0]))
    if k_defaults:
        p.notes.append("no fleet coefficient for " + ", ".join(k_defaults) + ": the stable "
                       "policy's fixed coefficient taken (docs/sabziev.md, 'No root taken')")
    sol, frame = _solve(clean, p, k, k0, dict(hold=hold, tol_m=tol_m, max_iter=max_iter,
                                              kt_max=kt_max, strict=strict,
                                              vertical_rule=vertical_rule, policy=policy),
                        surface)
    fallbacks = [f"{name}: no root of F in the stable range ({ax.report.reason}); the "
                 f"stable track with k = {ax.k:.4g} ended {ax.correction_m:+.1f} m from the end "
                 "point, removed linearly in time"
                 for name, ax in sol.axes.items() if ax.fallback and ax.report is not None]
    warn = list(sol.warnings) + fallbacks + p.notes
    for w in list(sol.warnings) + fallbacks:
        warnings.warn(f"sabziev: {w}", FlightReconWarning, stacklevel=2)
    k_sd = _nominal_k_sd(k, k_sd, k_defaults, p.notes)
    origin_sd = LIFTOFF_SD_M if liftoff is None else LIFTOFF_GIVEN_SD_M
    track, summary = _summary_of(p, sol, frame, k, k_sd, k_defaults, origin_sd, warn, hold,
                                 vertical_rule, policy)
    for pr in summary["health_problems"]:
        warnings.warn(f"sabziev unhealthy: {pr}", FlightReconWarning, stacklevel=2)
    return MethodResult(name="sabziev", track=track, summary=summary)
