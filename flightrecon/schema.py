"""The canonical flight-log schema: channel names, units, kinds and physical limits.

Conventions (docs/schema.md, "Conventions"); documented in ``docs/schema.md``:

* Body axes forward-right-down (FRD).  Load factor n = specific force / g0 (g0 = 9.80665 m/s^2).
  ``n_long_g`` positive forward, ``n_lat_g`` positive toward the right wing,
  ``n_norm_g = -f_z / g0`` (+1 at rest, 1/cos(roll) in a level coordinated turn).
* ``roll_deg`` positive right wing down, ``pitch_deg`` positive nose up, ``heading_deg`` true,
  clockwise from north in [0, 360).  Euler order yaw-pitch-roll (ZYX).
* Azimuth clockwise from true north at the station; radar range is slant range.
* ``wind_from_deg`` meteorological (where the wind blows from).  Track = heading + drift.
* ``baro_alt_m`` is pressure altitude (1013.25 hPa datum) unless the metadata says otherwise.
* A correction to a sensor reading is true minus measured.

Two kinds of channel (docs/schema.md, "Two kinds of channel"): *inputs* are cleaned and brought
to one grid; *measurements* are kept once each, at their own time.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal


@dataclass(frozen=True)
class Channel:
    """One canonical channel.

    Attributes
    ----------
    name : column name, unit suffix included
    unit : SI unit (or ``"1"``, ``"deg"``, ``"g"``)
    kind : ``"time"``, ``"input"`` (cleaned, on the grid) or ``"measurement"`` (own times)
    group : measurement group (``"gnss"``, ``"radar"``) or ``""``
    lo, hi : physically possible range; a value outside is a validation error
    required : must be present in every log
    angle : wraps at 360 deg (heading-like) - interpolate on the unwrapped series
    """

    name: str
    unit: str
    kind: Literal["time", "input", "measurement"]
    description: str
    lo: float
    hi: float
    required: bool = False
    group: str = ""
    angle: bool = False


CHANNELS: tuple[Channel, ...] = (
    Channel("t_s", "s", "time", "seconds from the flight's UTC epoch (metadata)", -1e9, 1e9, True),
    Channel("n_long_g", "g", "input", "body longitudinal load factor, + forward", -6, 6, True),
    Channel("n_lat_g", "g", "input", "body lateral load factor, + toward right wing", -6, 6, True),
    Channel("n_norm_g", "g", "input", "body normal load factor, -f_z/g0, +1 at rest", -6, 10, True),
    Channel("roll_deg", "deg", "input", "roll, + right wing down", -180, 180, True),
    Channel("pitch_deg", "deg", "input", "pitch, + nose up", -90, 90, True),
    Channel("heading_deg", "deg", "input", "true heading, clockwise from north", -360, 720, True,
            angle=True),
    Channel("tas_mps", "m/s", "input", "true airspeed", 0, 700, True),
    Channel("baro_alt_m", "m", "input", "pressure altitude, 1013.25 hPa datum", -1000, 25000, True),
    Channel("ias_mps", "m/s", "input", "indicated airspeed", 0, 700),
    Channel("cas_mps", "m/s", "input", "calibrated airspeed", 0, 700),
    Channel("sat_degc", "degC", "input", "static air temperature", -100, 70),
    Channel("doppler_gs_mps", "m/s", "input", "Doppler ground speed", 0, 800),
    Channel("drift_deg", "deg", "input", "drift angle, track = heading + drift", -60, 60),
    Channel("wind_speed_mps", "m/s", "input", "wind speed (recorded or forecast)", 0, 150),
    Channel("wind_from_deg", "deg", "input", "wind direction, where it blows from", -360, 720,
            angle=True),
    Channel("p_dps", "deg/s", "input", "body roll rate, + right wing going down", -500, 500),
    Channel("q_dps", "deg/s", "input", "body pitch rate, + nose going up", -500, 500),
    Channel("r_dps", "deg/s", "input", "body yaw rate, + nose going right", -500, 500),
    Channel("gnss_lat_deg", "deg", "measurement", "GNSS latitude", -90, 90, group="gnss"),
    Channel("gnss_lon_deg", "deg", "measurement", "GNSS longitude", -180, 360, group="gnss"),
    Channel("gnss_alt_m", "m", "measurement", "GNSS altitude (datum in metadata)", -1000, 25000,
            group="gnss"),
    Channel("gnss_vn_mps", "m/s", "measurement", "GNSS north velocity", -800, 800, group="gnss"),
    Channel("gnss_ve_mps", "m/s", "measurement", "GNSS east velocity", -800, 800, group="gnss"),
    Channel("gnss_h_sd_m", "m", "measurement", "GNSS horizontal position sd per axis "
            "(receiver's estimate)", 0, 1e5, group="gnss"),
    Channel("gnss_v_sd_m", "m", "measurement", "GNSS vertical position sd (receiver's estimate)",
            0, 1e5, group="gnss"),
    Channel("gnss_vel_sd_mps", "m/s", "measurement", "GNSS velocity sd per axis (receiver's "
            "estimate)", 0, 100, group="gnss"),
    Channel("gnss_hdop", "1", "measurement", "GNSS horizontal dilution of precision", 0, 100,
            group="gnss"),
    Channel("gnss_nacp", "1", "measurement", "ADS-B navigation accuracy category for position "
            "(NACp, 0-11)", 0, 11, group="gnss"),
    Channel("gnss_quality", "1", "measurement", "GNSS fix quality (NMEA GGA: 0 invalid, 1 GPS, "
            "2 DGPS, 4 RTK fixed, 5 RTK float, 6 estimated, 7 manual, 8 simulation)", 0, 9,
            group="gnss"),
    Channel("arms_range_m", "m", "measurement", "radar slant range from the station", 0, 1e6,
            group="radar"),
    Channel("arms_azimuth_deg", "deg", "measurement", "radar azimuth, clockwise from true north",
            -360, 720, group="radar", angle=True),
    Channel("arms_elevation_deg", "deg", "measurement", "radar elevation angle", -10, 90,
            group="radar"),
)

BY_NAME: dict[str, Channel] = {c.name: c for c in CHANNELS}
REQUIRED: tuple[str, ...] = tuple(c.name for c in CHANNELS if c.required)
INPUTS: tuple[str, ...] = tuple(c.name for c in CHANNELS if c.kind == "input")
MEASUREMENTS: tuple[str, ...] = tuple(c.name for c in CHANNELS if c.kind == "measurement")
GROUPS: dict[str, tuple[str, ...]] = {
    g: tuple(c.name for c in CHANNELS if c.group == g) for g in ("gnss", "radar")
}
SCHEMA_VERSION = 1
