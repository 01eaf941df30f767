"""Garmin avionics exports (G1000, G1000 NXi, Perspective, G3X / G3X Touch, G5) read as
recorded, with no mapping file.

The avionics write a CSV whose first line is an information line (``#airframe_info, ...``),
then a units line and the short names, or the long names with their units and the short names
(:mod:`flightrecon.ingest.garmin_layout`), then one row a second.  This module is the built-in
mapping of its columns to the canonical schema (docs/ingest.md, "Garmin glass-cockpit
exports"); a user mapping file overrides it channel by channel (:func:`merge_with_user`).
Columns are found by their short name or their long name (``AltInd`` / ``AltB`` / ``Baro
Altitude``), so each software version's spelling is read.

Conventions differ between units and versions; each one that matters is **checked from the
export's own data** (:mod:`flightrecon.ingest.garmin_checks`, :func:`garmin_reading`), with the
convention first seen on the shipped export ``sample_logs/g1000_sr22_LFQA_20220417.csv`` as the
built-in one where the data cannot tell:

* time: ``Lcl Date`` + ``Lcl Time`` local, ``UTCOfst`` the offset (UTC = local - offset); a
  unit writing only ``UTC Date`` + ``UTC Time`` is read in UTC;
* ``NormAc`` is n - 1 on the G1000 family (0 at rest), n on the long-name layouts: decided by
  its value at rest or in straight flight;
* ``LatAc`` is positive toward the right wing (it follows ``V d(track)/dt / g0`` in the taxi
  turns: slope +0.51, correlation +0.65 over 63 turning samples): ``n_lat_g = LatAc``;
* ``HDG`` is magnetic and ``MagVar`` the variation, its sign checked against the World
  Magnetic Model; ``TRK`` is magnetic on the G1000 family, true on the G3X Touch (``GPS Ground
  Track (deg true)``): decided by the track of consecutive GPS positions (on the shipped export
  the median difference is -0.07 deg for ``TRK + MagVar``, -1.76 deg for ``TRK``);
* ``AltInd`` / ``AltB`` is the altimeter's indication at the setting ``BaroA`` (inHg): the
  pressure altitude is the ISA height of the static pressure that setting implies
  (:func:`pressure_altitude_from_indicated`), checked at rest against ``AltMSL``; ``AltP``
  (``Pressure Altitude``) is read as it is.  The setting in use at the take-off and at the
  landing roll is the departure's and the arrival's QNH where the sidecar and the command line
  give none (:func:`altimeter_settings_hpa`);
* ``AltGPS`` is above the WGS-84 ellipsoid or MSL, decided by ``AltGPS - AltMSL`` (148 ft on
  the shipped export: the geoid there); ``GPSfix`` (``NoSoln``, ``2D``, ``3D``, ``3DDiff``)
  gives ``gnss_quality`` (0, 1, 1, 2: NMEA codes);
* ``OAT`` is taken as the static air temperature (the air-data computer corrects the probe's
  ram rise; at 150 kt an uncorrected probe would read about 3 degC high, 0.5 % on TAS);
* these recorders have no longitudinal accelerometer: ``n_long_g`` is derived
  (:func:`flightrecon.ingest.derive.derive_n_long`).

Columns mapped to no channel (engine, radios, autopilot, the avionics' own wind) are ignored
and listed in a warning.
"""

from __future__ import annotations

import dataclasses
import re
from typing import Any

import numpy as np

from flightrecon.constants import FOOT_M, KNOT_MPS
from flightrecon.errors import SchemaError
from flightrecon.geo.atmosphere import P0_PA, isa_pressure_pa, pressure_altitude_m
from flightrecon.ingest.garmin_checks import (
    Convention,
    altitude_datum,
    gps_height_datum,
    magvar_sign_wmm,
    normal_load_offset,
    track_reference,
)
from flightrecon.ingest.garmin_time import motion_period_s, motion_rows, regular_rows
from flightrecon.ingest.mapping import ChannelSpec, MappedTable, Mapping, TimeSpec
from flightrecon.ingest.readers import RawTable
from flightrecon.ingest.units import Unit, lookup_unit, to_canonical

__all__ = [
    "GARMIN_COLUMNS",
    "INHG_PA",
    "GarminReading",
    "altimeter_settings_hpa",
    "apply_garmin_columns",
    "garmin_mapping",
    "garmin_reading",
    "merge_with_user",
    "pressure_altitude_from_indicated",
]

