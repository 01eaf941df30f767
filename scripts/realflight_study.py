"""Real flights: two Cessna Citation II flight-test records against their own GPS (issue #35).

The records are the TU Delft flight-dynamics practical's exports of the laboratory aircraft
PH-LAB (public repository ``SybrenBootsma/SVV-flight-dynamics-B22``, no licence: the data are
never copied into this repository; docs/realflights.md says how to fetch them).  Each flight is
a folder of header-less one-column CSV files at 10 Hz (``time.csv`` and one file per channel).

The tool reads each flight's folder itself (:mod:`flightrecon.ingest.folder`: one column per
file, named by its stem), as ``flightrecon reconstruct FOLDER --sidecar CASE.meta.toml`` would;
nothing is assembled.  What the script writes per case, into a scratch folder (``--work``,
default a temporary folder), never into the repository nor the data's folder, is what the
analyst gives beside the data:

* a mapping naming the files (``Ahrs1_bNormAcc`` is ``nz - 1``: ``offset = 1.0``; the
  true-heading channel ``Fms1_trueHeading`` is dead, zero throughout, and is not mapped: the
  heading is propagated from the body rates at cleaning); in the GNSS cases the GPS position
  files (``Gps_lat``, ``GPS_long`` / ``Gps_long``, spelt as in each folder) as
  ``gnss_lat_deg`` / ``gnss_lon_deg`` too;
* a sidecar (naming the mapping in its ``[files]``) with the analyst's inputs, computed here
  from the files as an analyst would by hand: the UTC epoch (``GPS_date``, ``GPS_utcSec``),
  the QNH (from the pressure altitude at rest against the airfield's elevation), the departure
  and arrival points (the GPS position at the first and last sample: what an analyst knows
  from the flight's paperwork), the take-off runway's direction and threshold (from the GPS
  over the take-off roll); and the ``--start`` at the line-up.  These figures are read from
  the folder with the tool's own folder reader.

The GNSS cases' set-up is the sidecar's ``[gnss]`` table (:func:`gnss_table`, the tool's own
options, docs/ingest.md "Using the GNSS"): two gaps withheld (``withhold_s``), at most one fix
a second (``interval_s = 1``: the fixes at whole seconds of the 10 Hz frame) and the receiver's
sd :data:`GPS_RECEIVER_SD_M` per axis (``h_sd_m``), to which the tool adds the export's
rounding (sd 32 m): 35 m per axis.  The case ``b22-gnss-as-recorded`` withholds the two gaps
only: every 10 Hz fix with the tool's own sd, the export as written.

Each case runs through :func:`flightrecon.pipeline.reconstruct` (the CLI's own path) with
``keep_unhealthy`` so that an unhealthy track can still be measured, and is measured against
the GPS: horizontal RMS and maximum error of the joint smoother, of the default result and of
the dead-reckoning baselines (:func:`flightrecon.methods.baselines.dead_reckoning`), the mean
NEES per withheld gap and axis, and every method's status with its reason.

Only numbers are written: ``docs/tables/realflights.json`` and the table of
``docs/realflights.md`` (between its ``<!-- table -->`` markers).

Run::

    python scripts/realflight_study.py --data /path/to/SVV-flight-dynamics-B22/matlab
"""

from __future__ import annotations

import argparse
import datetime as dt
import json
import re
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
TABLE_JSON = ROOT / "docs" / "tables" / "realflights.json"
TABLE_MD = ROOT / "docs" / "realflights.md"

#: Rotterdam The Hague airport (EHRD), where both flights start: published elevation -15 ft
FIELD_ELEV_M = -4.5
#: geoid undulation (EGM96) about Rotterdam, m
GEOID_UNDULATION_M = 43.0
KT = 1852.0 / 3600.0
#: metres per degree of latitude, as the tool converts a recording step (gnss_quality.py)
M_PER_DEG = 111_320.0
FT = 0.3048
#: sd per axis of the 1 Hz GPS fixes: the export keeps five significant digits, so the
#: latitude steps by 0.001 deg (111 m; a uniform rounding error of sd 32 m) and the longitude by
#: 0.0001 deg (7 m); the receiver's own error and its latency (a few metres) are below that
GPS_FIX_SD_M = 35.0
#: the latitude's recording step [deg] (five significant digits at 51.9 N)
GPS_LAT_STEP_DEG = 0.001
#: the receiver's sd per axis given to the tool (``[gnss] h_sd_m``), the part of
#: :data:`GPS_FIX_SD_M` that is not the rounding the tool adds itself (``step / sqrt(12)``,
#: flightrecon/ingest/gnss_quality.py): 13.9 m, so that each fix keeps 35 m per axis
GPS_RECEIVER_SD_M = float(np.sqrt(GPS_FIX_SD_M ** 2
                                  - (GPS_LAT_STEP_DEG * M_PER_DEG) ** 2 / 12.0))
