"""International Standard Atmosphere (ICAO Doc 7488) and airspeed conversions.

Pressure altitude is the ISA altitude at which the static pressure equals the measured one
(1013.25 hPa datum).  Valid in the troposphere and the lower stratosphere (to 20 km).
"""

from __future__ import annotations

import numpy as np

P0_PA = 101325.0
T0_K = 288.15
RHO0 = 1.225
LAPSE_K_PER_M = -0.0065
R_AIR = 287.05287
GAMMA = 1.4
G0 = 9.80665
H_TROPOPAUSE_M = 11000.0
T_TROPOPAUSE_K = T0_K + LAPSE_K_PER_M * H_TROPOPAUSE_M
P_TROPOPAUSE_PA = P0_PA * (T_TROPOPAUSE_K / T0_K) ** (-G0 / (LAPSE_K_PER_M * R_AIR))
A0_MPS = float(np.sqrt(GAMMA * R_AIR * T0_K))


def isa_temperature_k(h_m):
    """ISA temperature [K] at pressure altitude ``h_m``."""
    h = np.asarray(h_m, float)
    return np.where(h < H_TROPOPAUSE_M, T0_K + LAPSE_K_PER_M * h, T_TROPOPAUSE_K)


def isa_pressure_pa(h_m):
    """ISA static pressure [Pa] at pressure altitude ``h_m``."""
    h = np.asarray(h_m, float)
    n = -G0 / (LAPSE_K_PER_M * R_AIR)
    tropo = P0_PA * (1.0 + LAPSE_K_PER_M * h / T0_K) ** n
    strato = P_TROPOPAUSE_PA * np.exp(-G0 * (h - H_TROPOPAUSE_M) / (R_AIR * T_TROPOPAUSE_K))
    return np.where(h < H_TROPOPAUSE_M, tropo, strato)


def pressure_altitude_m(p_pa):
    """Pressure altitude [m] for static pressure ``p_pa`` (inverse of :func:`isa_pressure_pa`)."""
    p = np.asarray(p_pa, float)
    n = -G0 / (LAPSE_K_PER_M * R_AIR)
    tropo = T0_K / LAPSE_K_PER_M * ((p / P0_PA) ** (1.0 / n) - 1.0)
    strato = H_TROPOPAUSE_M - R_AIR * T_TROPOPAUSE_K / G0 * np.log(p / P_TROPOPAUSE_PA)
    return np.where(p > P_TROPOPAUSE_PA, tropo, strato)


def cas_to_tas(cas_mps, pressure_alt_m, sat_degc):
    """Calibrated to true airspeed (compressible, subsonic).

    Impact pressure from CAS at sea level (St Venant), then Mach from the impact pressure at the
    static pressure of ``pressure_alt_m``, then TAS = M * a(SAT).
    """
    cas = np.asarray(cas_mps, float)
    p = isa_pressure_pa(pressure_alt_m)
    qc = P0_PA * ((1.0 + 0.2 * (cas / A0_MPS) ** 2) ** 3.5 - 1.0)
    mach = np.sqrt(5.0 * ((qc / p + 1.0) ** (2.0 / 7.0) - 1.0))
    t = np.asarray(sat_degc, float) + 273.15
    return mach * np.sqrt(GAMMA * R_AIR * t)


def tas_to_cas(tas_mps, pressure_alt_m, sat_degc):
    """True to calibrated airspeed (inverse of :func:`cas_to_tas`)."""
    tas = np.asarray(tas_mps, float)
    t = np.asarray(sat_degc, float) + 273.15
    mach = tas / np.sqrt(GAMMA * R_AIR * t)
    p = isa_pressure_pa(pressure_alt_m)
    qc = p * ((1.0 + 0.2 * mach**2) ** 3.5 - 1.0)
    return A0_MPS * np.sqrt(5.0 * ((qc / P0_PA + 1.0) ** (2.0 / 7.0) - 1.0))


STANDARD_QNH_HPA = 1013.25
"""The pressure datum of pressure altitude [hPa]."""