#: name of the built-in mapping in messages and notes
PRESET = "built-in Garmin mapping (flightrecon/ingest/garmin.py)"
#: one inch of mercury [Pa] (at 0 degC, standard gravity: the altimeter-setting unit)
INHG_PA = 3386.389
#: role -> the names a unit of the family gives its column (short names, then long names
#: without their unit), first found wins
ROLES: dict[str, tuple[str, ...]] = {
    "date": ("Lcl Date", "Date", "Local Date"), "time": ("Lcl Time", "Time", "Local Time"),
    "utc_offset": ("UTCOfst", "UTC Offset"), "utc_date": ("UTC Date",),
    "utc_time": ("UTC Time", "UTCTime"),
    "normac": ("NormAc", "Normal Acceleration"), "latac": ("LatAc", "Lateral Acceleration"),
    "roll": ("Roll",), "pitch": ("Pitch",), "hdg": ("HDG", "Magnetic Heading", "Heading"),
    "tas": ("TAS", "True Airspeed"), "ias": ("IAS", "Indicated Airspeed"),
    "alt_p": ("AltP", "Pressure Altitude"),
    "alt_ind": ("AltInd", "AltB", "Baro Altitude", "Indicated Altitude"),
    "baro_set": ("BaroA", "Baro Setting", "Baro"),
    "oat": ("OAT", "Outside Air Temp", "Outside Air Temperature"),
    "lat": ("Latitude",), "lon": ("Longitude",), "alt_gps": ("AltGPS", "GPS Altitude"),
    "alt_msl": ("AltMSL",), "gs": ("GndSpd", "GPS Ground Speed", "Ground Speed"),
    "trk": ("TRK", "GPS Ground Track", "Ground Track"),
    "vel_n": ("GPSVelN", "GPS Velocity N"), "vel_e": ("GPSVelE", "GPS Velocity E"),
    "magvar": ("MagVar", "Magnetic Variation"), "fix": ("GPSfix", "GPS Fix Status"),
}
#: canonical channel -> role of the column it is read from
GARMIN_COLUMNS: dict[str, str] = {
    "n_norm_g": "normac", "n_lat_g": "latac", "roll_deg": "roll", "pitch_deg": "pitch",
    "heading_deg": "hdg", "tas_mps": "tas", "ias_mps": "ias", "baro_alt_m": "alt_ind",
    "sat_degc": "oat", "gnss_lat_deg": "lat", "gnss_lon_deg": "lon", "gnss_alt_m": "alt_gps",
}
#: the export's unit spellings -> flightrecon's (units.py); anything else is refused
GARMIN_UNITS = {"ft": "ft", "ft msl": "ft", "ft wgs": "ft", "wgs84 ft": "ft", "ft baro": "ft",
                "feet": "ft", "m": "m", "kt": "kt", "kts": "kt", "knots": "kt",
                "fpm": "ft/min", "ft/min": "ft/min", "m/s": "m/s", "m/sec": "m/s",
                "deg": "deg", "degrees": "deg", "wgs84 deg": "deg", "deg true": "deg",
                "deg mag": "deg", "deg c": "degC", "g": "g"}
#: a column's unit when its unit text is empty (a long name without a bracket)
DEFAULT_UNITS = {"normac": "g", "latac": "g", "roll": "deg", "pitch": "deg", "hdg": "deg",
                 "tas": "kt", "ias": "kt", "alt_p": "ft", "alt_ind": "ft", "oat": "deg c",
                 "lat": "deg", "lon": "deg", "alt_gps": "ft", "alt_msl": "ft", "gs": "kt",
                 "trk": "deg", "vel_n": "m/s", "vel_e": "m/s", "magvar": "deg"}
#: a speed only the take-off and landing rolls and the flight reach (a fast taxi is 20 kt) [kt]
ROLL_SPEED_KT = 30.0


