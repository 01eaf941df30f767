"""Geodetic frames through pyproj (WGS-84): geodetic <-> ECEF <-> local tangent plane.

The local tangent plane (LTP) is east-north-up at an origin (normally the departure airfield).
Heights here are ellipsoidal; convert MSL with the flight's geoid undulation first.  No
ellipsoid formula is written by hand: PROJ's ``cart`` and ``topocentric`` operations do it.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from pyproj import Transformer

__all__ = ["TangentPlane", "ecef_to_geodetic", "geodetic_to_ecef", "offset_latlon"]


@lru_cache(maxsize=1)
def _cart() -> Transformer:
    return Transformer.from_pipeline("+proj=cart +ellps=WGS84")


def geodetic_to_ecef(lat_deg, lon_deg, h_m):
    """Geodetic latitude, longitude [deg] and ellipsoidal height [m] to ECEF x, y, z [m]."""
    x, y, z = _cart().transform(np.asarray(lon_deg, float), np.asarray(lat_deg, float),
                                np.asarray(h_m, float))
    return np.asarray(x), np.asarray(y), np.asarray(z)


def ecef_to_geodetic(x, y, z):
    """ECEF [m] to geodetic latitude, longitude [deg] and ellipsoidal height [m]."""
    lon, lat, h = _cart().transform(np.asarray(x, float), np.asarray(y, float),
                                    np.asarray(z, float), direction="INVERSE")
    return np.asarray(lat), np.asarray(lon), np.asarray(h)


@dataclass(frozen=True)
class TangentPlane:
    """East-north-up tangent plane at ``(lat0_deg, lon0_deg, h0_m)`` (ellipsoidal height).

    Examples
    --------
    >>> tp = TangentPlane(40.0, 49.0, 0.0)
    >>> e, n, u = tp.forward(40.0, 49.0, 100.0)
    >>> round(float(u), 6)
    100.0
    """

    lat0_deg: float
    lon0_deg: float
    h0_m: float = 0.0

    def _transformer(self) -> Transformer:
        # plain floats: a numpy scalar's repr ('np.float64(40.1)') would be read by PROJ as 0
        return _topo(float(self.lat0_deg), float(self.lon0_deg), float(self.h0_m))

    def forward(self, lat_deg, lon_deg, h_m):
        """Geodetic [deg, deg, m] -> (east, north, up) [m]."""
        e, n, u = self._transformer().transform(np.asarray(lon_deg, float),
                                                np.asarray(lat_deg, float),
                                                np.asarray(h_m, float))
        return np.asarray(e), np.asarray(n), np.asarray(u)

    def inverse(self, east_m, north_m, up_m):
        """(east, north, up) [m] -> geodetic latitude, longitude [deg], ellipsoidal height [m]."""
        lon, lat, h = self._transformer().transform(np.asarray(east_m, float),
                                                    np.asarray(north_m, float),
                                                    np.asarray(up_m, float),
                                                    direction="INVERSE")
        return np.asarray(lat), np.asarray(lon), np.asarray(h)


def offset_latlon(lat_deg: float, lon_deg: float, north_m: float,
                  east_m: float) -> tuple[float, float]:
    """Lat/lon [deg] of the point ``north_m``, ``east_m`` from ``(lat_deg, lon_deg)`` in its
    tangent plane, at the ground (runway thresholds, touchdown points, airfield offsets)."""
    # plain floats: the PROJ string is built from repr() (an np.float64 would not parse)
    lat, lon, _ = TangentPlane(float(lat_deg), float(lon_deg), 0.0).inverse(
        float(east_m), float(north_m), 0.0)
    return float(lat), float(lon)


@lru_cache(maxsize=64)
def _topo(lat0: float, lon0: float, h0: float) -> Transformer:
    lat0, lon0, h0 = float(lat0), float(lon0), float(h0)
    return Transformer.from_pipeline(
        "+proj=pipeline +step +proj=cart +ellps=WGS84 "
        f"+step +proj=topocentric +ellps=WGS84 +lat_0={lat0!r} +lon_0={lon0!r} +h_0={h0!r}"
    )


def msl_to_ellipsoid(h_msl_m, geoid_undulation_m: float = 0.0):
    """MSL height to ellipsoidal height with the flight's (constant) geoid undulation N."""
    return np.asarray(h_msl_m, float) + geoid_undulation_m


def output_plane(meta) -> TangentPlane:
    """The output tangent plane: east-north-up at the departure airfield, or, without one, at the
    flight's first GNSS fix or radar plot (``meta.origin``, set by the cleaning layer).

    Parameters
    ----------
    meta : :class:`flightrecon.types.FlightMeta` with ``departure`` or ``origin`` set.

    Raises
    ------
    MetadataError
        If the flight has neither a departure position nor a position fix (give
        ``--departure`` or a sidecar).
    """
    from flightrecon.errors import MetadataError

    d = meta.departure if meta.departure is not None else getattr(meta, "origin", None)
    if d is None:
        raise MetadataError("the flight has no departure position and no GNSS or radar fix to "
                            "place it: give --departure LAT,LON,ELEV_M or a sidecar [departure] "
                            "table")
    return TangentPlane(d.lat_deg, d.lon_deg,
                        float(msl_to_ellipsoid(d.elev_m, meta.geoid_undulation_m)))
