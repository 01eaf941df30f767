"""Radar geometry shared by the methods that use range/azimuth plots: horizontal range from the
slant range, and the drop of the station's tangent plane below the aircraft.

The station's tangent plane leaves the ellipsoid as ``r^2 / (2 R)`` at horizontal range ``r``
(785 m at 100 km), with ``R = sqrt(M N)`` the Gaussian radius of curvature of WGS-84 at the
station (:mod:`flightrecon.geo.ellipsoid`).  An aircraft ``dh`` above the station (same datum)
is ``u = dh - r^2 / (2 R)`` above the plane, and the slant range ``rho`` satisfies
``r^2 + u^2 = rho^2`` (docs/arms.md, "Frames and heights in the adapter").  Refraction is
ignored.
"""

from __future__ import annotations

import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.geo.ellipsoid import radii_from_sin


def gaussian_radius_m(lat_deg: float) -> float:
    """Gaussian radius of curvature ``sqrt(M N)`` of WGS-84 [m] at ``lat_deg``."""
    m, n = radii_from_sin(np.sin(np.radians(float(lat_deg))))
    return float(np.sqrt(m * n))


def plane_drop_m(r_m, lat_deg: float) -> np.ndarray:
    """Drop ``r^2 / (2 R)`` [m] of a tangent plane at ``lat_deg`` below the ellipsoid at
    horizontal distance ``r_m`` from its origin (``R`` the Gaussian radius there)."""
    r = np.asarray(r_m, dtype=np.float64)
    return r * r / (2.0 * gaussian_radius_m(lat_deg))


def horizontal_range(slant_m, *, lat_deg: float, elevation_deg=None, dh_m=None) -> np.ndarray:
    """Horizontal range in the station's tangent plane from the radar's slant range.

    With the elevation angle: ``r = rho cos(el)``.  With the altitude difference ``dh``
    (aircraft minus station, metres above the same datum): ``r`` solves
    ``r^2 + (dh - r^2 / (2 R))^2 = rho^2``; two fixed-point steps from
    ``r0 = sqrt(rho^2 - dh^2)`` converge to well under a metre below 500 km.  Without either,
    the slant range is returned unchanged.

    Parameters
    ----------
    slant_m : array_like, slant ranges [m]
    lat_deg : the station's latitude (for the Gaussian radius)
    elevation_deg, dh_m : array_like, optional

    Raises
    ------
    ValidationError
        If the altitude difference exceeds the slant range (inconsistent data).
    """
    rho = np.asarray(slant_m, dtype=np.float64)
    if elevation_deg is not None:
        return rho * np.cos(np.deg2rad(np.asarray(elevation_deg, dtype=np.float64)))
    if dh_m is None:
        return rho.copy()
    dh = np.asarray(dh_m, dtype=np.float64)
    r2 = rho ** 2 - dh ** 2
    if np.any(r2 < 0):
        raise ValidationError("radar plots: altitude difference to the station exceeds the slant "
                              "range; check the station elevation and the altitude datum",
                              rows=np.flatnonzero(r2 < 0)[:20] + 1)
    R = gaussian_radius_m(lat_deg)
    r = np.sqrt(r2)
    for _ in range(2):
        u = dh - r ** 2 / (2.0 * R)
        r = np.sqrt(np.maximum(rho ** 2 - u ** 2, 0.0))
    return r