@dataclasses.dataclass(frozen=True)
class GarminReading:
    """What a Garmin export is and how it is read (:func:`garmin_reading`).

    Attributes
    ----------
    variant : the unit and layout as the export names them, for ``flightrecon info``
    roles : role (:data:`ROLES`) -> the export's column
    normal_offset : added to the normal load column [g] (1: recorded as n - 1)
    magvar_sign : +1 when the recorded variation is east positive, -1 west positive
    track : ``"magnetic"`` or ``"true"`` (the ``TRK`` column)
    heading : ``"magnetic"`` or ``"true"`` (the ``HDG`` column)
    altitude : ``"indicated"`` (at the setting) or ``"pressure"`` (the ``baro_alt_m`` column)
    gnss_datum : ``"ellipsoid"`` or ``"msl"`` (``AltGPS``)
    undulation_m : ``AltGPS - AltMSL`` [m] when AltGPS is ellipsoidal, else ``None``
    conventions : each convention read, with its basis and evidence
    identity : ``aircraft_id``, ``aircraft_type``, ``registration`` and ``system_id`` found
    """

    variant: str
    roles: dict[str, str]
    normal_offset: float = 1.0
    magvar_sign: float = 1.0
    track: str = "magnetic"
    heading: str = "magnetic"
    altitude: str = "indicated"
    gnss_datum: str = "ellipsoid"
    undulation_m: float | None = None
    conventions: tuple[Convention, ...] = ()
    identity: dict[str, str] = dataclasses.field(default_factory=dict)

    @property
    def warnings(self) -> tuple[str, ...]:
        """The conventions' warnings (contradicted or undecided)."""
        return tuple(c.warning for c in self.conventions if c.warning)


def _resolve(raw: RawTable) -> dict[str, str]:
    """Role -> column: the column named so, else the column whose long name (unit removed)
    is so, case and spacing aside."""
    def key(x: str) -> str:
        return re.sub(r"\s+", " ", x.strip().lower())

    by_name = {key(c): c for c in raw.columns}
    by_long: dict[str, str] = {}
    for c, ln in raw.long_names.items():
        by_long.setdefault(key(re.sub(r"\s*\([^()]*\)\s*$", "", ln)), c)
    out: dict[str, str] = {}
    for role, names in ROLES.items():
        for n in names:
            col = by_name.get(key(n)) or by_long.get(key(n))
            if col is not None and col not in out.values():
                out[role] = col
                break
    return out


def _unit(raw: RawTable, role: str, col: str) -> Unit | None:
    text = raw.units.get(col, "").strip()
    name = GARMIN_UNITS.get(text.lower()) if text else GARMIN_UNITS.get(DEFAULT_UNITS.get(role,
                                                                                       ""))
    return lookup_unit(name) if name else None


def _si(raw: RawTable, roles: dict[str, str], role: str) -> np.ndarray | None:
    """The column of ``role`` in SI units (float64, file row order), or ``None``."""
    col = roles.get(role)
    if col is None or raw.columns[col].dtype != np.float64:
        return None
    unit = _unit(raw, role, col)
    return to_canonical(raw.columns[col], unit) if unit is not None else None


def _setting_pa(raw: RawTable, roles: dict[str, str]) -> np.ndarray | None:
    """The altimeter setting [Pa]: inHg (25-33) or hPa (700-1100) as its values show (the two
    ranges are apart: certain), whatever its unit text."""
    col = roles.get("baro_set")
    if col is None or raw.columns[col].dtype != np.float64:
        return None
    v = raw.columns[col]
    med = np.nanmedian(v) if np.isfinite(v).any() else np.nan
    if 20.0 < med < 35.0:
        return v * INHG_PA
    if 700.0 < med < 1100.0:
        return v * 100.0
    return None


def _variant(raw: RawTable, roles: dict[str, str]) -> str:
    info = raw.preamble
    unit = info.get("product") or info.get("Product") or ""
    name = info.get("airframe_name", "")
    sw = info.get("software_version") or info.get("unit_software_version") or "?"
    family = ("G3X / G3X Touch" if unit.upper().startswith("GDU") else
              "G1000 / G1000 NXi / Perspective" if "airframe_name" in info else "Garmin unit")
    alt = roles.get("alt_p") or roles.get("alt_ind") or "no altitude"
    if "alt_p" not in roles and "alt_ind" in roles:
        alt += " + " + roles["baro_set"] if "baro_set" in roles else " without a setting"
    what = ", ".join(x for x in (unit, name) if x)
    return (f"{family} ({what or 'unnamed'}), log_version {info.get('log_version', '?')}, "
            f"software {sw}, {raw.layout or 'units line'}; altitude from {alt}")


def _year(raw: RawTable, roles: dict[str, str]) -> float | None:
    """The year of the export's first date (a four-digit year in any date order)."""
    col = roles.get("date") or roles.get("utc_date")
    if col is None:
        return None
    for x in raw.columns[col][:2000]:
        m = re.search(r"(19|20)\d\d", str(x)) if x is not None else None
        if m:
            return float(m.group(0)) + 0.5
    return None


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


