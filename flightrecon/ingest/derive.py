"""Channels computed at ingest: true airspeed from IAS/CAS, true heading from magnetic heading.

* TAS from CAS (:func:`flightrecon.geo.atmosphere.cas_to_tas`: compressible, subsonic) with the
  static air temperature and the pressure altitude.  IAS is treated as CAS: no position-error
  correction is known for an arbitrary aircraft (documented in docs/ingest.md).  Where the
  temperature or the altitude is sampled on other rows than the airspeed (multi-rate logs), they
  are interpolated linearly in time to the airspeed rows (they are inputs, not measurements);
  without a temperature channel the ISA temperature at the pressure altitude is used (a warning).
* Magnetic -> true: ``true = magnetic + D`` with the World Magnetic Model declination D at the
  flight date (:mod:`flightrecon.geo.magnetic`), evaluated along the GNSS track when the log has
  GNSS positions, else at the departure airfield.
"""

from __future__ import annotations

import numpy as np

from flightrecon.errors import MetadataError, SchemaError
from flightrecon.geo.atmosphere import cas_to_tas, isa_temperature_k
from flightrecon.geo.magnetic import decimal_year, declination_deg, magnetic_to_true
from flightrecon.types import FlightMeta

__all__ = ["DECLINATION_POINTS", "derive_tas", "true_from_magnetic"]

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
