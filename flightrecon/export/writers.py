"""Writers for reconstructed trajectories: CSV, Parquet, GeoJSON, KML, and the summary JSON.

Every writer goes through :func:`flightrecon.export.atomic.atomic_path`: a hidden temporary file
beside the target, renamed on success, removed on failure or Ctrl-C.

Formats
-------
* CSV: one header line, units in the column names, ``.`` decimal point; with the summary
  known, ``time_utc`` (ISO-8601, milliseconds, ``Z``) after ``t_s`` and ``alt_msl_m``
  (ellipsoidal height minus the flight's geoid undulation) after ``alt_m``.
* Parquet: the same columns (without ``time_utc`` / ``alt_msl_m``: the epoch and undulation
  are in its metadata); the file's key-value metadata holds ``flightrecon`` (JSON: flight
  metadata, settings, software version, SHA-256 of every input file, column datums).
* GeoJSON (RFC 7946): a ``FeatureCollection`` with one ``LineString`` of
  ``[lon, lat, ellipsoidal height]`` and one ``Point`` feature per output sample (thinned to at
  most ``max_points``) whose properties carry ``t_s``, ``time_utc``, ``alt_msl_m`` and the
  standard deviations.
* KML 2.2 with the Google extensions: a styled ``LineString`` and a ``gx:Track`` (one
  ``when`` in UTC, one ``gx:coord`` and one ``gx:angles`` heading/tilt/roll per sample) that
  Google Earth's time slider replays, altitudes ``absolute`` (above mean sea level:
  ellipsoidal height minus the flight's geoid undulation, refused when unknown), and one
  labelled placemark per event (lift-off, touchdown, exceedances, outages...).
* CZML (Cesium): a document packet and one aircraft packet with sampled positions
  (cartographic degrees, ellipsoidal height) and the track as a path.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq

from flightrecon.errors import OutputError
from flightrecon.export.atomic import atomic_path


def escape(text: str) -> str:
    """``&``, ``<`` and ``>`` as XML entities (:func:`xml.sax.saxutils.escape`, imported only
    when a KML is written: it pulls in ``urllib`` and ``ssl``)."""
    from xml.sax.saxutils import escape as xml_escape

    return xml_escape(text)


FORMATS = ("csv", "parquet", "geojson", "kml", "czml")
_SUFFIX = {".csv": "csv", ".parquet": "parquet", ".pq": "parquet", ".geojson": "geojson",
           ".json": "geojson", ".kml": "kml", ".czml": "czml"}
#: the suffix a format is written with
SUFFIX_OF = {"csv": ".csv", "parquet": ".parquet", "geojson": ".geojson", "kml": ".kml",
             "czml": ".czml"}
METADATA_KEY = b"flightrecon"


def format_from_path(path: str | Path, fmt: str | None = None) -> str:
    """The output format: ``fmt`` if given, else from the suffix of ``path``.

    Raises
    ------
    OutputError
        If ``fmt`` is unknown, if the suffix tells no format and ``fmt`` is not given, or if
        the suffix names another format than ``fmt`` (``out.parquet`` with ``kml``).
    """
    suffix = Path(path).suffix.lower()
    if fmt:
        fmt = fmt.lower()
        if fmt not in FORMATS:
            raise OutputError(f"unknown output format '{fmt}' (choose from {', '.join(FORMATS)})")
        if suffix in _SUFFIX and _SUFFIX[suffix] != fmt:
            raise OutputError(f"the suffix '{suffix}' says {_SUFFIX[suffix]} but the format "
                              f"asked for is {fmt}: use {SUFFIX_OF[fmt]} or drop --format",
                              file=str(path))
        return fmt
    if suffix not in _SUFFIX:
        raise OutputError(f"cannot tell the output format from the suffix '{suffix}' "
                          "(use .csv, .parquet, .geojson, .kml or .czml, or --format)",
                          file=str(path))
    return _SUFFIX[suffix]


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.floating,)):
        return None if not np.isfinite(o) else float(o)
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def _clean_json(o: Any) -> Any:
    """Replace non-finite floats by None so the JSON is standard (RFC 8259)."""
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if isinstance(o, Mapping):
        return {str(k): _clean_json(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [_clean_json(v) for v in o]
    if isinstance(o, np.ndarray):
        return _clean_json(o.tolist())
    if isinstance(o, np.floating):
        return _clean_json(float(o))
    return o


def to_json(obj: Any) -> str:
    """Standard JSON (no NaN/Infinity), indented."""
    return json.dumps(_clean_json(obj), indent=2, default=_json_default, allow_nan=False)


def write_summary(path: str | Path, summary: Mapping[str, Any]) -> Path:
    """Write the summary JSON atomically."""
    text = to_json(summary) + "\n"
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_csv(path: str | Path, track: pd.DataFrame,
              metadata: Mapping[str, Any] | None = None) -> Path:
    """Write ``track`` as CSV; with ``metadata`` (the summary) add ``time_utc`` and
    ``alt_msl_m`` (:func:`with_utc_and_msl`)."""
    if metadata:
        track = with_utc_and_msl(track, metadata)
    with atomic_path(path) as tmp:
        track.to_csv(tmp, index=False, float_format="%.10g")
    return Path(path)


def _flight(metadata: Mapping[str, Any] | None) -> Mapping[str, Any]:
    fl = metadata.get("flight") if isinstance(metadata, Mapping) else None
    return fl if isinstance(fl, Mapping) else {}


def utc_strings(t_s: np.ndarray, epoch_utc: str | None) -> np.ndarray | None:
    """ISO-8601 UTC texts (milliseconds, ``Z``) of ``t_s`` seconds after ``epoch_utc``."""
    from flightrecon.events import parse_epoch

    t0 = parse_epoch(epoch_utc)
    if t0 is None:
        return None
    base = np.datetime64(t0.replace(tzinfo=None), "ms")
    t = np.asarray(t_s, float)
    ok = np.isfinite(t)
    out = np.full(len(t), "", dtype=object)
    stamps = base + (t[ok] * 1000.0).round().astype("timedelta64[ms]")
    out[ok] = np.char.add(np.datetime_as_string(stamps, unit="ms"), "Z")
    return out


def with_utc_and_msl(track: pd.DataFrame, metadata: Mapping[str, Any]) -> pd.DataFrame:
    """``track`` with ``time_utc`` after ``t_s`` (when the epoch is known) and ``alt_msl_m``
    after ``alt_m`` (ellipsoidal height minus the flight's geoid undulation, when known)."""
    fl = _flight(metadata)
    out = track.copy()
    if "t_s" in out.columns and "time_utc" not in out.columns:
        utc = utc_strings(out["t_s"].to_numpy(float), fl.get("epoch_utc"))
        if utc is not None:
            out.insert(out.columns.get_loc("t_s") + 1, "time_utc", utc)
    n = fl.get("geoid_undulation_m")
    if "alt_m" in out.columns and "alt_msl_m" not in out.columns and isinstance(n, (int, float)):
        out.insert(out.columns.get_loc("alt_m") + 1, "alt_msl_m",
                   out["alt_m"].to_numpy(float) - float(n))
    return out


def write_parquet(path: str | Path, track: pd.DataFrame, metadata: Mapping[str, Any]) -> Path:
    """Write ``track`` as Parquet with the ``flightrecon`` metadata block (module docstring).

    Snappy-compressed (the Parquet default).  Dictionary encoding is used only for the
    non-floating columns (``source``, ``up_source``, ``provenance``: a handful of distinct
    texts); measured floating-point columns have almost no repeated values, so a dictionary
    there costs time (it is built, then abandoned page by page) and saves nothing: on a
    576 000-row result the write takes 0.4 s instead of 0.9 s and the file is 6 % smaller.
    The pandas metadata is kept, so :func:`pandas.read_parquet` restores the same columns and
    dtypes.
    """
    table = pa.Table.from_pandas(track, preserve_index=False)
    md = dict(table.schema.metadata or {})
    md[METADATA_KEY] = to_json(metadata).encode("utf-8")
    table = table.replace_schema_metadata(md)
    dictionary = [f.name for f in table.schema if not pa.types.is_floating(f.type)]
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp, use_dictionary=dictionary)
    return Path(path)


