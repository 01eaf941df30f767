"""Channels computed at ingest: true airspeed from IAS/CAS, true heading from magnetic heading.

* TAS from CAS (:func:`flightrecon.geo.atmosphere.cas_to_tas`: compressible, subsonic) with the
  static air temperature and the pressure altitude.  IAS is treated as CAS: no position-error
  correction is known for an arbitrary aircraft (documented in docs/ingest.md).  Where the
  temperature or the altitude is sampled on other rows than the airspeed (multi-rate logs), they
  are interpolated linearly in time to the airspeed rows (they are inputs, not measurements);
  without a temperature channel the ISA temperature at the pressure altitude is used (a warning).
* Longitudinal load factor from airspeed and pitch, for recorders without a longitudinal
  accelerometer (Garmin glass cockpits): ``n_long = (dV/dt) / g0 + sin(pitch)``
  (:func:`derive_n_long`).
* Lateral load factor of coordinated flight, for recorders with the normal acceleration alone
  (many airline recorders): ``n_lat = 0`` (:func:`derive_n_lat`).
* Magnetic -> true: ``true = magnetic + D`` with the World Magnetic Model declination D at the
  flight date (:mod:`flightrecon.geo.magnetic`), evaluated along the GNSS track when the log has
  GNSS positions, else at the departure airfield.
"""

from __future__ import annotations

import numpy as np

from flightrecon.constants import G0
from flightrecon.errors import MetadataError, SchemaError
from flightrecon.geo.atmosphere import cas_to_tas, isa_temperature_k
from flightrecon.geo.magnetic import decimal_year, declination_deg, magnetic_to_true
from flightrecon.types import FlightMeta

__all__ = ["DECLINATION_POINTS", "N_LONG_HALF_WINDOW_S", "derive_n_lat", "derive_n_long",
           "derive_tas", "true_from_magnetic"]

#: number of points along the GNSS track where the WMM is evaluated (then interpolated in time)
DECLINATION_POINTS = 48


def _at(t: np.ndarray, v: np.ndarray, where: np.ndarray) -> np.ndarray:
    ok = ~np.isnan(v)
    if ok.sum() == 0:
        return np.full(int(where.sum()), np.nan)
    if ok.sum() == 1:
        return np.full(int(where.sum()), v[ok][0])
    return np.interp(t[where], t[ok], v[ok])


def derive_tas(t: np.ndarray, values: dict[str, np.ndarray], source: str,
               file: str) -> tuple[np.ndarray, list[str]]:
    """True airspeed [m/s] on the rows where ``cas_mps`` (``source="cas"``) or ``ias_mps``
    (``"ias"``) was sampled, NaN elsewhere.

    Raises
    ------
    SchemaError
        The airspeed or the pressure altitude channel is missing.
    """
    ch = {"cas": "cas_mps", "ias": "ias_mps"}[source]
    for need in (ch, "baro_alt_m"):
        if need not in values:
            raise SchemaError(f"tas_mps from {source} needs channel {need}", file=file,
                              column=need)
    warns: list[str] = []
    spd = values[ch]
    rows = ~np.isnan(spd)
    h = _at(t, values["baro_alt_m"], rows)
    if "sat_degc" in values and (~np.isnan(values["sat_degc"])).any():
        sat = _at(t, values["sat_degc"], rows)
    else:
        sat = isa_temperature_k(h) - 273.15
        warns.append(f"{file}: no static air temperature: TAS from {source.upper()} uses the ISA "
                     "temperature at the pressure altitude")
    if source == "ias":
        warns.append(f"{file}: IAS treated as CAS (no position-error correction) to compute TAS")
    tas = np.full(t.size, np.nan)
    tas[rows] = cas_to_tas(spd[rows], h, sat)
    return tas, warns


#: half-width of the airspeed difference that gives dV/dt for a derived n_long [s]: a 1 kt
#: airspeed quantum (0.51 m/s) becomes 0.51 / 6 / g0 = 0.009 g, and a speed change of a
#: light aircraft (seconds) is still followed
N_LONG_HALF_WINDOW_S = 3.0


