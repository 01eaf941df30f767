"""The WGS-84 ellipsoid's defining parameters, without any heavy import.

The semi-major axis and the inverse flattening are the two defining geometric parameters of
WGS-84 (NIMA TR8350.2, table 3.1): exact by definition.  They are written here rather than read
from PROJ at import so that every module (the ingest included) can use them without importing
pyproj; ``tests/test_foundation.py`` checks that they equal PROJ's ``WGS84`` ellipsoid to the
last bit.  The radii of curvature are :func:`flightrecon.geo.ellipsoid.radii_from_sin`.
"""

from __future__ import annotations

__all__ = ["WGS84_A", "WGS84_E2", "WGS84_F", "WGS84_INVERSE_FLATTENING"]

WGS84_A: float = 6378137.0
"""Semi-major axis [m] (defining parameter)."""
WGS84_INVERSE_FLATTENING: float = 298.257223563
"""Inverse flattening 1/f (defining parameter)."""
WGS84_F: float = 1.0 / WGS84_INVERSE_FLATTENING
"""Flattening."""
WGS84_E2: float = WGS84_F * (2.0 - WGS84_F)
"""First eccentricity squared."""
