"""A recorder export at the ED-112 / ICAO Annex 6 minimum rates, as an analyst gets it from a
flight data recorder: each parameter in its own slot of the one-second frame, quantised like a
12-bit ARINC 717 word, in the recorder's units, read back through a mapping file.

Rates and slots (``ED112_PARAMETERS``): vertical load 8 Hz, longitudinal and lateral load
4 Hz, pitch 4 Hz, roll 2 Hz, magnetic heading 1 Hz, calibrated airspeed (or, without a
temperature, true airspeed) 1 Hz in knots with the static air temperature, pressure altitude
1 Hz in feet.  A parameter sampled ``n`` times a second is read at ``k/n + slot`` seconds: its
samples are not simultaneous with the others' (the frame is serial).  Values between the
source log's own samples are interpolated linearly (the source is the 16-25 Hz recorder log or
the truth; a real recorder samples the signal at the slot's instant).

Quantisation (``resolution``): 12 bits over the parameter's range (loads -3..+6 g vertical,
+-1 g longitudinal and lateral; attitude and heading +-180 deg; airspeed 0..512 kt; altitude
in whole feet; temperature 0.25 deg C).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from flightrecon.constants import FOOT_M, KNOT_MPS
from flightrecon.geo.atmosphere import tas_to_cas
from flightrecon.geo.magnetic import decimal_year, declination_deg
from flightrecon.sim.recorder import channel_samples

__all__ = ["ED112_PARAMETERS", "Ed112Parameter", "ed112_export", "ed112_mapping"]


@dataclass(frozen=True)
class Ed112Parameter:
    """One recorded parameter: the canonical channel it comes from, its column in the export,
    rate [Hz], slot [s] within the second, resolution in the export's unit, unit, sign."""

    channel: str
    column: str
    rate_hz: int
    slot_s: float
    resolution: float
    unit: str
    sign: float = 1.0


ED112_PARAMETERS = (
    Ed112Parameter("n_norm_g", "VRTG", 8, 0.0000, 9.0 / 4096, "g"),
    Ed112Parameter("n_long_g", "LONG", 4, 0.0156, 2.0 / 4096, "g"),
    Ed112Parameter("n_lat_g", "LATG", 4, 0.0312, 2.0 / 4096, "g", sign=-1.0),
    Ed112Parameter("pitch_deg", "PTCH", 4, 0.0469, 360.0 / 4096, "deg"),
    Ed112Parameter("roll_deg", "ROLL", 2, 0.0625, 360.0 / 4096, "deg"),
    Ed112Parameter("heading_deg", "HDG_MAG", 1, 0.0781, 360.0 / 4096, "deg"),
    Ed112Parameter("cas_mps", "CAS_KT", 1, 0.0938, 512.0 / 4096, "kt"),
    Ed112Parameter("sat_degc", "SAT_C", 1, 0.1094, 0.25, "degC"),
    Ed112Parameter("baro_alt_m", "ALT_FT", 1, 0.1250, 1.0, "ft"),
)
"""The parameters, their rates, frame slots and 12-bit resolutions (module docstring)."""


def _own(log: pd.DataFrame, c: str) -> tuple[np.ndarray, np.ndarray]:
    return channel_samples(log, c, "the ED-112 export")


def _interp_angle(t: np.ndarray, ts: np.ndarray, v: np.ndarray) -> np.ndarray:
    r = np.unwrap(np.radians(v))
    return np.degrees(np.interp(t, ts, r))


def ed112_export(log: pd.DataFrame, *, lat_deg: float, lon_deg: float, epoch_utc: str
                 ) -> pd.DataFrame:
    """The canonical ``log`` as an ED-112 minimum-rate export (module docstring).

    Parameters
    ----------
    log : canonical recorder log (``t_s`` and the channels in SI units, NaN where not
        sampled); ``sat_degc`` optional (without it the export records the true airspeed)
    lat_deg, lon_deg, epoch_utc : where and when, for the magnetic declination of the
        recorded heading (the WMM at the departure; a recorder's flux valve measures it along
        the way, a few tenths of a degree apart on a local flight)

    Returns
    -------
    DataFrame
        ``TIME`` [s] and one column per parameter (NaN outside its slots); with
        :func:`ed112_mapping` it reads back through ``flightrecon``'s mapping.
    """
    t = log["t_s"].to_numpy(dtype=float)
    t0, t1 = float(np.nanmin(t)), float(np.nanmax(t))
    has_sat = "sat_degc" in log.columns and log["sat_degc"].notna().sum() >= 2
    dec = float(declination_deg(np.array([lat_deg]), np.array([lon_deg]), np.array([0.0]),
                                decimal_year(epoch_utc, 0.0))[0][0])
    columns: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    for p in ED112_PARAMETERS:
        if p.channel == "sat_degc" and not has_sat:
            continue
        k = np.arange(np.ceil(t0 * p.rate_hz), np.floor(t1 * p.rate_hz) + 1)
        ts = k / p.rate_hz + p.slot_s
        ts = ts[(ts >= t0) & (ts <= t1)]
        if p.channel == "cas_mps":
            tv, tas = _own(log, "tas_mps")
            v_tas = np.interp(ts, tv, tas)
            if has_sat:
                alt = np.interp(ts, *_own(log, "baro_alt_m"))
                sat = np.interp(ts, *_own(log, "sat_degc"))
                v = np.asarray(tas_to_cas(v_tas, alt, sat)) / KNOT_MPS
            else:
                v = v_tas / KNOT_MPS
        elif p.channel == "heading_deg":
            v = np.mod(_interp_angle(ts, *_own(log, "heading_deg")) - dec, 360.0)
        elif p.channel in ("pitch_deg", "roll_deg"):
            v = _interp_angle(ts, *_own(log, p.channel))
            v = (v + 180.0) % 360.0 - 180.0
        else:
            v = np.interp(ts, *_own(log, p.channel))
            if p.channel == "baro_alt_m":
                v = v / FOOT_M
        v = np.round(p.sign * v / p.resolution) * p.resolution
        columns[p.column] = (ts, v)
    times = np.unique(np.concatenate([ts for ts, _ in columns.values()]))
    out = {"TIME": times}
    for name, (ts, v) in columns.items():
        col = np.full(times.size, np.nan)
        col[np.searchsorted(times, ts)] = v
        out[name] = col
    return pd.DataFrame(out)


def ed112_mapping(export: pd.DataFrame) -> str:
    """The mapping file (TOML) that reads :func:`ed112_export`'s columns back."""
    lines = ['# flightrecon mapping of an ED-112 minimum-rate export', "[time]",
             'column = "TIME"', 'unit = "s"', ""]
    cas = "CAS_KT" in export.columns and "SAT_C" in export.columns
    for p in ED112_PARAMETERS:
        if p.column not in export.columns:
            continue
        channel = p.channel if p.channel != "cas_mps" or cas else "tas_mps"
        lines += [f"[channels.{channel}]", f'column = "{p.column}"', f'unit = "{p.unit}"']
        if p.sign < 0:
            lines.append("sign = -1")
        if p.channel == "heading_deg":
            lines.append('reference = "magnetic"')
        lines.append("")
    if cas:
        lines += ["[channels.tas_mps]", 'from = "cas"', ""]
    return "\n".join(lines)
