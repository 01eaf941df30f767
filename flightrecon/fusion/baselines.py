"""Baselines every estimator is compared with: air-data dead reckoning, with and without a
linear end-point correction (the simplest use of a known arrival point)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from flightrecon.geo.frames import output_plane
from flightrecon.geo.wind import wind_toward_ne
from flightrecon.types import CleanFlight


def dead_reckoning(clean: CleanFlight, *, corrected: bool = False,
                   wind: bool = True) -> pd.DataFrame:
    """Dead reckoning from airspeed and heading, lift-off to touchdown, from the departure point.

    North and east in the output tangent plane (``north_m``, ``east_m``), NaN outside the
    airborne interval.  With ``wind`` the known wind is added: the recorded wind
    (``wind_speed_mps``/``wind_from_deg``) when the log has it, else the winds-aloft table
    (``--wind``) at the recorded altitude (:func:`flightrecon.ingest.priors.wind_aloft_on_grid`);
    without either, or with ``wind=False``, zero wind.  Which one was used is in
    ``attrs["wind"]`` ("recorded", "winds_aloft", "none").  With ``corrected`` a correction
    growing linearly in time makes the track end at the arrival point.
    """
    from flightrecon.ingest.priors import wind_aloft_on_grid

    g = clean.grid
    t = g["t_s"].to_numpy(float)
    ph = clean.phases
    a, b = np.searchsorted(t, [ph.liftoff_t_s, ph.touchdown_t_s])
    psi = np.radians(g["heading_deg"].to_numpy(float))
    tas = g["tas_mps"].to_numpy(float)
    vn, ve = tas * np.cos(psi), tas * np.sin(psi)
    used = "none"
    wa = wind_aloft_on_grid(g, clean.meta) if wind else None
    if wind and {"wind_speed_mps", "wind_from_deg"} <= set(g.columns):
        w = np.nan_to_num(wind_toward_ne(g["wind_speed_mps"], g["wind_from_deg"]))
        vn, ve = vn + w[:, 0], ve + w[:, 1]
        used = "recorded"
    elif wa is not None:
        w = np.nan_to_num(wa[0])
        vn, ve = vn + w[:, 0], ve + w[:, 1]
        used = "winds_aloft"
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
    out = pd.DataFrame({"t_s": t, "north_m": n, "east_m": e})
    out.attrs["wind"] = used
    return out
