"""The default result chosen by the evidence the flight holds (issue #52, item 1;
flightrecon/pipeline/evidence.py, docs/output.md "How the default result is chosen").

Tracks are constructed on the shipped circuit from its truth, with known errors, and checked
on known positions (``--fix``) held out from the methods that do not take them (ARMS and the
azimuth filter take none): the evidence must reorder them when it says so, and a track whose
held-out miss exceeds 4 sd is never the default, whatever the priority says.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flightrecon.cleaning import clean_flight
from flightrecon.geo.frames import output_plane
from flightrecon.ingest import load_flight
from flightrecon.pipeline.evidence import HELD_OUT_K, Check, choose_order, track_checks
from flightrecon.pipeline.registry import DEFAULT_PRIORITY
from flightrecon.pipeline.run import default_order
from flightrecon.types import MethodResult, PositionFix

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
FIX_TIMES_S = (300.0, 450.0, 600.0)
FIX_SD_M = 50.0


@pytest.fixture(scope="module")
def circuit():
    """The cleaned circuit with three known positions from its truth, and the truth in the
    output plane."""
    clean = clean_flight(load_flight(SAMPLES / "circuit.parquet"))
    truth = pd.read_parquet(SAMPLES / "circuit.truth.parquet")
    fixes = tuple(PositionFix(t, float(np.interp(t, truth["t_s"], truth["lat_deg"])),
                              float(np.interp(t, truth["t_s"], truth["lon_deg"])),
                              float(np.interp(t, truth["t_s"], truth["alt_msl_m"])), FIX_SD_M)
                  for t in FIX_TIMES_S)
    clean = replace(clean, meta=replace(clean.meta, fixes=fixes))
    e, n, _ = output_plane(clean.meta).forward(truth["lat_deg"].to_numpy(),
                                               truth["lon_deg"].to_numpy(),
                                               truth["alt_m"].to_numpy())
    return clean, truth.assign(north_m=n, east_m=e)


def _result(truth: pd.DataFrame, name: str, offset_n_m: float, sd_m: float) -> MethodResult:
    """The truth displaced north by ``offset_n_m``, reporting ``sd_m`` per axis."""
    tr = pd.DataFrame({"t_s": truth["t_s"], f"{name}_north_m": truth["north_m"] + offset_n_m,
                       f"{name}_east_m": truth["east_m"], f"{name}_north_sd_m": sd_m,
                       f"{name}_east_sd_m": sd_m})
    return MethodResult(name=name, track=tr, summary={})


def test_the_better_track_on_held_out_fixes_goes_first(circuit):
    """ARMS comes before the azimuth filter in the priority; held-out fixes show ARMS 300 m
    off (1.3 sd: its sd is honest, nothing refutes it) and the azimuth filter 40 m off: the
    azimuth filter goes first, both stay in the order, and the summary says why."""
    clean, truth = circuit
    results = {"arms": _result(truth, "arms", 300.0, 200.0),
               "azimuth": _result(truth, "azimuth", 40.0, 100.0)}
    healthy = {m: True for m in results}
    checks = track_checks(results, healthy, clean)
    held = [c for c in checks["arms"] if c.held_out]
    assert len(held) == len(FIX_TIMES_S)
    assert [c.miss_m for c in held] == pytest.approx([300.0] * 3, abs=5.0)
    order, evidence = default_order(clean, results, healthy)
    assert order == ["azimuth", "arms"]
    assert evidence["azimuth"]["rank"] == 1 and evidence["arms"]["rank"] == 2
    assert "RMS miss of the points held out" in evidence["arms"]["why"]
    # without the evidence the priority stands
    assert choose_order({"arms": [], "azimuth": []}, DEFAULT_PRIORITY)[0] == ["arms", "azimuth"]


def test_a_track_missing_a_held_out_fix_by_more_than_4_sd_is_never_the_default(circuit):
    """ARMS 1 km off with an sd of 100 m (about 9 sd at each held-out fix): never the
    default, even alone among the checked tracks with the joint smoother (which took the
    fixes: no held-out evidence) after it; the reason names the miss in m and sd."""
    clean, truth = circuit
    results = {"joint": _result(truth, "joint", 30.0, 20.0),
               "arms": _result(truth, "arms", 1000.0, 100.0),
               "azimuth": _result(truth, "azimuth", 200.0, 150.0)}
    healthy = {m: True for m in results}
    order, evidence = default_order(clean, results, healthy)
    assert "arms" not in order
    assert order == ["joint", "azimuth"]
    assert evidence["arms"]["rank"] is None
    assert "never the default" in evidence["arms"]["why"] and "sd" in evidence["arms"]["why"]
    z = max(c["z"] for c in evidence["arms"]["checks"] if c["held_out"])
    assert z > HELD_OUT_K
    # the joint took the fixes: checked on them, none held out from it
    assert evidence["joint"]["checks"] and not any(c["held_out"]
                                                   for c in evidence["joint"]["checks"])


def test_a_refuted_track_is_never_chosen_on_constructed_checks():
    """The rule alone: whatever the priority and the other evidence, a held-out miss beyond
    4 sd keeps a track out; just within 4 sd it stays; every track refuted: the priority
    stands and is said."""
    ok = Check("fix", True, 100.0, HELD_OUT_K - 0.01)
    bad = Check("fix", True, 50.0, HELD_OUT_K + 0.01)
    order, why = choose_order({"joint": [bad], "sabziev": [ok]}, DEFAULT_PRIORITY)
    assert order == ["sabziev"] and "never the default" in why["joint"]
    order, why = choose_order({"joint": [bad], "sabziev": [bad]}, DEFAULT_PRIORITY)
    assert order == ["joint", "sabziev"]
    assert all("the priority stands" in w for w in why.values())
