"""Replay exports: KML opens as a time-animated track (gx:Track, one UTC ``when``, one
``gx:coord`` and one ``gx:angles`` per sample), events as a few labelled placemarks; CSV and
GeoJSON carry UTC time and MSL altitude; CZML for Cesium; a KML without a known geoid
undulation is refused."""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from _cli import run_cli

from flightrecon.errors import MetadataError, OutputError
from flightrecon.events import Event, events_table
from flightrecon.export.replay import track_angles, write_kml
from flightrecon.export.writers import format_from_path, write_track

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_logs"
KML = "{http://www.opengis.net/kml/2.2}"
GX = "{http://www.google.com/kml/ext/2.2}"
EPOCH = "2026-01-01T10:00:00Z"


def track(n=400, dt=0.5):
    """A level coordinated turn at 100 m/s, 3 deg/s, 1000 m ellipsoidal height."""
    t = np.arange(n) * dt
    psi = np.radians(3.0) * t
    v = 100.0
    vn, ve = v * np.cos(psi), v * np.sin(psi)
    r = v / np.radians(3.0)
    north, east = r * np.sin(psi), r * (1 - np.cos(psi))
    lat = 40.0 + north / 111_000.0
    lon = 50.0 + east / (111_000.0 * np.cos(np.radians(40.0)))
    return pd.DataFrame({"t_s": t, "north_m": north, "east_m": east, "up_m": 1000.0 + 0 * t,
                         "lat_deg": lat, "lon_deg": lon, "alt_m": 1000.0 + 0 * t,
                         "vn_mps": vn, "ve_mps": ve, "vu_mps": 0 * t,
                         "north_sd_m": 5 + 0 * t, "east_sd_m": 5 + 0 * t})


def summary():
    ev = [Event("liftoff", 10.0, "lift-off", "lift-off"),
          Event("exceedance", 50.0, "bank +50 deg", "bank", end_t_s=60.0, severity="alert"),
          Event("fixes", 0.0, "200 GNSS fixes", "fixes", end_t_s=199.5)]
    return {"flight": {"flight_id": "F1", "epoch_utc": EPOCH, "geoid_undulation_m": -22.0},
            "events": events_table(ev, EPOCH)}


def test_kml_is_a_time_animated_track(tmp_path):
    tr = track()
    p = write_kml(tmp_path / "t.kml", tr, "F1", metadata=summary())
    root = ET.parse(p).getroot()
    gx = root.find(f".//{GX}Track")
    whens = [w.text for w in gx.findall(f"{KML}when")]
    coords = [c.text.split() for c in gx.findall(f"{GX}coord")]
    angles = [a.text.split() for a in gx.findall(f"{GX}angles")]
    assert len(whens) == len(coords) == len(angles) == len(tr)
    t0 = datetime.fromisoformat(EPOCH.replace("Z", "+00:00"))
    parsed = [datetime.fromisoformat(w.replace("Z", "+00:00")) for w in whens]
    assert all(w.endswith("Z") for w in whens)
    assert parsed[0] == t0 and parsed[-1] == t0 + timedelta(seconds=float(tr["t_s"].iloc[-1]))
    assert all(b > a for a, b in zip(parsed, parsed[1:]))
    # altitude above MSL: 1000 m ellipsoidal minus the undulation -22 m
    assert float(coords[100][2]) == pytest.approx(1022.0)
    assert gx.find(f"{KML}altitudeMode").text == "absolute"
    # heading follows the turn, bank of a 3 deg/s turn at 100 m/s: atan(v w / g) = 28.1 deg
    h, tilt, roll = (float(x) for x in angles[100])
    assert h == pytest.approx(np.degrees(np.radians(3.0) * tr["t_s"].iloc[100]) % 360, abs=0.2)
    assert tilt == pytest.approx(0.0, abs=0.1) and roll == pytest.approx(28.1, abs=0.3)
    # a styled line, a few labelled events (no pushpin per sample)
    assert root.find(f".//{KML}Style/{KML}LineStyle/{KML}width") is not None
    names = [pm.find(f"{KML}name").text for pm in root.iter(f"{KML}Placemark")]
    assert "1. lift-off" in names and "2. bank +50 deg" in names
    assert len(names) == 2 + 2  # line, replay, two events (the fixes span is not a pin)