def derive_n_long(t: np.ndarray, values: dict[str, np.ndarray], file: str
                  ) -> tuple[np.ndarray, str]:
    """Longitudinal load factor [g] for a log with no longitudinal accelerometer.

    Along the body x axis the specific force is the acceleration plus the component of g0 up:
    ``n_long = (dV/dt) / g0 + sin(theta)`` with ``V`` the true airspeed and ``theta`` the pitch.
    ``dV/dt`` is the airspeed difference over +-:data:`N_LONG_HALF_WINDOW_S` (a centred
    difference of the airspeed interpolated linearly in time: the mean derivative over 6 s).

    What it costs against a measured channel: (1) ``dV/dt`` is the acceleration relative to
    the air: a wind changing along the track by ``dW/dt`` is missed by ``dW/dt / g0`` (gusts,
    shear: 0.01 g per 1 m/s in 10 s); (2) the angle of attack ``alpha`` (no sideslip, steady
    alpha): the body x axis sees ``u' + q w`` with ``u = V cos(alpha)``, ``w = V sin(alpha)``, and
    the body z equation gives ``q V cos(alpha) = g0 (n_norm - cos(theta) cos(phi))``, so
    ``n_long = (dV/dt / g0) cos(alpha) + sin(theta) + tan(alpha) (n_norm - cos(theta) cos(phi))``:
    the formula above misses ``alpha (n_norm - cos(theta) cos(phi))`` and ``alpha^2`` terms,
    0.025 g in a level turn at 30 deg of bank and 5 deg of alpha (n_norm = 1.155);
    (3) the 6 s difference smooths the speed changes and the 1-kt quantum of a Garmin TAS column
    leaves about 0.009 g of noise.  The joint smoother's accelerometer noise is one figure for
    the three axes (not per channel), so it is not widened; the airspeed measurement it fuses
    holds the along-track speed.

    Parameters
    ----------
    t : (N,) seconds
    values : channels on the rows (``tas_mps`` and ``pitch_deg`` needed; NaN where not sampled)
    file : for the note

    Returns
    -------
    n_long : (N,) on the rows where the pitch was sampled, NaN elsewhere [g]
    note : what was derived (for the ingest notes and the summary's warnings)

    Raises
    ------
    SchemaError
        ``tas_mps`` or ``pitch_deg`` missing or without two samples.
    """
    for need in ("tas_mps", "pitch_deg"):
        if need not in values or np.count_nonzero(~np.isnan(values[need])) < 2:
            raise SchemaError(f"n_long_g is not recorded and cannot be derived without {need}",
                              file=file, column=need)
    v, pitch = values["tas_mps"], values["pitch_deg"]
    ok = ~np.isnan(v)
    tv, vv = t[ok], v[ok]
    at = ~np.isnan(pitch)
    h = N_LONG_HALF_WINDOW_S
    lo = np.clip(t[at] - h, tv[0], tv[-1])
    hi = np.clip(t[at] + h, tv[0], tv[-1])
    span = hi - lo
    with np.errstate(invalid="ignore", divide="ignore"):
        vdot = np.where(span > 0, (np.interp(hi, tv, vv) - np.interp(lo, tv, vv)) / span, 0.0)
    out = np.full(t.size, np.nan)
    out[at] = vdot / G0 + np.sin(np.radians(pitch[at]))
    note = (f"{file}: n_long_g not recorded: derived as (dV/dt)/g0 + sin(pitch) from tas_mps and "
            f"pitch_deg (dV/dt over +-{h:g} s; misses along-track wind changes and "
            "angle-of-attack terms of order 0.01 g: docs/ingest.md)")
    return out, note


