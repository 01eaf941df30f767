"""The report of a recorder-only, a GNSS and a radar sample, rendered by a real headless
Chromium: every figure decoded by the browser, every section present, the screenshot not
blank.

Needs a Chromium (Debian: ``apt-get install chromium``; .ci/run installs it).  Without one the
test is skipped on a developer machine and fails under CI (``CI`` or
``FLIGHTRECON_REQUIRE_BROWSER`` set, as .ci/run does), so CI cannot pass without looking.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from _cli import run_cli

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_logs"


def _chromium() -> str | None:
    for name in ("chromium", "chromium-browser", "google-chrome", "google-chrome-stable"):
        path = shutil.which(name)
        if path:
            return path
    return None


CHROMIUM = _chromium()
if CHROMIUM is None and (os.environ.get("CI") or os.environ.get("FLIGHTRECON_REQUIRE_BROWSER")):
    raise RuntimeError("CI needs a Chromium for the report test (apt-get install chromium)")
pytestmark = pytest.mark.skipif(CHROMIUM is None, reason="no Chromium on this machine")

FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run", "--hide-scrollbars"]


def chromium(args: list[str], profile: Path) -> subprocess.CompletedProcess:
    return subprocess.run([CHROMIUM, *FLAGS, f"--user-data-dir={profile}", *args],
                          capture_output=True, text=True, timeout=180)


#: sample -> (log, truth, figures that must be in its report)
COMMON = {"ground_track", "altitude_profile", "speeds", "attitude", "load_factors",
          "method_differences", "sensor_corrections", "innovations"}
CASES = {
    "recorder-only": ("recorder-only.parquet", "circuit.truth.parquet",
                      COMMON | {"wind", "newton_history"}),
    "gnss": ("regional.parquet", "regional.truth.parquet", COMMON | {"wind", "newton_history"}),
    "radar": ("seed-ads-arms.parquet", "seed-ads-arms.truth.parquet",
              COMMON | {"air_data_error", "newton_history"}),
}


@pytest.fixture(scope="module")
def reports(tmp_path_factory):
    d = tmp_path_factory.mktemp("browser")
    # the recorder-only flight: the circuit without its GNSS channels (same sidecar)
    log = pd.read_parquet(SAMPLES / "circuit.parquet")
    log[[c for c in log.columns if not c.startswith("gnss_")]].to_parquet(
        d / "recorder-only.parquet")
    shutil.copy(SAMPLES / "circuit.meta.toml", d / "recorder-only.meta.toml")
    out = {}
    for name, (log_name, truth, _) in CASES.items():
        src = d / log_name if name == "recorder-only" else SAMPLES / log_name
        res = d / f"{name}.recon.parquet"
        assert run_cli(["reconstruct", str(src), "-o", str(res)]) == 0
        folder = d / f"{name}.report"
        assert run_cli(["plot", str(res), "--truth", str(SAMPLES / truth), "-o",
                        str(folder)]) == 0
        out[name] = folder / "report.html"
    return out


@pytest.mark.parametrize("name", list(CASES))
def test_every_figure_rendered_by_the_browser(reports, name, tmp_path):
    page = reports[name]
    dom = chromium(["--dump-dom", page.as_uri()], tmp_path / "profile1")
    assert dom.returncode == 0, dom.stderr[-2000:]
    body = re.search(r"<body([^>]*)>", dom.stdout).group(1)
    n = int(re.search(r'data-figures="(\d+)"', body).group(1))
    loaded = int(re.search(r'data-figures-loaded="(\d+)"', body).group(1))
    figures = set(re.findall(r'data-figure="([a-z_]+)"', dom.stdout))
    assert CASES[name][2] <= figures, CASES[name][2] - figures
    assert n == len(figures) and loaded == n  # each PNG decoded by the browser
    for section in ("flight", "events", "figures", "methods", "corrections", "warnings",
                    "inputs"):
        assert f'id="{section}"' in dom.stdout
    assert 'class="lead"' in dom.stdout or "class=lead" in dom.stdout
    # recorder channels were found again through the summary's SHA-256 (no note about them)
    assert "Recorder channels not drawn" not in dom.stdout
    # events table in UTC
    assert re.search(r"<td>2026-01-01 10:\d\d:\d\d\.\d</td>", dom.stdout)


@pytest.mark.parametrize("name", list(CASES))
def test_screenshot_not_blank(reports, name, tmp_path):
    from PIL import Image

    shot = tmp_path / f"{name}.png"
    r = chromium([f"--screenshot={shot}", "--window-size=1200,6000", reports[name].as_uri()],
                 tmp_path / "profile2")
    assert r.returncode == 0 and shot.is_file(), r.stderr[-2000:]
    img = np.asarray(Image.open(shot).convert("RGB"), dtype=np.int16)
    assert img.shape[:2] == (6000, 1200)
    non_white = (img.sum(axis=2) < 740).mean()
    colours = len(np.unique(img.reshape(-1, 3)[::97], axis=0))
    # text, tables and figures: far from blank (an empty page is 0 and 1)
    assert non_white > 0.05 and colours > 200, (non_white, colours)
