"""A simulated flight as a Garmin glass-cockpit CSV export (G1000 / G3X / Perspective), as the
avionics write it: read back as recorded, with no mapping file, by
:mod:`flightrecon.ingest.garmin` (issue #36, item 5).

The file copies the structure of the shipped real export
(``sample_logs/g1000_sr22_LFQA_20220417.csv``): an ``#airframe_info`` line, a units line
starting with ``#``, the header, then one row a second at whole UTC seconds, the cells padded
with spaces to the column's width.  Columns, units and conventions (those of the built-in
reader, docs/ingest.md "Garmin glass-cockpit exports"):

* ``Lcl Date``, ``Lcl Time``, ``UTCOfst``: local date and time, local = UTC + offset;
* ``Latitude``, ``Longitude`` [deg], ``AltGPS`` [ft wgs, above the ellipsoid], ``AltMSL``
  [ft msl, AltGPS less the geoid], ``GndSpd`` [kt], ``TRK`` [deg magnetic], ``GPSfix``
  (``3D``; ``NoSoln`` and empty position cells where the log has no fix at that second): the
  log's GNSS fixes at the second (linear between the log's own fixes, no more than 1.5 s apart);
* ``AltInd`` [ft]: the altimeter's indication at the setting ``BaroA`` [inHg, two decimals;
  the departure's QNH, kept for the whole flight], made from the log's pressure altitude
  (the inverse of :func:`flightrecon.ingest.garmin.pressure_altitude_from_indicated`);
* ``OAT`` [deg C]: the log's static air temperature; ``IAS`` [kt]: the calibrated airspeed of
  the log's TAS at its pressure altitude and temperature; ``TAS`` [kt, whole knots];
  ``VSpd`` [fpm]: the rate of the pressure altitude;
* ``Pitch``, ``Roll`` [deg]; ``LatAc`` [G, + toward the right wing]; ``NormAc`` [G, n - 1];
* ``HDG`` [deg magnetic] = the log's true heading less ``MagVar`` [deg, east positive, one
  decimal]: the World Magnetic Model's declination at the truth position and time;
* no longitudinal acceleration (the reader derives ``n_long_g`` from TAS and pitch).

Every channel is the log's own sample at the second (linear between its samples; angles on the
unwrapped series), rounded as the real export writes it (latitude 7 decimals, altitudes and
headings 0.1, speeds and attitudes 0.01, loads 0.01 g, TAS 1 kt).  Rows where the log has none
of the recorder's channels are left out.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.constants import FOOT_M, KNOT_MPS
from flightrecon.errors import ValidationError
from flightrecon.geo.atmosphere import P0_PA, isa_pressure_pa, pressure_altitude_m, tas_to_cas
from flightrecon.geo.magnetic import decimal_year, declination_deg
from flightrecon.sim.recorder import channel_samples
from flightrecon.types import FlightMeta

__all__ = [
    "GLASS_COCKPIT_COLUMNS",
    "glass_cockpit_export",
    "glass_cockpit_text",
    "indicated_from_pressure_altitude",
    "write_glass_cockpit",
]

#: one inch of mercury [Pa] (the altimeter-setting unit; the reader's ``INHG_PA``)
INHG_PA = 3386.389
#: column -> (unit text of the units line, decimals written; None: text)
GLASS_COCKPIT_COLUMNS: dict[str, tuple[str, int | None]] = {
    "Lcl Date": ("yyy-mm-dd", None),
    "Lcl Time": ("hh:mm:ss", None),
    "UTCOfst": ("hh:mm", None),
    "AtvWpt": ("ident", None),
    "Latitude": ("degrees", 7),
    "Longitude": ("degrees", 7),
    "AltInd": ("ft", 1),
    "BaroA": ("inch", 2),
    "AltMSL": ("ft msl", 1),
    "OAT": ("deg C", 1),
    "IAS": ("kt", 2),
    "GndSpd": ("kt", 2),
    "VSpd": ("fpm", 2),
    "Pitch": ("deg", 2),
    "Roll": ("deg", 2),
    "LatAc": ("G", 2),
    "NormAc": ("G", 2),
    "HDG": ("deg", 1),
    "TRK": ("deg", 1),
    "AltGPS": ("ft wgs", 1),
    "TAS": ("kt", 0),
    "MagVar": ("deg", 1),
    "GPSfix": ("enum", None),
}
#: longest interval between two GNSS fixes interpolated to a whole second [s]
MAX_FIX_GAP_S = 1.5


def indicated_from_pressure_altitude(pressure_alt_m: np.ndarray, setting_pa: np.ndarray | float
                                     ) -> np.ndarray:
    """The altimeter's indication [m] at the setting ``setting_pa`` [Pa] for the pressure
    altitude ``pressure_alt_m`` [m].

    The altimeter shows the ISA height of ``p * P0 / setting`` (the inverse of
    :func:`flightrecon.ingest.garmin.pressure_altitude_from_indicated`).
    """
    p = isa_pressure_pa(np.asarray(pressure_alt_m, dtype=float))
    return np.asarray(pressure_altitude_m(p * P0_PA / np.asarray(setting_pa, dtype=float)),
                      dtype=float)


def _own(log: pd.DataFrame, c: str) -> tuple[np.ndarray, np.ndarray]:
    return channel_samples(log, c, "the glass-cockpit export")


def _at(t: np.ndarray, log: pd.DataFrame, c: str, angle: bool = False) -> np.ndarray:
    """Channel ``c`` at the times ``t`` (linear between its own samples, NaN outside them)."""
    ts, v = _own(log, c)
    if angle:
        v = np.degrees(np.unwrap(np.radians(v)))
    out = np.interp(t, ts, v)
    out[(t < ts[0]) | (t > ts[-1])] = np.nan
    return out


def _fixes_at(t: np.ndarray, log: pd.DataFrame) -> dict[str, np.ndarray]:
    """The log's GNSS channels at ``t``: linear between two fixes at most
    :data:`MAX_FIX_GAP_S` apart, NaN elsewhere."""
    cols = ("gnss_lat_deg", "gnss_lon_deg", "gnss_alt_m", "gnss_vn_mps", "gnss_ve_mps")
    if not all(c in log.columns for c in cols):
        return {c: np.full(t.size, np.nan) for c in cols}
    g = log.dropna(subset=list(cols))
    tg = g["t_s"].to_numpy(dtype=float)
    out = {c: np.full(t.size, np.nan) for c in cols}
    if tg.size < 2:
        return out
    j = np.clip(np.searchsorted(tg, t, side="right"), 1, tg.size - 1)
    ok = (t >= tg[0]) & (t <= tg[-1]) & ((tg[j] - tg[j - 1] <= MAX_FIX_GAP_S)
                                         | (t == tg[j - 1]) | (t == tg[j]))
    for c in cols:
        v = np.interp(t, tg, g[c].to_numpy(dtype=float))
        out[c][ok] = v[ok]
    return out


def _utc_seconds(meta: FlightMeta, t_log: np.ndarray) -> tuple[np.ndarray, np.datetime64]:
    """Whole UTC seconds within the log's span: their ``t_s`` and the epoch."""
    if meta.epoch_utc is None:
        raise ValidationError("the glass-cockpit export needs the flight's epoch_utc")
    epoch = np.datetime64(meta.epoch_utc.strip().rstrip("Zz"), "ns")
    first = epoch + np.timedelta64(int(round(float(np.nanmin(t_log)) * 1e9)), "ns")
    whole = first.astype("datetime64[s]")
    if whole < first:
        whole = whole + np.timedelta64(1, "s")
    t0 = (whole - epoch) / np.timedelta64(1, "s")
    n = int(np.floor(float(np.nanmax(t_log)) - t0)) + 1
    return t0 + np.arange(max(n, 0), dtype=float), epoch