def _wmm_declination(raw: RawTable, roles: dict[str, str]) -> np.ndarray | None:
    """The WMM declination [deg] at the export's positions and date (NaN where no position),
    evaluated at a few dozen rows and interpolated (:mod:`flightrecon.geo.magnetic`)."""
    lat, lon, year = _si(raw, roles, "lat"), _si(raw, roles, "lon"), _year(raw, roles)
    if lat is None or lon is None or year is None:
        return None
    ok = np.flatnonzero(np.isfinite(lat) & np.isfinite(lon) & (np.abs(lat) + np.abs(lon) > 0))
    if not ok.size:
        return None
    from flightrecon.geo.magnetic import declination_deg

    pick = ok[np.unique(np.linspace(0, ok.size - 1, min(24, ok.size)).astype(int))]
    d, _ = declination_deg(lat[pick], lon[pick], 0.0, year)
    out = np.full(lat.size, np.nan)
    out[ok] = np.interp(ok, pick, d)
    return out


def _direction_conventions(raw: RawTable, roles: dict[str, str], layout_g1000: bool
                           ) -> tuple[float, str, str, list[Convention]]:
    """The variation's sign, the track's and the heading's reference (module docstring)."""
    convs: list[Convention] = []
    mv = _si(raw, roles, "magvar")
    wmm = _wmm_declination(raw, roles)
    sign, wmm_told = 1.0, False
    if mv is not None and wmm is not None:
        s_wmm, c = magvar_sign_wmm(mv, wmm, roles["magvar"])
        convs.append(c)
        sign, wmm_told = (s_wmm, True) if s_wmm is not None else (1.0, False)
    track = "magnetic" if layout_g1000 else "true"
    trk, gs = _si(raw, roles, "trk"), _si(raw, roles, "gs")
    lat, lon = _si(raw, roles, "lat"), _si(raw, roles, "lon")
    var = (sign * mv if mv is not None else wmm)
    if trk is not None and gs is not None and lat is not None and lon is not None \
            and var is not None:
        track, s_trk, c = track_reference(trk, var, lat, lon, gs, track, roles["trk"])
        convs.append(c)
        if s_trk is not None and s_trk < 0 and mv is not None:
            if wmm_told:
                convs.append(Convention(f"{roles['magvar']} sign", "as the WMM says", "data",
                                        "the GPS track fits the variation of the other sign",
                                        f"{roles['magvar']}: the WMM and the GPS track "
                                        "disagree on the variation's sign: the WMM's taken"))
            else:
                sign = -sign
                convs.append(Convention(roles["magvar"], "west positive (sign changed)",
                                        "data", "the GPS track fits TRK - variation"))
    # the G1000 family's HDG follows its navigation-angle setting, as TRK does; the long-name
    # layouts name it "Magnetic Heading"
    heading = track if layout_g1000 else "magnetic"
    if "hdg" in roles:
        convs.append(Convention(roles["hdg"], heading, "label" if not layout_g1000 else
                                "data" if convs and convs[-1].basis == "data" else "built-in",
                                "named 'Magnetic Heading'" if not layout_g1000 else
                                "the same navigation-angle reference as TRK"))
    return sign, track, heading, convs


