"""The Sabziev track on the ellipsoid (docs/sabziev.md, "The curvilinear frame"): the
flat-frame solution re-expressed as distances along the surface, and the fit in that frame."""

from __future__ import annotations

from typing import Any

import numpy as np

from flightrecon.methods.sabziev import SabzievSolution, fuse
from flightrecon.types import FlightMeta

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


def surface_fit(sol: SabzievSolution, plane: Any, meta: FlightMeta, origin: np.ndarray,
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
