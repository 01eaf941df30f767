"""End to end: the CLI on the shipped sample logs, every output format, errors and safety."""

from __future__ import annotations

import json
import re
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from _cli import run_cli

from flightrecon.export.writers import read_parquet_metadata

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_logs"


def sample_logs() -> list[Path]:
    logs = sorted(p for p in SAMPLES.glob("*.parquet")
                  if not re.search(r"\.(truth|recon|gnss|radar)\b", p.name))
    return logs


@pytest.fixture(scope="module")
def circuit_result(tmp_path_factory):
    d = tmp_path_factory.mktemp("circuit")
    out = d / "circuit.recon.parquet"
    code = run_cli(["reconstruct", str(SAMPLES / "circuit.parquet"), "-o", str(out)])
    assert code == 0
    return out


def test_sample_logs_exist():
    names = {p.stem for p in sample_logs()}
    assert {"circuit", "regional", "seed-ads-arms", "landing"} <= names


@pytest.mark.parametrize("log", sample_logs(), ids=lambda p: p.stem)
def test_reconstruct_every_sample(log, tmp_path):
    out = tmp_path / f"{log.stem}.csv"
    code = run_cli(["reconstruct", str(log), "-o", str(out)])
    assert code == 0
    df = pd.read_csv(out)
    for c in ("t_s", "north_m", "east_m", "up_m", "lat_deg", "lon_deg", "alt_m", "source"):
        assert c in df.columns
    summ = json.loads((tmp_path / f"{log.stem}.summary.json").read_text())
    assert summ["schema_version"] == 1
    assert any(m.get("status") == "ok" for m in summ["methods"].values())
    truth_p = log.with_name(log.stem + ".truth.parquet")
    if truth_p.exists():
        truth = pd.read_parquet(truth_p)
        m = pd.DataFrame({"t_s": df["t_s"]}).merge(truth[["t_s", "north_m", "east_m"]], on="t_s",
                                                   how="left")
        err = np.hypot(df["north_m"] - m["north_m"], df["east_m"] - m["east_m"])
        ok = np.isfinite(err)
        assert ok.sum() > 0.5 * len(df)
        # the default track is within 2 km of truth on every sample log (loose: a sanity
        # bound across methods; per-method accuracy is tested against truth elsewhere)
        assert np.nanmax(err) < 2000.0


def test_parquet_metadata_and_round_trip(circuit_result, tmp_path):
    md = read_parquet_metadata(circuit_result)
    assert md["software"]["name"] == "flightrecon"
    assert all(len(i["sha256"]) == 64 for i in md["inputs"])
    csv = tmp_path / "c.csv"
    assert run_cli(["export", str(circuit_result), "-o", str(csv)]) == 0
    a = pd.read_parquet(circuit_result)
    b = pd.read_csv(csv)
    num = [c for c in a.columns if a[c].dtype.kind == "f"]
    np.testing.assert_allclose(b[num].to_numpy(), a[num].to_numpy(), rtol=1e-9, atol=1e-9)


def test_geojson_and_kml_exports(circuit_result, tmp_path):
    gj = tmp_path / "c.geojson"
    assert run_cli(["export", str(circuit_result), "-o", str(gj)]) == 0
    doc = json.loads(gj.read_text())
    assert doc["type"] == "FeatureCollection"
    lon, lat, _ = doc["features"][0]["geometry"]["coordinates"][0]
    assert -180 <= lon <= 180 and -90 <= lat <= 90
    kml = tmp_path / "c.kml"
    assert run_cli(["export", str(circuit_result), "--format", "kml", "-o", str(kml)]) == 0
    root = ET.parse(kml).getroot()
    coords = root.find(".//{http://www.opengis.net/kml/2.2}coordinates").text.split()
    assert len(coords[0].split(",")) == 3


def test_report_html_self_contained(tmp_path):
    rep = tmp_path / "rep"
    out = tmp_path / "r.parquet"
    assert run_cli(["reconstruct", str(SAMPLES / "circuit.parquet"), "-o", str(out),
                    "--report", str(rep)]) == 0
    html = (rep / "report.html").read_text()
    assert "data:image/png;base64," in html
    assert not re.search(r'(src|href)="(?!data:)', html)


def test_never_overwrites_input(tmp_path):
    src = SAMPLES / "circuit.parquet"
    log = tmp_path / "c.parquet"
    log.write_bytes(src.read_bytes())
    for ext in (".meta.toml",):
        side = src.with_name("circuit" + ext)
        if side.exists():
            (tmp_path / ("c" + ext)).write_bytes(side.read_bytes())
    before = log.read_bytes()
    assert run_cli(["reconstruct", str(log), "-o", str(log)]) == 9
    assert log.read_bytes() == before


def test_missing_file_exit_code(tmp_path):
    assert run_cli(["reconstruct", str(tmp_path / "nope.parquet")]) == 3


def test_workers_option_gives_the_same_file(tmp_path):
    """--workers 1 and --workers 2 write the same track (threads change only the timing)."""
    log = SAMPLES / "circuit.parquet"
    a, b = tmp_path / "a.parquet", tmp_path / "b.parquet"
    assert run_cli(["reconstruct", str(log), "-o", str(a), "--workers", "1"]) == 0
    assert run_cli(["reconstruct", str(log), "-o", str(b), "--workers", "2"]) == 0
    pd.testing.assert_frame_equal(pd.read_parquet(a), pd.read_parquet(b), check_exact=True)
    assert run_cli(["reconstruct", str(log), "-o", str(a), "--workers", "0"]) == 2


def test_noise_file_overrides_the_joint_budget(tmp_path):
    """--noise FILE: its [joint] values reach the smoother (the summary echoes them); an unknown
    key, a zero standard deviation or a non-number is a metadata error (exit 7) naming the file."""
    noise = tmp_path / "n.toml"
    noise.write_text("[joint]\ntas_mps = 0.4\nairspeed_lag_s = 0.5\ntouchdown_m = 350\n")
    out = tmp_path / "c.csv"
    code = run_cli(["reconstruct", str(SAMPLES / "circuit.parquet"), "-o", str(out),
                    "--methods", "joint", "--noise", str(noise)])
    assert code == 0
    summ = json.loads((tmp_path / "c.summary.json").read_text())
    used = summ["methods"]["joint"]["settings"]["noise"]
    assert (used["tas_mps"], used["airspeed_lag_s"], used["touchdown_m"]) == (0.4, 0.5, 350.0)
    for body in ("tas_mps = 0\n", "tas_mps = \"fast\"\n", "no_such_setting = 1.0\n"):
        noise.write_text("[joint]\n" + body)
        assert run_cli(["reconstruct", str(SAMPLES / "circuit.parquet"), "-o",
                        str(tmp_path / "d.csv"), "--noise", str(noise)]) == 7
        assert not (tmp_path / "d.csv").exists()


def test_a_zero_noise_setting_is_refused_by_the_library():
    from flightrecon.methods.joint import JointNoise

    with pytest.raises(ValueError, match="'gnss_h_m' must be a positive number"):
        JointNoise(gnss_h_m=0.0)
    assert JointNoise(airspeed_lag_s=0.0).airspeed_lag_s == 0.0   # a lag may be zero