def test_kml_uses_the_recorded_attitude_when_given(tmp_path):
    tr = track(20)
    att = pd.DataFrame({"t_s": tr["t_s"], "heading_deg": 355.0 + 0 * tr["t_s"],
                        "pitch_deg": 4.0 + 0 * tr["t_s"], "roll_deg": -10.0 + 0 * tr["t_s"]})
    p = write_kml(tmp_path / "a.kml", tr, "F1", metadata=summary(), attitude=att)
    angles = [a.text for a in ET.parse(p).getroot().iter(f"{GX}angles")]
    assert angles[0] == "355.0 4.0 -10.0" and len(angles) == 20


def test_track_angles_heading_wraps():
    tr = track(300)  # 450 deg of turn
    h, _, _, source = track_angles(tr)
    assert np.all((h >= 0) & (h < 360)) and h.max() > 350 and "derived" in source


def test_kml_refuses_an_unknown_geoid_undulation(tmp_path):
    tr = track(10)
    with pytest.raises(MetadataError, match="geoid undulation"):
        write_track(tmp_path / "x.kml", tr, {})
    assert not (tmp_path / "x.kml").exists()
    write_track(tmp_path / "x.kml", tr, {}, geoid_undulation_m=0.0)
    text = (tmp_path / "x.kml").read_text()
    assert "No replay" in text and "gx:Track" not in text  # no epoch: no invented times


def test_csv_and_geojson_gain_utc_and_msl(tmp_path):
    tr = track(30)
    write_track(tmp_path / "t.csv", tr, summary())
    df = pd.read_csv(tmp_path / "t.csv")
    cols = list(df.columns)
    assert cols[cols.index("t_s") + 1] == "time_utc" and cols[cols.index("alt_m") + 1] == \
        "alt_msl_m"
    assert df["time_utc"].iloc[3] == "2026-01-01T10:00:01.500Z"
    np.testing.assert_allclose(df["alt_msl_m"], 1022.0)
    write_track(tmp_path / "t.geojson", tr, summary())
    doc = json.loads((tmp_path / "t.geojson").read_text())
    props = doc["features"][1]["properties"]
    assert props["time_utc"] == "2026-01-01T10:00:00.000Z" and props["alt_msl_m"] == 1022.0


def test_czml(tmp_path):
    tr = track(10)
    write_track(tmp_path / "t.czml", tr, summary())
    doc = json.loads((tmp_path / "t.czml").read_text())
    assert doc[0]["id"] == "document" and doc[0]["clock"]["interval"].startswith(
        "2026-01-01T10:00:00.000Z/")
    pos = doc[1]["position"]
    assert pos["epoch"] == EPOCH and len(pos["cartographicDegrees"]) == 4 * len(tr)


def test_suffix_contradicting_the_format_is_refused():
    with pytest.raises(OutputError, match="says parquet"):
        format_from_path("out.parquet", "kml")
    assert format_from_path("out.kml", "kml") == "kml"
    assert format_from_path("out.data", "kml") == "kml"  # an unknown suffix does not contradict


def test_reconstruct_to_kml_end_to_end(tmp_path):
    out = tmp_path / "c.kml"
    assert run_cli(["reconstruct", str(SAMPLES / "circuit.parquet"), "-o", str(out),
                    "--methods", "sabziev"]) == 0
    res = tmp_path / "c.parquet"
    assert run_cli(["export", str(tmp_path / "c.kml"), "-o", str(res)]) == 3  # not a result
    assert run_cli(["reconstruct", str(SAMPLES / "circuit.parquet"), "-o", str(res),
                    "--methods", "sabziev"]) == 0
    df = pd.read_parquet(res)
    summ = json.loads((tmp_path / "c.summary.json").read_text())
    n_geo = int(np.isfinite(df[["lat_deg", "lon_deg", "alt_m"]].to_numpy()).all(axis=1).sum())
    root = ET.parse(out).getroot()
    gx = root.find(f".//{GX}Track")
    n = len(gx.findall(f"{KML}when"))
    # one when / coord / angles per sample with a position (the Sabziev track starts at the
    # take-off roll)
    assert n == n_geo == len(gx.findall(f"{GX}angles")) == len(gx.findall(f"{GX}coord"))
    assert n > 0.8 * len(df)
    assert "recorded attitude" in root.find(f"{KML}Document/{KML}description").text
    names = [pm.find(f"{KML}name").text for pm in root.iter(f"{KML}Placemark")]
    assert any("lift-off" in s for s in names) and len(names) < 20
    # the summary lists the events with their UTC time
    lift = next(e for e in summ["events"] if e["kind"] == "liftoff")
    assert lift["utc"] == "2026-01-01T10:01:13.750Z" and lift["t_s"] == 73.75
