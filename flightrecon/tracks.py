"""One builder for every method's prefixed track columns (docs/output.md).

A method's track is a DataFrame on the grid times ``t_s`` with columns
``<prefix>_<quantity>_<unit>`` and their standard deviations ``<prefix>_<quantity>_sd_<unit>``;
samples the method does not cover are NaN.  Horizontal vectors are written as north/east pairs
in the output's axes: positions in the output tangent plane's, velocities in the local level at
the aircraft.  A method whose estimate lives in other axes (a radar station's plane, say) gives
the rotation ``M`` (or the Jacobian of the map) to them, and the builder writes
``M v`` and the standard deviations of ``M C M^T``.
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
        self.columns: dict[str, np.ndarray] = {"t_s": self.t_s}

    def _put(self, name: str, values: np.ndarray) -> None:
        col = np.full(self.t_s.size, np.nan)
        col[self.rows] = values
        self.columns[name] = col

    def add(self, quantity: str, unit: str, value: np.ndarray,
            sd: np.ndarray | None = None) -> None:
        """``<prefix>_<quantity>_<unit>`` and, if given, its ``_sd_`` column."""
        self._put(f"{self.prefix}_{quantity}_{unit}", np.asarray(value, dtype=np.float64))
        if sd is not None:
            self._put(f"{self.prefix}_{quantity}_sd_{unit}", np.asarray(sd, dtype=np.float64))

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

    def frame(self) -> pd.DataFrame:
        """The columns as a DataFrame (``t_s`` first)."""
        return pd.DataFrame(self.columns)