def garmin_reading(raw: RawTable) -> GarminReading:
    """The variant of a Garmin export and its conventions, each decided from the data where
    the data can tell (:mod:`flightrecon.ingest.garmin_checks`), with their evidence."""
    roles = _resolve(raw)
    g1000 = (raw.layout or "units line") == "units line"
    convs: list[Convention] = []
    offset = 1.0 if g1000 else 0.0
    nz, gs = _si(raw, roles, "normac"), _si(raw, roles, "gs")
    if nz is not None:
        roll = _si(raw, roles, "roll")
        offset, c = normal_load_offset(nz, gs if gs is not None else np.full(nz.size, np.nan),
                                       roll if roll is not None else np.zeros(nz.size),
                                       offset, roles["normac"])
        convs.append(c)
    sign, track, heading, dconv = _direction_conventions(raw, roles, g1000)
    convs += dconv
    altitude = "pressure" if "alt_p" in roles else "indicated"
    setting, alt, msl = _setting_pa(raw, roles), _si(raw, roles, "alt_ind"), _si(raw, roles,
                                                                                "alt_msl")
    if altitude == "indicated" and alt is not None and setting is not None:
        rest = gs if gs is not None else np.full(alt.size, np.nan)
        altitude, c = altitude_datum(alt, pressure_altitude_from_indicated(alt, setting),
                                     msl if msl is not None else np.full(alt.size, np.nan),
                                     rest, "indicated", roles["alt_ind"])
        convs.append(c)
    elif altitude == "indicated" and alt is not None:
        convs.append(Convention(roles["alt_ind"], "pressure", "built-in", "no altimeter "
                                "setting recorded", f"{roles['alt_ind']}: no altimeter setting "
                                "recorded: the altitude is read as a pressure altitude"))
        altitude = "pressure"
    datum, und = "ellipsoid", None
    g = _si(raw, roles, "alt_gps")
    if g is not None:
        datum, und, c = gps_height_datum(g, msl, raw.units.get(roles["alt_gps"], ""),
                                         roles["alt_gps"])
        convs.append(c)
    return GarminReading(_variant(raw, roles), roles, offset, sign, track, heading, altitude,
                         datum, und, tuple(convs), garmin_identity(raw.preamble))


def garmin_identity(info: dict[str, str]) -> dict[str, str]:
    """The aircraft as the information line names it: ``aircraft_id`` is the registration a
    unit writes (``aircraft_ident``, G3X), else the avionics' ``system_id`` (one per
    installation: the same on every export of an aircraft); ``aircraft_type`` the
    ``airframe_name`` (G1000 family)."""
    out: dict[str, str] = {}
    reg = info.get("aircraft_ident", "").strip()
    sid = info.get("system_id", "").strip()
    if reg:
        out.update(aircraft_id=reg, registration=reg, id_from="aircraft_ident")
    elif sid:
        out.update(aircraft_id=sid, id_from="system_id")
    if sid:
        out["system_id"] = sid
    kind = (info.get("airframe_name") or "").strip()
    if kind:
        out["aircraft_type"] = kind
    return out


def garmin_mapping(raw: RawTable, reading: GarminReading | None = None) -> Mapping:
    """The built-in mapping of a Garmin export: the time from the local date and time and
    the UTC offset (or the UTC date and time), and every channel of :data:`GARMIN_COLUMNS`
    whose column the file has, in the unit its units line or long name gives.

    Raises
    ------
    SchemaError
        No date and time columns, or a mapped column in a unit the export spells in a way
        flightrecon does not know.
    """
    rd = reading if reading is not None else garmin_reading(raw)
    roles = rd.roles
    if "date" in roles and "time" in roles:
        time = TimeSpec(roles["time"], "timestamp", None, roles["date"], roles.get("utc_offset"))
    elif "utc_date" in roles and "utc_time" in roles:
        time = TimeSpec(roles["utc_time"], "timestamp", None, roles["utc_date"], None)
    else:
        raise SchemaError("Garmin export without its date and time columns (Lcl Date, Lcl "
                          "Time, UTCOfst; or UTC Date, UTC Time)", file=raw.file,
                          column="Lcl Date")
    specs = []
    for channel, role in GARMIN_COLUMNS.items():
        if channel == "baro_alt_m" and "alt_p" in roles:
            role = "alt_p"
        col = roles.get(role)
        if col is None:
            continue
        unit = _unit(raw, role, col)
        if unit is None:
            raise SchemaError(f"Garmin export: unit '{raw.units.get(col, '')}' is not one "
                              f"flightrecon knows for {channel} (known: "
                              f"{', '.join(sorted(GARMIN_UNITS))}); map the column with a "
                              "mapping file (--mapping)", file=raw.file, column=col)
        off = rd.normal_offset if channel == "n_norm_g" else 0.0
        specs.append(ChannelSpec(channel, col, unit, offset=off))
    return Mapping(file=PRESET, time=time, channels=tuple(specs))


