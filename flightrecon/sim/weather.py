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
"""

from __future__ import annotations

from dataclasses import dataclass

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
    """

    speed0_mps: float = 0.0
    speed_gradient_per_s: float = 0.0
    from0_deg: float = 0.0
    veer_deg_per_m: float = 0.0
    speed_amp_mps: float = 0.0
    dir_amp_deg: float = 0.0
    period_s: float = 3600.0

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
        return -speed * np.cos(r), -speed * np.sin(r)
