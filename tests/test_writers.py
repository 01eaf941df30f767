"""Export formats: CSV/Parquet round trip with metadata, GeoJSON structure, KML as XML."""

import json
import xml.etree.ElementTree as ET

import numpy as np
import pandas as pd
import pytest

from flightrecon.errors import OutputError
from flightrecon.export.writers import (
    format_from_path,
    read_parquet_metadata,
    read_track,
    write_summary,
    write_track,
)


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
        if name == "r.csv":  # CSV adds the MSL altitude (the geoid undulation is known; no epoch)
            assert [c for c in back.columns if c not in track.columns] == ["alt_msl_m"]
            np.testing.assert_allclose(back["alt_msl_m"], track["alt_m"] + 20.0)
            back = back[list(track.columns)]
        pd.testing.assert_frame_equal(back.drop(columns="source"), track.drop(columns="source"),
                                      check_dtype=False, rtol=1e-9)
        assert list(back.columns) == list(track.columns)
    assert read_parquet_metadata(tmp_path / "r.parquet")["inputs"][0]["sha256"] == "00"


def test_parquet_is_exact_with_dictionary_only_on_text(tmp_path, track):
    """The Parquet result reads back bit for bit with the same dtypes (the text column
    included); only the text column is dictionary-encoded and the codec is Snappy."""
    import pyarrow.parquet as pq

    p = write_track(tmp_path / "r.parquet", track, META)
    back = pd.read_parquet(p)
    pd.testing.assert_frame_equal(back, track, check_exact=True)
    md = pq.ParquetFile(p).metadata
    for i in range(md.num_columns):
        col = md.row_group(0).column(i)
        dictionary = any("DICTIONARY" in e for e in col.encodings)
        assert dictionary == (col.path_in_schema == "source"), col.path_in_schema
        assert col.compression == "SNAPPY"
        assert col.statistics is not None


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