#: sd [m] per axis (north, east) of the truth itself: the GPS positions recorded to five
#: significant digits (0.001 deg of latitude, 0.0001 deg of longitude at 51.95 N), a uniform
#: rounding error ``step / sqrt(12)``; added to the reported variance in every NEES of this
#: study (the smoother's error is measured against a truth that is itself this uncertain: without
#: it a reported sd of 3 m against the 32 m rounding alone gives a north NEES above 100)
TRUTH_SD_M: tuple[float, float] = (
    GPS_LAT_STEP_DEG * M_PER_DEG / np.sqrt(12.0),
    0.0001 * M_PER_DEG * float(np.cos(np.radians(51.95))) / np.sqrt(12.0))
#: the withheld GNSS gaps: (start after lift-off [s], length [s])
GAPS: tuple[tuple[float, float], ...] = ((900.0, 300.0), (1800.0, 600.0))

#: the recorder channels: canonical channel -> (file stem, unit, extra keys); the stems are
#: matched whatever their case in the folder (``Gps_long.csv`` in one, ``GPS_long.csv`` in the
#: other), the mapping names each file as it is spelt there
RECORDER_CHANNELS: tuple[tuple[str, str, str, str], ...] = (
    ("n_long_g", "Ahrs1_bLongAcc", "g", ""),
    ("n_lat_g", "Ahrs1_bLatAcc", "g", ""),
    ("n_norm_g", "Ahrs1_bNormAcc", "g", "offset = 1.0\n"),
    ("roll_deg", "Ahrs1_Roll", "deg", ""),
    ("pitch_deg", "Ahrs1_Pitch", "deg", ""),
    ("p_dps", "Ahrs1_bRollRate", "deg/s", ""),
    ("q_dps", "Ahrs1_bPitchRate", "deg/s", ""),
    ("r_dps", "Ahrs1_bYawRate", "deg/s", ""),
    ("baro_alt_m", "Dadc1_alt", "ft", ""),
    ("tas_mps", "Dadc1_tas", "kt", ""),
    ("sat_degc", "Dadc1_sat", "degC", ""),
)
#: the GPS position, mapped as GNSS fixes in the GNSS cases only
GNSS_CHANNELS: tuple[tuple[str, str, str, str], ...] = (
    ("gnss_lat_deg", "Gps_lat", "deg", ""),
    ("gnss_lon_deg", "Gps_long", "deg", ""),
)
#: the files the analyst's figures and the truth are computed from (besides the mapped ones)
ANALYST_FILES = ("time", "Gps_lat", "Gps_long", "GPS_utcSec", "GPS_date", "Dadc1_alt",
                 "Dadc1_tas", "Ahrs1_bLongAcc", "Ahrs1_bYawRate")


# -- assembling a flight ----------------------------------------------------------------------

def analyst_table(folder: Path) -> tuple[pd.DataFrame, dict[str, str]]:
    """The files the analyst's figures and the truth are computed from, read with the tool's
    folder reader (:func:`flightrecon.ingest.folder.read_folder`, what ``flightrecon`` reads the
    folder with), and the stem of each file as spelt in the folder.

    Returns
    -------
    table : one column per file of :data:`ANALYST_FILES`, named as there
    stems : name as in :data:`ANALYST_FILES`, :data:`RECORDER_CHANNELS` and
        :data:`GNSS_CHANNELS` -> the file's stem in this folder (``GPS_long`` or ``Gps_long``)
    """
    from flightrecon.ingest.folder import read_folder

    cols, _, _ = read_folder(folder)
    by_lower = {k.lower(): k for k in cols}
    wanted = set(ANALYST_FILES) | {c[1] for c in RECORDER_CHANNELS + GNSS_CHANNELS}
    missing = sorted(w for w in wanted if w.lower() not in by_lower)
    if missing:
        raise SystemExit(f"{folder}: missing channel file(s) {', '.join(missing)}")
    stems = {w: by_lower[w.lower()] for w in wanted}
    return pd.DataFrame({w: cols[stems[w]] for w in ANALYST_FILES}), stems


def mapping_text(stems: dict[str, str], gnss: bool) -> str:
    """The mapping of the flight's folder: every channel names its file (its stem as spelt in
    this folder); with ``gnss`` the GPS position files as GNSS fixes too."""
    out = ["# flightrecon mapping of a PH-LAB flight-test folder (scripts/realflight_study.py)",
           "[time]", 'column = "time"', 'unit = "s"', ""]
    for ch, name, unit, extra in RECORDER_CHANNELS + (GNSS_CHANNELS if gnss else ()):
        out += [f"[channels.{ch}]", f'column = "{stems[name]}"', f'unit = "{unit}"']
        out += [extra.strip()] if extra else []
        out.append("")
    return "\n".join(out)


