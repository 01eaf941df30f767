"""The WGS-84 ellipsoid: its parameters from PROJ (through pyproj) and its radii of curvature.

One formula for the radii, compiled with numba so that the kernels call it per sample; on numpy
arrays it runs element-wise.  With ``w = 1 - e^2 sin^2(lat)``::

    N = a / sqrt(w)                (prime vertical, east-west)
    M = N (1 - e^2) / w            (meridian, north-south)

A move of ``dn`` metres north and ``de`` east at height ``h`` changes the latitude by
``dn / (M + h)`` and the longitude by ``de / ((N + h) cos(lat))`` (docs/schema.md, "Frames").
"""

from __future__ import annotations

import numba as nb
import numpy as np
from pyproj.crs import Ellipsoid

_WGS84 = Ellipsoid.from_name("WGS84")

WGS84_A: float = float(_WGS84.semi_major_metre)
"""Semi-major axis [m] (PROJ's WGS 84: 6378137)."""
WGS84_F: float = 1.0 / float(_WGS84.inverse_flattening)
"""Flattening (PROJ's WGS 84: 1 / 298.257223563)."""
WGS84_E2: float = WGS84_F * (2.0 - WGS84_F)
"""First eccentricity squared."""

_A = WGS84_A
_E2 = WGS84_E2


@nb.njit(cache=True, nogil=True)
def radii_from_sin(sin_lat):
    """Meridian and prime-vertical radii ``(M, N)`` [m] at the latitude whose sine is given.

    ``sin_lat`` a float or an array (element-wise).  Module docstring for the formula.
    """
    w = 1.0 - _E2 * sin_lat * sin_lat
    n = _A / np.sqrt(w)
    return n * (1.0 - _E2) / w, n
