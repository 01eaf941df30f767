"""Plus and minus for states that live on a manifold (compiled).

A Kalman filter or smoother corrects a state by adding a vector and compares two states by
subtracting them.  Where a state does not live in a vector space the two operations are replaced
by a *plus* ``x (+) dx`` (move the state by a tangent vector) and a *minus* ``y (-) x`` (the
tangent vector from ``x`` to ``y``), with ``x (+) (y (-) x) = y`` (navlie's ``plus``/``minus``;
Hertzberg et al. 2013, "boxplus").  Two geometries are implemented, selected by an integer flag
that the compiled kernels pass through:

* :data:`EUCLIDEAN`: ``x + dx`` and ``y - x`` on every component;
* :data:`LATLON`: the first two components are geodetic latitude and longitude [rad], their
  tangent vector north and east metres in the local-level frame at height ``h``; the other
  components are Euclidean.  The radii of curvature are WGS-84's at the mid-latitude of the move
  (second-order accurate); the minus takes the longitude difference the short way round (across
  the antimeridian), the plus leaves the longitude continuous (no wrap, so that a track stays
  interpolable).

docs/estimation.md, "Manifold states".
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flightrecon.geo.ellipsoid import radii_from_sin

EUCLIDEAN = 0
"""Every component Euclidean."""

LATLON = 1
"""Components 0 and 1 are latitude and longitude [rad]; their tangent is north/east metres."""


@nb.njit(cache=True, nogil=True)
def radii(lat_rad: float, h_m: float) -> tuple[float, float]:
    """Meridian and prime-vertical radii of curvature plus height, ``(M + h, N + h)`` [m].

    WGS-84 (:func:`flightrecon.geo.ellipsoid.radii_from_sin`).
    """
    m, n = radii_from_sin(np.sin(lat_rad))
    return m + h_m, n + h_m


@nb.njit(cache=True, nogil=True)
def boxplus(lat: float, lon: float, dn: float, de: float, h: float) -> tuple[float, float]:
    """Move ``(lat, lon)`` [rad] by ``dn`` north and ``de`` east metres in the local-level frame.

    The radii are taken at the mid-latitude of the move (second-order accurate).
    """
    mh, nh = radii(lat, h)
    latm = lat + 0.5 * dn / mh
    mh, nh = radii(latm, h)
    return lat + dn / mh, lon + de / (nh * np.cos(latm))


@nb.njit(cache=True, nogil=True)
def _short_way(dlon: float) -> float:
    """A longitude difference [rad] into [-pi, pi] (exact: one addition of 2 pi, only when
    needed, so that an ordinary difference keeps every bit)."""
    if dlon > np.pi:
        return dlon - 2.0 * np.pi
    if dlon < -np.pi:
        return dlon + 2.0 * np.pi
    return dlon


@nb.njit(cache=True, nogil=True)
def boxminus(lat1: float, lon1: float, lat0: float, lon0: float, h: float) -> tuple[float, float]:
    """North/east metres from ``(lat0, lon0)`` to ``(lat1, lon1)`` [rad] (inverse of boxplus to
    second order; the longitude difference is taken the short way round)."""
    latm = 0.5 * (lat1 + lat0)
    mh, nh = radii(latm, h)
    return (lat1 - lat0) * mh, _short_way(lon1 - lon0) * nh * np.cos(latm)


@nb.njit(cache=True, nogil=True)
def state_plus_into(geom: int, x: np.ndarray, dx: np.ndarray, h: float, out: np.ndarray) -> None:
    """``out = x (+) dx`` in the geometry ``geom`` (:data:`EUCLIDEAN` or :data:`LATLON`; ``h``
    the height [m] for the radii, unused when Euclidean).  ``out`` may be ``x``."""
    n = x.shape[0]
    i0 = 0
    if geom == LATLON:
        lat, lon = boxplus(x[0], x[1], dx[0], dx[1], h)
        out[0] = lat
        out[1] = lon
        i0 = 2
    for i in range(i0, n):
        out[i] = x[i] + dx[i]


@nb.njit(cache=True, nogil=True)
def state_minus_into(geom: int, y: np.ndarray, x: np.ndarray, h: float, out: np.ndarray) -> None:
    """``out = y (-) x`` in the geometry ``geom`` (see :func:`state_plus_into`)."""
    n = x.shape[0]
    i0 = 0
    if geom == LATLON:
        dn, de = boxminus(y[0], y[1], x[0], x[1], h)
        out[0] = dn
        out[1] = de
        i0 = 2
    for i in range(i0, n):
        out[i] = y[i] - x[i]
