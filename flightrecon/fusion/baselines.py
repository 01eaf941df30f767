"""Baselines every estimator is compared with: air-data dead reckoning, with and without a
linear end-point correction (the simplest use of a known arrival point)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from flightrecon.geo.frames import output_plane
from flightrecon.geo.wind import wind_toward_ne
from flightrecon.types import CleanFlight


def dead_reckoning(clean: CleanFlight, *, corrected: bool = False) -> pd.DataFrame:
    """Dead reckoning from airspeed and heading, lift-off to touchdown, from the departure point.

    North and east in the output tangent plane (``north_m``, ``east_m``), NaN outside the
    airborne interval.  Recorded wind (``wind_speed_mps``/``wind_from_deg``) is added when the
    log has it.  With ``corrected`` a correction growing linearly in time makes the track end at
    the arrival point.
    """
    g = clean.grid
    t = g["t_s"].to_numpy(float)
    ph = clean.phases
    a, b = np.searchsorted(t, [ph.liftoff_t_s, ph.touchdown_t_s])
    psi = np.radians(g["heading_deg"].to_numpy(float))
    tas = g["tas_mps"].to_numpy(float)
    vn, ve = tas * np.cos(psi), tas * np.sin(psi)
    if {"wind_speed_mps", "wind_from_deg"} <= set(g.columns):
        w = np.nan_to_num(wind_toward_ne(g["wind_speed_mps"], g["wind_from_deg"]))
        vn, ve = vn + w[:, 0], ve + w[:, 1]
    dt = np.diff(t, prepend=t[0])
    n = np.full(len(t), np.nan)
    e = np.full(len(t), np.nan)
    n[a:b] = np.cumsum(np.nan_to_num(vn * dt)[a:b])
    e[a:b] = np.cumsum(np.nan_to_num(ve * dt)[a:b])
    if corrected and b - a > 1:
        arr = clean.meta.arrival
        if arr is None:
            raise ValueError("a linear end-point correction needs the arrival point")
        ea, na, _ = output_plane(clean.meta).forward(arr.lat_deg, arr.lon_deg, arr.elev_m)
        frac = (t[a:b] - t[a]) / (t[b - 1] - t[a])
        n[a:b] += frac * (float(na) - n[b - 1])
        e[a:b] += frac * (float(ea) - e[b - 1])
    return pd.DataFrame({"t_s": t, "north_m": n, "east_m": e})
