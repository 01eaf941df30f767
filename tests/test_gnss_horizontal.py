"""GNSS as receivers write it: fixes without height, per-fix accuracy, quality flags, SNS noise
overrides.  The Monte Carlo is scripts/mc_gnss_horizontal.py (40 runs,
docs/tables/gnss_horizontal_mc.md); here it runs at 3 runs."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from _scripts import load_script

from flightrecon.errors import MetadataError
from flightrecon.ingest import load_flight
from flightrecon.ingest.gnss_quality import R95_PER_SD, accuracy_from_dop
from flightrecon.methods.sns import MODEL_AIRSPEED, default_noise
from flightrecon.methods.sns.method import sns_noise_with
from flightrecon.pipeline import ReconstructSettings, reconstruct

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"


def test_horizontal_fixes_within_fix_accuracy_reduced_mc():
    """3 runs (the full study: 40).  Outside the dropout, the horizontal error of the joint
    smoother and of SNS with lat/lon-only fixes is within the fixes' 2-D RMS accuracy
    (2.83 m), and the joint track moves by under 0.1 m against the same fixes with heights
    (measured: 0.001 m).  The joint smoother used exactly 2/3 of the position scalars (north
    and east, no down)."""
    mc = load_script("mc_gnss_horizontal")
    rows = [mc.one_run(mc.SEED0 + i) for i in range(3)]
    fix = np.sqrt(2.0) * rows[0]["fix_h_sd_m"]
    for r in rows:
        h, w = r["horizontal"], r["with_height"]
        assert h["joint_rms_h_m"] < fix and h["sns_rms_h_m"] < fix, r
        assert abs(h["joint_rms_h_m"] - w["joint_rms_h_m"]) < 0.1
        assert abs(h["sns_rms_h_m"] - w["sns_rms_h_m"]) < 0.1
        assert h["joint_gnss_pos_used"] * 3 == w["joint_gnss_pos_used"] * 2


def _lat_lon_only(tmp: Path, extra: dict | None = None) -> Path:
    d = pd.read_csv(SAMPLES / "circuit.csv").drop(columns=["gnss_alt_m"])
    for k, v in (extra or {}).items():
        d[k] = np.where(d["gnss_lat_deg"].notna(), v, np.nan)
    log = tmp / "c.csv"
    d.to_csv(log, index=False)
    (tmp / "c.meta.toml").write_text((SAMPLES / "circuit.meta.toml").read_text())
    return log


def test_reconstruct_with_lat_lon_only(tmp_path):
    """The whole pipeline on circuit.csv without gnss_alt_m: joint and SNS ok, SNS says it
    used the fixes horizontally, the vertical comes from the pressure altitude."""
    rec = reconstruct(_lat_lon_only(tmp_path), settings=ReconstructSettings(
        methods=("joint", "sns")), record=False)
    st = rec.summary["methods"]
    assert st["joint"]["status"] == "ok" and st["sns"]["status"] == "ok"
    assert any("without height used horizontally" in n for n in st["sns"].get("notes", []))
    tr = pd.read_parquet(SAMPLES / "circuit.truth.parquet")
    t = rec.track["t_s"].to_numpy()
    air = ~np.interp(t, tr.t_s, tr.on_ground.astype(float)).astype(bool)
    from flightrecon.geo.frames import output_plane

    e, n, u = output_plane(rec.clean.meta).forward(tr.lat_deg.to_numpy(), tr.lon_deg.to_numpy(),
                                                   tr.alt_m.to_numpy())
    dh = np.hypot(rec.track["north_m"] - np.interp(t, tr.t_s, n),
                  rec.track["east_m"] - np.interp(t, tr.t_s, e))[air]
    du = (rec.track["up_m"] - np.interp(t, tr.t_s, u))[air]
    assert np.sqrt(np.mean(dh ** 2)) < 3.0
    assert np.sqrt(np.mean(du ** 2)) < 15.0   # pressure altitude only: baro errors


def test_hdop_nacp_conversion():
    sd = accuracy_from_dop(np.array([1.0, np.nan, 2.0]), np.array([9.0, 10.0, 0.0]), 3)
    assert sd[0] == pytest.approx(3.0 / np.sqrt(2.0))          # HDOP wins where given
    assert sd[1] == pytest.approx(10.0 / R95_PER_SD)           # NACp 10: EPU < 10 m
    assert sd[2] == pytest.approx(2 * 3.0 / np.sqrt(2.0))
    assert R95_PER_SD == pytest.approx(2.4477, abs=1e-4)
    assert np.isnan(accuracy_from_dop(None, np.array([0.0]), 1)[0])   # NACp 0: unknown


def test_quality_flags_and_hdop_at_ingest(tmp_path):
    d = pd.read_csv(SAMPLES / "circuit.csv")
    fix = np.flatnonzero(d["gnss_lat_deg"].notna().to_numpy())
    d["gnss_quality"] = np.where(d["gnss_lat_deg"].notna(), 1.0, np.nan)
    d.loc[fix[10:13], "gnss_quality"] = 0.0        # invalid
    d.loc[fix[20], "gnss_quality"] = 6.0           # estimated (dead reckoning)
    d["gnss_hdop"] = np.where(d["gnss_lat_deg"].notna(), 1.2, np.nan)
    d.to_csv(tmp_path / "q.csv", index=False)
    (tmp_path / "q.meta.toml").write_text((SAMPLES / "circuit.meta.toml").read_text())
    with pytest.warns(Warning, match="fix quality 0, 6"):
        fl = load_flight(tmp_path / "q.csv")
    masked = fl.data["gnss_lat_deg"].to_numpy()[fix[[10, 11, 12, 20]]]
    assert np.isnan(masked).all()
    (rep,) = [r for r in fl.meta.ingest.repairs if r["channel"] == "gnss_quality"]
    assert rep["count"] == 4 and rep["rows"] == [int(i) + 1 for i in fix[[10, 11, 12, 20]]]
    sd = fl.data["gnss_h_sd_m"].to_numpy()[fix]
    assert np.allclose(sd, 1.2 * 3.0 / np.sqrt(2.0))


def test_per_fix_accuracy_changes_the_weight(tmp_path):
    """Fixes declared 10x less accurate than the default: the joint track's reported sd grows."""
    s = ReconstructSettings(methods=("joint",))
    a = reconstruct(_lat_lon_only(tmp_path), settings=s, record=False)
    b = reconstruct(_lat_lon_only(tmp_path, {"gnss_h_sd_m": 50.0}), settings=s, record=False)
    sa = np.nanmedian(a.track["north_sd_m"])
    sb = np.nanmedian(b.track["north_sd_m"])
    assert sb > 3.0 * sa, (sa, sb)


def test_sns_noise_overrides():
    nz = sns_noise_with(MODEL_AIRSPEED, {"pos_sd_m": 1.5, "heading_sd_deg": 0.3})
    d = default_noise(MODEL_AIRSPEED)
    assert nz.pos_sd_m == 1.5 and nz.sensor_sd[1] == pytest.approx(np.radians(0.3))
    assert nz.sensor_sd[0] == d.sensor_sd[0] and nz.vel_sd_mps == d.vel_sd_mps
    with pytest.raises(MetadataError, match="unknown SNS noise setting"):
        sns_noise_with(MODEL_AIRSPEED, {"pos_sd": 1.0})
    with pytest.raises(MetadataError, match="positive"):
        sns_noise_with(MODEL_AIRSPEED, {"pos_sd_m": 0.0})
