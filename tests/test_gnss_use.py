"""The analyst's GNSS options (flightrecon/ingest/gnss_use.py, docs/ingest.md "Using the
GNSS"): withheld windows, an interval, the receiver's sd, from the keyword, the sidecar and the
command line."""

from __future__ import annotations

import json
import shutil
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flightrecon.errors import MetadataError
from flightrecon.ingest import load_flight
from flightrecon.ingest.gnss_quality import M_PER_DEG
from flightrecon.ingest.gnss_use import (
    GnssUse,
    interval_slots,
    parse_gnss_sd,
    parse_window,
)
from tests._cli import run_cli
from tests.test_ingest_support import load_quiet

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"
#: 'circuit': one GNSS fix a second at t = 0, 1, ..., 900 s (901 fixes)
CIRCUIT = SAMPLES / "circuit.csv"


def _fix_times(fl) -> np.ndarray:
    d = fl.data
    return d["t_s"].to_numpy()[np.isfinite(d["gnss_lat_deg"].to_numpy())]


def test_slots_keep_the_whole_seconds_of_a_10_hz_frame_summed_in_floats():
    """A 10 Hz clock summed from 0.1 s steps writes 0.99999999 for 1 s: the slots (which start
    1 ms early) still keep exactly the fixes nearest each whole second, one per second."""
    t = np.cumsum(np.full(1000, 0.1)) - 0.1          # 0, 0.1, ... as a recorder adds them
    assert not np.all(np.abs(t - np.round(t)) == 0.0)   # the float sum is not exact
    keep = interval_slots(t, np.ones(t.size, bool), 1.0)
    kept = t[keep]
    assert kept.size == 100
    np.testing.assert_allclose(kept, np.arange(100.0), atol=1e-9)


def test_interval_windows_and_record_on_circuit():
    """Every 2 s: the fixes at even seconds (451 of 901); a window 100..200 s then withholds
    the 51 even seconds inside it (ends included); the record says so, count by count."""
    use = GnssUse(withhold_s=((100.0, 200.0),), interval_s=2.0)
    fl, _ = load_quiet(CIRCUIT, gnss_use=use)
    tf = _fix_times(fl)
    expect = np.array([s for s in range(0, 901, 2) if not 100 <= s <= 200], float)
    np.testing.assert_array_equal(tf, expect)
    rec = fl.meta.ingest.gnss_use
    assert rec["fixes_read"] == 901 and rec["interval_dropped"] == 450
    assert rec["withheld_windows"] == [{"start_s": 100.0, "end_s": 200.0, "fixes_withheld": 51}]
    assert rec["fixes_used"] == 400 == tf.size
    # every GNSS channel of a withheld fix goes, not only the position
    d = fl.data
    assert np.isfinite(d["gnss_vn_mps"].to_numpy()).sum() == 400


def test_a_window_without_fixes_warns_and_withholds_nothing():
    """A window outside the record is a mistake the tool can only guess at: a warning, no
    refusal, every fix kept."""
    fl, warns = load_quiet(CIRCUIT, gnss_use=GnssUse(withhold_s=((5000.0, 6000.0),)))
    assert _fix_times(fl).size == 901
    assert any("5000..6000 s" in w and "no fix lies there" in w for w in warns)


def _rounded_copy(tmp_path: Path) -> Path:
    """'circuit' as an export keeping 0.001 deg of latitude, 0.0001 deg of longitude and the
    GNSS height in whole tens of feet (its sidecar beside it)."""
    df = pd.read_csv(CIRCUIT)
    df["gnss_lat_deg"] = df["gnss_lat_deg"].round(3)
    df["gnss_lon_deg"] = df["gnss_lon_deg"].round(4)
    df["gnss_alt_m"] = (df["gnss_alt_m"] / 3.048).round() * 3.048
    out = tmp_path / "rounded.csv"
    df.to_csv(out, index=False)
    shutil.copy(SAMPLES / "circuit.meta.toml", tmp_path / "rounded.meta.toml")
    return out


