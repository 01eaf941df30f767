"""Scenarios, files and CLI of the simulator: schema-valid logs, the sidecar format shared
with ingest, byte-identical output for one seed, fleets."""

from __future__ import annotations

import json
import tomllib

import numpy as np
import pytest
from click.testing import CliRunner

from flightrecon.errors import ValidationError
from flightrecon.schema import BY_NAME, REQUIRED
from flightrecon.sim import simulate, simulate_fleet, write_simulation
from flightrecon.sim.scenarios import SCENARIOS


@pytest.mark.parametrize("name", ["circuit", "regional", "seed-ads-arms", "landing"])
def test_scenario_log_is_schema_valid(name):
    r = simulate(name, seed=1)
    log = r.log
    assert log.columns[0] == "t_s"
    assert set(REQUIRED) <= set(log.columns)
    assert set(log.columns) <= set(BY_NAME)
    assert np.all(np.diff(log.t_s.to_numpy()) > 0)
    for c in log.columns:
        v = log[c].dropna().to_numpy()
        ch = BY_NAME[c]
        assert v.size > 0, c
        assert v.min() >= ch.lo and v.max() <= ch.hi, c
    assert r.meta.departure is not None and r.meta.arrival is not None
    if name in ("seed-ads-arms", "landing"):
        assert r.meta.station is not None
        assert log.arms_range_m.notna().sum() > 100
    assert r.truth.columns[0] == "t_s"
    json.dumps(r.sensor_truth, allow_nan=False)


def test_regional_properties():
    """Two airfields about 300 km apart, about 1 h, a GNSS dropout, wind varying with height."""
    from pyproj import Geod
    r = simulate("regional", seed=0)
    m = r.meta
    d = Geod(ellps="WGS84").inv(m.departure.lon_deg, m.departure.lat_deg, m.arrival.lon_deg,
                                m.arrival.lat_deg)[2]
    assert 250e3 < d < 400e3
    assert r.truth.t_s.iloc[-1] == pytest.approx(3600.0)
    g = r.log.dropna(subset=["gnss_lat_deg"])
    assert not ((g.t_s >= 1500) & (g.t_s < 2100)).any()
    tr = r.truth
    w = np.hypot(tr.wind_n_mps, tr.wind_e_mps)
    assert w[tr.alt_msl_m > 4000].mean() > w[tr.alt_msl_m < 500].mean() + 10
    assert m.qnh_departure_hpa != m.qnh_arrival_hpa
    assert (tr.pressure_alt_m - tr.alt_msl_m).abs().max() > 100  # non-standard atmosphere


def test_same_seed_byte_identical_files(tmp_path):
    for sub in ("a", "b"):
        (tmp_path / sub).mkdir()
        r = simulate("landing", seed=5)
        write_simulation(r, tmp_path / sub / "x.parquet")
        write_simulation(r, tmp_path / sub / "x.csv")
    names = sorted(p.name for p in (tmp_path / "a").iterdir())
    assert names == ["x.csv", "x.meta.toml", "x.parquet", "x.sensors.json", "x.truth.parquet"]
    for n in names:
        assert (tmp_path / "a" / n).read_bytes() == (tmp_path / "b" / n).read_bytes(), n
    other = simulate("landing", seed=6)
    write_simulation(other, tmp_path / "c.parquet")
    assert (tmp_path / "c.parquet").read_bytes() != (tmp_path / "a" / "x.parquet").read_bytes()


