"""Height above the departure field from the pressure altitude, with its standard deviation:
what the default result's height is where no estimator gives one (docs/output.md, "Heights").

The pressure altitude ``h_p`` and the field's ``h_p,f`` (its elevation under the departure's
QNH, :func:`~flightrecon.geo.atmosphere.field_pressure_altitude_m`) give the height above the
field through the temperature of the air column (:func:`~flightrecon.geo.atmosphere.
height_above_field_m`, eq. 2)::

    H = (h_p - h_p,f) + dT (F(h_p) - F(h_p,f))

with ``dT`` the air's mean departure from the ISA temperature: from the recorded static air
temperature where the log has one (the mean over the airborne samples of ``SAT - T_ISA(h_p)``),
else 0.  Its variance has two independent parts (eq. 3)::

    sd(H)^2 = sd_datum(t)^2 + (sd_T (F(h_p) - F(h_p,f)))^2

* the datum: the field's pressure altitude is as good as the QNH. Given, it is a reported
  whole hectopascal (``QNH_SD_HPA`` 1 hPa, rounding and reading together) and the sea-level
  pressure changes over the flight (``QNH_DRIFT_HPA_PER_H`` 1 hPa per hour, a moving weather
  system's order); not given, the standard atmosphere stands for the day's QNH, whose spread
  about 1013.25 hPa is ``QNH_CLIMATE_SD_HPA`` (10 hPa: the standard deviation of mid-latitude
  sea-level pressure is 8-12 hPa).  At ``DH_P_DQNH_M`` = 8.3 m per hPa near sea level.
* the temperature: ``sd_T`` the recorded SAT's spread about its mean combined with what a probe
  does not tell of the column (``SAT_COLUMN_K`` 1.5 K, the joint smoother's
  ``sat_column_k``); without SAT ``ISA_DEVIATION_SD_K`` (10 K: days 10 K off the ISA are
  common, the ICAO standard's hot and cold atmospheres reach 20-30 K).
"""

from __future__ import annotations

import numpy as np

from flightrecon.geo.atmosphere import height_above_field_m, isa_temperature_k

QNH_SD_HPA = 1.0
QNH_DRIFT_HPA_PER_H = 1.0
QNH_CLIMATE_SD_HPA = 10.0
DH_P_DQNH_M = 8.3
SAT_COLUMN_K = 1.5
ISA_DEVIATION_SD_K = 10.0
#: fewest airborne temperature samples for a mean ISA deviation
MIN_SAT_SAMPLES = 60

__all__ = ["pressure_height_m", "isa_deviation_k", "QNH_SD_HPA", "QNH_DRIFT_HPA_PER_H",
           "QNH_CLIMATE_SD_HPA", "DH_P_DQNH_M", "SAT_COLUMN_K", "ISA_DEVIATION_SD_K",
           "MIN_SAT_SAMPLES"]


def isa_deviation_k(h_p_m: np.ndarray, sat_degc: np.ndarray | None,
                    airborne: np.ndarray) -> tuple[float, float] | None:
    """The air's mean departure from the ISA temperature [K] over the ``airborne`` samples with
    a temperature, and its spread (standard deviation); ``None`` with fewer than
    :data:`MIN_SAT_SAMPLES`."""
    if sat_degc is None:
        return None
    sat = np.asarray(sat_degc, float)
    h = np.asarray(h_p_m, float)
    ok = airborne & np.isfinite(sat) & np.isfinite(h)
    if ok.sum() < MIN_SAT_SAMPLES:
        return None
    dev = sat[ok] + 273.15 - isa_temperature_k(h[ok])
    return float(np.mean(dev)), float(np.std(dev))


def pressure_height_m(t_s: np.ndarray, h_p_m: np.ndarray, h_p_field_m: float, *,
                      qnh_known: bool, deviation: tuple[float, float] | None,
                      t0_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Height above the field [m] and its sd [m] (eq. 2-3 of the module) of the pressure
    altitudes ``h_p_m`` at the times ``t_s``; ``deviation``: :func:`isa_deviation_k` (``None``:
    no temperature, ``dT`` = 0 with the climatological spread); ``t0_s`` when the field's QNH
    held (the take-off: the datum's drift grows from it)."""
    h_p = np.asarray(h_p_m, float)
    dT, spread = (0.0, None) if deviation is None else deviation
    H = height_above_field_m(h_p, h_p_field_m, dT)
    dF = height_above_field_m(h_p, h_p_field_m, 1.0) - (h_p - h_p_field_m)
    sd_T = ISA_DEVIATION_SD_K if spread is None else float(np.hypot(spread, SAT_COLUMN_K))
    if qnh_known:
        hours = np.abs(np.asarray(t_s, float) - t0_s) / 3600.0
        sd_datum = DH_P_DQNH_M * np.sqrt(QNH_SD_HPA ** 2 + (QNH_DRIFT_HPA_PER_H * hours) ** 2)
    else:
        sd_datum = np.full(len(h_p), DH_P_DQNH_M * QNH_CLIMATE_SD_HPA)
    return H, np.sqrt(sd_datum ** 2 + (sd_T * dF) ** 2)
