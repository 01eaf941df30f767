"""Simulated weather: a non-standard atmosphere and a wind field varying with altitude and time.

Atmosphere (docs/simulator.md, "Atmosphere"): the ISA temperature gradient with a temperature
offset ``dT`` and a sea-level pressure ``p_sl`` different from 1013.25 hPa.  With geopotential
height ``H = r z / (r + z)`` (``z`` geometric height above MSL, ``r`` = 6 356 766 m as in ICAO Doc
7488) the hydrostatic equation ``dp/dH = -g0 p / (R T(H))`` with ``T(H) = T0 + dT + L H`` has the
exact solution ``p = p_sl (T(H) / (T0 + dT))^(-g0 / (L R))``.  Pressure altitude is then
:func:`flightrecon.geo.atmosphere.pressure_altitude_m` of that pressure.  Only the troposphere
(H < 11 km) is modelled.

Wind (where the air moves TO, north/east components): speed and meteorological direction vary
linearly with height and sinusoidally with time; smooth in both, so the truth stays C2.
Optionally a random part: per component a random walk in time plus one in height, each drawn
at knots (every ``rw_knot_s`` seconds, ``rw_knot_m`` metres) and joined by cubic splines, so
that the wind stays C2 while it varies as the joint smoother's wind model assumes at scales
beyond the knots.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.geo.atmosphere import (
    G0,
    H_TROPOPAUSE_M,
    LAPSE_K_PER_M,
    R_AIR,
    T0_K,
    isa_pressure_pa,
    pressure_altitude_m,
)

__all__ = ["Atmosphere", "WindField", "geopotential_height_m", "qnh_hpa"]

R_GEOPOTENTIAL_M = 6356766.0
"""Earth radius used for geopotential height (ICAO Doc 7488)."""


def geopotential_height_m(z_msl_m):
    """Geopotential height [m'] from geometric height above MSL [m]: ``H = r z / (r + z)``."""
    z = np.asarray(z_msl_m, float)
    return R_GEOPOTENTIAL_M * z / (R_GEOPOTENTIAL_M + z)


@dataclass(frozen=True)
class Atmosphere:
    """Non-standard troposphere.

    Attributes
    ----------
    temp_offset_k : temperature offset from ISA at every height [K]
    p_sl_start_pa, p_sl_end_pa : true sea-level pressure at ``t = 0`` and at ``t = t_end_s``;
        linear in time in between (a weather system moving over the route) [Pa]
    t_end_s : time of ``p_sl_end_pa`` [s]
    """

    temp_offset_k: float = 0.0
    p_sl_start_pa: float = 101325.0
    p_sl_end_pa: float = 101325.0
    t_end_s: float = 1.0

    def sea_level_pressure_pa(self, t_s):
        """True sea-level pressure [Pa] at time ``t_s``."""
        frac = np.clip(np.asarray(t_s, float) / self.t_end_s, 0.0, 1.0)
        return self.p_sl_start_pa + (self.p_sl_end_pa - self.p_sl_start_pa) * frac

    def temperature_k(self, z_msl_m):
        """Static air temperature [K] at geometric height above MSL."""
        h = geopotential_height_m(z_msl_m)
        if np.any(h >= H_TROPOPAUSE_M):
            raise ValidationError("the simulated atmosphere covers the troposphere only "
                                  "(geopotential height below 11 km)")
        return T0_K + self.temp_offset_k + LAPSE_K_PER_M * h

    def pressure_pa(self, z_msl_m, t_s):
        """Static pressure [Pa]: exact solution of the hydrostatic equation (module docstring)."""
        t_k = self.temperature_k(z_msl_m)
        expo = -G0 / (LAPSE_K_PER_M * R_AIR)
        return self.sea_level_pressure_pa(t_s) * (t_k / (T0_K + self.temp_offset_k)) ** expo

    def pressure_altitude_m(self, z_msl_m, t_s):
        """Pressure altitude [m] (1013.25 hPa datum) at geometric height above MSL."""
        return pressure_altitude_m(self.pressure_pa(z_msl_m, t_s))


def qnh_hpa(atmosphere: Atmosphere, elev_msl_m: float, t_s: float) -> float:
    """QNH [hPa]: the altimeter setting with which an altimeter on the field reads its elevation.

    ``QNH = p_ISA(pressure_alt(p_field) - elev)``; differs from the true sea-level pressure
    when the temperature is not ISA.
    """
    pa = float(atmosphere.pressure_altitude_m(elev_msl_m, t_s))
    return float(isa_pressure_pa(pa - elev_msl_m)) / 100.0


@dataclass(frozen=True)
class WindField:
    """Horizontal wind varying with height and time.

    ``speed = speed0 + speed_gradient * z + speed_amp * sin(2 pi t / period)`` (clipped at 0),
    ``from = from0 + veer * z + dir_amp * sin(2 pi t / period + 1)`` (meteorological, deg).

    Attributes
    ----------
    speed0_mps : speed at MSL [m/s]
    speed_gradient_per_s : speed increase per metre of height [(m/s)/m]
    from0_deg : direction the wind blows FROM at MSL [deg]
    veer_deg_per_m : clockwise turn of the direction with height [deg/m]
    speed_amp_mps, dir_amp_deg, period_s : slow time variation
    rw_time_mps_sqrt_s, rw_alt_mps_sqrt_m : intensity of the random part, per component: the
        standard deviation of its change over 1 s of time and over 1 m of height; 0: none
    rw_seed : the random part's draw (the same seed, the same wind)
    rw_knot_s, rw_knot_m : knot spacing of the random part in time [s] (over 0-48 h) and height
        [m] (over -1000 to 20000 m)
    """

    speed0_mps: float = 0.0
    speed_gradient_per_s: float = 0.0
    from0_deg: float = 0.0
    veer_deg_per_m: float = 0.0
    speed_amp_mps: float = 0.0
    dir_amp_deg: float = 0.0
    period_s: float = 3600.0
    rw_time_mps_sqrt_s: float = 0.0
    rw_alt_mps_sqrt_m: float = 0.0
    rw_seed: int = 0
    rw_knot_s: float = 60.0
    rw_knot_m: float = 30.0

    def speed_from(self, z_msl_m, t_s):
        """Wind speed [m/s] and meteorological direction [deg, unwrapped]."""
        z = np.asarray(z_msl_m, float)
        ph = 2.0 * np.pi * np.asarray(t_s, float) / self.period_s
        speed = np.maximum(self.speed0_mps + self.speed_gradient_per_s * z
                           + self.speed_amp_mps * np.sin(ph), 0.0)
        frm = self.from0_deg + self.veer_deg_per_m * z + self.dir_amp_deg * np.sin(ph + 1.0)
        return speed, frm

    def velocity(self, z_msl_m, t_s):
        """Wind velocity (north, east) [m/s]: where the air moves TO (= from + 180 deg)."""
        speed, frm = self.speed_from(z_msl_m, t_s)
        r = np.radians(frm)
        wn, we = -speed * np.cos(r), -speed * np.sin(r)
        if self.rw_time_mps_sqrt_s > 0.0 or self.rw_alt_mps_sqrt_m > 0.0:
            ft, fz = _random_walks(self.rw_seed, self.rw_time_mps_sqrt_s, self.rw_alt_mps_sqrt_m,
                                   self.rw_knot_s, self.rw_knot_m)
            d = ft(np.asarray(t_s, float)) + fz(np.asarray(z_msl_m, float))
            wn, we = wn + d[..., 0], we + d[..., 1]
        return wn, we


@lru_cache(maxsize=8)
def _random_walks(seed: int, q_t: float, q_z: float, knot_s: float, knot_m: float):
    """Cubic splines (north, east) through random walks at knots: in time from 0 (value 0) to
    48 h, in height from -1000 m to 20000 m (value 0 at MSL); increments N(0, q^2 spacing)."""
    from scipy.interpolate import CubicSpline

    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([int(seed), 7919])))
    tk = np.arange(0.0, 48 * 3600.0 + knot_s, knot_s)
    bt = np.vstack([np.zeros((1, 2)), np.cumsum(
        rng.normal(0.0, q_t * np.sqrt(knot_s), (len(tk) - 1, 2)), axis=0)])
    zk = np.arange(-1000.0, 20000.0 + knot_m, knot_m)
    bz = np.vstack([np.zeros((1, 2)), np.cumsum(
        rng.normal(0.0, q_z * np.sqrt(knot_m), (len(zk) - 1, 2)), axis=0)])
    bz -= CubicSpline(zk, bz)(0.0)
    return CubicSpline(tk, bt), CubicSpline(zk, bz)
