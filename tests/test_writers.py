"""Export formats: CSV/Parquet round trip with metadata, GeoJSON structure, KML as XML."""

import json
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest

from flightrecon.errors import OutputError
from flightrecon.export.writers import (format_from_path, read_parquet_metadata, read_track,
                                        write_summary, write_track)


@pytest.fixture
def track():
    n = 500
    t = np.arange(n) * 0.5
    return pd.DataFrame({
        "t_s": t,
        "north_m": 50.0 * t, "north_sd_m": 3.0 + 0 * t,
        "east_m": 10.0 * t, "east_sd_m": 4.0 + 0 * t,
        "up_m": 2.0 * t, "up_sd_m": np.nan,
        "lat_deg": 40.0 + t * 1e-4, "lon_deg": 49.0 + t * 1e-4, "alt_m": 20.0 + t,
        "source": pd.array(["sns"] * n, dtype="string"),
    })


META = {"flight": {"flight_id": "F1", "aircraft_id": "A1", "geoid_undulation_m": -20.0},
        "software": {"version": "x"}, "inputs": [{"path": "a.csv", "sha256": "00"}]}


def test_format_from_suffix():
    assert format_from_path("a.CSV") == "csv"
    assert format_from_path("a.x", "kml") == "kml"
    with pytest.raises(OutputError):
        format_from_path("a.txt")


def test_csv_and_parquet_round_trip(tmp_path, track):
    for name in ("r.csv", "r.parquet"):
        p = write_track(tmp_path / name, track, META)
        back, md = read_track(p)
        pd.testing.assert_frame_equal(back.drop(columns="source"), track.drop(columns="source"),
                                      check_dtype=False, rtol=1e-9)
        assert list(back.columns) == list(track.columns)
    assert read_parquet_metadata(tmp_path / "r.parquet")["inputs"][0]["sha256"] == "00"


def test_geojson_rfc7946_structure(tmp_path, track):
    p = write_track(tmp_path / "r.geojson", track, META)
    doc = json.loads(p.read_text())
    assert doc["type"] == "FeatureCollection"
    line = doc["features"][0]
    assert line["geometry"]["type"] == "LineString"
    lon, lat, h = line["geometry"]["coordinates"][0]  # RFC 7946: lon, lat, height
    assert (lon, lat, h) == (49.0, 40.0, 20.0)
    pts = [f for f in doc["features"] if f["geometry"]["type"] == "Point"]
    assert pts and pts[0]["properties"]["north_sd_m"] == 3.0
    assert pts[0]["properties"]["up_sd_m"] is None  # NaN written as null, never as NaN


def test_kml_parses_with_msl_altitude(tmp_path, track):
    p = write_track(tmp_path / "r.kml", track, META)
    root = ET.parse(p).getroot()
    ns = {"k": "http://www.opengis.net/kml/2.2"}
    coords = root.find(".//k:LineString/k:coordinates", ns).text.split()
    lon, lat, alt = map(float, coords[0].split(","))
    assert (lon, lat) == (49.0, 40.0)
    assert alt == pytest.approx(40.0)  # 20 m ellipsoidal - (-20 m) undulation = 40 m MSL
    assert root.find(".//k:altitudeMode", ns).text == "absolute"


def test_summary_is_standard_json(tmp_path):
    p = write_summary(tmp_path / "s.json", {"x": float("nan"), "k": np.float64(1.5)})
    assert json.loads(p.read_text()) == {"x": None, "k": 1.5}
