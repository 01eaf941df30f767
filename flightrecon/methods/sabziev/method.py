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
  ``sabziev_up_m`` is this pressure-consistent height above the departure airfield (the same
  datum as the pipeline's baro fallback).
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
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.errors import (
    FlightReconWarning,
    MetadataError,
    SchemaError,
    ValidationError,
)
from flightrecon.geo.atmosphere import field_pressure_altitude_m, isa_temperature_k
from flightrecon.geo.wind import wind_toward_ne
from flightrecon.methods.baselines import (
    ARRIVAL_POINT_SD_M,
    DR_WALK_MPS_SQRT_S,
    corrected_track_sd_m,
)
from flightrecon.methods.sabziev import KT_MAX, SabzievSolution, air_velocity, fuse
from flightrecon.types import CleanFlight, FlightMeta, MethodResult, Position, PositionFix

__all__ = ["END_FIX_TOLERANCE_S", "REQUIRED_CHANNELS", "end_fix", "field_pressure_altitude_m",
           "run_sabziev"]

END_FIX_TOLERANCE_S = 2.0
"""A known position this close to the end of the fusion interval [s] (or two grid steps, if
longer) serves as its end point when there is no arrival position."""

REQUIRED_CHANNELS = ("n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg", "heading_deg",
                     "tas_mps", "baro_alt_m")


def _interval(clean: CleanFlight, t: np.ndarray) -> tuple[int, int, list[str]]:
    notes = []
    ph = clean.phases
    i0, i1 = 0, len(t) - 1
    if ph is None:
        notes.append("no phases detected: the whole record is used, its first and last samples "
                     "taken as the departure and arrival points")
        return i0, i1, notes
    if not ph.starts_airborne and np.isfinite(ph.liftoff_t_s):
        i0 = int(np.argmin(np.abs(t - ph.liftoff_t_s)))
    elif ph.starts_airborne:
        notes.append("record starts airborne: the departure position is taken as the position "
                     "at the first sample")
    if not ph.ends_airborne and np.isfinite(ph.touchdown_t_s):
        i1 = int(np.argmin(np.abs(t - ph.touchdown_t_s)))
    elif ph.ends_airborne:
        notes.append("record ends airborne: the arrival position is taken as the position at "
                     "the last sample")
    if i1 - i0 < 2:
        raise ValidationError(f"lift-off to touchdown spans {i1 - i0 + 1} grid samples: "
                              "nothing to fuse")
    return i0, i1, notes


def end_fix(clean: CleanFlight) -> PositionFix | None:
    """The known position (``--fix``) at the end of the fusion interval, if any: the last fix
    within :data:`END_FIX_TOLERANCE_S` (or two grid steps) of the interval's last sample."""
    fixes = clean.meta.fixes
    if not fixes or len(clean.grid) < 3:
        return None
    t = clean.grid["t_s"].to_numpy(dtype=np.float64)
    try:
        _i0, i1, _notes = _interval(clean, t)
    except ValidationError:
        return None
    tol = max(END_FIX_TOLERANCE_S, 2.0 * float(np.median(np.diff(t))))
    near = [f for f in fixes if abs(f.t_s - t[i1]) <= tol]
    return near[-1] if near else None


def _column(grid: pd.DataFrame, name: str, sl: slice, notes: list[str]) -> np.ndarray:
    x = grid[name].to_numpy(dtype=np.float64)[sl].copy()
    bad = ~np.isfinite(x)
    if bad.all():
        raise ValidationError("no valid samples between lift-off and touchdown", column=name)
    if bad.any():
        idx = np.arange(len(x))
        x[bad] = np.interp(idx[bad], idx[~bad], x[~bad])
        notes.append(f"{name}: {int(bad.sum())} missing samples bridged linearly for the fusion")
    return x


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
        (:data:`flightrecon.methods.sabziev.solve.POLICIES`; docs/sabziev.md "Root finding" and
        "The adapter"): with ``stable`` the vertical reference is the pressure height relative
        to its recorded value at lift-off, made consistent with the end points
        (:func:`end_consistent_height`)
    surface : with policy ``stable`` and an end point, fit in the curvilinear frame
        (:func:`_surface_fit`: distances along the surface, then the tangent plane); False
        keeps the paper's flat frame

    Returns
    -------
    MethodResult
        ``track`` on the grid times: ``sabziev_north_m``, ``sabziev_east_m``, ``sabziev_up_m``
        (tangent plane at the departure airfield; up is the pressure-consistent height above
        it), ``sabziev_vn_mps``, ``sabziev_ve_mps``, ``sabziev_vu_mps``, NaN outside
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
    from flightrecon.geo.frames import output_plane

    meta = clean.meta
    plane = output_plane(meta)  # raises MetadataError without a departure
    grid = clean.grid
    arr, fix_end = _end_sources(clean, arrival, k)
    t_all = grid["t_s"].to_numpy(dtype=np.float64)
    i0, i1, notes = _interval(clean, t_all)
    sl = slice(i0, i1 + 1)
    t = t_all[sl]
    cols = {c: _column(grid, c, sl, notes) for c in REQUIRED_CHANNELS}
    a_ned = _acceleration(clean, cols, sl, len(t_all), acceleration_ned)
    hp_dep = field_pressure_altitude_m(meta.departure.elev_m, meta.qnh_departure_hpa)
    origin = _liftoff_origin(meta, plane, liftoff, hp_dep)
    h_rel = cols["baro_alt_m"] - hp_dep - origin[2]
    psi = np.radians(cols["heading_deg"])
    wind, wind_source = _wind(grid, meta, sl, notes)
    n_unused = len(meta.fixes) - (1 if fix_end is not None else 0) if meta.fixes else 0
    if n_unused > 0:
        notes.append(f"{n_unused} known position(s) (--fix) inside the interval not used: the "
                     "boundary-value fusion has no place for them (the joint smoother uses them)")
    reference: dict[str, Any] = {"datum": "field pressure altitude under QNH"}
    if policy == "stable":
        h_rel, reference = _liftoff_datum(clean, t_all, sl, cols["baro_alt_m"])
        if clean.phases is None or clean.phases.starts_airborne:
            # the first sample is in the air: the track starts at the aircraft's pressure
            # height above the departure field (under its QNH), not at the field
            up0 = reference["liftoff_pressure_alt_m"] - hp_dep if liftoff is None else 0.0
            reference["start_height_m"] = up0
            origin = origin + np.array([0.0, 0.0, up0])
    h_pressure = h_rel
    v0 = _liftoff_velocity(clean, t, h_rel, cols, psi, wind, notes, liftoff_velocity_ned)
    end_ned, end_info = _end_point(meta, plane, arr, fix_end, hp_dep, origin, h_rel,
                                   geometric=policy == "stable")
    if policy == "stable" and end_ned is not None:
        h_rel, corr = end_consistent_height(t, h_rel, -float(end_ned[2]))
        reference.update(corr)
    k, k_defaults = resolve_coefficients(k, float(t[-1] - t[0]))
    if k_defaults:
        notes.append("no fleet coefficient for " + ", ".join(k_defaults) + ": the stable "
                     "policy's fixed coefficient taken (docs/sabziev.md, 'No root taken')")
    sol = fuse(t, a_ned, cols["tas_mps"], psi, h_rel, v0, end_ned, wind, k, k0=k0, hold=hold,
               tol_m=tol_m, max_iter=max_iter, kt_max=kt_max, strict=strict,
               vertical_rule=vertical_rule, policy=policy)
    frame: dict[str, Any] = {"frame": "flat (tangent plane at the departure airfield)"}
    grid_heading = heading_reference(clean) == "grid"
    if grid_heading:
        frame["why"] = ("the heading propagated from the body rates is a grid heading (north of "
                        "the departure's tangent plane), whose frame is flat")
    if (policy == "stable" and surface and not grid_heading and end_ned is not None
            and k is None):
        sol, frame = _surface_fit(sol, plane, meta, origin, end_ned, dict(
            t=t, a_ned=a_ned, tas=cols["tas_mps"], heading_rad=psi, h_rel=h_rel, v0_ned=v0,
            wind_ne=wind), dict(hold=hold, tol_m=tol_m, max_iter=max_iter, kt_max=kt_max,
                               strict=strict, vertical_rule=vertical_rule, policy=policy))
    fallbacks = [f"{name}: no root of F in the stable range ({ax.report.reason}); the "
                 f"stable track with k = {ax.k:.4g} ended {ax.correction_m:+.1f} m from the end "
                 "point, removed linearly in time"
                 for name, ax in sol.axes.items() if ax.fallback and ax.report is not None]
    warn = list(sol.warnings) + fallbacks + notes
    for w in list(sol.warnings) + fallbacks:
        warnings.warn(f"sabziev: {w}", FlightReconWarning, stacklevel=2)
    if k_sd is not None and k_defaults:
        # a defaulted axis has no fleet spread: a nominal one (FIXED_K_REL_SD), said
        assert k is not None
        k_sd = tuple(FIXED_K_REL_SD * abs(k[i]) if (f"k{i + 1}" in k_defaults
                                                    and not np.isfinite(x)) else float(x)
                     for i, x in enumerate(k_sd))  # type: ignore[assignment]
        notes.append(f"track sd of {', '.join(k_defaults)}: a nominal {FIXED_K_REL_SD:.0%} of "
                     "the fixed coefficient, not a measured spread")
    origin_sd = LIFTOFF_SD_M if liftoff is None else LIFTOFF_GIVEN_SD_M
    track = _track(t_all, sl, sol, k_sd, origin, origin_sd)
    summary = _summary(sol, k, k_sd, t, v0, end_info, warn, hold, vertical_rule)
    if k_sd is None and end_ned is not None and policy == "stable":
        end_sd = fix_end.sd_m if arr is None and fix_end is not None else ARRIVAL_POINT_SD_M
        summary["track_sd"] = _bridge_sd_columns(track, sl, t, origin_sd, end_sd)
    summary["wind_source"] = wind_source
    summary["policy"] = policy
    summary["k_defaults"] = k_defaults
    if k_sd is not None:
        summary["liftoff_sd_m"] = origin_sd
    if summary["mode"] == "boundary-value":
        _conditioning(sol, summary["axes"])
    summary["frame"] = frame
    summary["vertical_reference"] = reference
    sc, r2, spread = baro_accelerometer_scale(t, -a_ned[:, 2], cols["baro_alt_m"])
    reference.update({"baro_vs_accelerometer": _num(sc), "baro_vs_accelerometer_r2": _num(r2),
                      "baro_vs_accelerometer_spread_m": _num(spread)})
    problems = self_check(sol, t, h_pressure, cols["tas_mps"], reference)
    summary["healthy"] = not problems
    summary["health_problems"] = problems
    for pr in problems:
        warnings.warn(f"sabziev unhealthy: {pr}", FlightReconWarning, stacklevel=2)
    return MethodResult(name="sabziev", track=track, summary=summary)


def heading_reference(clean: CleanFlight) -> str:
    """What the grid's ``heading_deg`` is measured from: ``"grid"`` when the cleaning propagated
    it from the body rates anchored by runway rolls only (the report's ``heading_reference``;
    docs/sabziev.md, "Flat frame and a curved Earth"), else ``"true"`` (a recorded heading)."""
    for r in clean.report:
        if r.get("action") == "heading_from_rates":
            return str(r.get("heading_reference", "true"))
    return "true"


WGS84_A_M = 6378137.0
"""WGS-84 semi-major axis [m]."""

WGS84_E2 = 6.69437999014e-3
"""WGS-84 first eccentricity squared."""

SURFACE_TOL_M = 0.1
"""The curvilinear end point is iterated until it misses the arrival by less than this [m]."""


def surface_track(lat0_deg: float, lon0_deg: float, north_m: np.ndarray, east_m: np.ndarray,
                  h_m: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Latitude and longitude of a track given as distances flown north and east.

    The fusion integrates local-level north and east velocities (docs/sabziev.md, "Flat frame
    and a curved Earth"): its ``x``, ``z`` are distances along the meridian and the parallel
    at the aircraft, ``d phi = dx / (M + h)``, ``d lambda = dz / ((N + h) cos phi)``
    (WGS-84 radii of curvature ``M``, ``N``), summed along the path with the midpoint
    latitude (two passes: the radii at the first pass's latitudes).

    Parameters
    ----------
    lat0_deg, lon0_deg : start [deg]
    north_m, east_m : (N,) distances flown north and east from the start [m]
    h_m : (N,) ellipsoidal height [m]

    Returns
    -------
    lat_deg, lon_deg : (N,) arrays
    """
    dx = np.diff(north_m)
    dz = np.diff(east_m)
    hm = 0.5 * (h_m[1:] + h_m[:-1])
    phi0 = np.radians(lat0_deg)
    phi = np.full(len(north_m), phi0)
    for _ in range(2):
        pm = 0.5 * (phi[1:] + phi[:-1])
        w = 1.0 - WGS84_E2 * np.sin(pm) ** 2
        M = WGS84_A_M * (1.0 - WGS84_E2) / w**1.5
        phi = phi0 + np.concatenate([[0.0], np.cumsum(dx / (M + hm))])
    pm = 0.5 * (phi[1:] + phi[:-1])
    N = WGS84_A_M / np.sqrt(1.0 - WGS84_E2 * np.sin(pm) ** 2)
    lam = np.radians(lon0_deg) + np.concatenate([[0.0], np.cumsum(dz / ((N + hm) * np.cos(pm)))])
    return np.degrees(phi), np.degrees(lam)


def _surface_fit(sol: SabzievSolution, plane: Any, meta: FlightMeta, origin: np.ndarray,
                 end_ned: np.ndarray, inputs: dict[str, Any],
                 opts: dict[str, Any]) -> tuple[SabzievSolution, dict[str, Any]]:
    """The boundary-value fit in the curvilinear frame (policy ``stable``).

    The flat fit compares distances flown north and east with the arrival's tangent-plane
    coordinates; over hundreds of kilometres the two differ (chord against arc, meridian
    convergence: 1.7 km after 170 km, 244 km after 1845 km on JSBSim flights).  Here the
    track's distances are turned into latitude and longitude (:func:`surface_track`) and then
    into the output plane, and the horizontal targets of the fit are moved by the remaining
    miss (in surface metres at the end) until the plane end point is met within
    :data:`SURFACE_TOL_M` (at most 6 fits; the miss shrinks by the ratio of the path's
    distortion, ~1e-3 per 100 km).  Returns the solution with its position in plane
    coordinates relative to the lift-off point and the frame's report."""
    from dataclasses import replace as dc_replace

    from flightrecon.geo.frames import msl_to_ellipsoid

    h_dep = msl_to_ellipsoid(meta.departure.elev_m, meta.geoid_undulation_m)
    lat0, lon0, _ = plane.inverse(float(origin[1]), float(origin[0]), 0.0)
    target = np.array([float(end_ned[0]) + origin[0], float(end_ned[1]) + origin[1]])
    shift = np.zeros(2)
    first_miss = float("nan")
    miss = np.full(2, np.nan)
    it = 0
    cur = sol
    for it in range(1, 7):
        h_ell = h_dep + origin[2] + cur.up_m
        lat, lon = surface_track(float(lat0), float(lon0), cur.north_m, cur.east_m, h_ell)
        e, n, _u = plane.forward(lat, lon, h_ell)
        miss = np.array([float(n[-1]) - target[0], float(e[-1]) - target[1]])
        if it == 1:
            first_miss = float(np.hypot(*miss))
        if not np.all(np.isfinite(miss)) or np.max(np.abs(miss)) <= SURFACE_TOL_M:
            break
        # the miss in surface metres at the end: the plane's axes turn by the convergence
        gam = -np.radians(float(lon[-1]) - float(lon0)) * np.sin(np.radians(float(lat[-1])))
        c, s_ = np.cos(gam), np.sin(gam)
        shift -= np.array([c * miss[0] + s_ * miss[1], -s_ * miss[0] + c * miss[1]])
        end = np.array([end_ned[0] + shift[0], end_ned[1] + shift[1], end_ned[2]])
        cur = fuse(inputs["t"], inputs["a_ned"], inputs["tas"], inputs["heading_rad"],
                   inputs["h_rel"], inputs["v0_ned"], end, inputs["wind_ne"], None, **opts)
    xyz = cur.xyz_m.copy()
    xyz[:, 0] = np.asarray(n, dtype=np.float64) - origin[0]
    xyz[:, 2] = np.asarray(e, dtype=np.float64) - origin[1]
    res = cur.end_residual_m.copy()
    res[0], res[2] = miss
    out = dc_replace(cur, xyz_m=xyz, end_residual_m=res)
    return out, {"frame": "curvilinear (distances along the surface, then the tangent plane)",
                 "fits": it, "flat_frame_miss_m": first_miss,
                 "target_shift_m": [float(x) for x in shift],
                 "end_miss_m": float(np.hypot(*miss))}


LIFTOFF_DATUM_S = 2.0
"""The pressure height's datum is its mean over this long [s] before lift-off (after the first
sample when the record starts airborne)."""

SCALE_MAX = 0.15
"""Largest relative pressure-height scale error explained by the air mass
(:func:`end_consistent_height`: 15 %, an air mass 40 K off the standard atmosphere)."""


def _liftoff_datum(clean: CleanFlight, t_all: np.ndarray, sl: slice,
                   baro: np.ndarray) -> tuple[np.ndarray, dict[str, Any]]:
    """The pressure height relative to its recorded value at lift-off (the paper's ``h``,
    "relative to the lift-off point"; seed 001 section IV): the mean of the recorded pressure
    altitude over :data:`LIFTOFF_DATUM_S` before lift-off, or after the first sample of a
    record that starts airborne.  No QNH is needed: the datum is the aircraft's own reading."""
    g = clean.grid["baro_alt_m"].to_numpy(dtype=np.float64)
    t0 = t_all[sl.start]
    ph = clean.phases
    if ph is not None and not ph.starts_airborne:
        win = (t_all >= t0 - LIFTOFF_DATUM_S) & (t_all <= t0)
    else:
        win = (t_all >= t0) & (t_all <= t0 + LIFTOFF_DATUM_S)
    vals = g[win][np.isfinite(g[win])]
    ref = float(np.mean(vals)) if len(vals) else float(baro[0])
    info: dict[str, Any] = {"datum": "recorded pressure altitude at lift-off",
                            "liftoff_pressure_alt_m": ref, "hypsometric": False}
    h = baro - ref
    if "sat_degc" in clean.grid.columns:
        sat = clean.grid["sat_degc"].to_numpy(dtype=np.float64)[sl]
        ok = np.isfinite(sat)
        if ok.sum() >= 0.9 * len(sat):
            idx = np.arange(len(sat))
            sat = np.interp(idx, idx[ok], sat[ok])
            # from the lift-off reading: the first sample's offset from it scaled alike
            h = hypsometric_height(baro, sat) + (baro[0] - ref) * (sat[0] + 273.15) / float(
                isa_temperature_k(baro[0]))
            info["hypsometric"] = True
    return h, info


def hypsometric_height(h_p: np.ndarray, sat_degc: np.ndarray) -> np.ndarray:
    """Geometric height gained along a record from pressure altitude and static air temperature.

    The hypsometric equation ``dz = (T / T_ISA(h_p)) dh_p`` (the standard atmosphere's pressure
    altitude scaled by the ratio of the actual to the standard temperature at the same
    pressure; ICAO Doc 7488), integrated by the trapezoidal rule from the first sample.

    Parameters
    ----------
    h_p : (N,) pressure altitude [m] (1013.25 hPa datum)
    sat_degc : (N,) static air temperature [degC]

    Returns
    -------
    (N,) geometric height relative to the first sample [m]
    """
    ratio = (np.asarray(sat_degc, dtype=np.float64) + 273.15) / isa_temperature_k(h_p)
    dz = 0.5 * (ratio[1:] + ratio[:-1]) * np.diff(h_p)
    return np.concatenate([[0.0], np.cumsum(dz)])


def end_consistent_height(t: np.ndarray, h: np.ndarray,
                          y_T: float) -> tuple[np.ndarray, dict[str, Any]]:
    """The pressure height made consistent with the end point (policy ``stable``).

    The pressure height ``h`` (relative to lift-off) ends at ``h_T`` (mean of the last second),
    the end point is at ``y_T`` (geometric, relative to lift-off); their difference
    ``D = y_T - h_T`` is the pressure height's error at the end: an air mass off the standard
    atmosphere (a scale error, about 3.5 % per 10 K) and the change of sea-level pressure over
    the flight (a datum drift).  It is removed as

    * a scale error, ``h (1 + D/h_T)``, when the flight ends near its highest point (``|h_T|``
      at least half the largest ``|h|``) and ``|D| <= SCALE_MAX |h_T|``; or else
    * a drift linear in time, ``h + D (t - t_0)/T``.

    Without it the undamped baro-inertial loop cannot both follow the pressure height and meet
    the end point: ``F(k2)`` then has roots only where the loop lets the track stray from
    ``h`` by ``D`` (docs/sabziev.md, "Signs and branches").

    Parameters
    ----------
    t : (N,) grid [s]
    h : (N,) pressure height relative to lift-off [m]
    y_T : end height relative to lift-off [m]

    Returns
    -------
    h_c : (N,) the corrected reference [m]
    info : ``end_mismatch_m`` (D), ``model`` (``scale`` or ``drift``), ``scale`` (1 + D/h_T
        or 1)
    """
    n_end = max(1, int(round(1.0 / (t[1] - t[0]))))
    h_T = float(np.mean(h[-n_end:]))
    D = float(y_T - h_T)
    h_max = float(np.max(np.abs(h)))
    if abs(h_T) >= 0.5 * h_max and abs(h_T) > 0 and abs(D) <= SCALE_MAX * abs(h_T):
        scale = 1.0 + D / h_T
        h_c = h * scale
        # the mean of the last second now ends at y_T; the last sample exactly:
        h_c = h_c + (y_T - h_c[-1]) * (t - t[0]) / (t[-1] - t[0])
        return h_c, {"end_mismatch_m": D, "model": "scale", "scale": scale}
    h_c = h + (y_T - h[-1]) * (t - t[0]) / (t[-1] - t[0])
    return h_c, {"end_mismatch_m": D, "model": "drift", "scale": 1.0}


SCALE_WINDOW_S = 20.0
"""Window [s] of the second differences compared by :func:`baro_accelerometer_scale`."""

SCALE_BAND = (0.7, 1.4)
"""Ratio of the pressure height's to the accelerometers' height changes outside which the
vertical is unhealthy (a unit error: feet read as metres gives 3.28, metres as feet 0.30; an
air mass 40 K off standard 1.15; measured 0.92-1.06 on the corpus and JSBSim flights)."""


def baro_accelerometer_scale(t: np.ndarray, a_y: np.ndarray,
                             h: np.ndarray, window_s: float = SCALE_WINDOW_S
                             ) -> tuple[float, float, float]:
    """How much faster the pressure height changes than the vertical accelerometer says.

    Second differences over ``window_s`` of the pressure height,
    ``h(t+W) - 2 h(t) + h(t-W)``, against the same of the doubly integrated vertical
    acceleration (``int int a_y``, trapezoidal), on non-overlapping windows; the least-squares
    slope with an intercept (a constant accelerometer error ``b`` adds ``b W^2`` to every
    window).  A correct pressure height gives a slope near 1; an altitude in feet read as
    metres 3.28.

    Returns
    -------
    slope, r2, spread_m : the slope, the fit's coefficient of determination and the standard
        deviation of the accelerometer's second differences [m] (below a few metres the flight
        has too little vertical manoeuvring to tell; NaN with fewer than 4 windows)
    """
    dt = float(t[1] - t[0])
    v = np.concatenate([[0.0], np.cumsum(0.5 * (a_y[1:] + a_y[:-1]) * dt)])
    y = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)])
    k = max(1, int(round(window_s / dt)))
    idx = np.arange(k, len(t) - k, k)
    if len(idx) < 4:
        return float("nan"), float("nan"), float("nan")
    dd_h = h[idx + k] - 2.0 * h[idx] + h[idx - k]
    dd_a = y[idx + k] - 2.0 * y[idx] + y[idx - k]
    A = np.column_stack([dd_a, np.ones_like(dd_a)])
    coef = np.linalg.lstsq(A, dd_h, rcond=None)[0]
    var = float(np.var(dd_h))
    r2 = 1.0 - float(np.var(dd_h - A @ coef)) / var if var > 0 else float("nan")
    return float(coef[0]), r2, float(np.std(dd_a))


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


def _end_sources(clean: CleanFlight, arrival: Position | None,
                 k: tuple[float, float, float] | None
                 ) -> tuple[Position | None, PositionFix | None]:
    """Check the grid has the required channels and the fusion an end point or ``k``; return
    the arrival position (``arrival`` over the metadata's) and the known position at the end
    (:func:`end_fix`, looked for only without an arrival position and ``k``)."""
    missing = [c for c in ("t_s", *REQUIRED_CHANNELS) if c not in clean.grid.columns]
    if missing:
        raise SchemaError(f"the Sabziev fusion needs {', '.join(missing)}")
    arr = arrival if arrival is not None else clean.meta.arrival
    fix_end = end_fix(clean) if arr is None and k is None else None
    if k is None and arr is None and fix_end is None:
        raise MetadataError("the Sabziev fusion needs the arrival position (--arrival), a known "
                            "position at the end of the record (--fix) or the coefficients k "
                            "(--k / fleet coefficients)")
    return arr, fix_end


def _acceleration(clean: CleanFlight, cols: dict[str, np.ndarray], sl: slice, n_all: int,
                  acceleration_ned: np.ndarray | None) -> np.ndarray:
    """The kinematic acceleration (north, east, down) [m/s^2] on the fusion interval ``sl``:
    the given whole-grid ``acceleration_ned`` cut to it, or computed from the loads
    (:func:`flightrecon.geo.kinematics.kinematic_acceleration_ned`)."""
    if acceleration_ned is None:
        from flightrecon.geo.kinematics import kinematic_acceleration_ned

        return kinematic_acceleration_ned(cols["n_long_g"], cols["n_lat_g"], cols["n_norm_g"],
                                          cols["roll_deg"], cols["pitch_deg"],
                                          cols["heading_deg"], lat_deg=clean.meta.departure.lat_deg,
                                          h_m=cols["baro_alt_m"])
    a_ned = np.asarray(acceleration_ned, dtype=np.float64)
    if a_ned.shape != (n_all, 3):
        raise ValidationError(f"acceleration_ned must have shape ({n_all}, 3)")
    return a_ned[sl]


def _liftoff_origin(meta: FlightMeta, plane: Any, liftoff: Position | None,
                    hp_dep: float) -> np.ndarray:
    """The lift-off point in the output frame: north, east [m] in the plane and up [m] as the
    pressure height above the departure airfield (module docstring); zero without ``liftoff``."""
    from flightrecon.geo.frames import msl_to_ellipsoid

    origin = np.zeros(3)
    if liftoff is not None:
        e0, n0, _u0 = plane.forward(liftoff.lat_deg, liftoff.lon_deg,
                                    msl_to_ellipsoid(liftoff.elev_m, meta.geoid_undulation_m))
        origin = np.array([float(n0), float(e0),
                           field_pressure_altitude_m(liftoff.elev_m, meta.qnh_departure_hpa)
                           - hp_dep])
    return origin


def _wind(grid: pd.DataFrame, meta: FlightMeta, sl: slice,
          notes: list[str]) -> tuple[np.ndarray | None, str]:
    """The wind (toward north, east) [m/s] on the interval ``sl`` and where it came from:
    the recorded wind, else the winds-aloft table at the recorded altitude (docs/wind.md),
    else ``(None, "none")``."""
    if all(c in grid.columns and np.isfinite(grid[c].to_numpy(dtype=float)[sl]).any()
           for c in ("wind_speed_mps", "wind_from_deg")):
        return (wind_toward_ne(_column(grid, "wind_speed_mps", sl, notes),
                               _column(grid, "wind_from_deg", sl, notes)), "recorded")
    if meta.wind_aloft:
        from flightrecon.ingest.priors import wind_aloft_on_grid

        wa = wind_aloft_on_grid(grid.iloc[sl], meta)
        if wa is not None and np.isfinite(wa[0]).any():
            ok = np.isfinite(wa[0]).all(axis=1)
            idx = np.arange(len(ok))
            wind = np.column_stack([np.interp(idx, idx[ok], wa[0][ok, i]) for i in range(2)])
            if not ok.all():
                notes.append(f"winds aloft: no pressure altitude on {int((~ok).sum())} samples; "
                             "the wind there is bridged linearly")
            return wind, "winds_aloft"
    return None, "none"


def _end_point(meta: FlightMeta, plane: Any, arr: Position | None, fix_end: PositionFix | None,
               hp_dep: float, origin: np.ndarray, h_rel: np.ndarray,
               geometric: bool = False) -> tuple[np.ndarray | None, dict[str, Any]]:
    """The boundary-value end point relative to the lift-off point (north, up, east order of
    :func:`~flightrecon.methods.sabziev.fuse`'s ``end_ned``: north, east, down) and its summary
    entry: the arrival position, else the known position at the end (``fix_end``), else none
    (initial-value mode).  Vertically in pressure terms, or with ``geometric`` (policy
    ``stable``) the elevation difference itself."""
    from flightrecon.geo.frames import msl_to_ellipsoid

    if arr is None and fix_end is None:
        return None, {}
    qnh_arr = meta.qnh_arrival_hpa if meta.qnh_arrival_hpa is not None \
        else meta.qnh_departure_hpa
    if arr is not None:
        e, n, _u = plane.forward(arr.lat_deg, arr.lon_deg,
                                 msl_to_ellipsoid(arr.elev_m, meta.geoid_undulation_m))
        y_T = (arr.elev_m - meta.departure.elev_m if geometric
               else field_pressure_altitude_m(arr.elev_m, qnh_arr) - hp_dep)
        source = "arrival"
    else:
        assert fix_end is not None
        # the known position at the end: horizontally the fix; vertically its altitude in
        # pressure terms, or without one the recorded pressure height there
        y_T = (float(h_rel[-1] + origin[2]) if fix_end.alt_msl_m is None
               else fix_end.alt_msl_m - meta.departure.elev_m if geometric
               else field_pressure_altitude_m(fix_end.alt_msl_m, qnh_arr) - hp_dep)
        # placed in the output plane at its height (without one, the field's elevation plus
        # the pressure height: the plane's north and east move 1.6 m per km of height at 10 km)
        h_f = msl_to_ellipsoid(meta.departure.elev_m + y_T if fix_end.alt_msl_m is None
                               else fix_end.alt_msl_m, meta.geoid_undulation_m)
        e, n, _u = plane.forward(fix_end.lat_deg, fix_end.lon_deg, h_f)
        source = f"fix at t = {fix_end.t_s:g} s"
    end_ned = np.array([float(n) - origin[0], float(e) - origin[1], -(y_T - origin[2])])
    return end_ned, {"north_m": float(n), "east_m": float(e), "up_m": float(y_T),
                     ("up_geometric_m" if geometric else "up_pressure_m"): float(y_T),
                     "departure_pressure_alt_m": hp_dep,
                     "liftoff_point_m": [float(x) for x in origin], "source": source}


def _liftoff_velocity(clean: CleanFlight, t, h_rel, cols, psi, wind, notes,
                      given: tuple[float, float, float] | None = None) -> np.ndarray:
    """The ground velocity at lift-off (north, east, down) [m/s]: ``given`` (checked), else
    the phases' from the ground roll, else the air-derived velocity (plus wind) and the 2 s
    baro climb rate at the first sample (module docstring)."""
    if given is not None:
        v0 = np.asarray(given, dtype=np.float64)
        if v0.shape != (3,) or not np.all(np.isfinite(v0)):
            raise ValidationError("liftoff_velocity_ned must be three finite numbers")
        return v0
    ph = clean.phases
    if ph is not None and not ph.starts_airborne \
            and np.all(np.isfinite(ph.liftoff_velocity_ned_mps)):
        return np.asarray(ph.liftoff_velocity_ned_mps, dtype=np.float64)
    n_fit = max(2, min(len(t), round(2.0 / (t[1] - t[0])) + 1))
    climb = float(np.polyfit(t[:n_fit] - t[0], h_rel[:n_fit], 1)[0])
    vn, ve = air_velocity(cols["tas_mps"][:1], psi[:1], np.array([climb]),
                          None if wind is None else wind[:1])
    notes.append("lift-off velocity not known from the ground roll: air-derived velocity"
                 f"{' plus wind' if wind is not None else ''} and the 2 s baro climb rate at "
                 "the first sample")
    return np.array([float(vn[0]), float(ve[0]), -climb])


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
    (:func:`flightrecon.methods.sabziev.solve.vertical_target_w`).

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
    from flightrecon.methods.sabziev.solve import TAU_FALLBACK_S, vertical_target_w

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


def _conditioning(sol: SabzievSolution, axes: dict[str, Any]) -> None:
    """Add to each axis with a root its end-point sensitivity ``dF_dk`` (exact, the diagonal of
    the sensitivity recursion at the end) and ``k_sd = K_SD_END_M / |dF/dk|``."""
    for name in ("x", "y", "z"):
        ax = sol.axes[name]
        if ax.report is None or not ax.report.converged or ax.fallback:
            continue
        d = float(np.asarray(ax.dposition_dk)[-1])
        axes[name]["dF_dk"] = _num(d)
        axes[name]["k_sd"] = _num(K_SD_END_M / abs(d)) if d != 0.0 else None


LIFTOFF_SD_M = 1000.0
"""Horizontal sd [m] of the lift-off point when it is not given (the departure airfield's
reference point stands for it: 1-3 km from the real lift-off point on airfields, 800 m in the
simulator), added in quadrature to the spread from ``k_sd`` in the ``*_sd_m`` columns: without
it the sd is zero at lift-off, which the pipeline's health check rightly refuses."""

LIFTOFF_GIVEN_SD_M = 10.0
"""The same when the lift-off point is given (``liftoff=``)."""


def _track(t_all, sl, sol: SabzievSolution, k_sd, origin: np.ndarray,
           origin_sd_m: float = 0.0) -> pd.DataFrame:
    """The output columns, built in one (N, m) float block (one DataFrame block, no copies);
    with ``k_sd`` the sd columns, the horizontal ones with ``origin_sd_m`` in quadrature."""
    n = len(t_all)
    names = (("sabziev_north_m", 0), ("sabziev_east_m", 2), ("sabziev_up_m", 1))
    vnames = (("sabziev_vn_mps", 0), ("sabziev_ve_mps", 2), ("sabziev_vu_mps", 1))
    offset = (origin[0], origin[2], origin[1])  # Sabziev order: north, up, east
    cols = ["t_s"] + [c for c, _ in names] + [c for c, _ in vnames]
    if k_sd is not None:
        # order as before: per axis (north, up, east) the position then the velocity spread
        for (cname, _), (vname, _) in zip(sorted(names, key=lambda x: x[1]),
                                          sorted(vnames, key=lambda x: x[1])):
            cols += [cname.replace("_m", "_sd_m"), vname.replace("_mps", "_sd_mps")]
    block = np.full((n, len(cols)), np.nan)
    block[:, 0] = t_all
    for c, (_cname, j) in enumerate(names, start=1):
        block[sl, c] = sol.xyz_m[:, j] + offset[j]
    for c, (_vname, j) in enumerate(vnames, start=4):
        block[sl, c] = sol.vxyz_mps[:, j]
    if k_sd is not None:
        psd = sol.position_sd_m(k_sd)
        vsd = sol.velocity_sd_mps(k_sd)
        for j in range(3):
            floor = origin_sd_m if j != 1 else 0.0  # horizontal (north 0, east 2) only
            block[sl, 7 + 2 * j] = np.hypot(psd[:, j], floor)
            block[sl, 8 + 2 * j] = vsd[:, j]
    return pd.DataFrame(block, columns=cols, copy=False)


def _bridge_sd_columns(track: pd.DataFrame, sl: slice, t: np.ndarray, start_sd_m: float,
                       end_sd_m: float) -> dict[str, Any]:
    """The horizontal sd columns of a boundary-value track without a fleet spread of ``k``
    (``sabziev_north_sd_m``, ``sabziev_east_sd_m``, in place on ``track``'s rows ``sl``): the
    stable track is in effect a dead reckoning corrected to both ends, and its sd that of
    :func:`flightrecon.methods.baselines.corrected_track_sd_m` (the lift-off point's sd, the
    end point's, the wind's random walk between them).  Returns the model's summary entry."""
    sd = corrected_track_sd_m(t, float(t[0]), float(t[-1]), start_sd_m, end_sd_m)
    for c in ("sabziev_north_sd_m", "sabziev_east_sd_m"):
        col = np.full(len(track), np.nan)
        col[sl] = sd
        track[c] = col
    return {"model": "dead reckoning corrected to both ends (fusion.baselines."
                     "corrected_track_sd_m)", "start_sd_m": start_sd_m, "end_sd_m": end_sd_m,
            "wind_walk_mps_sqrt_s": DR_WALK_MPS_SQRT_S, "largest_sd_m": float(np.max(sd))}


def _num(x: float) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None


def _summary(sol: SabzievSolution, k, k_sd, t, v0, end_info, warn, hold, rule) -> dict:
    axes = {}
    history = {}
    for name, ax in sol.axes.items():
        if ax.report is None:
            axes[name] = {"converged": True, "k": _num(ax.k), "mode": "initial-value"}
            continue
        d = ax.report.as_dict()
        history[name] = d.pop("history")
        d["k_used"] = _num(ax.k)
        d["fallback"] = bool(ax.fallback)
        d["end_correction_m"] = _num(ax.correction_m)
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
        "k1": _num(sol.k[0]), "k2": _num(sol.k[1]), "k3": _num(sol.k[2]),
        "k_sd": None if k_sd is None else [float(x) for x in k_sd],
        "axes": axes,
        "history": history,
        "end_point": end_info,
        "end_residual_m": {"north": _num(res[0]), "up": _num(res[1]), "east": _num(res[2])},
        "interval_s": [float(t[0]), float(t[-1])],
        "liftoff_velocity_ned_mps": [float(x) for x in v0],
        "wind_modelled": bool(sol.wind_modelled),
        "hold": hold,
        "vertical_rule": rule,
        "warnings": warn,
    }