def _recorded_at(t: np.ndarray, log: pd.DataFrame
                 ) -> tuple[np.ndarray, dict[str, np.ndarray], np.ndarray]:
    """The attitude, airspeed, pressure altitude and load factors at the export's seconds
    ``t``, the seconds where one of them is missing dropped; the SAT there (NaN unless
    sampled at least twice)."""
    rec = {c: _at(t, log, c, angle=c == "heading_deg") for c in
           ("roll_deg", "pitch_deg", "heading_deg", "tas_mps", "baro_alt_m", "n_lat_g",
            "n_norm_g")}
    keep = np.all([np.isfinite(v) for v in rec.values()], axis=0)
    t = t[keep]
    rec = {c: v[keep] for c, v in rec.items()}
    sat = (_at(t, log, "sat_degc") if "sat_degc" in log.columns
           and log["sat_degc"].notna().sum() >= 2 else np.full(t.size, np.nan))
    return t, rec, sat


def _magnetic_variation_deg(t: np.ndarray, truth: pd.DataFrame, meta: FlightMeta
                            ) -> np.ndarray:
    """The avionics' magnetic variation [deg, 0.1 deg] at the truth's position at ``t``."""
    tt = truth["t_s"].to_numpy(dtype=float)
    pos = [np.interp(t, tt, truth[c].to_numpy(dtype=float)) for c in
           ("lat_deg", "lon_deg", "alt_m")]
    year = float(decimal_year(meta.epoch_utc or "", float(np.mean(t)) if t.size else 0.0))
    decl, _ = declination_deg(pos[0], pos[1], pos[2], year)
    return np.round(np.asarray(decl, dtype=np.float64), 1)


