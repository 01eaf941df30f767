"""The Sabziev adapter's inputs from a cleaned flight (docs/sabziev.md, "The adapter"): the
interval, the channels on it, the kinematic acceleration, the lift-off origin and velocity,
the wind, the end point and where it comes from, and the heading's reference."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from flightrecon.errors import (
    MetadataError,
    SchemaError,
    ValidationError,
)
from flightrecon.geo.atmosphere import field_pressure_altitude_m
from flightrecon.geo.wind import wind_toward_ne
from flightrecon.methods.sabziev import air_velocity
from flightrecon.types import CleanFlight, FlightMeta, Position, PositionFix

END_FIX_TOLERANCE_S = 2.0
"""A known position this close to the end of the fusion interval [s] (or two grid steps, if
longer) serves as its end point when there is no arrival position."""

REQUIRED_CHANNELS = ("n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg", "heading_deg",
                     "tas_mps", "baro_alt_m")


def flight_interval(clean: CleanFlight, t: np.ndarray) -> tuple[int, int, list[str]]:
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
        _i0, i1, _notes = flight_interval(clean, t)
    except ValidationError:
        return None
    tol = max(END_FIX_TOLERANCE_S, 2.0 * float(np.median(np.diff(t))))
    near = [f for f in fixes if abs(f.t_s - t[i1]) <= tol]
    return near[-1] if near else None


def grid_column(grid: pd.DataFrame, name: str, sl: slice, notes: list[str]) -> np.ndarray:
    x = grid[name].to_numpy(dtype=np.float64)[sl].copy()
    bad = ~np.isfinite(x)
    if bad.all():
        raise ValidationError("no valid samples between lift-off and touchdown", column=name)
    if bad.any():
        idx = np.arange(len(x))
        x[bad] = np.interp(idx[bad], idx[~bad], x[~bad])
        notes.append(f"{name}: {int(bad.sum())} missing samples bridged linearly for the fusion")
    return x



def heading_reference(clean: CleanFlight) -> str:
    """What the grid's ``heading_deg`` is measured from: ``"grid"`` when the cleaning propagated
    it from the body rates anchored by runway rolls only (the report's ``heading_reference``;
    docs/sabziev.md, "Flat frame and a curved Earth"), else ``"true"`` (a recorded heading)."""
    for r in clean.report:
        if r.get("action") == "heading_from_rates":
            return str(r.get("heading_reference", "true"))
    return "true"


def end_sources(clean: CleanFlight, arrival: Position | None,
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


def acceleration_on_interval(clean: CleanFlight, cols: dict[str, np.ndarray], sl: slice, n_all: int,
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


def liftoff_origin(meta: FlightMeta, plane: Any, liftoff: Position | None,
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


def wind_on_interval(grid: pd.DataFrame, meta: FlightMeta, sl: slice,
          notes: list[str]) -> tuple[np.ndarray | None, str]:
    """The wind (toward north, east) [m/s] on the interval ``sl`` and where it came from:
    the recorded wind, else the winds-aloft table at the recorded altitude (docs/wind.md),
    else ``(None, "none")``."""
    if all(c in grid.columns and np.isfinite(grid[c].to_numpy(dtype=float)[sl]).any()
           for c in ("wind_speed_mps", "wind_from_deg")):
        return (wind_toward_ne(grid_column(grid, "wind_speed_mps", sl, notes),
                               grid_column(grid, "wind_from_deg", sl, notes)), "recorded")
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


def end_point_ned(meta: FlightMeta, plane: Any, arr: Position | None, fix_end: PositionFix | None,
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


def liftoff_velocity(clean: CleanFlight, t, h_rel, cols, psi, wind, notes,
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