def read_parquet_metadata(path: str | Path) -> dict[str, Any]:
    """The ``flightrecon`` metadata block of a result Parquet file."""
    md = pq.read_schema(path).metadata or {}
    if METADATA_KEY not in md:
        return {}
    return json.loads(md[METADATA_KEY].decode("utf-8"))


def _thin_index(n: int, max_points: int) -> np.ndarray:
    if n <= max_points:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, max_points).round().astype(int))


def _sd_columns(track: pd.DataFrame) -> list[str]:
    return [c for c in track.columns if "_sd_" in c and not c.startswith(("sabziev_", "arms_",
                                                                            "azimuth_", "sns_"))]


def _geo_rows(track: pd.DataFrame) -> pd.DataFrame:
    for c in ("lat_deg", "lon_deg", "alt_m"):
        if c not in track.columns:
            raise OutputError(f"the result has no '{c}' column: cannot write a map format")
    ok = np.isfinite(track[["lat_deg", "lon_deg", "alt_m"]].to_numpy()).all(axis=1)
    return track.loc[ok]


def write_geojson(path: str | Path, track: pd.DataFrame, properties: Mapping[str, Any],
                  max_points: int = 2000, metadata: Mapping[str, Any] | None = None) -> Path:
    """RFC 7946 FeatureCollection: the track as a LineString plus thinned Point features
    carrying ``t_s``, ``time_utc`` and ``alt_msl_m`` (when the summary gives the epoch and the
    geoid undulation) and the standard deviations."""
    rows = _geo_rows(track)
    if metadata:
        rows = with_utc_and_msl(rows, metadata)
    coords = np.round(rows[["lon_deg", "lat_deg", "alt_m"]].to_numpy(), 8).tolist()
    sd_cols = _sd_columns(rows)
    features = [{
        "type": "Feature",
        "geometry": {"type": "LineString", "coordinates": coords},
        "properties": {**_clean_json(dict(properties)), "height_datum": "WGS-84 ellipsoid"},
    }]
    extra = [c for c in ("time_utc", "alt_msl_m", "source") if c in rows.columns]
    for i in _thin_index(len(rows), max_points):
        r = rows.iloc[i]
        props: dict[str, Any] = {"t_s": float(r["t_s"])}
        for c in extra:
            props[c] = str(r[c]) if c != "alt_msl_m" else float(r[c])
        for c in sd_cols:
            props[c] = float(r[c])
        features.append({"type": "Feature",
                         "geometry": {"type": "Point",
                                      "coordinates": [round(float(r["lon_deg"]), 8),
                                                      round(float(r["lat_deg"]), 8),
                                                      round(float(r["alt_m"]), 3)]},
                         "properties": _clean_json(props)})
    doc = {"type": "FeatureCollection", "features": features}
    text = json.dumps(doc, allow_nan=False)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


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