def _local_ne(lat: np.ndarray, lon: np.ndarray, lat0: float, lon0: float
              ) -> tuple[np.ndarray, np.ndarray]:
    """North and east [m] of a small area about ``lat0, lon0`` (equirectangular)."""
    r = 6371000.0
    return (np.radians(lat - lat0) * r, np.radians(lon - lon0) * r * np.cos(np.radians(lat0)))


def epoch_of(df: pd.DataFrame) -> dt.datetime:
    """UTC of ``time = 0``: ``GPS_date`` (ddmmyy) and ``GPS_utcSec`` (whole seconds of the day,
    truncated, so ``utcSec - time`` lies in (c - 1, c]: c is its largest value)."""
    d = f"{int(df['GPS_date'].iloc[0]):06d}"
    day = dt.datetime(2000 + int(d[4:6]), int(d[2:4]), int(d[0:2]), tzinfo=dt.UTC)
    c = float(np.max(df["GPS_utcSec"].to_numpy() - df["time"].to_numpy()))
    return day + dt.timedelta(seconds=round(c, 1))


def take_off_roll(df: pd.DataFrame) -> tuple[float, float, float]:
    """Start of the take-off roll, lift-off (first airspeed above 60 kt and the GPS leaving the
    runway's line is not needed here: the air-data computer reports no airspeed below about
    40 kt, so lift-off is taken at the pressure altitude 50 ft above its value at the roll) and
    the line-up (the last yaw rate above 3 deg/s before the roll) [s of ``time``]."""
    t = df["time"].to_numpy()
    tas = df["Dadc1_tas"].to_numpy()
    ax = pd.Series(df["Ahrs1_bLongAcc"].to_numpy()).rolling(20, center=True,
                                                             min_periods=1).mean().to_numpy()
    i_fast = int(np.flatnonzero(tas > 60.0)[0])
    # the roll: the longitudinal load above 0.1 g continuously up to the fast sample
    i0 = i_fast
    while i0 > 0 and ax[i0 - 1] > 0.1:
        i0 -= 1
    yaw = np.abs(df["Ahrs1_bYawRate"].to_numpy())
    turning = np.flatnonzero(yaw[:i0] > 3.0)
    t_lineup = min(float(t[turning[-1]]), float(t[i0])) if len(turning) else float(t[0])
    alt = df["Dadc1_alt"].to_numpy()
    i_lo = i0 + int(np.flatnonzero(alt[i0:] > alt[i0] + 50.0)[0])
    return float(t[i0]), float(t[i_lo]), t_lineup


def runway_from_gps(df: pd.DataFrame, t0: float, t1: float) -> tuple[float, float, float]:
    """Direction [deg true] of the take-off roll from a straight-line fit of the GPS positions
    between ``t0`` and ``t1``, and the position of the fitted line at ``t0`` (the threshold)."""
    t = df["time"].to_numpy()
    sel = (t >= t0) & (t <= t1)
    lat, lon = df["Gps_lat"].to_numpy()[sel], df["Gps_long"].to_numpy()[sel]
    n, e = _local_ne(lat, lon, lat[0], lon[0])
    # principal direction of the points, oriented along the motion
    X = np.c_[n - n.mean(), e - e.mean()]
    _, _, vt = np.linalg.svd(X, full_matrices=False)
    d = vt[0]
    if np.dot(d, [n[-1] - n[0], e[-1] - e[0]]) < 0:
        d = -d
    brg = float(np.degrees(np.arctan2(d[1], d[0])) % 360.0)
    # threshold: the roll's first point projected on the line
    s0 = float(np.dot(X[0], d))
    n0, e0 = n.mean() + s0 * d[0], e.mean() + s0 * d[1]
    r = 6371000.0
    lat0 = float(lat[0] + np.degrees(n0 / r))
    lon0 = float(lon[0] + np.degrees(e0 / (r * np.cos(np.radians(lat[0])))))
    return brg, lat0, lon0


def qnh_from_rest(p_alt_m: float, elev_m: float) -> float:
    """The QNH [hPa] under which a field at ``elev_m`` has the pressure altitude ``p_alt_m``."""
    from scipy.optimize import brentq

    from flightrecon.geo.atmosphere import field_pressure_altitude_m

    return float(brentq(lambda q: field_pressure_altitude_m(elev_m, q) - p_alt_m, 940.0, 1060.0))


