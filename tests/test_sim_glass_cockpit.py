"""A simulated flight written as a Garmin glass-cockpit CSV (flightrecon/sim/glass_cockpit.py)
reads back as recorded through the built-in Garmin reader, with the recorder's values."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flightrecon.constants import FOOT_M, KNOT_MPS
from flightrecon.ingest import load_flight
from flightrecon.ingest.garmin import pressure_altitude_from_indicated
from flightrecon.sim.glass_cockpit import (
    INHG_PA,
    glass_cockpit_export,
    glass_cockpit_text,
    indicated_from_pressure_altitude,
    write_glass_cockpit,
)

UTC_OFFSET_MIN = -300


@pytest.fixture(scope="module")
def circuit():
    pytest.importorskip("jsbsim")
    from flightrecon.sim import simulate

    return simulate("jsbsim-circuit", 1, airframe="c172p")


@pytest.fixture(scope="module")
def exported(circuit, tmp_path_factory):
    path = tmp_path_factory.mktemp("g1000") / "circuit.csv"
    write_glass_cockpit(circuit, path, utc_offset_min=UTC_OFFSET_MIN)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        flight = load_flight(path)
    return path, flight


def _log_at(log: pd.DataFrame, t: np.ndarray, c: str) -> np.ndarray:
    """The simulated log's channel ``c`` at the whole seconds ``t`` (its own samples)."""
    s = log.dropna(subset=[c]).set_index("t_s")[c]
    return s.reindex(t).to_numpy(float)


def test_indicated_altitude_inverts_the_readers_pressure_altitude():
    h = np.array([-100.0, 0.0, 500.0, 3000.0, 9000.0])
    setting = np.full(h.size, 1023.25e2)
    ind = indicated_from_pressure_altitude(h, setting)
    assert np.allclose(pressure_altitude_from_indicated(ind, setting), h, atol=1e-6)
    # a QNH 10 hPa above standard reads about 270 ft (82 m) above the pressure altitude
    assert ind[1] - h[1] == pytest.approx(10 * 27 * FOOT_M, rel=0.03)


def test_file_has_the_avionics_three_line_structure(exported):
    path, _ = exported
    lines = Path(path).read_text().splitlines()
    assert lines[0].startswith("#airframe_info, log_version=")
    assert lines[1].startswith("#yyy-mm-dd, hh:mm:ss,")
    header = [c.strip() for c in lines[2].split(",")]
    units = [u.strip() for u in lines[1].lstrip("#").split(",")]
    assert len(units) == len(header)
    assert dict(zip(header, units))["AltGPS"] == "ft wgs"
    for c in ("Lcl Date", "Lcl Time", "UTCOfst", "Latitude", "Longitude", "AltInd", "BaroA",
              "AltMSL", "OAT", "IAS", "GndSpd", "VSpd", "Pitch", "Roll", "LatAc", "NormAc",
              "HDG", "TRK", "AltGPS", "TAS", "MagVar", "GPSfix"):
        assert c in header
    assert not {"LonAc", "LongAc", "n_long_g"} & set(header)
    first = [c.strip() for c in lines[3].split(",")]
    assert first[header.index("UTCOfst")] == "-05:00"
    assert first[header.index("Lcl Time")] == "05:00:00"  # 10:00:00 UTC at -5 h


def test_reads_back_as_recorded(circuit, exported):
    _, flight = exported
    d = flight.data
    log = circuit.log
    t = d["t_s"].to_numpy(float)
    # whole seconds of the simulated epoch (the sidecar's), one a second
    assert np.allclose(t, np.round(t)) and np.all(np.diff(t) == 1.0)
    assert flight.meta.epoch_utc == circuit.meta.epoch_utc
    assert t[0] == 0.0 and t[-1] == np.floor(log["t_s"].max())

    # heading: magnetic in the file, back to true within the two 0.1-deg roundings
    hdg = _log_at(log, t, "heading_deg")
    dh = (d["heading_deg"].to_numpy(float) - hdg + 180.0) % 360.0 - 180.0
    assert np.nanmax(np.abs(dh)) <= 0.11
    raw = pd.read_csv(exported[0], skiprows=[0, 1], skipinitialspace=True)
    assert 5.0 < raw["MagVar"].abs().min()  # 6.5 deg east there: a wrong sign would show
    dmag = (raw["HDG"].to_numpy(float) - hdg + 180.0) % 360.0 - 180.0
    assert np.allclose(dmag, -raw["MagVar"].to_numpy(float), atol=0.11)

    # pressure altitude through the altimeter at the QNH setting, 0.1 ft written
    assert raw["BaroA"].iloc[0] == pytest.approx(circuit.meta.qnh_departure_hpa * 100 / INHG_PA,
                                                 abs=0.005)
    assert (raw["AltInd"] - d["baro_alt_m"] / FOOT_M).median() > 250  # QNH 1024 hPa
    assert np.nanmax(np.abs(d["baro_alt_m"] - _log_at(log, t, "baro_alt_m"))) < 0.05
    # loads: NormAc = n - 1, 0.01 g written
    assert np.nanmax(np.abs(d["n_norm_g"] - _log_at(log, t, "n_norm_g"))) <= 0.0051
    assert np.nanmax(np.abs(d["n_lat_g"] - _log_at(log, t, "n_lat_g"))) <= 0.0051
    assert abs(float(raw["NormAc"].median())) < 0.05
    for c in ("roll_deg", "pitch_deg"):
        assert np.nanmax(np.abs(d[c] - _log_at(log, t, c))) <= 0.0051
    assert np.nanmax(np.abs(d["tas_mps"] - _log_at(log, t, "tas_mps"))) <= 0.51 * KNOT_MPS
    assert np.nanmax(np.abs(d["sat_degc"] - _log_at(log, t, "sat_degc"))) <= 0.051
    # no longitudinal channel in the file: derived by the reader
    assert "n_long_g" in flight.meta.ingest.derived_channels

    # GNSS: the log's fixes, ellipsoidal height, velocity from GndSpd along TRK + MagVar
    for c, tol in (("gnss_lat_deg", 6e-8), ("gnss_lon_deg", 6e-8), ("gnss_alt_m", 0.02)):
        assert np.nanmax(np.abs(d[c] - _log_at(log, t, c))) <= tol
    fast = np.hypot(_log_at(log, t, "gnss_vn_mps"), _log_at(log, t, "gnss_ve_mps")) > 20
    for c in ("gnss_vn_mps", "gnss_ve_mps"):
        assert np.nanmax(np.abs(d[c] - _log_at(log, t, c))[fast]) < 0.12
    assert set(np.unique(d["gnss_quality"].dropna())) == {1.0}


