"""GNSS fixes as exports write them (issue #35 item 5): positions rounded to a few digits get
their rounding in the fix sd, and a fix repeated at the recorder's rate is used once."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from flightrecon.ingest import load_flight
from flightrecon.ingest.gnss_quality import recording_step

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"


def _load(path: Path):
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        fl = load_flight(path)
    return fl, [str(x.message) for x in w]


def _circuit(tmp_path: Path, name: str, df: pd.DataFrame) -> Path:
    p = tmp_path / f"{name}.parquet"
    df.to_parquet(p)
    (tmp_path / f"{name}.meta.toml").write_text((SAMPLES / "circuit.meta.toml").read_text())
    return p


def test_recording_step_finds_the_digits_kept():
    rng = np.random.default_rng(0)
    x = 51.9 + np.cumsum(rng.uniform(0, 0.003, 500))
    assert recording_step(np.round(x, 3)) is not None
    assert abs(recording_step(np.round(x, 3)) - 0.001) < 1e-9
    assert recording_step(x) is None          # full precision: no step


def test_latitude_in_steps_of_111_m_gets_its_rounding_in_the_fix_sd(tmp_path):
    """Five significant digits (0.001 deg of latitude = 111 m): sd 111/sqrt(12) = 32 m added
    in quadrature to the receiver's 3 m; the full-precision log keeps no figure."""
    d = pd.read_parquet(SAMPLES / "circuit.parquet")
    fl, _ = _load(_circuit(tmp_path, "full", d))
    assert "gnss_h_sd_m" not in fl.data.columns
    d["gnss_lat_deg"] = d["gnss_lat_deg"].round(3)
    fl, _ = _load(_circuit(tmp_path, "rounded", d))
    sd = fl.data["gnss_h_sd_m"].dropna().to_numpy()
    want = np.hypot(3.0, 0.001 * 111_320.0 / np.sqrt(12.0))
    assert sd.size == fl.data["gnss_lat_deg"].notna().sum()
    np.testing.assert_allclose(sd, want, rtol=1e-6)
    assert any("recorded in steps" in n for n in fl.meta.ingest.notes)


def test_a_fix_written_again_at_the_recorders_rate_is_used_once(tmp_path):
    """A 1 Hz receiver on a 16 Hz frame (each fix on every row until the next): the repeats
    are masked and reported; the first row of each fix keeps it."""
    d = pd.read_parquet(SAMPLES / "circuit.parquet")
    fix = d["gnss_lat_deg"].notna().to_numpy()
    n_fix = int(fix.sum())
    for c in ("gnss_lat_deg", "gnss_lon_deg", "gnss_alt_m", "gnss_vn_mps", "gnss_ve_mps"):
        d[c] = d[c].ffill()
    fl, warns = _load(_circuit(tmp_path, "held", d))
    kept = fl.data["gnss_lat_deg"].notna().to_numpy()
    assert abs(int(kept.sum()) - n_fix) <= 1
    assert any("same position written again" in w for w in warns), warns
