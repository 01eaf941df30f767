"""One builder for every method's prefixed track columns (docs/output.md), used by all five
methods (joint, sabziev, arms, azimuth, sns).

A method's track is a DataFrame on the grid times ``t_s`` with columns
``<prefix>_<quantity>_<unit>`` and their standard deviations ``<prefix>_<quantity>_sd_<unit>``;
samples the method does not cover are NaN.  The prefixed columns mean what the unprefixed
ones of the default result mean:

* horizontal vectors are north/east pairs in the output's axes: positions in the output tangent
  plane's, velocities in the local level at the aircraft.  A method whose estimate lives in
  other axes (a radar station's plane, say) gives the rotation ``M`` (or the Jacobian of the
  map) to them, and the builder writes ``M v`` and the standard deviations of ``M C M^T``
  (:meth:`TrackColumns.add_horizontal`);
* ``<p>_up_m`` is the up of the output tangent plane (not a height: the plane falls below the
  ellipsoid by about d^2 / 2R, 31 m at 20 km from its origin), and ``<p>_lat_deg``,
  ``<p>_lon_deg``, ``<p>_alt_m`` the WGS-84 position with its ellipsoidal height, all from one
  conversion through PROJ (:meth:`TrackColumns.add_place`); a method that estimates a height
  above the departure airfield along the local vertical (the Sabziev fusion) gives it, and the
  builder converts it (:func:`plane_up_of_height`) and keeps it as ``<p>_height_m``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

_SWAP = np.array([[0.0, 1.0], [1.0, 0.0]])


class TrackColumns:
    """Collects a method's columns on the grid (``rows``: the grid rows it covers)."""

    def __init__(self, prefix: str, t_s: np.ndarray, rows: Any = None) -> None:
        self.prefix = prefix
        self.t_s = np.asarray(t_s, dtype=np.float64)
        self.rows = slice(None) if rows is None else rows
        self.columns: dict[str, Any] = {"t_s": self.t_s}

    def _put(self, name: str, values: np.ndarray) -> None:
        if isinstance(self.rows, slice) and self.rows == slice(None) \
                and values.shape == self.t_s.shape:
            self.columns[name] = values     # every row covered: taken as it is, no copy
            return
        col = np.full(self.t_s.size, np.nan)
        col[self.rows] = values
        self.columns[name] = col

    def add(self, quantity: str, unit: str, value: np.ndarray,
            sd: np.ndarray | None = None) -> None:
        """``<prefix>_<quantity>_<unit>`` and, if given, its ``_sd_`` column."""
        self._put(f"{self.prefix}_{quantity}_{unit}", np.asarray(value, dtype=np.float64))
        if sd is not None:
            self._put(f"{self.prefix}_{quantity}_sd_{unit}", np.asarray(sd, dtype=np.float64))

    def add_sd(self, quantity: str, unit: str, sd: np.ndarray) -> None:
        """``<prefix>_<quantity>_sd_<unit>`` alone: the sd of a column whose value came without
        one, from another error model than the value's (the Sabziev bridge's dead-reckoning
        sd)."""
        self._put(f"{self.prefix}_{quantity}_sd_{unit}", np.asarray(sd, dtype=np.float64))

    def add_text(self, quantity: str, values: Any) -> None:
        """``<prefix>_<quantity>``: a text column of every row (pandas ``string``; the joint
        smoother's ``joint_sources``)."""
        self.columns[f"{self.prefix}_{quantity}"] = pd.array(values, dtype="string")

    def add_horizontal(self, north: str, east: str, unit: str, value: np.ndarray,
                       cov: np.ndarray, to_output: np.ndarray | None = None, *,
                       order: str = "ne", value_is_output: bool = False) -> None:
        """A horizontal vector (K, 2) with covariance (K, 2, 2), in ``order`` ("ne": north
        first, "en": east first) and the axes of ``to_output`` (K, 2, 2) or (2, 2) (same
        order); the identity if ``None``.  ``value_is_output``: the vector is already in the
        output's axes (a position mapped through geodesy), only its covariance is rotated.
        Writes north, its sd, east, its sd."""
        v = np.asarray(value, dtype=np.float64)
        C = np.asarray(cov, dtype=np.float64)
        M = None if to_output is None else np.asarray(to_output, dtype=np.float64)
        if order == "en":
            v = v[..., ::-1]
            C = C[..., ::-1, ::-1]
            M = None if M is None else _SWAP @ M @ _SWAP
        elif order != "ne":
            raise ValueError(f"order must be 'ne' or 'en', got {order!r}")
        if M is not None:
            MT = np.swapaxes(M, -1, -2)
            C = M @ C @ MT
            if not value_is_output:
                v = np.einsum("...ij,...j->...i", np.broadcast_to(M, C.shape), v)
        self.add(north, unit, v[..., 0], np.sqrt(C[..., 0, 0]))
        self.add(east, unit, v[..., 1], np.sqrt(C[..., 1, 1]))

    def add_place(self, plane: Any, east: np.ndarray, north: np.ndarray, *,
                  up: np.ndarray | None = None, height: np.ndarray | None = None,
                  up_sd: np.ndarray | None = None,
                  geodetic: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None) -> None:
        """``<p>_up_m`` (and its sd), ``<p>_lat_deg``, ``<p>_lon_deg``, ``<p>_alt_m`` of the
        covered rows, in the meaning of the default result's columns (docs/output.md).

        Parameters
        ----------
        plane : the output tangent plane (:func:`flightrecon.geo.frames.output_plane`)
        east, north : the plane position the method gives (its ``<p>_east_m, <p>_north_m``)
        up : the plane's up; or ``height``: the height above the plane's origin along the
            local vertical (converted by :func:`plane_up_of_height` and written as
            ``<p>_height_m`` too)
        up_sd : sd of the vertical (the same for the height and the plane's up: the
            conversion's derivative is 1 to 1e-6 within a few hundred km)
        geodetic : ``(lat_deg, lon_deg, alt_m)`` where the method has them exactly (from its own
            earth-fixed states); otherwise they are the plane position converted by PROJ

        A position without a vertical (NaN) gets the latitude and longitude at the plane's own
        height and no ``alt_m``, as the default result does.
        """
        e = np.asarray(east, dtype=np.float64)
        n = np.asarray(north, dtype=np.float64)
        if height is not None:
            h_rel = np.asarray(height, dtype=np.float64)
            up, lat, lon, alt = plane_up_of_height(plane, e, n, h_rel)
            self._put(f"{self.prefix}_height_m", h_rel)
        elif up is None:
            raise ValueError("add_place needs the plane's up or a height")
        else:
            up = np.asarray(up, dtype=np.float64)
            lat, lon, alt = (plane.inverse(e, n, up) if geodetic is None else
                             tuple(np.asarray(g, dtype=np.float64) for g in geodetic))
        lat, lon, alt = (np.array(a, dtype=np.float64) for a in (lat, lon, alt))
        miss = ~np.isfinite(up) & np.isfinite(e) & np.isfinite(n)
        if miss.any():
            la, lo, _ = plane.inverse(e[miss], n[miss], np.zeros(int(miss.sum())))
            lat[miss], lon[miss], alt[miss] = la, lo, np.nan
        self.add("up", "m", up, None if up_sd is None else np.asarray(up_sd, dtype=np.float64))
        self.add("lat", "deg", lat)
        self.add("lon", "deg", lon)
        self.add("alt", "m", alt)

    def frame(self) -> pd.DataFrame:
        """The columns as a DataFrame (``t_s`` first; the arrays are not copied)."""
        return pd.DataFrame(self.columns, copy=False)