def test_sidecar_format(tmp_path):
    r = simulate("seed-ads-arms", seed=0)
    write_simulation(r, tmp_path / "s.csv")
    doc = tomllib.loads((tmp_path / "s.meta.toml").read_text())
    assert set(doc) == {"flight", "departure", "arrival", "station"}
    f = doc["flight"]
    assert set(f) == {"aircraft_id", "flight_id", "epoch_utc", "gnss_alt_datum", "baro_datum",
                      "geoid_undulation_m", "gnss_lever_arm_m", "qnh_departure_hpa",
                      "qnh_arrival_hpa"}
    assert f["epoch_utc"].endswith("Z") and len(f["gnss_lever_arm_m"]) == 3
    # this record starts airborne and ends without a landing: no runway directions
    for t in ("departure", "arrival", "station"):
        assert set(doc[t]) == {"lat_deg", "lon_deg", "elev_m"}
    assert doc["station"]["lat_deg"] == pytest.approx(r.meta.station.lat_deg, abs=1e-12)
    # airfields of a take-off and a landing carry the runway's true direction and threshold
    # (as a runway database would), read back by the ingest side unchanged
    from flightrecon.ingest.sidecar import load_sidecar

    c = simulate("circuit", seed=0, duration_s=900.0)
    write_simulation(c, tmp_path / "c.csv")
    doc = tomllib.loads((tmp_path / "c.meta.toml").read_text())
    back = load_sidecar(tmp_path / "c.meta.toml").meta
    for t in ("departure", "arrival"):
        assert set(doc[t]) == {"lat_deg", "lon_deg", "elev_m", "runway_true_deg",
                               "threshold_lat_deg", "threshold_lon_deg"}
        for k in ("runway_true_deg", "threshold_lat_deg", "threshold_lon_deg"):
            assert getattr(getattr(back, t), k) == pytest.approx(getattr(getattr(c.meta, t), k),
                                                                 abs=1e-12)
    assert c.meta.departure.runway_true_deg == pytest.approx(160.0)
    # the circuit's take-off roll starts at the threshold, ARP_OFFSET_M before the reference
    from flightrecon.geo.frames import TangentPlane
    from flightrecon.sim.scenarios import ARP_OFFSET_M

    d = c.meta.departure
    e, n, _ = TangentPlane(d.lat_deg, d.lon_deg).forward(d.threshold_lat_deg,
                                                         d.threshold_lon_deg, 0.0)
    assert float(np.hypot(e, n)) == pytest.approx(ARP_OFFSET_M, abs=0.01)
    assert np.degrees(np.arctan2(-e, -n)) % 360 == pytest.approx(160.0, abs=1e-6)
    sensors = json.loads((tmp_path / "s.sensors.json").read_text())
    assert sensors["airdata_error_gm"]["tau_s"] == 360.0
    import pandas as pd
    log = pd.read_csv(tmp_path / "s.csv")
    assert np.allclose(log.tas_mps, r.log.tas_mps, rtol=1e-9, equal_nan=True)


def test_fleet_shares_persistent_errors():
    flights = simulate_fleet("B7", 2, seed=4)
    a, b = (f.sensor_truth for f in flights)
    assert a["persistent_errors"] == b["persistent_errors"]
    assert a["weather"] != b["weather"]
    assert [f.meta.flight_id for f in flights] == ["F01", "F02"]
    assert {f.meta.aircraft_id for f in flights} == {"B7"}
    assert not np.array_equal(flights[0].log.n_norm_g.to_numpy()[:100],
                              flights[1].log.n_norm_g.to_numpy()[:100])
    other = simulate_fleet("B8", 1, seed=4)[0].sensor_truth
    assert other["persistent_errors"] != a["persistent_errors"]


def test_unknown_scenario_and_override_are_errors():
    with pytest.raises(ValidationError):
        simulate("nope")
    with pytest.raises(ValidationError):
        simulate("circuit", gnss_hzz=2.0)
    with pytest.raises(ValidationError):
        simulate("circuit", gnss_hz=3.0)  # 3 Hz does not divide the 16 Hz truth grid
    with pytest.raises(ValidationError):
        simulate("circuit", seed=-1)