def flight_facts(df: pd.DataFrame) -> dict[str, Any]:
    """What the analyst knows of the flight (epoch, QNH, airfields, runway, phases)."""
    t = df["time"].to_numpy()
    t_roll, t_lo, t_lineup = take_off_roll(df)
    brg, thr_lat, thr_lon = runway_from_gps(df, t_roll, t_lo)
    alt_m = df["Dadc1_alt"].to_numpy() * FT
    rest0 = float(np.median(alt_m[t < t[0] + 60.0]))
    tas = df["Dadc1_tas"].to_numpy()
    ends_on_ground = bool(tas[-1] < 40.0)
    rest1 = float(np.median(alt_m[t > t[-1] - 5.0])) if ends_on_ground else None
    lat, lon = df["Gps_lat"].to_numpy(), df["Gps_long"].to_numpy()
    return {
        "epoch_utc": epoch_of(df).strftime("%Y-%m-%dT%H:%M:%S.%f")[:-5] + "Z",
        "qnh_departure_hpa": qnh_from_rest(rest0, FIELD_ELEV_M),
        "qnh_arrival_hpa": (qnh_from_rest(rest1, FIELD_ELEV_M) if rest1 is not None
                            else qnh_from_rest(rest0, FIELD_ELEV_M)),
        "first_fix": (float(lat[0]), float(lon[0])), "last_fix": (float(lat[-1]), float(lon[-1])),
        "runway_true_deg": brg, "threshold": (thr_lat, thr_lon),
        "roll_start_s": t_roll, "liftoff_s": t_lo, "lineup_s": t_lineup,
        "ends_on_ground": ends_on_ground, "t_end_s": float(t[-1]), "t_start_s": float(t[0]),
    }


def _toml_position(name: str, lat: float, lon: float, runway: float | None = None,
                   threshold: tuple[float, float] | None = None) -> str:
    s = f"[{name}]\nlat_deg = {lat:.6f}\nlon_deg = {lon:.6f}\nelev_m = {FIELD_ELEV_M}\n"
    if runway is not None:
        s += f"runway_true_deg = {runway:.2f}\n"
        if threshold is not None:
            s += f"threshold_lat_deg = {threshold[0]:.6f}\nthreshold_lon_deg = {threshold[1]:.6f}\n"
    return s


def write_case(facts: dict[str, Any], stems: dict[str, str], folder: Path, stem: str, *,
               arrival: str, gnss: bool, gnss_text: str = "") -> Path:
    """The mapping and the sidecar of one case in ``folder`` (the scratch folder: never the
    data's); returns the sidecar.  ``arrival`` is ``"none"``, ``"last_fix"`` (the GPS's last
    position, with the runway when the record ends on the ground) or ``"departure"`` (the
    departure airfield: where the flight was planned to end)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"{stem}.mapping.toml").write_text(mapping_text(stems, gnss))
    lat0, lon0 = facts["first_fix"]
    side = ("[flight]\naircraft_id = \"PH-LAB\"\n"
            f"flight_id = \"{stem}\"\n"
            f"epoch_utc = \"{facts['epoch_utc']}\"\n"
            "baro_datum = \"pressure\"\n"
            f"geoid_undulation_m = {GEOID_UNDULATION_M}\n"
            f"qnh_departure_hpa = {facts['qnh_departure_hpa']:.2f}\n"
            f"qnh_arrival_hpa = {facts['qnh_arrival_hpa']:.2f}\n\n"
            + _toml_position("departure", lat0, lon0, facts["runway_true_deg"],
                             facts["threshold"]))
    if arrival == "last_fix":
        lat1, lon1 = facts["last_fix"]
        if facts["ends_on_ground"]:
            side += "\n" + _toml_position("arrival", lat1, lon1, facts["runway_true_deg"],
                                          facts["threshold"])
        else:
            side += "\n" + _toml_position("arrival", lat1, lon1)
    elif arrival == "departure":
        side += "\n" + _toml_position("arrival", lat0, lon0, facts["runway_true_deg"],
                                      facts["threshold"])
    if gnss_text:
        side += "\n" + gnss_text
    side += f"\n[files]\nmapping = \"{stem}.mapping.toml\"\n"
    path = folder / f"{stem}.meta.toml"
    path.write_text(side)
    return path


def gnss_gaps(facts: dict[str, Any]) -> list[tuple[float, float]]:
    """The withheld gaps of :data:`GAPS` as (start, end) in ``time`` [s]."""
    return [(facts["liftoff_s"] + a, facts["liftoff_s"] + a + n) for a, n in GAPS]


def gnss_table(gaps: list[tuple[float, float]], as_recorded: bool) -> str:
    """The sidecar's ``[gnss]`` table of a GNSS case (docs/ingest.md, "Using the GNSS"): the
    ``gaps`` withheld; unless ``as_recorded``, at most one fix a second (1 Hz from the 10 Hz
    frame: the export's five significant digits do not make ten independent fixes a second)
    and the receiver's sd :data:`GPS_RECEIVER_SD_M` (the tool adds the export's rounding)."""
    out = ["[gnss]", "withhold_s = [" + ", ".join(f"[{a!r}, {b!r}]" for a, b in gaps) + "]"]
    if not as_recorded:
        out += ["interval_s = 1.0", f"h_sd_m = {GPS_RECEIVER_SD_M!r}"]
    return "\n".join(out) + "\n"


# -- measuring --------------------------------------------------------------------------------

def truth_ne(rec: Any, df: pd.DataFrame, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The GPS position at ``t`` in the result's tangent plane (north, east) [m]."""
    from flightrecon.geo.frames import output_plane

    plane = output_plane(rec.clean.meta)
    tt = df["time"].to_numpy()
    lat = np.interp(t, tt, df["Gps_lat"].to_numpy(), left=np.nan, right=np.nan)
    lon = np.interp(t, tt, df["Gps_long"].to_numpy(), left=np.nan, right=np.nan)
    h = np.interp(t, tt, df["Dadc1_alt"].to_numpy() * FT) + GEOID_UNDULATION_M
    ok = np.isfinite(lat)
    e = np.full(len(t), np.nan)
    n = np.full(len(t), np.nan)
    ee, nn, _ = plane.forward(lat[ok], lon[ok], h[ok])
    e[ok], n[ok] = ee, nn
    return n, e


