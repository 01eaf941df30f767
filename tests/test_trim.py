"""``--start`` / ``--end`` on clean, reconstruct and batch (flightrecon.cleaning.trim)."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flightrecon.cleaning import CleaningSettings, clean_flight
from flightrecon.cli.main import main
from flightrecon.errors import ValidationError
from flightrecon.ingest import load_flight
from flightrecon.pipeline import ReconstructSettings, reconstruct

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"


def test_trim_seconds_and_utc_agree():
    fl = load_flight(SAMPLES / "handmade.csv")        # epoch 2026-03-15T09:00:00Z
    a = clean_flight(fl, settings=CleaningSettings(start=30, end=200.5))
    b = clean_flight(fl, settings=CleaningSettings(start="2026-03-15T09:00:30Z",
                                                   end="2026-03-15 09:03:20.5"))
    t = a.grid["t_s"].to_numpy()
    assert t[0] >= 30.0 and t[-1] <= 200.5 and t[0] < 30.2 and t[-1] > 200.3
    pd.testing.assert_frame_equal(a.grid, b.grid)
    assert a.gnss["t_s"].between(30.0, 200.5).all() and len(a.gnss) == 171
    (tr,) = [e for e in a.report if e["action"] == "trim"]
    assert tr["start_s"] == 30.0 and tr["end_s"] == 200.5
    assert tr["count"] + tr["kept_rows"] == len(fl.data)
    # the input flight is untouched
    assert len(fl.data) == len(load_flight(SAMPLES / "handmade.csv").data)


@pytest.mark.parametrize("start,end,words", [(100, 50, "must be after"),
                                             ("soon", None, "neither seconds"),
                                             (1e6, None, "keeps 0 row")])
def test_trim_refused(start, end, words):
    fl = load_flight(SAMPLES / "handmade.csv")
    with pytest.raises(ValidationError, match=words):
        clean_flight(fl, settings=CleaningSettings(start=start, end=end))


def test_clean_cli_trims(tmp_path, capsys):
    out = tmp_path / "c.parquet"
    with pytest.raises(SystemExit) as ex:
        main(["-q", "clean", str(SAMPLES / "handmade.csv"), "-o", str(out), "--start", "60",
              "--end", "2026-03-15T09:02:00Z"])
    assert ex.value.code == 0, capsys.readouterr().err
    g = pd.read_parquet(out)
    assert g["t_s"].min() >= 60.0 and g["t_s"].max() <= 120.0
    doc = json.loads((tmp_path / "c.cleaning.json").read_text())
    assert doc["settings"]["start"] == "60"


def test_reconstruct_trimmed_starts_airborne():
    """circuit.csv cut at 120 s: the record starts in the air, the joint smoother still runs
    and its track starts at the cut."""
    s = ReconstructSettings(methods=("joint",), start=120.0)
    rec = reconstruct(SAMPLES / "circuit.csv", settings=s, record=False)
    assert rec.clean.phases.starts_airborne
    assert rec.summary["methods"]["joint"]["status"] == "ok"
    assert rec.track["t_s"].iloc[0] >= 120.0
    assert rec.summary["settings"]["start"] == 120.0
    full = reconstruct(SAMPLES / "circuit.csv", settings=ReconstructSettings(methods=("joint",)),
                       record=False)
    m = full.track.set_index("t_s").loc[rec.track["t_s"].iloc[200:-200]]
    d = np.hypot(m["north_m"].to_numpy() - rec.track["north_m"].iloc[200:-200].to_numpy(),
                 m["east_m"].to_numpy() - rec.track["east_m"].iloc[200:-200].to_numpy())
    # GNSS throughout: the cut record agrees with the full one to within the fixes' accuracy
    assert np.sqrt(np.mean(d ** 2)) < 3.0
