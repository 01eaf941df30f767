"""Normal gravity of the WGS-84 ellipsoid (Somigliana) with the ellipsoidal free-air correction.

Implements NIMA TR8350.2 (WGS-84, 3rd ed.), eq. (4-1) for the surface value and eq. (4-3) for the
height dependence; used by :func:`flightrecon.geo.kinematics.kinematic_acceleration_ned`
(docs/schema.md, "Conventions": ``a_NED = C_nb g0 [n_long, n_lat, -n_norm] + [0, 0, g(lat, h)]``).
Normal gravity includes the centrifugal acceleration of the earth's rotation; it ignores the
gravity anomaly and deflection of the vertical (tens of mGal, a few arc-seconds).
"""

from __future__ import annotations

import numpy as np

from flightrecon.geo.wgs84 import WGS84_A, WGS84_E2, WGS84_F

__all__ = ["GAMMA_EQUATOR", "GAMMA_POLE", "normal_gravity"]

GAMMA_EQUATOR = 9.7803253359
"""Normal gravity on the ellipsoid at the equator [m/s^2] (TR8350.2 table 3.4)."""
GAMMA_POLE = 9.8321849378
"""Normal gravity on the ellipsoid at the poles [m/s^2] (TR8350.2 table 3.4)."""
_K_SOMIGLIANA = 0.00193185265241
"""Somigliana's constant k = (b gamma_p) / (a gamma_e) - 1 (TR8350.2 table 3.4)."""
_M_RATIO = 0.00344978650684
"""m = omega^2 a^2 b / GM (TR8350.2 table 3.4)."""


def normal_gravity(lat_deg, h_m=0.0):
    """Magnitude of normal gravity [m/s^2] at geodetic latitude and ellipsoidal height.

    Parameters
    ----------
    lat_deg : array_like
        Geodetic latitude [deg].
    h_m : array_like
        Height above the WGS-84 ellipsoid [m] (broadcast against ``lat_deg``).

    Returns
    -------
    numpy.ndarray
        ``gamma_h = gamma (1 - 2/a (1 + f + m - 2 f sin^2 phi) h + 3 h^2 / a^2)`` with Somigliana's
        ``gamma = gamma_e (1 + k sin^2 phi) / sqrt(1 - e^2 sin^2 phi)`` (TR8350.2 eqs. 4-1, 4-3).

    Examples
    --------
    >>> round(float(normal_gravity(0.0, 0.0)), 10)
    9.7803253359
    """
    s2 = np.sin(np.radians(np.asarray(lat_deg, float))) ** 2
    h = np.asarray(h_m, float)
    gamma = GAMMA_EQUATOR * (1.0 + _K_SOMIGLIANA * s2) / np.sqrt(1.0 - WGS84_E2 * s2)
    return gamma * (1.0 - 2.0 / WGS84_A * (1.0 + WGS84_F + _M_RATIO - 2.0 * WGS84_F * s2) * h
                    + 3.0 * h * h / WGS84_A**2)
