"""The output frame's origin for a flight with no departure airfield.

A tangent plane needs a point, not an airfield.  When the metadata give no departure, the first
GNSS fix (latitude, longitude, and its height where recorded) places the frame; without GNSS,
the first radar plot of a known station (range, azimuth and elevation, or the pressure altitude
where the elevation is missing).  The height is stored as MSL elevation like an airfield's:
the fix's height minus the geoid undulation for an ellipsoidal datum, else the pressure altitude
at the fix's time (a frame origin need not be exact in height: every estimator works in
geodetic or ECEF coordinates and the plane is an output convenience, docs/schema.md "Frames").
The origin is never used as an airfield: no end point, no field level, no runway.
"""

from __future__ import annotations

import dataclasses

import numpy as np
import pandas as pd

from flightrecon.cleaning.report import report_entry
from flightrecon.types import FlightMeta, Position

__all__ = ["frame_origin", "with_origin"]


def _baro_at(grid: pd.DataFrame, t: float) -> float:
    if "baro_alt_m" not in grid.columns or not len(grid):
        return 0.0
    b = grid["baro_alt_m"].to_numpy(float)
    tt = grid["t_s"].to_numpy(float)
    ok = np.isfinite(b)
    return float(np.interp(t, tt[ok], b[ok])) if ok.any() else 0.0


def frame_origin(meta: FlightMeta, grid: pd.DataFrame, gnss: pd.DataFrame,
                 radar: pd.DataFrame) -> tuple[Position | None, str]:
    """The origin (module docstring) and how it was found; ``(None, why)`` if there is no fix."""
    if len(gnss) and {"gnss_lat_deg", "gnss_lon_deg"} <= set(gnss.columns):
        lat = gnss["gnss_lat_deg"].to_numpy(float)
        lon = gnss["gnss_lon_deg"].to_numpy(float)
        ok = np.flatnonzero(np.isfinite(lat) & np.isfinite(lon))
        if len(ok):
            i = int(ok[0])
            t = float(gnss["t_s"].iloc[i])
            h = float(gnss["gnss_alt_m"].iloc[i]) if "gnss_alt_m" in gnss.columns else np.nan
            if np.isfinite(h):
                elev = h - meta.geoid_undulation_m if meta.gnss_alt_datum.lower() != "msl" else h
                how = f"first GNSS fix (t = {t:.2f} s) with its height"
            else:
                elev = _baro_at(grid, t)
                how = f"first GNSS fix (t = {t:.2f} s), height from the pressure altitude"
            return Position(float(lat[i]), float(lon[i] - 360.0 * (lon[i] > 180.0)), elev), how
    st = meta.station
    if st is not None and len(radar) and {"arms_range_m", "arms_azimuth_deg"} <= set(radar.columns):
        r = radar["arms_range_m"].to_numpy(float)
        az = radar["arms_azimuth_deg"].to_numpy(float)
        ok = np.flatnonzero(np.isfinite(r) & np.isfinite(az))
        if len(ok):
            from flightrecon.geo.frames import offset_latlon

            i = int(ok[0])
            t = float(radar["t_s"].iloc[i])
            elev = _baro_at(grid, t)
            el = (float(radar["arms_elevation_deg"].iloc[i])
                  if "arms_elevation_deg" in radar.columns else np.nan)
            if np.isfinite(el):
                rh = r[i] * np.cos(np.radians(el))
            else:
                dz = elev - st.elev_m
                rh = float(np.sqrt(max(r[i] ** 2 - dz ** 2, 0.0)))
            lat, lon = offset_latlon(st.lat_deg, st.lon_deg, rh * np.cos(np.radians(az[i])),
                                     rh * np.sin(np.radians(az[i])))
            return (Position(lat, lon, elev),
                    f"first radar plot (t = {t:.2f} s) from the station, height from the "
                    "pressure altitude")
    return None, "no GNSS fix and no radar plot with a station"


def with_origin(meta: FlightMeta, grid: pd.DataFrame, gnss: pd.DataFrame,
                radar: pd.DataFrame) -> tuple[FlightMeta, list[dict]]:
    """``meta`` with ``origin`` set when it has no departure (and no origin yet), and the
    report entry saying so."""
    if meta.departure is not None or meta.origin is not None:
        return meta, []
    o, how = frame_origin(meta, grid, gnss, radar)
    if o is None:
        return meta, [report_entry("frame", "no_origin", f"no departure airfield and {how}: "
                                   "give --departure", count=0)]
    return dataclasses.replace(meta, origin=o), [report_entry(
        "frame", "origin", f"no departure airfield: the output frame's origin is the {how} "
        "(not an airfield: no end point, no field level)", count=1, lat_deg=o.lat_deg,
        lon_deg=o.lon_deg, elev_m=o.elev_m)]