def test_combine_assembles_the_result_table():
    """``pipeline.combine``: horizontal source by priority, vertical source joint > sabziev >
    baro; where the joint smoother gives no height, up and its vertical velocity equal the
    conversion of the heights done on *every* sample (the conversion is restricted to those
    samples and their neighbours), bit for bit; lat/lon/alt are the tangent-plane position
    converted back; the method columns follow and the table is its own (editing it leaves the
    method's track unchanged)."""
    from flightrecon.geo.atmosphere import isa_pressure_pa, pressure_altitude_m
    from flightrecon.geo.frames import output_plane
    from flightrecon.pipeline import combine
    from flightrecon.tracks import plane_up_of_height
    from flightrecon.types import CleanFlight, FlightMeta, MethodResult, Position

    n = 400
    t = np.arange(n) * 0.25
    meta = FlightMeta(departure=Position(40.0, 49.0, 10.0), qnh_departure_hpa=1013.25)
    baro = 10.0 + 0.5 * t  # pressure altitude [m]
    grid = pd.DataFrame({"t_s": t, "baro_alt_m": baro})
    clean = CleanFlight(grid=grid, rate_hz=4.0, gnss=pd.DataFrame({"t_s": []}),
                        radar=pd.DataFrame({"t_s": []}), meta=meta)
    north, east = 250.0 * t * 3, -120.0 * t * 3  # reaches 75 km: the plane leaves the ellipsoid

    def track(name, **extra):
        cols = {"t_s": t, f"{name}_north_m": north + 1.0, f"{name}_east_m": east - 1.0}
        for q in ("north_sd_m", "east_sd_m", "vn_mps", "vn_sd_mps", "ve_mps", "ve_sd_mps"):
            cols[f"{name}_{q}"] = np.full(n, 2.0)
        cols.update(extra)
        return pd.DataFrame(cols)

    j = track("joint")
    j.loc[100:140, ["joint_north_m", "joint_east_m"]] = np.nan
    j_up = 30.0 + t
    j_up[50:80] = np.nan
    j_up[390:] = np.nan
    j_up[0] = np.nan
    for c, v in (("up_m", j_up), ("up_sd_m", 1.0), ("vu_mps", 4.0), ("vu_sd_mps", 0.1),
                 ("wind_n_mps", 3.0), ("wind_e_mps", -2.0), ("wind_n_sd_mps", 0.5),
                 ("wind_e_sd_mps", 0.5)):
        j[f"joint_{c}"] = v
    j["joint_sources"] = pd.array(["air+gnss_pos"] * n, dtype="string")
    sab_up = 20.0 + 0.4 * t
    sab_up[60:70] = np.nan
    # the fusion's own vertical is its height above the departure airfield
    sab = track("sabziev", sabziev_height_m=sab_up, sabziev_up_sd_m=np.full(n, 5.0))
    results = {"joint": MethodResult("joint", j, {}), "sns": MethodResult("sns", track("sns"), {}),
               "sabziev": MethodResult("sabziev", sab, {})}
    # a method with a hole in its track is never healthy (issue #39): by its own verdict
    # the joint feeds nothing; with the verdicts given, the per-sample fill is tested
    assert set(combine(clean, results)["source"].dropna()) == {"sns"}
    out = combine(clean, results, healthy={"joint": True, "sns": True, "sabziev": True})

    src = np.where(np.isnan(j["joint_north_m"].to_numpy()), "sns", "joint")
    np.testing.assert_array_equal(out["source"].to_numpy(dtype=object), src)
    j_ok = np.isfinite(j_up)
    h_field = float(pressure_altitude_m(isa_pressure_pa(10.0)))
    height = np.where(np.isfinite(sab_up), sab_up, baro - h_field)
    ups = np.where(j_ok, "joint", np.where(np.isfinite(sab_up), "sabziev", "baro"))
    np.testing.assert_array_equal(out["up_source"].to_numpy(dtype=object), ups)
    plane = output_plane(meta)
    e, nn = out["east_m"].to_numpy(), out["north_m"].to_numpy()
    up_all = plane_up_of_height(plane, e, nn, height)[0]
    assert np.nanmax(np.abs(up_all - height)) > 100.0  # the conversion matters here
    np.testing.assert_array_equal(out["up_m"].to_numpy()[~j_ok], up_all[~j_ok])
    np.testing.assert_array_equal(out["up_m"].to_numpy()[j_ok], j_up[j_ok])
    vu_all = np.gradient(up_all) / np.gradient(t)
    np.testing.assert_array_equal(out["vu_mps"].to_numpy()[~j_ok], vu_all[~j_ok])
    lat, lon, alt = plane.inverse(e, nn, out["up_m"].to_numpy())
    np.testing.assert_array_equal(out["alt_m"].to_numpy(), alt)
    np.testing.assert_array_equal(out["lat_deg"].to_numpy(), lat)
    np.testing.assert_array_equal(out["lon_deg"].to_numpy(), lon)
    assert list(out.columns[-len(sab.columns) - len(results["sns"].track.columns) + 2:]) == [
        c for m in ("sabziev", "sns") for c in results[m].track.columns if c != "t_s"]
    assert str(out["provenance"].dtype) == "str" and out["provenance"].iloc[0] == "air+gnss_pos"
    out.loc[0, "sns_north_m"] = -1.0
    out.loc[0, "t_s"] = -1.0
    assert results["sns"].track["sns_north_m"].iloc[0] == north[0] + 1.0
    assert grid["t_s"].iloc[0] == 0.0


def test_a_position_without_a_height_keeps_its_latitude_and_longitude():
    """No departure airfield for the pressure altitude and no healthy height (the joint
    unhealthy): the default result had NaN latitude and longitude under a finite north/east.
    Now they are the plane's position at its own height; alt_m stays unknown."""
    from flightrecon.pipeline import combine
    from flightrecon.types import CleanFlight, FlightMeta, MethodResult, Position

    n = 200
    t = np.arange(n) * 0.5
    meta = FlightMeta(origin=Position(40.0, 49.0, 10.0))
    grid = pd.DataFrame({"t_s": t, "baro_alt_m": 500.0 + t})
    clean = CleanFlight(grid=grid, rate_hz=2.0, gnss=pd.DataFrame({"t_s": []}),
                        radar=pd.DataFrame({"t_s": []}), meta=meta)
    tr = pd.DataFrame({"t_s": t, "sns_north_m": 60.0 * t, "sns_east_m": 10.0 * t,
                       "sns_north_sd_m": 5.0, "sns_east_sd_m": 5.0})
    out = combine(clean, {"sns": MethodResult("sns", tr, {})}, healthy={"sns": True})
    assert np.isfinite(out[["lat_deg", "lon_deg"]].to_numpy()).all()
    assert out["alt_m"].isna().all()
    # 6 km north of the origin: 0.054 deg of latitude
    assert abs(out["lat_deg"].iloc[-1] - (40.0 + 60.0 * t[-1] / 111_000.0)) < 2e-3