def _geoid_or_refuse(metadata: Mapping[str, Any] | None, geoid_undulation_m: float | None,
                     what: str) -> float:
    if geoid_undulation_m is not None:
        return float(geoid_undulation_m)
    n = _flight(metadata).get("geoid_undulation_m")
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


#: the KML styles: the line, the aircraft, and the events by severity
_KML_STYLES = (
    '<Style id="line"><LineStyle><color>ff0080ff</color><width>3</width></LineStyle>'
    "</Style>"
    '<Style id="aircraft"><IconStyle><scale>1.1</scale><Icon><href>'
    "http://maps.google.com/mapfiles/kml/shapes/airports.png</href></Icon></IconStyle>"
    "<LineStyle><color>ff00ffff</color><width>2</width></LineStyle></Style>"
    + "".join(f'<Style id="event-{sev}"><IconStyle><color>{col}</color><scale>0.9</scale>'
              "</IconStyle><LabelStyle><scale>0.8</scale></LabelStyle></Style>"
              for sev, col in (("info", "ff00ff00"), ("caution", "ff00c0ff"),
                               ("warning", "ff0000ff"))))


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
    n_geoid = _geoid_or_refuse(metadata, geoid_undulation_m, "KML")
    rows = _geo_rows(track)
    rows = rows.iloc[_thin_index(len(rows), max_samples)]
    lat, lon = rows["lat_deg"].to_numpy(float), rows["lon_deg"].to_numpy(float)
    alt_msl = rows["alt_m"].to_numpy(float) - n_geoid
    t = rows["t_s"].to_numpy(float)
    coords = " ".join(f"{lo:.7f},{la:.7f},{h:.1f}" for lo, la, h in zip(lon, lat, alt_msl))
    fl = _flight(metadata)
    utc = utc_strings(t, fl.get("epoch_utc"))
    heading, pitch, roll, angle_source = track_angles(rows, attitude)
    thinned = len(rows) < len(_geo_rows(track))
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

    fl = _flight(metadata)
    utc = utc_strings(np.zeros(1), fl.get("epoch_utc"))
    if utc is None:
        raise MetadataError("CZML needs the flight's UTC epoch (the summary's flight.epoch_utc)")
    rows = _geo_rows(track)
    rows = rows.iloc[_thin_index(len(rows), max_samples)]
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
    text = json.dumps(_clean_json(doc), allow_nan=False)
    with atomic_path(path) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(path)