def plane_up_of_height(plane: Any, east: np.ndarray, north: np.ndarray,
                       height_above_origin: np.ndarray, where: np.ndarray | None = None
                       ) -> tuple[np.ndarray, Any, Any, Any]:
    """Tangent-plane ``up`` of points given by plane (east, north) and height above the plane's
    origin along the local vertical; returns (up, lat, lon, ellipsoidal height).

    Two fixed-point steps (the local vertical is within a few mrad of the plane's normal for
    flights of a few hundred km) give millimetres.  With the boolean mask ``where`` only those
    points are converted (each point's conversion is independent of the others): ``up`` is the
    input height elsewhere and ``lat, lon, h`` are ``None``.
    """
    h_in = np.asarray(height_above_origin, float)
    if where is not None:
        up = h_in.copy()
        idx = np.flatnonzero(where)
        if len(idx):
            up[idx] = plane_up_of_height(plane, np.asarray(east)[idx],
                                         np.asarray(north)[idx], h_in[idx])[0]
        return up, None, None, None
    target = plane.h0_m + h_in
    up = h_in.copy()
    ok = np.isfinite(east) & np.isfinite(north) & np.isfinite(up)
    for _ in range(3):
        lat, lon, h = plane.inverse(east, north, up)
        up = np.where(ok, up + (target - h), up)
    lat, lon, h = plane.inverse(east, north, up)
    return up, lat, lon, h