def errors(t: np.ndarray, n: np.ndarray, e: np.ndarray, tn: np.ndarray, te: np.ndarray,
           t0: float, t1: float) -> dict[str, float | None]:
    """Horizontal RMS and largest error [m] between ``t0`` and ``t1`` (finite samples)."""
    sel = (t >= t0) & (t <= t1) & np.isfinite(n) & np.isfinite(e) & np.isfinite(tn)
    if not sel.any():
        return {"rms_m": None, "max_m": None, "final_m": None}
    d = np.hypot(n[sel] - tn[sel], e[sel] - te[sel])
    return {"rms_m": float(np.sqrt(np.mean(d ** 2))), "max_m": float(np.max(d)),
            "final_m": float(d[-1])}


def flight_nees(t: np.ndarray, tr: pd.DataFrame, tn: np.ndarray, te: np.ndarray, t0: float,
                t1: float, prefix: str = "joint_") -> dict[str, float | None]:
    """The joint smoother's mean NEES per axis between ``t0`` and ``t1`` (the truth's own
    rounding, :data:`TRUTH_SD_M`, added to the reported variance) and its median reported sd:
    is it honestly unsure?  ``prefix``: whose columns (``""``: the default result's)."""
    sn = tr[f"{prefix}north_sd_m"].to_numpy(float)
    se = tr[f"{prefix}east_sd_m"].to_numpy(float)
    dn = tr[f"{prefix}north_m"].to_numpy(float) - tn
    de = tr[f"{prefix}east_m"].to_numpy(float) - te
    sel = (t >= t0) & (t <= t1) & np.isfinite(dn) & np.isfinite(de) & (sn > 0) & (se > 0)
    if not sel.any():
        return {"nees_north": None, "nees_east": None, "sd_median_m": None}
    tvn, tve = TRUTH_SD_M[0] ** 2, TRUTH_SD_M[1] ** 2
    return {"nees_north": float(np.mean(dn[sel] ** 2 / (sn[sel] ** 2 + tvn))),
            "nees_east": float(np.mean(de[sel] ** 2 / (se[sel] ** 2 + tve))),
            "sd_median_m": float(np.median(np.hypot(sn[sel], se[sel])))}


def method_table(rec: Any) -> dict[str, Any]:
    """Every method's status and reason."""
    out = {}
    for m, s in rec.summary["methods"].items():
        out[m] = {"status": s.get("status"), "reason": s.get("reason"),
                  "checks": sorted({str(p.get("check")) for p in
                                    (s.get("health") or {}).get("problems", [])})}
    return out


def joint_figures(rec: Any) -> dict[str, Any]:
    """The joint smoother's heading bias and wind (speed range, reported sd) from its result."""
    res = rec.results.get("joint")
    if res is None:
        return {}
    s = rec.summary["methods"]["joint"]
    corr = s.get("corrections", {})
    hb = corr.get("heading_bias_deg") or corr.get("heading_bias_rad")
    tr = res.track
    out: dict[str, Any] = {}
    if hb is not None:
        out["heading_bias_deg"] = [hb["value"], hb["sd"]]
    if "joint_wind_n_mps" in tr.columns:
        w = np.hypot(tr["joint_wind_n_mps"], tr["joint_wind_e_mps"]).to_numpy(float)
        out["wind_speed_mps_range"] = [float(np.nanmin(w)), float(np.nanmax(w))]
        if "joint_wind_n_sd_mps" in tr.columns:
            sd = np.hypot(tr["joint_wind_n_sd_mps"], tr["joint_wind_e_sd_mps"]).to_numpy(float)
            out["wind_sd_mps_median"] = float(np.nanmedian(sd))
    return out