def write_track(path: str | Path, track: pd.DataFrame, metadata: Mapping[str, Any],
                fmt: str | None = None, *, attitude: pd.DataFrame | None = None,
                geoid_undulation_m: float | None = None) -> Path:
    """Write ``track`` in the format chosen by ``fmt`` or the suffix of ``path``.

    ``metadata`` is the summary (may be empty for a bare CSV result: then no UTC time and no
    MSL altitude are added, and KML is refused unless ``geoid_undulation_m`` is given);
    ``attitude`` the recorder's attitude for the KML replay.
    """
    fmt = format_from_path(path, fmt)
    if fmt == "csv":
        return write_csv(path, track, metadata)
    if fmt == "parquet":
        return write_parquet(path, track, metadata)
    flight = _flight(metadata)
    name = str(flight.get("flight_id") or Path(path).stem)
    if geoid_undulation_m is not None:
        metadata = {**metadata, "flight": {**flight, "geoid_undulation_m": geoid_undulation_m}}
    if fmt == "geojson":
        return write_geojson(path, track, {"name": name, "flight": flight}, metadata=metadata)
    if fmt == "czml":
        return write_czml(path, track, name, metadata)
    return write_kml(path, track, name, geoid_undulation_m, metadata=metadata,
                     attitude=attitude)


def read_track(path: str | Path) -> tuple[pd.DataFrame, dict[str, Any]]:
    """Read a result written by :func:`write_track` (CSV or Parquet) with its metadata."""
    from flightrecon.errors import InputFileError

    p = Path(path)
    if not p.is_file():
        raise InputFileError("no such result file", file=str(p))
    try:
        if p.suffix.lower() in (".parquet", ".pq"):
            return pd.read_parquet(p), read_parquet_metadata(p)
        if p.suffix.lower() == ".csv":
            return pd.read_csv(p), {}
    except (OSError, ValueError, pa.ArrowException) as exc:
        raise InputFileError(f"cannot read result: {exc}", file=str(p)) from exc
    raise InputFileError("a result to convert must be .csv or .parquet", file=str(p))