def test_receiver_sd_given_and_the_rounding_added_per_axis(tmp_path):
    """--gnss-sd 14:20 on an export rounded to 0.001 deg (111 m: sd 32.1 m) and 10 ft (3.05 m:
    sd 0.88 m): horizontal hypot(14, 32.1), vertical hypot(20, 0.88), on every fix; the
    record names what was given and what was added."""
    log = _rounded_copy(tmp_path)
    fl, _ = load_quiet(log, gnss_use=GnssUse(h_sd_m=14.0, v_sd_m=20.0))
    d = fl.data
    fix = np.isfinite(d["gnss_lat_deg"].to_numpy())
    r_h = 0.001 * M_PER_DEG / np.sqrt(12.0)
    r_v = 3.048 / np.sqrt(12.0)
    # the detected step is the smallest difference of the recorded values: equal to the
    # nominal one to the float rounding of the CSV (1e-9 relative)
    np.testing.assert_allclose(d["gnss_h_sd_m"].to_numpy()[fix], np.hypot(14.0, r_h),
                               rtol=1e-6)
    np.testing.assert_allclose(d["gnss_v_sd_m"].to_numpy()[fix], np.hypot(20.0, r_v),
                               rtol=1e-6)
    rec = fl.meta.ingest.gnss_use
    assert rec["given_h_sd_m"] == 14.0 and rec["given_v_sd_m"] == 20.0
    assert rec["rounding_h_sd_m"] == pytest.approx(r_h, rel=1e-6)
    assert rec["rounding_v_sd_m"] == pytest.approx(r_v, rel=1e-6)
    # without the option: the rounding on the tool's default receiver figure (3 m)
    fl0, _ = load_quiet(log)
    np.testing.assert_allclose(fl0.data["gnss_h_sd_m"].to_numpy()[fix], np.hypot(3.0, r_h),
                               rtol=1e-6)


def test_user_sd_wins_over_the_log_figure_with_a_note(tmp_path):
    """A log recording its own sd (50 m): the user's 7 m replaces it on every fix, and the
    note says it replaced the log's."""
    df = pd.read_csv(CIRCUIT)
    df["gnss_h_sd_m"] = np.where(df["gnss_lat_deg"].notna(), 50.0, np.nan)
    log = tmp_path / "withsd.csv"
    df.to_csv(log, index=False)
    shutil.copy(SAMPLES / "circuit.meta.toml", tmp_path / "withsd.meta.toml")
    fl, _ = load_quiet(log, gnss_use=GnssUse(h_sd_m=7.0))
    sd = fl.data["gnss_h_sd_m"].dropna().to_numpy()
    assert sd.size == 901 and np.all(sd == 7.0)
    assert any("in place of the log's (recorded) on 901" in n
               for n in fl.meta.ingest.notes)


def test_sidecar_gnss_table_and_the_keyword_wins_option_by_option(tmp_path):
    """The sidecar's [gnss] says every 2 s and 50 m; the keyword says 7 m: every 2 s (the
    sidecar's) with 7 m (the keyword's)."""
    shutil.copy(CIRCUIT, tmp_path / "c.csv")
    side = (SAMPLES / "circuit.meta.toml").read_text()
    (tmp_path / "c.meta.toml").write_text(side + "\n[gnss]\ninterval_s = 2.0\nh_sd_m = 50.0\n")
    fl, _ = load_quiet(tmp_path / "c.csv")
    assert _fix_times(fl).size == 451
    assert set(fl.data["gnss_h_sd_m"].dropna()) == {50.0}
    fl, _ = load_quiet(tmp_path / "c.csv", gnss_use=GnssUse(h_sd_m=7.0))
    assert _fix_times(fl).size == 451
    assert set(fl.data["gnss_h_sd_m"].dropna()) == {7.0}
    (tmp_path / "c.meta.toml").write_text(side + "\n[gnss]\ninterval_s = -1\n")
    with pytest.raises(MetadataError, match="interval_s"):
        load_quiet(tmp_path / "c.csv")


def test_old_withhold_key_still_works_with_a_deprecation_warning():
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        fl = load_flight(CIRCUIT, meta_overrides={"withhold_gnss": True})
    assert any(x.category is DeprecationWarning and "gnss_use" in str(x.message) for x in w)
    assert not [c for c in fl.data.columns if c.startswith("gnss_")]


def test_option_parsers():
    assert parse_window("10:20.5") == (10.0, 20.5)
    assert parse_gnss_sd("14") == (14.0, None)
    assert parse_gnss_sd("14:20") == (14.0, 20.0)
    for bad in ("20:10", "1", "a:b", "1:2:3"):
        with pytest.raises(MetadataError):
            parse_window(bad)
    for bad in ("0", "-3", "x", "1:2:3"):
        with pytest.raises(MetadataError):
            parse_gnss_sd(bad)


