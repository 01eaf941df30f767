"""The replay formats: KML 2.2 with the Google extensions (a styled line, a ``gx:Track`` with
heading/tilt/roll per sample, one placemark per event, altitudes above mean sea level) and CZML
for Cesium (sampled positions, ellipsoidal height); the formats are described in
:mod:`flightrecon.export.writers`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.export.atomic import atomic_path
from flightrecon.export.encode import (
    clean_json,
    escape,
    flight_of,
    geo_rows,
    thin_index,
    utc_strings,
)


def track_angles(track: pd.DataFrame, attitude: pd.DataFrame | None = None
                 ) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """Heading, pitch and bank [deg] per sample of ``track`` for a replay, and where they
    come from.

    With ``attitude`` (a table with ``t_s`` and the recorder's ``heading_deg``, ``pitch_deg``,
    ``roll_deg``) the recorded attitude, interpolated to the track's times.  Otherwise derived
    from the reconstructed velocity: heading = track angle atan2(v_e, v_n), pitch = flight-path
    angle atan2(v_u, ground speed), bank = atan(V * d(track)/dt / g) (coordinated turn).
    """
    t = track["t_s"].to_numpy(float)
    if attitude is not None and {"t_s", "heading_deg", "pitch_deg", "roll_deg"} <= set(
            attitude.columns):
        ta = attitude["t_s"].to_numpy(float)
        out = []
        for c in ("heading_deg", "pitch_deg", "roll_deg"):
            v = attitude[c].to_numpy(float)
            ok = np.isfinite(v)
            if c == "heading_deg":  # interpolate the unwrapped angle
                v = np.degrees(np.unwrap(np.radians(np.where(ok, v, 0.0))))
            out.append(np.interp(t, ta[ok], v[ok]) if ok.sum() >= 2 else np.zeros(len(t)))
        return np.mod(out[0], 360.0), out[1], out[2], "recorded attitude"
    vn = track["vn_mps"].to_numpy(float) if "vn_mps" in track.columns else np.zeros(len(t))
    ve = track["ve_mps"].to_numpy(float) if "ve_mps" in track.columns else np.zeros(len(t))
    vu = track["vu_mps"].to_numpy(float) if "vu_mps" in track.columns else np.zeros(len(t))
    vn, ve, vu = (np.nan_to_num(x) for x in (vn, ve, vu))
    gs = np.hypot(vn, ve)
    psi = np.unwrap(np.arctan2(ve, vn))
    rate = np.gradient(psi, t) if len(t) > 1 else np.zeros(len(t))
    moving = gs > 10.0
    bank = np.where(moving, np.degrees(np.arctan(gs * rate / 9.80665)), 0.0)
    pitch = np.degrees(np.arctan2(vu, np.maximum(gs, 1e-6)))
    return (np.mod(np.degrees(psi), 360.0), np.where(moving, pitch, 0.0), bank,
            "derived from the reconstructed velocity (track angle, flight-path angle, "
            "coordinated-turn bank)")


def geoid_or_refuse(metadata: Mapping[str, Any] | None, geoid_undulation_m: float | None,
                     what: str) -> float:
    if geoid_undulation_m is not None:
        return float(geoid_undulation_m)
    n = flight_of(metadata).get("geoid_undulation_m")
    if isinstance(n, (int, float)) and math.isfinite(n):
        return float(n)
    from flightrecon.errors import MetadataError

    raise MetadataError(f"{what} altitudes are above mean sea level, and this result carries no "
                        "geoid undulation (a CSV result without its summary): keep "
                        "<stem>.summary.json beside it, or give --geoid-undulation METRES "
                        "(ellipsoid minus MSL in the area; 0 only if you mean it)")


_KML_EVENT_KINDS = ("liftoff", "touchdown", "impact", "end_airborne", "exceedance", "outage",
                    "gap", "source_change")


def _kml_event_marks(metadata: Mapping[str, Any] | None, t: np.ndarray, lat: np.ndarray,
                     lon: np.ndarray, alt_msl: np.ndarray, epoch_utc: Any, *, with_time: bool
                     ) -> list[str]:
    """One KML point per event of the summary on the track (numbered as the events table),
    time-stamped in UTC when the epoch is known."""
    from flightrecon.events import events_from_summary

    marks = []
    events = events_from_summary(metadata or {})
    for num, e in enumerate(events, start=1):
        if e.kind not in _KML_EVENT_KINDS or not np.isfinite(e.t_s) or len(t) < 2:
            continue
        la = float(np.interp(e.t_s, t, lat))
        lo = float(np.interp(e.t_s, t, lon))
        h = float(np.interp(e.t_s, t, alt_msl))
        stamp = ""
        u = utc_strings(np.array([e.t_s]), epoch_utc) if with_time else None
        if u is not None:
            stamp = f"<TimeStamp><when>{u[0]}</when></TimeStamp>"
        marks.append(f"<Placemark><name>{num}. {escape(e.label)}</name>"
                     f"<description>{escape(e.detail)}</description>{stamp}"
                     f"<styleUrl>#event-{escape(e.severity)}</styleUrl><Point><altitudeMode>"
                     f"absolute</altitudeMode><coordinates>{lo:.7f},{la:.7f},{h:.1f}"
                     "</coordinates></Point></Placemark>")
    return marks


#: the KML styles: the line, the aircraft, and the events by severity.  No style names an
#: image: an ``IconStyle`` without an ``Icon`` is drawn with the viewer's own placemark icon
#: (tinted by ``color``), so a replay opened with no network shows every mark; an ``Icon``
#: linking a web server's image shows a broken-image mark there (issue 53)
_KML_STYLES = (
    '<Style id="line"><LineStyle><color>ff0080ff</color><width>3</width></LineStyle>'
    "</Style>"
    '<Style id="aircraft"><IconStyle><color>ffffff00</color><scale>1.3</scale></IconStyle>'
    "<LineStyle><color>ff00ffff</color><width>2</width></LineStyle></Style>"
    + "".join(f'<Style id="event-{sev}"><IconStyle><color>{col}</color><scale>0.9</scale>'
              "</IconStyle><LabelStyle><scale>0.8</scale></LabelStyle></Style>"
              for sev, col in (("info", "ff00ff00"), ("caution", "ff00c0ff"),
                               ("alert", "ff0000ff"))))


def write_kml(path: str | Path, track: pd.DataFrame, name: str,
              geoid_undulation_m: float | None = None, *,
              metadata: Mapping[str, Any] | None = None, attitude: pd.DataFrame | None = None,
              max_samples: int = 200_000) -> Path:
    """KML 2.2 replay: a styled line, a ``gx:Track`` and the events (module docstring).

    Parameters
    ----------
    track : result table (``t_s``, ``lat_deg``, ``lon_deg``, ``alt_m``, velocities)
    name : document name
    geoid_undulation_m : ellipsoid minus MSL [m]; default: the summary's (``metadata``);
        refused (:class:`~flightrecon.errors.MetadataError`) when neither gives it
    metadata : the summary (epoch for the UTC ``when``, events, geoid undulation)
    attitude : recorder attitude for ``gx:angles`` (:func:`track_angles`)
    max_samples : the track is thinned evenly to at most this many samples (Google Earth
        slows down beyond a few hundred thousand); every written sample has one ``when``,
        one ``gx:coord`` and one ``gx:angles``
    """
    n_geoid = geoid_or_refuse(metadata, geoid_undulation_m, "KML")
    rows = geo_rows(track)
    rows = rows.iloc[thin_index(len(rows), max_samples)]
    lat, lon = rows["lat_deg"].to_numpy(float), rows["lon_deg"].to_numpy(float)
    alt_msl = rows["alt_m"].to_numpy(float) - n_geoid
    t = rows["t_s"].to_numpy(float)
    coords = " ".join(f"{lo:.7f},{la:.7f},{h:.1f}" for lo, la, h in zip(lon, lat, alt_msl))
    fl = flight_of(metadata)
    utc = utc_strings(t, fl.get("epoch_utc"))
    heading, pitch, roll, angle_source = track_angles(rows, attitude)
    thinned = len(rows) < len(geo_rows(track))
    desc = ("flightrecon reconstruction. Altitude mode absolute: metres above mean sea level "
            f"(WGS-84 ellipsoidal height minus geoid undulation {n_geoid:g} m). ")
    parts = []
    if utc is not None:
        whens = "".join(f"<when>{u}</when>" for u in utc)
        gxc = "".join(f"<gx:coord>{lo:.7f} {la:.7f} {h:.1f}</gx:coord>"
                      for lo, la, h in zip(lon, lat, alt_msl))
        gxa = "".join(f"<gx:angles>{h:.1f} {p:.1f} {r:.1f}</gx:angles>"
                      for h, p, r in zip(heading, pitch, roll))
        parts.append(
            f"<Placemark><name>{escape(name)} replay</name><styleUrl>#aircraft</styleUrl>"
            "<gx:Track><altitudeMode>absolute</altitudeMode>"
            f"{whens}{gxc}{gxa}</gx:Track></Placemark>")
        desc += (f"Replay: gx:Track with {len(rows)} UTC samples"
                 + (" (thinned evenly)" if thinned else "") + f"; gx:angles heading/tilt/roll "
                 f"= heading/pitch/bank, {angle_source}. ")
    else:
        desc += "No replay: the flight's UTC epoch is unknown, so no time stamps. "
    marks = _kml_event_marks(metadata, t, lat, lon, alt_msl, fl.get("epoch_utc"),
                             with_time=utc is not None)
    styles = _KML_STYLES
    text = (
        '<?xml version="1.0" encoding="UTF-8"?>\n'
        '<kml xmlns="http://www.opengis.net/kml/2.2" xmlns:gx="http://www.google.com/kml/ext/2.2">'
        f"<Document><name>{escape(name)}</name><description>{escape(desc)}</description>"
        f"{styles}"
        f"<Placemark><name>{escape(name)} track</name><styleUrl>#line</styleUrl><LineString>"
        f"<tessellate>0</tessellate><altitudeMode>absolute</altitudeMode><coordinates>{coords}"
        "</coordinates></LineString></Placemark>"
        + "".join(parts)
        + f"<Folder><name>events</name>{''.join(marks)}</Folder>"
        "</Document></kml>\n")
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_czml(path: str | Path, track: pd.DataFrame, name: str,
               metadata: Mapping[str, Any] | None = None, max_samples: int = 200_000) -> Path:
    """CZML for Cesium: a document packet with the clock and one packet with the sampled
    position (``cartographicDegrees``: lon, lat, WGS-84 ellipsoidal height, as Cesium wants)
    and a path.  Needs the UTC epoch."""
    from flightrecon.errors import MetadataError

    fl = flight_of(metadata)
    utc = utc_strings(np.zeros(1), fl.get("epoch_utc"))
    if utc is None:
        raise MetadataError("CZML needs the flight's UTC epoch (the summary's flight.epoch_utc)")
    rows = geo_rows(track)
    rows = rows.iloc[thin_index(len(rows), max_samples)]
    t = rows["t_s"].to_numpy(float)
    ends = utc_strings(np.array([t[0], t[-1]]), fl.get("epoch_utc"))
    if ends is None:  # not reached: the epoch was checked above
        raise MetadataError("CZML needs the flight's UTC epoch (the summary's flight.epoch_utc)")
    start, end = ends
    epoch = str(fl.get("epoch_utc"))
    samples = np.column_stack([t, rows["lon_deg"].to_numpy(float),
                               rows["lat_deg"].to_numpy(float), rows["alt_m"].to_numpy(float)])
    doc = [
        {"id": "document", "name": name, "version": "1.0",
         "clock": {"interval": f"{start}/{end}", "currentTime": start, "multiplier": 10,
                   "range": "CLAMPED", "step": "SYSTEM_CLOCK_MULTIPLIER"}},
        {"id": "aircraft", "name": name, "availability": f"{start}/{end}",
         "position": {"epoch": epoch, "cartographicDegrees": np.round(samples, 7).ravel().tolist()},
         "point": {"pixelSize": 8, "color": {"rgba": [255, 128, 0, 255]}},
         "path": {"width": 2, "leadTime": 0, "trailTime": 1e9, "resolution": 1,
                  "material": {"solidColor": {"color": {"rgba": [255, 128, 0, 255]}}}}},
    ]
    text = json.dumps(clean_json(doc), allow_nan=False)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)