def gap_nees(t: np.ndarray, n: np.ndarray, e: np.ndarray, sdn: np.ndarray, sde: np.ndarray,
             tn: np.ndarray, te: np.ndarray, gaps: list[tuple[float, float]]
             ) -> list[dict[str, float]]:
    """Per withheld gap: the largest error and the mean NEES per axis (squared error over the
    reported variance with the truth's own, :data:`TRUTH_SD_M`, averaged over the gap's
    samples)."""
    out = []
    for a, b in gaps:
        sel = (t > a) & (t < b) & np.isfinite(n) & np.isfinite(tn) & (sdn > 0) & (sde > 0)
        if not sel.any():
            continue
        dn, de = n[sel] - tn[sel], e[sel] - te[sel]
        out.append({"start_s": a, "length_s": b - a,
                    "max_error_m": float(np.max(np.hypot(dn, de))),
                    "sd_north_m": [float(np.min(sdn[sel])), float(np.max(sdn[sel]))],
                    "sd_east_m": [float(np.min(sde[sel])), float(np.max(sde[sel]))],
                    "nees_north": float(np.mean(dn ** 2 / (sdn[sel] ** 2
                                                           + TRUTH_SD_M[0] ** 2))),
                    "nees_east": float(np.mean(de ** 2 / (sde[sel] ** 2
                                                         + TRUTH_SD_M[1] ** 2)))})
    return out


def run_case(name: str, data: Path, df: pd.DataFrame, stems: dict[str, str],
             facts: dict[str, Any], work: Path, *, arrival: str, start: bool,
             gnss: bool = False, gnss_as_recorded: bool = False,
             last_fix_as_fix: bool = False,
             joint_noise: dict[str, float] | None = None) -> dict[str, Any]:
    """One case: its mapping and sidecar, the tool reading the flight's folder ``data``,
    measuring against the GPS of ``df``.  With ``gnss`` the GPS position is mapped and the
    sidecar's ``[gnss]`` table withholds the gaps (:func:`gnss_table`; thinned to 1 Hz with the
    receiver's sd unless ``gnss_as_recorded``)."""
    from flightrecon.errors import FlightReconError
    from flightrecon.methods.baselines import dead_reckoning
    from flightrecon.pipeline import ReconstructSettings, reconstruct

    gaps = gnss_gaps(facts) if gnss else []
    sidecar = write_case(facts, stems, work / name, name, arrival=arrival, gnss=gnss,
                         gnss_text=gnss_table(gaps, gnss_as_recorded) if gnss else "")
    over: dict[str, Any] = {}
    if last_fix_as_fix:
        lat1, lon1 = facts["last_fix"]
        over["fixes"] = [f"{facts['t_end_s']:.1f},{lat1:.6f},{lon1:.6f}"]
    settings = ReconstructSettings(start=facts["lineup_s"] if start else None,
                                   keep_unhealthy=True, joint_noise=joint_noise or None)
    t_wall = time.time()
    out: dict[str, Any] = {"case": name, "arrival": arrival, "start_s": settings.start,
                           "gnss": gnss, "gnss_as_recorded": gnss_as_recorded,
                           "fix_at_end": last_fix_as_fix}
    try:
        rec = reconstruct(data, sidecar=sidecar, meta_overrides=over or None,
                          settings=settings, record=False)
    except FlightReconError as exc:
        out.update({"exit": exc.exit_code, "error": str(exc)[:500]})
        return out
    out["seconds"] = round(time.time() - t_wall, 1)
    out["methods"] = method_table(rec)
    res_method = rec.summary["result"]["method"]
    out["result_method"] = res_method
    out["exit"] = 0 if res_method is not None else 8
    out["warnings_top"] = [w for w in rec.summary.get("warnings", []) if "unhealthy" in w
                           or "implausible" in w][:10]
    out["joint"] = joint_figures(rec)
    out["gap_calibration"] = (rec.summary["methods"].get("joint") or {}).get("gap_calibration")
    if gnss:
        out["gnss_use"] = rec.summary["measurements"].get("gnss_use")
    tr = rec.track
    t = tr["t_s"].to_numpy(float)
    tn, te = truth_ne(rec, df, t)
    ph = rec.clean.phases
    t_lo = ph.liftoff_t_s if np.isfinite(ph.liftoff_t_s) else t[0]
    t_td = ph.touchdown_t_s if np.isfinite(ph.touchdown_t_s) else t[-1]
    out["airborne_s"] = [float(t_lo), float(t_td)]
    errs: dict[str, Any] = {}
    if "joint_north_m" in tr.columns:
        errs["joint"] = errors(t, tr["joint_north_m"].to_numpy(float),
                               tr["joint_east_m"].to_numpy(float), tn, te, t_lo, t_td)
    if "joint_north_sd_m" in tr.columns:
        errs["joint_nees"] = flight_nees(t, tr, tn, te, t_lo, t_td)
    if res_method is not None:
        errs["result"] = errors(t, tr["north_m"].to_numpy(float), tr["east_m"].to_numpy(float),
                                tn, te, t_lo, t_td)
        errs["result_nees"] = flight_nees(t, tr, tn, te, t_lo, t_td, prefix="")
    for m in ("sabziev", "sns"):
        if f"{m}_north_m" in tr.columns:
            errs[m] = errors(t, tr[f"{m}_north_m"].to_numpy(float),
                             tr[f"{m}_east_m"].to_numpy(float), tn, te, t_lo, t_td)
    try:
        dr = dead_reckoning(rec.clean, wind=False)
        errs["dr_no_wind"] = errors(dr["t_s"].to_numpy(), dr["north_m"].to_numpy(),
                                    dr["east_m"].to_numpy(),
                                    *truth_ne(rec, df, dr["t_s"].to_numpy()), t_lo, t_td)
        if rec.clean.meta.arrival is not None:
            drc = dead_reckoning(rec.clean, wind=False, corrected=True)
        else:   # closed at a known position at the record's end, if there is one
            from flightrecon.track_evidence import corrected_dead_reckoning

            got = corrected_dead_reckoning(rec.clean)
            drc = got[0] if got is not None else None
        if drc is not None:
            errs["dr_linear"] = errors(drc["t_s"].to_numpy(), drc["north_m"].to_numpy(),
                                       drc["east_m"].to_numpy(),
                                       *truth_ne(rec, df, drc["t_s"].to_numpy()), t_lo, t_td)
    except (ValueError, KeyError) as exc:
        errs["dr_error"] = str(exc)
    out["errors"] = errs
    if gaps and "joint_north_m" in tr.columns:
        out["gaps"] = gap_nees(t, tr["joint_north_m"].to_numpy(float),
                               tr["joint_east_m"].to_numpy(float),
                               tr["joint_north_sd_m"].to_numpy(float),
                               tr["joint_east_sd_m"].to_numpy(float), tn, te, gaps)
    hr = [r for r in rec.clean.report if r.get("action") == "heading_from_rates"]
    if hr:
        out["heading_from_rates"] = {k: hr[0].get(k) for k in
                                     ("gyro_bias_q_dps", "gyro_bias_r_dps", "gyro_bias_sd_dps",
                                      "heading_sd_max_deg", "why")}
    return out