def test_missing_fixes_are_written_as_no_solution(circuit):
    log = circuit.log.copy()
    gcols = [c for c in log.columns if c.startswith("gnss_")]
    log.loc[(log.t_s > 100.5) & (log.t_s < 140.5), gcols] = np.nan
    whole = glass_cockpit_export(circuit.log, circuit.truth, circuit.meta)
    ex = glass_cockpit_export(log, circuit.truth, circuit.meta)
    t = np.arange(len(ex))
    gap = (t > 100) & (t < 141)
    assert (whole["GPSfix"][gap] == "3D").all()
    assert (ex["GPSfix"][gap] == "NoSoln").all() and (ex["Latitude"][gap] == "").all()
    assert (ex[~gap] == whole[~gap]).all().all()
    text = glass_cockpit_text(ex)
    assert text.count("NoSoln") == int((ex["GPSfix"] == "NoSoln").sum()) > int(gap.sum()) - 1


def test_simulate_writes_the_garmin_export_beside_the_log(tmp_path):
    """``flightrecon simulate --export garmin`` writes ``<stem>.garmin.csv`` and its sidecar
    beside the log, byte for byte :func:`write_glass_cockpit` of the same flight, and the
    export reads back through ``load_flight`` without a mapping with the sidecar's runways:
    one row a whole second over the log, the heading back to the log's within the two 0.1-deg
    roundings (magnetic in the file, the variation written beside it).  The point-mass
    circuit: no JSBSim needed."""
    from _cli import run_cli

    from flightrecon.sim import simulate

    log = tmp_path / "c.parquet"
    assert run_cli(["simulate", "circuit", "--seed", "3", "--export", "garmin",
                    "-o", str(log)]) == 0
    ex, side = tmp_path / "c.garmin.csv", tmp_path / "c.garmin.meta.toml"
    assert ex.exists() and side.exists()
    r = simulate("circuit", 3)
    write_glass_cockpit(r, tmp_path / "direct.csv")
    assert ex.read_bytes() == (tmp_path / "direct.csv").read_bytes()
    assert side.read_bytes() == (tmp_path / "direct.meta.toml").read_bytes()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        flight = load_flight(ex)
    t = flight.data["t_s"].to_numpy(float)
    assert np.all(np.diff(t) == 1.0) and t[-1] == np.floor(r.log["t_s"].max())
    assert flight.meta.departure is not None and flight.meta.departure.runway_true_deg == \
        r.meta.departure.runway_true_deg
    dh = (flight.data["heading_deg"].to_numpy(float) - _log_at(r.log, t, "heading_deg")
          + 180.0) % 360.0 - 180.0
    assert np.nanmax(np.abs(dh)) <= 0.11


def test_fleet_study_on_one_circuit(tmp_path):
    """``scripts/onehz_fleet_study.py`` at reduced size: one circuit, recorder only and a
    120-s gap, within the bars of issue #36 item 5 (docs/tables/onehz_fleet.md: 0.71, gap 0.12,
    NEES at most 1.8)."""
    pytest.importorskip("jsbsim")
    from tests._scripts import load_script

    study = load_script("onehz_fleet_study")
    r = study.one_flight("jsbsim-circuit", "c172p", 1, tmp_path)
    ro = r["recorder_only"]
    assert ro["health"]["healthy"]
    assert ro["ratio_to_dr"] < study.BAR_RECORDER
    assert max(ro["joint"][f"nees_{a}"] for a in "neu") < study.BAR_NEES
    assert [g["length_s"] for g in r["gaps"]] == [120.0]  # 402 s airborne: no room for 300 s
    g = r["gaps"][0]
    assert g["ratio_to_dr"] < study.BAR_GAP
    assert max(g[f"nees_{a}"] for a in "neu") < study.BAR_NEES
    assert g["with_gps"]["rms_h_m"] < 5.0
    md = study.markdown([r], [1])
    assert "jsbsim-circuit c172p s1 | 402 |" in md and " **x** |" not in md