def test_cli_options_reach_the_summary(tmp_path):
    """reconstruct --withhold-gnss 300:400 --gnss-interval 2 --gnss-sd 6: the summary's
    measurements record the options and their counts (even seconds 0..900 without 300..400:
    400 fixes); a reversed window is a usage error (exit 2)."""
    out = tmp_path / "r.csv"
    code = run_cli(["reconstruct", str(CIRCUIT), "--methods", "sns", "--withhold-gnss",
                    "300:400", "--gnss-interval", "2", "--gnss-sd", "6", "-o", str(out)])
    assert code == 0
    summ = json.loads((tmp_path / "r.summary.json").read_text())
    use = summ["measurements"]["gnss_use"]
    assert use["options"]["withhold_s"] == [[300.0, 400.0]]
    assert use["options"]["interval_s"] == 2.0 and use["given_h_sd_m"] == 6.0
    assert use["withheld_windows"][0]["fixes_withheld"] == 51
    assert use["fixes_used"] == 400 == summ["measurements"]["gnss_fixes"]
    assert any(e["action"] == "gnss_use" for e in summ["cleaning"]["report"])
    assert run_cli(["reconstruct", str(CIRCUIT), "--withhold-gnss", "400:300",
                    "-o", str(tmp_path / "x.csv")]) == 2


def test_clean_and_info_take_the_same_gnss_options(tmp_path, capsys):
    """clean and info read the log with the same options as reconstruct: --gnss-interval 2 and
    a withheld window leave 400 of the 901 fixes in the cleaned GNSS table and in info's
    count; --no-gnss none; a bad --gnss-sd is a usage error (exit 2)."""
    out = tmp_path / "c.parquet"
    assert run_cli(["clean", str(CIRCUIT), "--withhold-gnss", "300:400", "--gnss-interval",
                    "2", "-o", str(out)]) == 0
    assert len(pd.read_parquet(tmp_path / "c.gnss.parquet")) == 400
    assert run_cli(["clean", str(CIRCUIT), "--no-gnss", "-o",
                    str(tmp_path / "n.parquet")]) == 0
    assert not (tmp_path / "n.gnss.parquet").exists() or len(
        pd.read_parquet(tmp_path / "n.gnss.parquet")) == 0
    # the withheld columns are not "ignored columns not in the schema" (the run's warnings
    # are in its report)
    report = json.loads((tmp_path / "n.cleaning.json").read_text())
    assert not any("not in the schema" in w for w in report["warnings"])
    capsys.readouterr()
    assert run_cli(["info", str(CIRCUIT), "--json", "--withhold-gnss", "300:400",
                    "--gnss-interval", "2"]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["channels"]["gnss_lat_deg"]["samples"] == 400
    assert run_cli(["info", str(CIRCUIT), "--gnss-sd", "-1"]) == 2


def test_batch_gnss_options_reach_every_flight_and_its_key(tmp_path):
    """batch --no-gnss reconstructs each flight without its fixes (the summary's measurements
    say 0 used) and the settings' key changes with the GNSS options (a re-run with other
    options redoes the flights), not with the default options."""
    from flightrecon.batch.manifest import settings_key
    from flightrecon.pipeline import ReconstructSettings

    s = ReconstructSettings()
    assert settings_key(s, "csv", None, GnssUse()) == settings_key(s, "csv", None)
    assert settings_key(s, "csv", None, GnssUse(withhold=True)) != settings_key(s, "csv", None)
    logs = tmp_path / "logs"
    logs.mkdir()
    shutil.copy(CIRCUIT, logs / "circuit.csv")
    shutil.copy(SAMPLES / "circuit.meta.toml", logs / "circuit.meta.toml")
    out = tmp_path / "out"
    assert run_cli(["-q", "batch", str(logs), "--out", str(out), "--workers", "1",
                    "--methods", "sabziev", "--no-gnss", "--format", "csv"]) == 0
    summ = json.loads(next(out.rglob("*.summary.json")).read_text())
    assert summ["measurements"]["gnss_fixes"] == 0
    assert summ["measurements"]["gnss_use"]["options"]["withhold"] is True
    assert summ["methods"]["sns"]["reason"].startswith("the GNSS withheld")
    assert summ["methods"]["joint"]["reason"].startswith("not among the methods asked for")
