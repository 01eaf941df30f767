"""Baselines every estimator is compared with: air-data dead reckoning, with and without a
linear end-point correction (the simplest use of a known arrival point)."""

from __future__ import annotations

import numpy as np
import pandas as pd

from flightrecon.geo.frames import output_plane
from flightrecon.geo.wind import wind_toward_ne
from flightrecon.types import CleanFlight

DR_WALK_MPS_SQRT_S = 0.1
"""Random walk [m/s/sqrt(s)] of the wind behind a dead reckoning corrected to both ends:
twice the joint smoother's default wind walk (``JointNoise.wind_rw_mps_sqrt_s``, 0.05), the
wind the track does not know changing as a random walk (:func:`bridge_sd_m`)."""

ARRIVAL_POINT_SD_M = 1500.0
"""Horizontal sd [m] per axis of the touchdown about the arrival's reference point (the
airfield's reference point stands for where the aircraft touched down: the joint smoother's
``endpoint_h_m``)."""


SHEAR_SD_MPS_PER_M = 3.0e-3
"""Sd [m/s per m of height] per horizontal axis of the wind's unknown change with height
behind a dead reckoning that holds one wind over the flight (zero, recorded or a table: the
linear end correction turns whatever it holds into one mean wind): the thermal-wind shear of
the mid-latitude troposphere, a jet of 30-40 m/s at 10-12 km over a surface wind of a few m/s
(Holton, *An Introduction to Dynamic Meteorology*, 4th ed., section 3.4), 3 m/s per km.  A
climb through a 55 m/s jet at 10.7 km (108 kt over Riyadh-Jeddah) is 1.7 sd of it."""


def profile_wind_sd_m(t_s: np.ndarray, h_m: np.ndarray, t0_s: float, t1_s: float,
                      shear_sd_mps_per_m: float = SHEAR_SD_MPS_PER_M) -> np.ndarray:
    """Position sd [m] per horizontal axis of a dead reckoning corrected linearly to both ends
    when the wind changes with height by an unknown shear ``g`` of sd ``shear_sd_mps_per_m``:
    the wind ``w0 + g (h - h0)`` integrated from ``t0_s`` and pinned at ``t1_s`` leaves::

        x(t) = g B(t),   B(t) = H(t) - (s / T) H(t1),   H(t) = integral of h from t0 to t

    (``s = t - t0``, ``T = t1 - t0``; the mean wind and ``h0`` fall out with the correction),
    so its sd is ``shear_sd |B(t)|``: zero at both ends and at a level flight, largest where
    the height spent away from the flight's mean height has accumulated (a long climb to
    cruise).  ``h_m`` is the pressure altitude on ``t_s`` (NaN taken as its neighbours)."""
    t = np.asarray(t_s, float)
    h = np.asarray(h_m, float)
    ok = np.isfinite(h)
    if ok.sum() < 2 or t1_s <= t0_s:
        return np.zeros(len(t))
    h = np.interp(t, t[ok], h[ok])
    inside = (t >= t0_s) & (t <= t1_s)
    hi = np.where(inside, h, 0.0)
    dt = np.diff(t, prepend=t[0])
    H = np.cumsum(hi * dt)
    k1 = int(np.searchsorted(t, t1_s, side="right")) - 1
    H_end = float(H[max(k1, 0)])
    s = np.clip(t - t0_s, 0.0, t1_s - t0_s)
    B = np.where(inside, H - s / (t1_s - t0_s) * H_end, 0.0)
    return shear_sd_mps_per_m * np.abs(B)


def bridge_sd_m(t_s: np.ndarray, t0_s: float, t1_s: float, walk_mps_per_sqrt_s: float
                ) -> np.ndarray:
    """Position sd [m] of a dead reckoning corrected linearly to both ends when the wind is a
    random walk of intensity ``walk_mps_per_sqrt_s``: the integral ``X`` of the walk from
    ``t0_s``, less ``s / T`` times its end value, has the variance
    ``q^2 (s^3 / 3 - s^3 + s^4 / (3 T) + s^2 T / 3)`` (``s = t - t0``, ``T = t1 - t0``;
    ``q^2 T^3 / 48`` half-way, zero at both ends)."""
    T = max(t1_s - t0_s, 1e-9)
    s = np.clip(np.asarray(t_s, float) - t0_s, 0.0, T)
    var = s ** 3 / 3.0 - s ** 3 + s ** 4 / (3.0 * T) + s ** 2 * T / 3.0
    return walk_mps_per_sqrt_s * np.sqrt(np.maximum(var, 0.0))


def corrected_track_sd_m(t_s: np.ndarray, t0_s: float, t1_s: float, start_sd_m: float,
                         end_sd_m: float, walk_mps_per_sqrt_s: float = DR_WALK_MPS_SQRT_S
                         ) -> np.ndarray:
    """Position sd [m] per horizontal axis of a track integrated from a start point of sd
    ``start_sd_m`` and corrected linearly in time to an end point of sd ``end_sd_m``: the two
    ends' errors carried by the correction, ``(1 - s/T) e_0 + (s/T) e_1``, and the wind's
    random walk between them (:func:`bridge_sd_m`), independent::

        sd(t)^2 = ((1 - s/T) sd_0)^2 + ((s/T) sd_1)^2 + bridge(t)^2

    The Sabziev fusion's stable track, a dead reckoning corrected to both ends in effect
    (docs/sabziev.md: 0.93-1.05 times dead reckoning with a linear end correction on JSBSim's
    fleet), reports it (docs/sabziev.md, "The track's sd")."""
    T = max(t1_s - t0_s, 1e-9)
    f = np.clip((np.asarray(t_s, float) - t0_s) / T, 0.0, 1.0)
    return np.sqrt(((1.0 - f) * start_sd_m) ** 2 + (f * end_sd_m) ** 2
                   + bridge_sd_m(t_s, t0_s, t1_s, walk_mps_per_sqrt_s) ** 2)


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