def _local_time(epoch: np.datetime64, t: np.ndarray, utc_offset_min: int
                ) -> tuple[pd.DatetimeIndex, str]:
    """The local time stamps (whole seconds) of ``t`` and the ``UTCOfst`` text (``+hh:mm``)."""
    local = (epoch + (t * 1e9).round().astype("timedelta64[ns]")
             + np.timedelta64(int(utc_offset_min), "m")).astype("datetime64[s]")
    sign = "+" if utc_offset_min >= 0 else "-"
    ofst = f"{sign}{abs(int(utc_offset_min)) // 60:02d}:{abs(int(utc_offset_min)) % 60:02d}"
    return pd.DatetimeIndex(local), ofst


def _as_text(values: dict[str, Any]) -> pd.DataFrame:
    """The columns of :data:`GLASS_COCKPIT_COLUMNS` as the avionics write them (their
    decimals; headings in [0, 360); empty where not finite)."""
    out = {}
    for col, (_, dec) in GLASS_COCKPIT_COLUMNS.items():
        v = values[col]
        if dec is None:
            out[col] = [str(x) for x in v]
            continue
        v = np.round(np.asarray(v, dtype=float), dec)
        if col in ("HDG", "TRK"):
            v = np.mod(v, 360.0)
        out[col] = ["" if not np.isfinite(x) else f"{x + 0.0:.{dec}f}" for x in v]
    return pd.DataFrame(out)


def glass_cockpit_export(log: pd.DataFrame, truth: pd.DataFrame, meta: FlightMeta, *,
                         utc_offset_min: int = 0, baro_setting_hpa: float | None = None
                         ) -> pd.DataFrame:
    """The canonical simulated ``log`` as a Garmin glass-cockpit export (module docstring).

    Parameters
    ----------
    log : canonical recorder log (``t_s`` from ``meta.epoch_utc`` and the channels in SI units,
        NaN where not sampled), e.g. ``flightrecon.sim.simulate(...).log``
    truth : the flight's truth (``t_s``, ``lat_deg``, ``lon_deg``, ``alt_m``): where the
        avionics' magnetic variation is taken
    meta : the flight's metadata (``epoch_utc``; ``qnh_departure_hpa`` for the altimeter
        setting; ``geoid_undulation_m`` for ``AltMSL``)
    utc_offset_min : the local time's offset from UTC [min] (local = UTC + offset)
    baro_setting_hpa : the altimeter setting [hPa]; default the departure's QNH, else 1013.25

    Returns
    -------
    DataFrame
        One row a second, the columns of :data:`GLASS_COCKPIT_COLUMNS` as text, formatted as
        the avionics write them (:func:`glass_cockpit_text` adds the header lines).

    Raises
    ------
    ValidationError
        A recorder channel the export needs is not sampled, or no ``epoch_utc``.
    """
    t, epoch = _utc_seconds(meta, log["t_s"].to_numpy(dtype=float))
    t, rec, sat = _recorded_at(t, log)
    gps = _fixes_at(t, log)
    fix = np.isfinite(gps["gnss_lat_deg"])
    magvar = _magnetic_variation_deg(t, truth, meta)

    setting_hpa = (baro_setting_hpa if baro_setting_hpa is not None else
                   meta.qnh_departure_hpa if meta.qnh_departure_hpa is not None else 1013.25)
    baro_inhg = round(setting_hpa * 100.0 / INHG_PA, 2)
    alt_ind = indicated_from_pressure_altitude(rec["baro_alt_m"], baro_inhg * INHG_PA)
    vspd = (np.gradient(rec["baro_alt_m"], t) / FOOT_M * 60.0 if t.size > 1
            else np.zeros(t.size))
    ias = (np.asarray(tas_to_cas(rec["tas_mps"], rec["baro_alt_m"], sat), dtype=float)
           if np.isfinite(sat).any() else rec["tas_mps"])
    gs = np.hypot(gps["gnss_vn_mps"], gps["gnss_ve_mps"])
    trk = np.degrees(np.arctan2(gps["gnss_ve_mps"], gps["gnss_vn_mps"]))
    geoid = meta.geoid_undulation_m or 0.0

    stamp, ofst = _local_time(epoch, t, utc_offset_min)
    values: dict[str, Any] = {
        "Lcl Date": stamp.strftime("%Y-%m-%d"), "Lcl Time": stamp.strftime("%H:%M:%S"),
        "UTCOfst": np.full(t.size, ofst), "AtvWpt": np.full(t.size, ""),
        "Latitude": gps["gnss_lat_deg"], "Longitude": gps["gnss_lon_deg"],
        "AltInd": alt_ind / FOOT_M, "BaroA": np.full(t.size, baro_inhg),
        "AltMSL": (gps["gnss_alt_m"] - geoid) / FOOT_M, "OAT": sat,
        "IAS": ias / KNOT_MPS, "GndSpd": gs / KNOT_MPS, "VSpd": vspd,
        "Pitch": rec["pitch_deg"], "Roll": rec["roll_deg"],
        "LatAc": rec["n_lat_g"], "NormAc": rec["n_norm_g"] - 1.0,
        "HDG": np.mod(rec["heading_deg"] - magvar, 360.0),
        "TRK": np.where(gs > 0.0, np.mod(trk - magvar, 360.0), np.nan),
        "AltGPS": gps["gnss_alt_m"] / FOOT_M, "TAS": rec["tas_mps"] / KNOT_MPS,
        "MagVar": magvar, "GPSfix": np.where(fix, "3D", "NoSoln"),
    }
    return _as_text(values)


