"""Joint post-flight smoother against simulated truth (reduced Monte Carlo for CI).

The full study is ``scripts/mc_joint.py`` (tables in docs/tables/joint_mc.md); here one or two
seeds per case, with bounds set well outside what those seeds give so that the test fails on a
real regression (a sign or frame error moves the errors by orders of magnitude) and not on noise.
"""

import importlib.util
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]
_spec = importlib.util.spec_from_file_location("mc_joint", ROOT / "scripts" / "mc_joint.py")
mc = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(mc)


@pytest.fixture(scope="module")
def gnss_run():
    return mc.one_run("gnss", 2001)


def test_gnss_case_accuracy_and_consistency(gnss_run):
    j = gnss_run["joint"]
    # 2 m / 4 m GNSS at 1 Hz with a 2-minute dropout: the smoothed error is about 1 m RMS
    assert j["rms_h_m"] < 3.0
    # at least as good as the SNS smoother on the same data
    assert j["rms_h_m"] <= gnss_run["sns"]["rms_h_m"]
    # time-averaged NEES of one run: 1 dof per component; with time correlation a single run's
    # average is far from chi2 - accept 0.2 .. 4 (a factor 2 on the standard deviation)
    assert 0.2 < j["nees_n"] < 4.0 and 0.2 < j["nees_e"] < 4.0


def test_corrupted_gnss_is_flagged_and_does_not_drag():
    r = mc.one_run("corrupt_gnss", 4001)
    assert r["joint_sources"]["gnss_pos"]["flagged_inconsistent"]
    # 500 m jump for 60 s: the track stays at the clean-case accuracy (metres, not hundreds)
    assert r["joint"]["rms_h_m"] < 5.0
    assert r["joint"]["max_h_m"] < 20.0


def test_radar_clock_offset_estimated():
    r = mc.one_run("corrupt_radar", 5001)
    off = r["joint_clock"]["radar"]
    # the simulator stamps the radar 2 s late (rounded to its 1/16 s truth grid)
    assert abs(off["value"] - 2.0) < 0.3
    assert r["joint"]["rms_h_m"] < 10.0


def test_recorder_only_beats_linear_end_point_correction():
    r = mc.one_run("recorder", 1001)
    assert r["joint"]["rms_h_m"] < r["dr_linear"]["rms_h_m"]
    assert np.isfinite(r["joint"]["rms_h_m"])
