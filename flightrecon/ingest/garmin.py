"""Garmin glass-cockpit exports (G1000, G3X, Perspective) read as recorded, with no mapping file.

The avionics write a CSV whose first line is ``#airframe_info, ...``, the second a units line
(``#yyy-mm-dd, hh:mm:ss, hh:mm, ident, degrees, ...``), the third the header, then one row a
second (:mod:`flightrecon.ingest.readers` recognises it).  This module is the built-in mapping
of its columns to the canonical schema (docs/ingest.md, "Garmin glass-cockpit exports"); a user
mapping file overrides it channel by channel (:func:`merge_with_user`).

Conventions, checked on the shipped export ``sample_logs/g1000_sr22_LFQA_20220417.csv``:

* time: ``Lcl Date`` + ``Lcl Time`` local, ``UTCOfst`` the offset (UTC = local - offset);
* ``NormAc`` is n - 1 (0 at rest; +0.04 g in the turns beyond 15 deg of bank): ``n_norm_g =
  NormAc + 1``;
* ``LatAc`` is positive toward the right wing (it follows ``V d(track)/dt / g0`` in the taxi
  turns: slope +0.51, correlation +0.65 over 63 turning samples): ``n_lat_g = LatAc``;
* ``HDG`` and ``TRK`` are magnetic; ``MagVar`` is the magnetic variation, east positive
  (+1.4..+2.0 deg over northern France in 2022, as the WMM gives): the track computed from
  consecutive GPS positions is ``TRK + MagVar`` (median difference -0.07 deg over the samples
  above 60 kt, against -1.76 deg for ``TRK`` itself), so ``heading_deg = HDG + MagVar`` and the
  GNSS velocity is ``GndSpd`` along ``TRK + MagVar``;
* ``AltInd`` is the altimeter's indication at the setting ``BaroA`` (inHg): the pressure
  altitude is the ISA height of the static pressure that setting implies
  (:func:`pressure_altitude_from_indicated`).  The QNH altitude itself has no canonical channel
  and is not kept.  The setting in use at the take-off and at the landing roll is the
  departure's and the arrival's QNH (``qnh_departure_hpa``, ``qnh_arrival_hpa``) where the sidecar and the command
  line give none (:func:`altimeter_settings_hpa`; theirs wins, and a note gives the recorded
  one);
* ``AltGPS`` ("ft wgs") is the GPS height above the WGS-84 ellipsoid (``AltMSL`` is the same
  less the geoid, 148 ft there): ``gnss_alt_m``; ``GPSfix`` (``NoSoln``, ``2D``, ``3D``,
  ``3DDiff``) gives ``gnss_quality`` (0, 1, 1, 2: NMEA codes);
* ``OAT`` is taken as the static air temperature (the air-data computer corrects the probe's
  ram rise; at 150 kt an uncorrected probe would read about 3 degC high, 0.5 % on TAS);
* these recorders have no longitudinal accelerometer: ``n_long_g`` is derived
  (:func:`flightrecon.ingest.derive.derive_n_long`).

Columns mapped to no channel (engine, radios, autopilot, the avionics' own wind) are ignored
and listed in a warning.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from flightrecon.constants import FOOT_M, KNOT_MPS
from flightrecon.errors import SchemaError
from flightrecon.geo.atmosphere import P0_PA, isa_pressure_pa, pressure_altitude_m
from flightrecon.ingest.mapping import ChannelSpec, MappedTable, Mapping, TimeSpec
from flightrecon.ingest.readers import RawTable
from flightrecon.ingest.units import lookup_unit

__all__ = [
    "GARMIN_COLUMNS",
    "INHG_PA",
    "altimeter_settings_hpa",
    "apply_garmin_columns",
    "garmin_mapping",
    "merge_with_user",
    "pressure_altitude_from_indicated",
]

#: name of the built-in mapping in messages and notes
PRESET = "built-in Garmin mapping (flightrecon/ingest/garmin.py)"
#: one inch of mercury [Pa] (at 0 degC, standard gravity: the altimeter-setting unit)
INHG_PA = 3386.389
#: canonical channel -> (Garmin column, offset added in the canonical unit)
GARMIN_COLUMNS: dict[str, tuple[str, float]] = {
    "n_norm_g": ("NormAc", 1.0),
    "n_lat_g": ("LatAc", 0.0),
    "roll_deg": ("Roll", 0.0),
    "pitch_deg": ("Pitch", 0.0),
    "heading_deg": ("HDG", 0.0),
    "tas_mps": ("TAS", 0.0),
    "ias_mps": ("IAS", 0.0),
    "baro_alt_m": ("AltInd", 0.0),
    "sat_degc": ("OAT", 0.0),
    "gnss_lat_deg": ("Latitude", 0.0),
    "gnss_lon_deg": ("Longitude", 0.0),
    "gnss_alt_m": ("AltGPS", 0.0),
}
#: the export's unit spellings -> flightrecon's (units.py); anything else is refused
GARMIN_UNITS = {"ft": "ft", "ft msl": "ft", "ft wgs": "ft", "kt": "kt", "fpm": "ft/min",
                "deg": "deg", "degrees": "deg", "deg c": "degC", "g": "g"}
#: GPSfix text -> NMEA fix quality (0 invalid, 1 GPS, 2 differential: SBAS)
GPS_FIX_QUALITY = {"nosoln": 0.0, "2d": 1.0, "3d": 1.0, "2ddiff": 2.0, "3ddiff": 2.0}
TIME_COLUMNS = ("Lcl Time", "Lcl Date", "UTCOfst")
#: a speed only the take-off and landing rolls and the flight reach (a fast taxi is 20 kt) [kt]
ROLL_SPEED_KT = 30.0


def garmin_mapping(raw: RawTable) -> Mapping:
    """The built-in mapping of a Garmin export: the time from ``Lcl Date`` + ``Lcl Time`` +
    ``UTCOfst``, and every channel of :data:`GARMIN_COLUMNS` whose column the file has, in the
    unit its units line gives.

    Raises
    ------
    SchemaError
        No ``Lcl Time`` / ``Lcl Date`` column, or a mapped column in a unit the units line
        spells in a way flightrecon does not know.
    """
    for c in TIME_COLUMNS[:2]:
        if c not in raw.columns:
            raise SchemaError("Garmin export without its local date and time columns "
                              f"({', '.join(TIME_COLUMNS)})", file=raw.file, column=c)
    time = TimeSpec("Lcl Time", "timestamp", None, "Lcl Date",
                    "UTCOfst" if "UTCOfst" in raw.columns else None)
    specs = []
    for channel, (col, offset) in GARMIN_COLUMNS.items():
        if col not in raw.columns:
            continue
        text = raw.units.get(col, "").strip()
        name = GARMIN_UNITS.get(text.lower())
        unit = lookup_unit(name) if name else None
        if unit is None:
            raise SchemaError(f"Garmin export: unit '{text}' of the units line is not one "
                              f"flightrecon knows for {channel} (known: "
                              f"{', '.join(sorted(GARMIN_UNITS))}); map the column with a "
                              "mapping file (--mapping)", file=raw.file, column=col)
        specs.append(ChannelSpec(channel, col, unit, offset=offset))
    return Mapping(file=PRESET, time=time, channels=tuple(specs))


def merge_with_user(preset: Mapping, user: Mapping | None) -> Mapping:
    """The preset with the user's mapping laid over it: the user's ``[time]`` and channels win;
    a preset channel whose column the user maps to another channel is left out."""
    if user is None:
        return preset
    theirs = {s.channel for s in user.channels}
    cols = {s.column for s in user.channels if s.column}
    kept = [s for s in preset.channels if s.channel not in theirs and s.column not in cols]
    return dataclasses.replace(user, time=user.time or preset.time,
                               channels=(*kept, *user.channels))


def pressure_altitude_from_indicated(alt_ind_m: np.ndarray, setting_pa: np.ndarray
                                     ) -> np.ndarray:
    """Pressure altitude [m] from an altimeter's indication ``alt_ind_m`` [m] at the setting
    ``setting_pa`` [Pa].

    The altimeter shows the ISA height of the static pressure with the sea-level pressure
    replaced by the setting: ``p = setting * (1 + L h_ind / T0)^(-g0 / (L R))``, i.e.
    ``p = isa_pressure(h_ind) * setting / P0``; the pressure altitude is the ISA height of that
    pressure (``flightrecon.geo.atmosphere``).  Near sea level this is the rule of thumb
    ``h_p = h_ind + 27 ft/hPa * (1013.25 hPa - setting)``.
    """
    p = isa_pressure_pa(alt_ind_m) * (np.asarray(setting_pa, dtype=float) / P0_PA)
    return np.asarray(pressure_altitude_m(p), dtype=float)


def altimeter_settings_hpa(raw: RawTable, mt: MappedTable) -> tuple[float, float] | None:
    """The altimeter setting ``BaroA`` [hPa] in use when the aircraft first and last moved
    faster than :data:`ROLL_SPEED_KT` (``IAS``, else ``GndSpd``: the take-off and the landing
    roll), or at the first and last rows that record one when it never did; ``None`` without
    the column.

    The pilot sets the departure's QNH before the take-off and the arrival's before the
    landing: on the shipped export the first rows still hold the previous flight's 30.33 inHg,
    set to 30.18 inHg on the apron before the take-off (the pressure altitude at rest then
    matches the field's elevation under it within 1 m; under 30.33, 41 m off).  A QFE setting
    would read as the field's elevation lower; a record cut in the air may end on the standard
    29.92 inHg.
    """
    col = raw.columns.get("BaroA")
    if col is None or col.dtype != np.float64 or not mt.rows.size:
        return None
    order = np.argsort(mt.time, kind="stable")
    v = col[mt.rows - 1][order]
    ok = np.isfinite(v) & (v > 0.0)
    if not ok.any():
        return None
    speed = None
    for name in ("IAS", "GndSpd"):
        c = raw.columns.get(name)
        if c is not None and c.dtype == np.float64 and (c > ROLL_SPEED_KT).any():
            speed = c[mt.rows - 1][order]
            break
    fast = (np.flatnonzero(ok & (speed > ROLL_SPEED_KT)) if speed is not None
            else np.zeros(0, dtype=np.int64))
    idx = fast if fast.size else np.flatnonzero(ok)
    return float(v[idx[0]]) * INHG_PA / 100.0, float(v[idx[-1]]) * INHG_PA / 100.0


def _filled(t: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``v`` with its gaps filled by linear interpolation in time (ends held)."""
    ok = ~np.isnan(v)
    if ok.all() or not ok.any():
        return v
    return np.interp(t, t[ok], v[ok])


def apply_garmin_columns(raw: RawTable, mt: MappedTable, used: Mapping,
                         withhold_gnss: bool = False) -> MappedTable:
    """The Garmin conventions that need two columns, applied to the channels the built-in
    mapping gave (a channel the user mapped is left as the user said):

    * ``heading_deg`` = ``HDG + MagVar`` (magnetic -> true with the recorded variation);
    * ``baro_alt_m`` from ``AltInd`` at the setting ``BaroA``
      (:func:`pressure_altitude_from_indicated`);
    * ``gnss_vn_mps`` / ``gnss_ve_mps`` from ``GndSpd`` and ``TRK + MagVar``;
    * ``gnss_quality`` from ``GPSfix``.

    ``MagVar`` and ``BaroA`` are interpolated in time over the rows they miss.  Not applied to
    the GNSS channels when ``withhold_gnss``.
    """
    preset = {s.channel: s for s in garmin_mapping(raw).channels}
    own = {s.channel for s in used.channels if preset.get(s.channel) == s}
    vals = dict(mt.values)
    src = dict(mt.source_column)
    notes = list(mt.notes)
    order = np.argsort(mt.time, kind="stable")
    tsec = np.empty(mt.time.size)
    tsec[order] = (mt.time[order] - mt.time[order][0]) / 1e9 if mt.time.size else 0.0

    def col(name: str) -> np.ndarray | None:
        if name not in raw.columns or raw.columns[name].dtype != np.float64:
            return None
        return raw.columns[name][mt.rows - 1]

    magvar = col("MagVar")
    if magvar is not None and (~np.isnan(magvar)).any():
        magvar = _filled(tsec, magvar)
        if "heading_deg" in own:
            vals["heading_deg"] = np.mod(vals["heading_deg"] + magvar, 360.0)
            src["heading_deg"] = "HDG"
            notes.append("heading_deg <- HDG + MagVar (magnetic -> true with the recorded "
                         f"variation, east positive: {np.nanmin(magvar):.1f}.."
                         f"{np.nanmax(magvar):.1f} deg)")
    elif "heading_deg" in own:
        # no variation recorded: the World Magnetic Model converts it (derive.py)
        mt = dataclasses.replace(mt, magnetic=(*mt.magnetic, "heading_deg"))
    baro = col("BaroA")
    if "baro_alt_m" in own and baro is not None and (~np.isnan(baro)).any():
        setting = _filled(tsec, baro) * INHG_PA
        vals["baro_alt_m"] = pressure_altitude_from_indicated(vals["baro_alt_m"], setting)
        notes.append("baro_alt_m <- AltInd [ft] at the altimeter setting BaroA [inHg] "
                     f"({np.nanmin(setting) / 100:.1f}..{np.nanmax(setting) / 100:.1f} hPa) "
                     "-> pressure altitude (ISA)")
    gs, trk = col("GndSpd"), col("TRK")
    if not withhold_gnss and gs is not None and trk is not None and "gnss_lat_deg" in own:
        true_trk = np.radians(trk + (magvar if magvar is not None else 0.0))
        v = gs * KNOT_MPS
        vals["gnss_vn_mps"] = v * np.cos(true_trk)
        vals["gnss_ve_mps"] = v * np.sin(true_trk)
        src["gnss_vn_mps"] = src["gnss_ve_mps"] = "GndSpd"
        notes.append("gnss_vn_mps, gnss_ve_mps <- GndSpd [kt] along TRK + MagVar (true track)")
    fix = raw.columns.get("GPSfix")
    if not withhold_gnss and fix is not None and fix.dtype == object and "gnss_lat_deg" in own:
        txt = np.array([str(x).strip().lower() if x is not None else "" for x in
                        fix[mt.rows - 1]], dtype=object)
        q = np.array([GPS_FIX_QUALITY.get(x, np.nan) for x in txt], dtype=float)
        vals["gnss_quality"] = q
        src["gnss_quality"] = "GPSfix"
        notes.append("gnss_quality <- GPSfix (NoSoln 0, 2D/3D 1, 2DDiff/3DDiff 2)")
    if "gnss_alt_m" in own:
        notes.append(f"gnss_alt_m <- AltGPS [ft, WGS-84 ellipsoid] ({FOOT_M} m/ft)")
    return dataclasses.replace(mt, values=vals, source_column=src, notes=tuple(notes))
