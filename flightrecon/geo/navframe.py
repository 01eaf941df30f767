"""Moving local-level (north-east-down) frame for estimators on long flights.

docs/schema.md, "Frames": a tangent plane at the departure airfield fails over long flights, so
estimators propagate latitude, longitude and ellipsoidal height with north/east/up velocity in a
frame that moves with the aircraft; the tangent plane is only an output convenience.

The position rates are the standard geodetic kinematic equations (Titterton & Weston,
*Strapdown Inertial Navigation Technology*, eq. 3.79; Groves, *Principles of GNSS, Inertial and
Multisensor Integrated Navigation Systems*, eq. 5.56)::

    d(lat)/dt = v_N / (R_M(lat) + h),   d(lon)/dt = v_E / ((R_N(lat) + h) cos lat),   dh/dt = v_U

with the meridian and prime-vertical radii of curvature of WGS-84.  Conversions to and from
ECEF go through pyproj (:mod:`flightrecon.geo.frames`); no ellipsoid inversion is hand-written.
Valid away from the poles (``|lat| < 89.9 deg``, where the longitude rate is singular).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flightrecon.constants import WGS84_OMEGA
from flightrecon.errors import ValidationError
from flightrecon.geo.ellipsoid import radii_from_sin
from flightrecon.geo.frames import ecef_to_geodetic, geodetic_to_ecef
from flightrecon.geo.wgs84 import WGS84_A, WGS84_E2

__all__ = [
    "MAX_ABS_LAT_DEG",
    "ecef_to_geodetic",
    "ecef_to_ned_vector",
    "geodetic_to_ecef",
    "integrate_local_level",
    "ned_to_ecef_matrix",
    "ned_to_ecef_vector",
    "horizontal_rotation",
    "north_azimuth_in_plane",
    "radii_of_curvature",
    "transport_rate_ned",
    "frame_rate_acceleration",
]

MAX_ABS_LAT_DEG = 89.9
"""Latitude limit of the local-level propagation (the longitude rate diverges at the poles)."""

_MAX_SUBSTEP_M = 5000.0
"""Longest distance covered by one RK4 sub-step; the local truncation error scales as
(step / R)^5 R, i.e. below 1e-12 m for 5 km steps."""


def radii_of_curvature(lat_deg):
    """Meridian and prime-vertical radii of curvature of WGS-84 [m] at ``lat_deg``.

    ``R_M = a (1 - e^2) / (1 - e^2 sin^2 lat)^(3/2)``, ``R_N = a / sqrt(1 - e^2 sin^2 lat)``
    (Groves eqs. 2.105-2.106), by :func:`flightrecon.geo.ellipsoid.radii_from_sin`.

    Returns
    -------
    (R_M, R_N) : tuple of numpy.ndarray
    """
    # the formula's Python function on the arrays (numpy, the same operations element by
    # element, so the same numbers): the compiled kernel serves the kernels' scalars, and an
    # array specialisation of it cost 0.3 s of a cold start's compilation
    return radii_from_sin.py_func(np.sin(np.radians(np.asarray(lat_deg, float))))


def ned_to_ecef_matrix(lat_deg, lon_deg) -> np.ndarray:
    """Rotation matrices ``C_en`` (NED -> ECEF), shape (N, 3, 3) (Groves eq. 2.150, transposed).

    Columns are the north, east and down unit vectors expressed in ECEF.
    """
    lat, lon = np.broadcast_arrays(np.radians(np.atleast_1d(np.asarray(lat_deg, float))),
                                   np.radians(np.atleast_1d(np.asarray(lon_deg, float))))
    sl, cl = np.sin(lat), np.cos(lat)
    so, co = np.sin(lon), np.cos(lon)
    C = np.empty(lat.shape + (3, 3))
    C[..., 0, 0], C[..., 0, 1], C[..., 0, 2] = -sl * co, -so, -cl * co
    C[..., 1, 0], C[..., 1, 1], C[..., 1, 2] = -sl * so, co, -cl * so
    C[..., 2, 0], C[..., 2, 1], C[..., 2, 2] = cl, 0.0, -sl
    return C


def horizontal_rotation(from_lat_deg, from_lon_deg, to_lat_deg, to_lon_deg) -> np.ndarray:
    """Matrices ``M`` (N, 2, 2) with ``[n, e]_to = M [n, e]_from`` for horizontal vectors.

    A horizontal vector given in the local-level north/east axes at ``from`` (a tangent plane's
    axes are those at its origin) is expressed in the local-level north/east axes at ``to``:
    ``M`` is the horizontal block of ``C_ne(to) C_en(from)`` (:func:`ned_to_ecef_matrix`).  Its
    main effect is the rotation by the meridian convergence, about ``dlon sin(lat)``; the block
    drops the small vertical component that the vector acquires at ``to`` (``sin`` of the angle
    between the two verticals, 3e-3 at 20 km).  Covariances rotate as ``M C M^T``.
    """
    Cf = ned_to_ecef_matrix(from_lat_deg, from_lon_deg)
    Ct = ned_to_ecef_matrix(to_lat_deg, to_lon_deg)
    M = np.einsum("...ki,...kj->...ij", Ct, Cf)
    return np.ascontiguousarray(M[..., :2, :2])


def north_azimuth_in_plane(plane_lat_deg: float, plane_lon_deg: float, lat_deg, lon_deg
                           ) -> np.ndarray:
    """Azimuth [rad] of true north at ``(lat, lon)`` in a tangent plane's axes (the meridian
    convergence), clockwise from the plane's north.

    Exact: the local north unit vector at the point, ``n_p = C_en(point) e_N``, projected on the
    plane's north and east axes, ``gamma = atan2(E_0 . n_p, N_0 . n_p)`` (no finite
    difference); about ``dlon sin(lat)``.
    """
    lat, lon = np.broadcast_arrays(np.radians(np.atleast_1d(np.asarray(lat_deg, float))),
                                   np.radians(np.atleast_1d(np.asarray(lon_deg, float))))
    l0, o0 = np.radians(float(plane_lat_deg)), np.radians(float(plane_lon_deg))
    sl, cl, so, co = np.sin(lat), np.cos(lat), np.sin(lon), np.cos(lon)
    sl0, cl0, so0, co0 = np.sin(l0), np.cos(l0), np.sin(o0), np.cos(o0)
    # n_p = (-sl co, -sl so, cl); N_0 = (-sl0 co0, -sl0 so0, cl0); E_0 = (-so0, co0, 0)
    dot_n = sl0 * sl * (co0 * co + so0 * so) + cl0 * cl
    dot_e = sl * (so0 * co - co0 * so)
    return np.arctan2(dot_e, dot_n)


def ned_to_ecef_vector(lat_deg, lon_deg, v_ned) -> np.ndarray:
    """Rotate NED vectors (N, 3) into ECEF (N, 3) at the given positions."""
    C = ned_to_ecef_matrix(lat_deg, lon_deg)
    return np.einsum("...ij,...j->...i", C, np.asarray(v_ned, float))


def ecef_to_ned_vector(lat_deg, lon_deg, v_ecef) -> np.ndarray:
    """Rotate ECEF vectors (N, 3) into NED (N, 3) at the given positions."""
    C = ned_to_ecef_matrix(lat_deg, lon_deg)
    return np.einsum("...ji,...j->...i", C, np.asarray(v_ecef, float))


def transport_rate_ned(lat_deg, h_m, vn_mps, ve_mps) -> np.ndarray:
    """Transport rate ``omega_en`` of the local-level frame, NED components [rad/s], (N, 3).

    ``omega_en = [v_E / (R_N + h), -v_N / (R_M + h), -v_E tan(lat) / (R_N + h)]``
    (Groves eq. 5.44): the rotation of the north-east-down frame as it is carried over the
    curved earth (about 4e-5 rad/s at 250 m/s; a heading rate of 2.2 deg/min).
    """
    lat_deg, h, vn, ve = np.broadcast_arrays(*(np.atleast_1d(np.asarray(a, float))
                                               for a in (lat_deg, h_m, vn_mps, ve_mps)))
    rm, rn = radii_of_curvature(lat_deg)
    lat = np.radians(lat_deg)
    return np.stack(np.broadcast_arrays(ve / (rn + h), -vn / (rm + h),
                                        -ve * np.tan(lat) / (rn + h)), axis=-1)


def frame_rate_acceleration(lat_deg, h_m, v_ned) -> np.ndarray:
    """The acceleration of an Earth-relative NED velocity that the accelerometers do not
    sense: ``-(2 omega_ie + omega_en) x v`` [m/s^2], (N, 3) (Coriolis and transport rate).

    With ``omega_ie = Omega (cos(lat), 0, -sin(lat))`` the Earth's rate and ``omega_en`` the
    transport rate (:func:`transport_rate_ned`), the velocity obeys
    ``dv/dt = f + g - (2 omega_ie + omega_en) x v`` (Groves eq. 5.54; ``f + g`` is
    :func:`~flightrecon.geo.kinematics.kinematic_acceleration_ned`).  At 230 m/s and 50 deg
    latitude the Coriolis part alone is 0.026 m/s^2 (2.6 mg), always to the right of the track in
    the northern hemisphere: over an hour of cruise, 90 m/s of velocity or, held by an
    accelerometer bias, that bias wrong by 2.6 mg.
    """
    v = np.atleast_2d(np.asarray(v_ned, float))
    lat_deg = np.broadcast_to(np.asarray(lat_deg, float), (len(v),))
    w_en = transport_rate_ned(lat_deg, h_m, v[:, 0], v[:, 1])
    lat = np.radians(lat_deg)
    w_ie = WGS84_OMEGA * np.c_[np.cos(lat), np.zeros(len(v)), -np.sin(lat)]
    return -np.cross(2.0 * w_ie + w_en, v)


@nb.njit(cache=True, nogil=True)
def _rates(lat, h, vn, ve, vu, a, e2):
    rm, rn = radii_from_sin(np.sin(lat))
    return vn / (rm + h), ve / ((rn + h) * np.cos(lat)), vu


@nb.njit(cache=True, nogil=True)
def _integrate_kernel(lat0, lon0, h0, vn, ve, vu, dt, a, e2, max_sub_m):
    n = vn.shape[0]
    lat = np.empty(n + 1)
    lon = np.empty(n + 1)
    h = np.empty(n + 1)
    lat[0], lon[0], h[0] = lat0, lon0, h0
    for k in range(n):
        dist = np.sqrt(vn[k] ** 2 + ve[k] ** 2 + vu[k] ** 2) * dt[k]
        nsub = int(np.ceil(dist / max_sub_m)) if dist > max_sub_m else 1
        hs = dt[k] / nsub
        p, q, r = lat[k], lon[k], h[k]
        for _ in range(nsub):
            k1 = _rates(p, r, vn[k], ve[k], vu[k], a, e2)
            k2 = _rates(p + 0.5 * hs * k1[0], r + 0.5 * hs * k1[2], vn[k], ve[k], vu[k], a, e2)
            k3 = _rates(p + 0.5 * hs * k2[0], r + 0.5 * hs * k2[2], vn[k], ve[k], vu[k], a, e2)
            k4 = _rates(p + hs * k3[0], r + hs * k3[2], vn[k], ve[k], vu[k], a, e2)
            p += hs / 6.0 * (k1[0] + 2.0 * k2[0] + 2.0 * k3[0] + k4[0])
            q += hs / 6.0 * (k1[1] + 2.0 * k2[1] + 2.0 * k3[1] + k4[1])
            r += hs / 6.0 * (k1[2] + 2.0 * k2[2] + 2.0 * k3[2] + k4[2])
        lat[k + 1], lon[k + 1], h[k + 1] = p, q, r
    return lat, lon, h


def integrate_local_level(lat0_deg: float, lon0_deg: float, h0_m: float, vn_mps, ve_mps, vu_mps,
                          dt_s) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Propagate geodetic position from north/east/up velocities held constant over each step.

    Integrates the geodetic position equations (module docstring) with the velocity
    ``(vn[k], ve[k], vu[k])`` held constant over step ``k`` of length ``dt[k]``, by classical
    Runge-Kutta (sub-stepped to at most 5 km per sub-step).  The ODE right-hand side is smooth
    in latitude and height, so the result is exact for piecewise-constant velocity to far below a
    millimetre (tested against pyproj's geodesic over 400 km legs).  Compiled with numba.

    Parameters
    ----------
    lat0_deg, lon0_deg, h0_m : float
        Initial geodetic latitude, longitude [deg] and ellipsoidal height [m].
    vn_mps, ve_mps, vu_mps : array_like, shape (N,)
        North, east, up velocity over each step [m/s].
    dt_s : float or array_like, shape (N,)
        Step lengths [s], each > 0.

    Returns
    -------
    lat_deg, lon_deg, h_m : numpy.ndarray, shape (N + 1,)
        Positions at the step boundaries, the initial point first; longitude wrapped to
        [-180, 180).

    Raises
    ------
    ValidationError
        Non-finite input, a non-positive step, or a path reaching ``|lat| > 89.9 deg``.
    """
    vn = np.ascontiguousarray(np.atleast_1d(np.asarray(vn_mps, float)))
    ve = np.ascontiguousarray(np.broadcast_to(np.asarray(ve_mps, float), vn.shape), dtype=float)
    vu = np.ascontiguousarray(np.broadcast_to(np.asarray(vu_mps, float), vn.shape), dtype=float)
    dt = np.ascontiguousarray(np.broadcast_to(np.asarray(dt_s, float), vn.shape), dtype=float)
    if vn.ndim != 1:
        raise ValidationError("velocities must be one-dimensional arrays")
    if not (np.all(np.isfinite(vn)) and np.all(np.isfinite(ve)) and np.all(np.isfinite(vu))
            and np.all(np.isfinite(dt)) and np.isfinite([lat0_deg, lon0_deg, h0_m]).all()):
        raise ValidationError("local-level propagation needs finite velocities, steps and start")
    if np.any(dt <= 0.0):
        raise ValidationError("local-level propagation needs positive time steps")
    if abs(lat0_deg) > MAX_ABS_LAT_DEG:
        raise ValidationError(f"start latitude beyond +-{MAX_ABS_LAT_DEG} deg")
    lat, lon, h = _integrate_kernel(np.radians(lat0_deg), np.radians(lon0_deg), float(h0_m),
                                    vn, ve, vu, dt, WGS84_A, WGS84_E2, _MAX_SUBSTEP_M)
    lat_d = np.degrees(lat)
    if np.any(np.abs(lat_d) > MAX_ABS_LAT_DEG):
        raise ValidationError(f"path reaches latitude beyond +-{MAX_ABS_LAT_DEG} deg, where the "
                              "local-level longitude rate is singular")
    lon_d = (np.degrees(lon) + 180.0) % 360.0 - 180.0
    return lat_d, lon_d, h
