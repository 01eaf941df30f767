"""Physical constants (SI)."""

G0 = 9.80665
"""Standard gravity [m/s^2]: the unit of load factor, not the local gravity."""

KNOT_MPS = 1852.0 / 3600.0
FOOT_M = 0.3048
FPM_MPS = FOOT_M / 60.0
HPA_PA = 100.0

# WGS-84: the ellipsoid's defining parameters are in flightrecon.geo.wgs84 (equal to PROJ's; no
# heavy import), its radii of curvature from one formula in flightrecon.geo.ellipsoid; geodesy
# itself goes through pyproj

WGS84_OMEGA = 7.292115e-5
"""Earth rotation rate [rad/s] (WGS-84 defining constant)."""

__all__ = ["FOOT_M", "FPM_MPS", "G0", "HPA_PA", "KNOT_MPS", "WGS84_OMEGA"]
