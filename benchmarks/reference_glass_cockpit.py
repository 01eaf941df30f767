"""The bare minimum a script does with a glass-cockpit export: the speed reference for
``benchmarks/bench_glass_cockpit.py``.

Usage::

    python benchmarks/reference_glass_cockpit.py EXPORT.csv OUT.parquet

It starts Python, reads a Garmin CSV export with pandas (the airframe line and the units line
skipped), smooths its GPS positions with filterpy's Kalman filter and RTS smoother (a 4-state
constant-velocity model on a local east/north plane, one step a row, 10 m measurement sd) and
writes the smoothed positions to Parquet.  No checks, no cleaning, no sensor model: what
flightrecon does beyond this is what its time buys.
"""

from __future__ import annotations

import sys

import numpy as np
import pandas as pd
from filterpy.kalman import KalmanFilter

#: the mean Earth radius [m] (a local plane is all the reference needs)
EARTH_RADIUS_M = 6_371_000.0


def smooth_positions(east_m: np.ndarray, north_m: np.ndarray, dt_s: float = 1.0,
                     sd_m: float = 10.0, accel_sd_mps2: float = 1.0) -> np.ndarray:
    """RTS-smoothed east/north positions [m] of a constant-velocity model (filterpy)."""
    kf = KalmanFilter(dim_x=4, dim_z=2)
    kf.F = np.array([[1, 0, dt_s, 0], [0, 1, 0, dt_s], [0, 0, 1, 0], [0, 0, 0, 1]], float)
    kf.H = np.array([[1, 0, 0, 0], [0, 1, 0, 0]], float)
    kf.R = np.eye(2) * sd_m**2
    g = np.array([[dt_s**2 / 2, 0], [0, dt_s**2 / 2], [dt_s, 0], [0, dt_s]])
    kf.Q = g @ g.T * accel_sd_mps2**2
    kf.x = np.array([east_m[0], north_m[0], 0.0, 0.0])
    kf.P = np.diag([sd_m**2, sd_m**2, 100.0, 100.0])
    z = np.column_stack([east_m, north_m])
    mu, cov, _, _ = kf.batch_filter(z)
    xs, _, _, _ = kf.rts_smoother(mu, cov)
    return xs[:, :2]


def main(path: str, out: str) -> None:
    df = pd.read_csv(path, skiprows=2, skipinitialspace=True, low_memory=False)
    df.columns = [str(c).strip() for c in df.columns]
    lat = pd.to_numeric(df["Latitude"], errors="coerce").to_numpy()
    lon = pd.to_numeric(df["Longitude"], errors="coerce").to_numpy()
    ok = np.isfinite(lat) & np.isfinite(lon)
    lat, lon = lat[ok], lon[ok]
    lat0, lon0 = np.radians(lat[0]), np.radians(lon[0])
    north = (np.radians(lat) - lat0) * EARTH_RADIUS_M
    east = (np.radians(lon) - lon0) * EARTH_RADIUS_M * np.cos(lat0)
    en = smooth_positions(east, north)
    pd.DataFrame({"east_m": en[:, 0], "north_m": en[:, 1]}).to_parquet(out)


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2])