def altimeter_settings_hpa(raw: RawTable, mt: MappedTable, reading: GarminReading | None = None
                           ) -> tuple[float, float] | None:
    """The altimeter setting [hPa] in use when the aircraft first and last moved faster than
    :data:`ROLL_SPEED_KT` (``IAS``, else ``GndSpd``: the take-off and the landing roll), or at
    the first and last rows that record one when it never did; ``None`` without the column.

    The pilot sets the departure's QNH before the take-off and the arrival's before the
    landing: on the shipped export the first rows still hold the previous flight's 30.33 inHg,
    set to 30.18 inHg on the apron before the take-off (the pressure altitude at rest then
    matches the field's elevation under it within 1 m; under 30.33, 41 m off).  A QFE setting
    would read as the field's elevation lower; a record cut in the air may end on the standard
    29.92 inHg.
    """
    roles = reading.roles if reading is not None else _resolve(raw)
    setting = _setting_pa(raw, roles)
    if setting is None or not mt.rows.size:
        return None
    order = np.argsort(mt.time, kind="stable")
    v = setting[mt.rows - 1][order]
    ok = np.isfinite(v) & (v > 0.0)
    if not ok.any():
        return None
    speed = None
    for role in ("ias", "gs"):
        c = _si(raw, roles, role)
        if c is not None and (c > ROLL_SPEED_KT * KNOT_MPS).any():
            speed = c[mt.rows - 1][order] / KNOT_MPS
            break
    fast = (np.flatnonzero(ok & (speed > ROLL_SPEED_KT)) if speed is not None
            else np.zeros(0, dtype=np.int64))
    idx = fast if fast.size else np.flatnonzero(ok)
    return float(v[idx[0]]) / 100.0, float(v[idx[-1]]) / 100.0


def _filled(t: np.ndarray, v: np.ndarray) -> np.ndarray:
    """``v`` with its gaps filled by linear interpolation in time (ends held)."""
    ok = ~np.isnan(v)
    if ok.all() or not ok.any():
        return v
    return np.interp(t, t[ok], v[ok])


def _gnss_columns(raw: RawTable, mt: MappedTable, rd: GarminReading, magvar: np.ndarray | None,
                  vals: dict[str, np.ndarray], src: dict[str, str], notes: list[str]) -> None:
    """The GNSS velocity (recorded north / east, else the ground speed along the track) and
    the fix quality, into ``vals`` / ``src``."""
    roles = rd.roles
    vn, ve = _si(raw, roles, "vel_n"), _si(raw, roles, "vel_e")
    gs, trk = _si(raw, roles, "gs"), _si(raw, roles, "trk")
    if vn is not None and ve is not None:
        vals["gnss_vn_mps"], vals["gnss_ve_mps"] = vn[mt.rows - 1], ve[mt.rows - 1]
        src["gnss_vn_mps"], src["gnss_ve_mps"] = roles["vel_n"], roles["vel_e"]
        notes.append(f"gnss_vn_mps, gnss_ve_mps <- {roles['vel_n']}, {roles['vel_e']} [m/s]")
    elif gs is not None and trk is not None:
        var = magvar if (rd.track == "magnetic" and magvar is not None) else 0.0
        true_trk = np.radians(trk[mt.rows - 1] + var)
        v = gs[mt.rows - 1]
        vals["gnss_vn_mps"] = v * np.cos(true_trk)
        vals["gnss_ve_mps"] = v * np.sin(true_trk)
        src["gnss_vn_mps"] = src["gnss_ve_mps"] = roles["gs"]
        along = (f"{roles['trk']} + {roles.get('magvar', 'variation')} (magnetic -> true)"
                 if rd.track == "magnetic" and magvar is not None else
                 f"{roles['trk']} (true)")
        notes.append(f"gnss_vn_mps, gnss_ve_mps <- {roles['gs']} along {along}")
    fix = raw.columns.get(roles.get("fix", ""))
    if fix is not None and fix.dtype == object:
        q = np.array([_fix_quality(x) for x in fix[mt.rows - 1]], dtype=float)
        vals["gnss_quality"] = q
        src["gnss_quality"] = roles["fix"]
        notes.append(f"gnss_quality <- {roles['fix']} (NoSoln 0, 2D/3D 1, 2DDiff/3DDiff 2)")


def _fix_quality(x: Any) -> float:
    """NMEA fix quality of a Garmin fix text (``NoSoln``, ``2D``, ``3D``, ``3D-``, ``3DDiff``)."""
    t = re.sub(r"[^a-z0-9]", "", str(x).lower()) if x is not None else ""
    if not t or t.startswith(("nosoln", "none", "no")):
        return 0.0
    if "diff" in t or "sbas" in t or "waas" in t:
        return 2.0
    return 1.0 if t.startswith(("2d", "3d")) else np.nan