def glass_cockpit_text(export: pd.DataFrame, *, airframe_name: str = "Simulated aircraft",
                       system_id: str = "SIM") -> str:
    """The export as the avionics write the file: the ``#airframe_info`` line, the units line,
    the header, then the rows, every cell right-aligned to its column's width.

    Parameters
    ----------
    export : :func:`glass_cockpit_export`'s table
    airframe_name, system_id : the airframe line's ``airframe_name`` and ``system_id``
    """
    cols = list(export.columns)
    units = [GLASS_COCKPIT_COLUMNS.get(c, ("", None))[0] for c in cols]
    width = [max(len(c), len(u), int(export[c].str.len().max() or 0)) if len(export)
             else max(len(c), len(u)) for c, u in zip(cols, units)]
    info = (f'#airframe_info, log_version="1.03", log_content_version="1.02", Product="GIFD", '
            f'airframe_name="{airframe_name}", unit_software_part_number="flightrecon-sim", '
            f'system_id="{system_id}", mode=NORMAL, ')
    lines = [info, "#" + ", ".join(u.rjust(w - (1 if i == 0 else 0))
                                   for i, (u, w) in enumerate(zip(units, width))),
             ", ".join(c.rjust(w) for c, w in zip(cols, width))]
    cells = export.to_numpy(dtype=object)
    lines += [", ".join(str(v).rjust(w) for v, w in zip(row, width)) for row in cells]
    return "\n".join(lines) + "\n"


def write_glass_cockpit(result: Any, path: str | Path, *, utc_offset_min: int = 0,
                        sidecar: bool = True) -> dict[str, Path]:
    """Write ``result`` (:class:`~flightrecon.sim.scenarios.SimResult`) as a glass-cockpit CSV
    at ``path`` and, with ``sidecar``, its metadata beside it (``<stem>.meta.toml``: airfields
    with their runways, QNH, geoid, GNSS lever arm and datum, the epoch).

    Returns
    -------
    dict
        The written paths by role (``export``, ``meta``).
    """
    from flightrecon.export.atomic import write_text_atomic
    from flightrecon.sim.sidecar import meta_toml, sibling

    path = Path(path)
    ex = glass_cockpit_export(result.log, result.truth, result.meta,
                              utc_offset_min=utc_offset_min)
    model = result.sensor_truth.get("jsbsim", {}).get("model") or result.meta.aircraft_id
    out = {"export": write_text_atomic(path, glass_cockpit_text(
        ex, airframe_name=f"{model} (simulated)"))}
    if sidecar:
        out["meta"] = write_text_atomic(sibling(path, ".meta.toml"), meta_toml(result.meta))
    return out
