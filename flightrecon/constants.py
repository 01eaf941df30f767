"""Physical constants (SI)."""

G0 = 9.80665
"""Standard gravity [m/s^2]: the unit of load factor, not the local gravity."""

KNOT_MPS = 1852.0 / 3600.0
FOOT_M = 0.3048
FPM_MPS = FOOT_M / 60.0
HPA_PA = 100.0

# WGS-84 (for reference and for the normal-gravity formula; geodesy itself goes through pyproj)
WGS84_A = 6378137.0
WGS84_F = 1.0 / 298.257223563
WGS84_E2 = WGS84_F * (2.0 - WGS84_F)
WGS84_OMEGA = 7.292115e-5