def apply_garmin_columns(raw: RawTable, mt: MappedTable, used: Mapping,
                         withhold_gnss: bool = False, reading: GarminReading | None = None,
                         warns: list[str] | None = None) -> MappedTable:
    """The Garmin conventions that need two columns, applied to the channels the built-in
    mapping gave (a channel the user mapped is left as the user said):

    * ``heading_deg`` = ``HDG`` + the variation (sign checked) when ``HDG`` is magnetic;
    * ``baro_alt_m`` from the altimeter's reading at the setting
      (:func:`pressure_altitude_from_indicated`) when the column is indicated;
    * ``gnss_vn_mps`` / ``gnss_ve_mps`` recorded, or from the ground speed and the track;
    * ``gnss_quality`` from the fix status.

    The variation and the setting are interpolated in time over the rows they miss.  Not
    applied to the GNSS channels when ``withhold_gnss``.  Whole-second stamps that jitter
    about a regular 1 Hz series are re-timed first at the rows' period
    (:func:`.garmin_time.regular_rows`; the warning saying so is appended to ``warns``).
    """
    rd = reading if reading is not None else garmin_reading(raw)
    roles = rd.roles
    if mt.time_kind == "timestamp" and used.time is not None \
            and used.time.column in (roles.get("time"), roles.get("utc_time")):
        lat, lon, gs = (_si(raw, roles, k) for k in ("lat", "lon", "gs"))
        period, between = None, None
        if lat is not None and lon is not None and gs is not None:
            lat, lon, gs = lat[mt.rows - 1], lon[mt.rows - 1], gs[mt.rows - 1]
            period = motion_period_s(lat, lon, gs)
            between = motion_rows(lat, lon, gs, period) if period is not None else None
        t_new, note = regular_rows(mt.time, period, between)
        if note is not None:
            mt = dataclasses.replace(mt, time=t_new)
            if warns is not None:
                warns.append(f"{raw.file}: column '{used.time.column}': {note}")
    preset = {s.channel: s for s in garmin_mapping(raw, rd).channels}
    own = {s.channel for s in used.channels if preset.get(s.channel) == s}
    vals, src, notes = dict(mt.values), dict(mt.source_column), list(mt.notes)
    order = np.argsort(mt.time, kind="stable")
    tsec = np.empty(mt.time.size)
    tsec[order] = (mt.time[order] - mt.time[order][0]) / 1e9 if mt.time.size else 0.0
    mv_all = _si(raw, roles, "magvar")
    magvar = None
    if mv_all is not None and np.isfinite(mv_all[mt.rows - 1]).any():
        magvar = rd.magvar_sign * _filled(tsec, mv_all[mt.rows - 1])
    if "heading_deg" in own and rd.heading == "magnetic":
        if magvar is not None:
            vals["heading_deg"] = np.mod(vals["heading_deg"] + magvar, 360.0)
            notes.append(f"heading_deg <- {roles['hdg']} + {roles['magvar']} (magnetic -> "
                         f"true with the recorded variation, east positive: "
                         f"{np.nanmin(magvar):.1f}..{np.nanmax(magvar):.1f} deg)")
        else:   # no variation recorded: the World Magnetic Model converts it (derive.py)
            mt = dataclasses.replace(mt, magnetic=(*mt.magnetic, "heading_deg"))
    setting = _setting_pa(raw, roles)
    if "baro_alt_m" in own and rd.altitude == "indicated" and "alt_p" not in roles \
            and setting is not None and np.isfinite(setting[mt.rows - 1]).any():
        s_pa = _filled(tsec, setting[mt.rows - 1])
        vals["baro_alt_m"] = pressure_altitude_from_indicated(vals["baro_alt_m"], s_pa)
        notes.append(f"baro_alt_m <- {roles['alt_ind']} at the altimeter setting "
                     f"{roles['baro_set']} ({np.nanmin(s_pa) / 100:.1f}.."
                     f"{np.nanmax(s_pa) / 100:.1f} hPa) -> pressure altitude (ISA)")
    if not withhold_gnss and "gnss_lat_deg" in own:
        _gnss_columns(raw, mt, rd, magvar, vals, src, notes)
    if "gnss_alt_m" in own:
        notes.append(f"gnss_alt_m <- {roles['alt_gps']} [above the "
                     f"{'WGS-84 ellipsoid' if rd.gnss_datum == 'ellipsoid' else 'geoid (MSL)'}"
                     f"] ({FOOT_M} m/ft)")
    return dataclasses.replace(mt, values=vals, source_column=src, notes=tuple(notes))