def _check_qnh(qnh_hpa: float) -> float:
    from flightrecon.errors import MetadataError

    q = float(qnh_hpa)
    if not (800.0 < q < 1100.0):
        raise MetadataError(f"QNH {q} hPa is outside 800..1100 hPa")
    return q


def field_pressure_altitude_m(elev_msl_m: float, qnh_hpa: float | None) -> float:
    """Pressure altitude [m] of an airfield of MSL elevation ``elev_msl_m`` under ``qnh_hpa``.

    ``H_p = pressure_altitude(p_ISA(elev) * QNH / 1013.25)``: the station pressure is the ISA
    pressure at the elevation scaled to the QNH.  ``qnh_hpa=None`` means standard pressure
    (``H_p = elev``).  Near sea level ``dH_p/dQNH = -8.3 m/hPa``.
    """
    q = STANDARD_QNH_HPA if qnh_hpa is None else _check_qnh(qnh_hpa)
    p = float(isa_pressure_pa(float(elev_msl_m))) * q / STANDARD_QNH_HPA
    return float(pressure_altitude_m(p))


def pressure_to_msl_m(h_p_m, qnh_hpa: float | None) -> np.ndarray:
    """Pressure altitude to ISA altitude above MSL with the sea-level pressure ``qnh_hpa``
    (the inverse of :func:`field_pressure_altitude_m` along a column of ISA air); ``None``:
    standard pressure, the altitude unchanged."""
    h = np.asarray(h_p_m, dtype=np.float64)
    if qnh_hpa is None:
        return h
    q = _check_qnh(qnh_hpa)
    return np.asarray(pressure_altitude_m(isa_pressure_pa(h) * STANDARD_QNH_HPA / q),
                      dtype=np.float64)


def height_above_field_m(h_p_m, h_p_field_m: float, isa_deviation_k: float) -> np.ndarray:
    """Height [m] above a field of a point at pressure altitude ``h_p_m``, in air whose
    temperature is the ISA's plus the constant deviation ``isa_deviation_k`` [K].

    The hydrostatic equation of an ideal gas, ``g0 dH = -R T dp / p`` (``H`` geopotential
    height), and the definition of pressure altitude, ``g0 dh_p = -R T_ISA(h_p) dp / p``, give
    (eq. 1)::

        dH / dh_p = T / T_ISA(h_p) = 1 + dT / T_ISA(h_p)

    and, from the field's pressure altitude ``h_p,f`` to ``h_p`` (eq. 2)::

        H - H_f = (h_p - h_p,f) + dT (F(h_p) - F(h_p,f)),   F(h) = int_0^h dh' / T_ISA(h')

    with ``F(h) = ln(T_ISA(h) / T0) / L`` in the troposphere (``T_ISA = T0 + L h``) and
    ``F(11 km) + (h - 11 km) / T_11`` above it (``T_11`` = 216.65 K), to 20 km.

    A warm day (``dT > 0``) puts the aircraft higher above the field than its pressure altitude
    says, by ``dT / T`` (1 % per 2.9 K near 288 K).  Geopotential and geometric height differ by
    less than 0.05 % below 3 km (gravity's change with height and latitude).  Worked number:
    ``h_p,f = 0``, ``h_p = 1500 m``, ``dT = +10 K``: ``T_ISA = 278.4 K``, ``H = 1500 -
    1538.46 ln(278.4 / 288.15) = 1552.96 m``.
    """
    def f(h):
        tropo = np.minimum(h, H_TROPOPAUSE_M)
        return (np.log((T0_K + LAPSE_K_PER_M * tropo) / T0_K) / LAPSE_K_PER_M
                + np.maximum(h - H_TROPOPAUSE_M, 0.0) / T_TROPOPAUSE_K)

    h = np.asarray(h_p_m, dtype=np.float64)
    h_f = np.asarray(float(h_p_field_m), dtype=np.float64)
    return np.asarray((h - h_f) + float(isa_deviation_k) * (f(h) - f(h_f)), dtype=np.float64)
