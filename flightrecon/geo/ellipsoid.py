"""The WGS-84 ellipsoid: its parameters (:mod:`flightrecon.geo.wgs84`, equal to PROJ's) and its
radii of curvature.

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

from flightrecon.geo.wgs84 import WGS84_A, WGS84_E2, WGS84_F

__all__ = ["WGS84_A", "WGS84_E2", "WGS84_F", "radii_from_sin"]

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