CASES: tuple[tuple[str, str, dict[str, Any]], ...] = (
    ("ref-recorder", "ref", {"arrival": "none", "start": True}),
    ("ref-airport-arrival", "ref", {"arrival": "departure", "start": True}),
    ("ref-last-fix", "ref", {"arrival": "none", "start": True, "last_fix_as_fix": True}),
    ("b22-recorder", "b22", {"arrival": "last_fix", "start": True}),
    ("b22-whole-record", "b22", {"arrival": "last_fix", "start": False}),
    ("ref-gnss-gaps", "ref", {"arrival": "none", "start": True, "gnss": True}),
    ("b22-gnss-gaps", "b22", {"arrival": "last_fix", "start": True, "gnss": True}),
    ("b22-gnss-as-recorded", "b22", {"arrival": "last_fix", "start": True, "gnss": True,
                                     "gnss_as_recorded": True}),
)


def _fmt(x: Any, unit: str = "", digits: int = 0) -> str:
    if x is None:
        return "-"
    if abs(x) >= 1000 and unit == "m":
        return f"{x / 1000:.1f} km"
    return f"{x:.{digits}f}{' ' + unit if unit else ''}"


def markdown_table(results: list[dict[str, Any]]) -> str:
    """The study's table (one row per case; the reasons in full are in the JSON)."""
    rows = ["| case | exit, result from | result RMS, NEES n / e | joint: status (failed checks) | "
            "joint RMS / max | joint NEES n / e, median sd | other methods: status (checks), RMS "
            "| DR no wind | DR + linear | joint heading bias, wind | withheld GNSS gaps: max "
            "error, NEES n / e |",
            "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in results:
        if "error" in r:
            rows.append(f"| {r['case']} | exit {r['exit']}: {r['error'][:120]} "
                        "| | | | | | | | | |")
            continue
        e = r["errors"]

        def status(m: str, r: dict[str, Any] = r) -> str:
            st = r["methods"].get(m, {})
            ch = ", ".join(st.get("checks") or [])
            return f"{st.get('status')}" + (f" ({ch})" if ch else "")

        je = e.get("joint", {})
        jn = e.get("joint_nees", {})
        jf = r.get("joint", {})
        hb = jf.get("heading_bias_deg")
        ws = jf.get("wind_speed_mps_range")
        jtxt = (f"{hb[0]:+.1f} ± {hb[1]:.1f} deg" if hb else "-") + (
            f", {ws[0]:.0f}-{ws[1]:.0f} m/s" if ws else "")
        others = "; ".join(
            f"{m} {status(m)}, {_fmt(e.get(m, {}).get('rms_m'), 'm')}"
            for m in ("sabziev", "sns") if r["methods"].get(m, {}).get("status") != "skipped")
        ntxt = (f"{jn['nees_north']:.1f} / {jn['nees_east']:.1f}, "
                f"{_fmt(jn['sd_median_m'], 'm')}" if jn.get("nees_north") is not None else "-")
        rn = e.get("result_nees", {})
        rtxt = "-" if r["result_method"] is None else (
            f"{_fmt(e.get('result', {}).get('rms_m'), 'm')}, "
            + (f"{rn['nees_north']:.1f} / {rn['nees_east']:.1f}"
               if rn.get("nees_north") is not None else "no sd"))
        gtxt = "; ".join(f"{g['length_s']:.0f} s: {_fmt(g['max_error_m'], 'm')}, "
                         f"{g['nees_north']:.1f} / {g['nees_east']:.1f}"
                         for g in r.get("gaps", []))
        rows.append(
            f"| {r['case']} | {r['exit']}, {r['result_method'] or 'nothing written'} | "
            f"{rtxt} | {status('joint')} | "
            f"{_fmt(je.get('rms_m'), 'm')} / {_fmt(je.get('max_m'), 'm')} | {ntxt} | "
            f"{others or '-'} | "
            f"{_fmt(e.get('dr_no_wind', {}).get('rms_m'), 'm')} | "
            f"{_fmt(e.get('dr_linear', {}).get('rms_m'), 'm')} | {jtxt} | {gtxt or '-'} |")
    return "\n".join(rows)


def regenerate_line(a: argparse.Namespace) -> str:
    """The table's first line: the command that wrote it, the data folder as ``DIR/matlab``
    (where the reader fetched it; a local path says nothing to another reader)."""
    cases = (" --cases " + " ".join(a.cases)) if a.cases else ""
    return f"Regenerate: `python scripts/realflight_study.py --data DIR/matlab{cases}`\n\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, required=True,
                    help="the fetched 'matlab' folder (flight 'ref'; 'Our-data' inside: B22)")
    ap.add_argument("--work", type=Path, default=None,
                    help="scratch folder for the cases' mappings and sidecars "
                    "(default: a temporary folder)")
    ap.add_argument("--cases", nargs="*", default=None, help="run only these cases")
    ap.add_argument("--no-write", action="store_true", help="print, do not write the tables")
    ap.add_argument("--joint-noise", nargs="*", default=[], metavar="NAME=VALUE",
                    help="joint noise settings for every case (what a noise file's [joint] "
                    "table gives), e.g. ahrs_tilt_mps2_per_g=1.0; with any, the tables are "
                    "not written")
    a = ap.parse_args(argv)
    joint_noise = {k: float(v) for k, v in (x.split("=", 1) for x in a.joint_noise)}
    if joint_noise:
        a.no_write = True
    flights = {"ref": a.data, "b22": a.data / "Our-data"}
    read = {k: analyst_table(v) for k, v in flights.items()}
    facts = {k: flight_facts(df) for k, (df, _) in read.items()}
    for k, f in facts.items():
        print(k, json.dumps({x: f[x] for x in ("epoch_utc", "qnh_departure_hpa",
                                               "qnh_arrival_hpa", "runway_true_deg",
                                               "roll_start_s", "liftoff_s", "lineup_s",
                                               "ends_on_ground")}), flush=True)
    tmp = tempfile.TemporaryDirectory(prefix="realflights-") if a.work is None else None
    work = Path(tmp.name) if tmp is not None else a.work
    results = []
    for name, flight, kw in CASES:
        if a.cases and name not in a.cases:
            continue
        print(f"== {name}", flush=True)
        df, stems = read[flight]
        r = run_case(name, flights[flight], df, stems, facts[flight], work, **kw,
                     joint_noise=joint_noise)
        print(json.dumps(r, indent=1, default=str), flush=True)
        results.append(r)
    if tmp is not None:
        tmp.cleanup()
    doc = {"generated_utc": dt.datetime.now(dt.UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
           "command": regenerate_line(a).split("`")[1],
           "flights": {k: {x: v for x, v in f.items()} for k, f in facts.items()},
           "cases": results}
    table = regenerate_line(a) + markdown_table(results)
    print(table)
    if not a.no_write:
        TABLE_JSON.write_text(json.dumps(doc, indent=1, default=str) + "\n")
        if TABLE_MD.exists():
            text = TABLE_MD.read_text()
            new = re.sub(r"<!-- table -->.*<!-- /table -->",
                         lambda _m: f"<!-- table -->\n{table}\n<!-- /table -->", text, flags=re.S)
            TABLE_MD.write_text(new)
    return 0


if __name__ == "__main__":
    sys.exit(main())