def test_cli_simulate(tmp_path):
    from flightrecon.cli.main import cli
    out = tmp_path / "l.parquet"
    res = CliRunner().invoke(cli, ["simulate", "landing", "--seed", "2", "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert out.exists() and (tmp_path / "l.truth.parquet").exists()
    assert (tmp_path / "l.meta.toml").exists() and (tmp_path / "l.sensors.json").exists()
    res = CliRunner().invoke(cli, ["simulate", "circuit", "--fleet-flights", "2", "-o",
                                   str(tmp_path / "f.csv")])
    assert res.exit_code == 0, res.output
    assert (tmp_path / "f_F01.csv").exists() and (tmp_path / "f_F02.meta.toml").exists()


def test_all_scenarios_registered():
    assert set(SCENARIOS) == {"circuit", "regional", "seed-ads-arms", "landing", "longhaul"}


@pytest.mark.slow
def test_longhaul_size_and_speed():
    """10 h at 16 Hz: 576 000 rows, generated in well under a minute (vectorised)."""
    import time
    t0 = time.process_time()
    r = simulate("longhaul", seed=0)
    assert len(r.truth) == 576_000 and len(r.log) == 576_000
    assert time.process_time() - t0 < 40.0
    assert r.log.gnss_lat_deg.notna().sum() > 34_000


def test_foreign_export_round_trip():
    """Foreign columns convert back exactly: TAS from IAS (cas_to_tas with the row's SAT and
    pressure altitude), true heading = magnetic + WMM declination, feet, flipped lateral sign."""
    from flightrecon.constants import FOOT_M, KNOT_MPS
    from flightrecon.geo.atmosphere import cas_to_tas
    from flightrecon.geo.magnetic import decimal_year, declination_deg
    from flightrecon.sim.foreign import FOREIGN_MAPPING_TOML, foreign_log
    r = simulate("circuit", seed=1, truth_rate_hz=4.0, loads_hz=4.0, attitude_hz=4.0,
                 airspeed_hz=4.0, baro_hz=4.0, gnss_hz=0.0)
    log = r.log.iloc[::40].reset_index(drop=True)  # 91 rows keep the WMM calls cheap
    f = foreign_log(log, r.truth, r.meta.epoch_utc)
    assert list(f.columns) == ["TIME", "VRTG", "LONG", "LATG", "PTCH", "ROLL", "HDG_MAG",
                               "IAS_KT", "ALT_FT", "SAT"]
    tas = cas_to_tas(f.IAS_KT * KNOT_MPS, f.ALT_FT * FOOT_M, f.SAT)
    assert np.allclose(tas, log.tas_mps, rtol=1e-10)
    tr = r.truth.set_index("t_s").loc[log.t_s]
    dec, _ = declination_deg(tr.lat_deg, tr.lon_deg, tr.alt_m, decimal_year(r.meta.epoch_utc))
    hdg = np.mod(f.HDG_MAG + dec, 360.0)
    assert np.allclose(np.angle(np.exp(1j * np.radians(hdg - log.heading_deg))), 0, atol=1e-9)
    assert np.allclose(f.LATG, -log.n_lat_g)
    assert abs(dec).max() > 1.0  # the declination matters at this airfield (about 6.5 deg E)
    doc = tomllib.loads(FOREIGN_MAPPING_TOML)
    assert doc["channels"]["n_lat_g"]["sign"] == -1
    assert doc["channels"]["heading_deg"]["reference"] == "magnetic"
    assert doc["channels"]["tas_mps"] == {"from": "ias"}


@pytest.mark.parametrize("value, words", [("400.0", "[0, 360)"), ('"north"', "number"),
                                          ("-1", "[0, 360)"), ("nan", "number")])
def test_bad_runway_direction_is_a_metadata_error(tmp_path, value, words):
    from flightrecon.errors import MetadataError
    from flightrecon.ingest.sidecar import load_sidecar

    p = tmp_path / "x.meta.toml"
    p.write_text(f"[departure]\nlat_deg = 40.0\nlon_deg = 50.0\nrunway_true_deg = {value}\n")
    with pytest.raises(MetadataError) as exc:
        load_sidecar(p)
    assert words in str(exc.value) and "runway_true_deg" in str(exc.value)


def test_a_station_has_no_runway(tmp_path):
    from flightrecon.errors import MetadataError
    from flightrecon.ingest.sidecar import load_sidecar

    p = tmp_path / "x.meta.toml"
    p.write_text("[station]\nlat_deg = 40.0\nlon_deg = 50.0\nrunway_true_deg = 10.0\n")
    with pytest.raises(MetadataError, match="no runway"):
        load_sidecar(p)


@pytest.mark.parametrize("body, words", [
    ("runway_true_deg = 160.0\nthreshold_lat_deg = 40.005\n", "threshold_lon_deg is missing"),
    ("threshold_lat_deg = 40.005\nthreshold_lon_deg = 50.0\n", "needs the runway's direction"),
    ("runway_true_deg = 160.0\nthreshold_lat_deg = 40.5\nthreshold_lon_deg = 50.0\n",
     "55.5 km from the airfield reference point"),
    ("runway_true_deg = 160.0\nthreshold_lat_deg = 95.0\nthreshold_lon_deg = 50.0\n",
     "outside [-90, 90]"),
])
def test_bad_runway_threshold_is_a_metadata_error(tmp_path, body, words):
    from flightrecon.errors import MetadataError
    from flightrecon.ingest.sidecar import load_sidecar

    p = tmp_path / "x.meta.toml"
    p.write_text("[arrival]\nlat_deg = 40.0\nlon_deg = 50.0\n" + body)
    with pytest.raises(MetadataError) as exc:
        load_sidecar(p)
    assert words in str(exc.value) and "[arrival]" in str(exc.value)


def test_runway_threshold_is_read(tmp_path):
    from flightrecon.ingest.sidecar import load_sidecar

    p = tmp_path / "x.meta.toml"
    p.write_text("[departure]\nlat_deg = 40.0\nlon_deg = 50.0\nrunway_true_deg = 0.0\n"
                 "threshold_lat_deg = 39.993\nthreshold_lon_deg = 50.0\n")
    sc = load_sidecar(p)
    assert sc.meta.departure.threshold == (39.993, 50.0) and not sc.warnings
    p.write_text("[station]\nlat_deg = 40.0\nlon_deg = 50.0\n"
                 "threshold_lat_deg = 39.993\nthreshold_lon_deg = 50.0\n")
    with pytest.raises(Exception, match="no runway"):
        load_sidecar(p)