def derive_n_lat(t: np.ndarray, values: dict[str, np.ndarray], file: str
                 ) -> tuple[np.ndarray, str]:
    """Lateral load factor [g] of coordinated flight, for a log with no lateral accelerometer.

    In body axes the lateral specific force is ``f_y = m^-1 (Y_aero + Y_thrust)``: the side
    force of the airframe, which the pilot (or the yaw damper) holds near zero by centring the
    ball, whatever the bank: in a coordinated turn the horizontal component of the lift, not a
    side force, turns the aircraft, and ``n_lat = 0`` (docs/schema.md, "Conventions": the
    body-to-NED rotation of ``g0 [n_long, n_lat, -n_norm]`` gives the turn's centripetal
    acceleration ``g0 n_norm sin(phi)`` through the bank angle).  The estimators use the three
    loads only through that rotation, so what is missed is the side force itself: a sideslip
    ``beta`` gives ``n_lat ~ (q S CY_beta beta) / (m g0)``, a few hundredths of a g in a
    slip or a crabbed approach, and on the ground the whole centripetal acceleration of a taxi
    turn (``V psi_dot / g0``, 0.1 g at 10 m/s and 6 deg/s) and the side load of a crosswind
    roll.  Its cost is measured on the JSBSim fleet (docs/ingest.md, "Normal acceleration
    alone").

    Parameters
    ----------
    t : (N,) seconds
    values : channels on the rows (``n_norm_g`` needed; NaN where not sampled)
    file : for the note

    Returns
    -------
    n_lat : (N,) 0 on the rows where ``n_norm_g`` was sampled, NaN elsewhere [g]
    note : what was assumed (for the ingest notes and the summary's warnings)

    Raises
    ------
    SchemaError
        ``n_norm_g`` missing or without a sample.
    """
    n = values.get("n_norm_g")
    if n is None or not np.any(~np.isnan(n)):
        raise SchemaError("n_lat_g is not recorded and cannot be taken as coordinated flight's "
                          "without n_norm_g", file=file, column="n_norm_g")
    out = np.where(np.isnan(n), np.nan, 0.0)
    note = (f"{file}: n_lat_g not recorded: taken as 0 g, the lateral load of coordinated "
            "flight (misses the side force of a sideslip and of ground turns: a few "
            "hundredths of a g in the air; the joint smoother widens its loads' noise for it, "
            "the other estimators do not: docs/ingest.md, 'Normal acceleration alone')")
    return out, note


def true_from_magnetic(t: np.ndarray, mag_deg: np.ndarray, values: dict[str, np.ndarray],
                       meta: FlightMeta, file: str, column: str) -> tuple[np.ndarray, list[str]]:
    """True heading-like angle [deg, [0, 360)] from a magnetic one.

    Raises
    ------
    MetadataError
        No flight date (``epoch_utc``) or no position (GNSS or departure).
    """
    if meta.epoch_utc is None:
        raise MetadataError(f"column '{column}' is magnetic: the flight date (epoch_utc in the "
                            "sidecar, or timestamps in the log) is needed for the declination",
                            file=file)
    notes: list[str] = []
    lat = values.get("gnss_lat_deg")
    lon = values.get("gnss_lon_deg")
    ok = None if lat is None or lon is None else (~np.isnan(lat) & ~np.isnan(lon))
    if ok is not None and ok.sum() >= 1:
        idx = np.flatnonzero(ok)
        pick = idx[np.unique(np.linspace(0, idx.size - 1, min(DECLINATION_POINTS, idx.size))
                             .round().astype(int))]
        alt = values.get("gnss_alt_m")
        alt_p = np.nan_to_num(alt[pick]) if alt is not None else np.zeros(pick.size)
        year = decimal_year(meta.epoch_utc, float(np.median(t[pick])))
        d, note = declination_deg(lat[pick], lon[pick], alt_p, year)
        decl = np.interp(t, t[pick], d)
        where = f"along the GNSS track ({pick.size} points)"
    elif meta.departure is not None:
        dep = meta.departure
        year = decimal_year(meta.epoch_utc, float(t[0]) if t.size else 0.0)
        d, note = declination_deg(dep.lat_deg, dep.lon_deg, dep.elev_m, year)
        decl = np.full(t.size, float(d))
        where = "at the departure airfield"
    else:
        raise MetadataError(f"column '{column}' is magnetic: a position is needed for the "
                            "declination (GNSS positions in the data, or --departure / a sidecar "
                            "[departure] table)", file=file)
    if note:
        notes.append(note)
    notes.append(f"{column}: magnetic -> true with WMM declination {where}, "
                 f"{float(np.min(decl)):.2f}..{float(np.max(decl)):.2f} deg")
    return magnetic_to_true(mag_deg, decl), notes
