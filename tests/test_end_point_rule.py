"""A given end point is met within its sd, or the method is unhealthy with the reason (issue
#52, item 3; flightrecon/pipeline/health.py, :func:`end_point_problems`).

Before the rule, a track whose own sd had grown wide at the end passed the arrival check by
its own width (an A320 export ended 12.6 km from the arrival given, its east sd 11.6 km, exit
0), and a record that ends fast with its arrival kept (the arrival taken as the position at the
last sample) was not checked at all.
"""

from __future__ import annotations

import json
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from _cli import run_cli

from flightrecon.cleaning import clean_flight
from flightrecon.geo.frames import output_plane
from flightrecon.ingest import load_flight
from flightrecon.pipeline import method_health
from flightrecon.pipeline.health import END_POINT_K
from flightrecon.types import MethodResult, Position

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
CIRCUIT = SAMPLES / "circuit.parquet"
#: the record cut on final, 32 m above the field (tests/test_arrival_end.py): it ends fast and
#: keeps its arrival as the position at its last sample
END_ON_FINAL_S = 820.0


def _moved(arr: Position, plane, d_east_m: float) -> Position:
    """The arrival ``d_east_m`` east of where it is, at its elevation."""
    e, n, u = plane.forward(arr.lat_deg, arr.lon_deg, arr.elev_m)
    lat, lon, _ = plane.inverse(e + d_east_m, n, u)
    return replace(arr, lat_deg=float(lat), lon_deg=float(lon), threshold_lat_deg=None,
                   threshold_lon_deg=None)


@pytest.fixture(scope="module")
def circuit():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        clean = clean_flight(load_flight(CIRCUIT))
    truth = pd.read_parquet(SAMPLES / "circuit.truth.parquet")
    e, n, _ = output_plane(clean.meta).forward(truth["lat_deg"].to_numpy(),
                                               truth["lon_deg"].to_numpy(),
                                               truth["alt_m"].to_numpy())
    return clean, truth.assign(north_m=n, east_m=e)


def test_a_wide_sd_does_not_excuse_missing_the_arrival(circuit):
    """The true track reporting 11.6 km per axis at every sample: with the true arrival it is
    healthy; with the arrival 12 km east it is unhealthy, the reason giving the miss in km and
    in sd of the end point (the previous arrival check, 4 sd of the end point and the track
    together, let it pass: 66 km of tolerance)."""
    clean, truth = circuit
    sd = 11_600.0
    tr = pd.DataFrame({"t_s": truth["t_s"], "joint_north_m": truth["north_m"],
                       "joint_east_m": truth["east_m"], "joint_north_sd_m": sd,
                       "joint_east_sd_m": sd})
    res = MethodResult(name="joint", track=tr, summary={})
    h = method_health(res, clean)
    assert h["healthy"], h["problems"]
    moved = replace(clean, meta=replace(clean.meta, arrival=_moved(
        clean.meta.arrival, output_plane(clean.meta), 12_000.0)))
    h = method_health(res, moved)
    assert not h["healthy"]
    prob = [p for p in h["problems"] if p["check"] == "end_point"]
    assert len(prob) == 1, h["problems"]
    assert "from the arrival given" in prob[0]["what"]
    assert "does not honour it" in prob[0]["what"]
    assert prob[0]["worst"] > END_POINT_K


def _reconstruct(tmp_path: Path, tag: str, arrival: Position) -> tuple[int, dict]:
    out = tmp_path / f"{tag}.parquet"
    code = run_cli(["reconstruct", str(CIRCUIT), "--methods", "sns", "--end",
                    f"{END_ON_FINAL_S:g}", "--arrival",
                    f"{arrival.lat_deg:.7f},{arrival.lon_deg:.7f},{arrival.elev_m:g}",
                    "--keep-unhealthy", "-o", str(out)])
    summary = json.loads(out.with_suffix(".summary.json").read_text())
    return code, summary


def test_a_track_ending_away_from_the_arrival_given_is_marked(circuit, tmp_path):
    """The circuit with its GNSS, cut on final (the arrival kept as the position at the last
    sample), SNS alone: with the true arrival SNS is ok; with the arrival given 12 km east
    SNS, which follows its GNSS and not the arrival, is unhealthy with the miss named, and
    no healthy track is left for the default (before the rule: ok, exit 0)."""
    clean, _ = circuit
    arr = clean.meta.arrival
    code, s = _reconstruct(tmp_path, "true", arr)
    assert code == 0
    assert s["methods"]["sns"]["status"] == "ok"
    code, s = _reconstruct(tmp_path, "moved", _moved(arr, output_plane(clean.meta), 12_000.0))
    st = s["methods"]["sns"]
    assert st["status"] == "unhealthy"
    assert "from the arrival given (the aircraft's position at the last sample)" in st["reason"]
    assert s["result"]["method"] is None
    assert np.isfinite(st["health"]["problems"][-1]["spans_s"][0][0])


@pytest.fixture(scope="module")
def regional_recorder_only():
    """The regional flight (59 minutes, a climb to 4.4 km) without its GNSS, both ends known,
    and its dead reckoning with the linear end correction."""
    from flightrecon.ingest.gnss_use import GnssUse
    from flightrecon.track_evidence import corrected_dead_reckoning

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        clean = clean_flight(load_flight(SAMPLES / "regional.parquet",
                                         gnss_use=GnssUse(withhold=True)))
    got = corrected_dead_reckoning(clean)
    assert got is not None
    return clean, got[0], got[1]


def _sheared(clean, dr: pd.DataFrame, t_end: float, shear_mps_per_km: float) -> MethodResult:
    """Dead reckoning displaced by what a wind shear of ``shear_mps_per_km`` over the flight's
    height profile does to it once pinned at both ends (|B(t)| times the shear,
    :func:`flightrecon.methods.baselines.profile_wind_sd_m`), sd 300 m per axis."""
    from flightrecon.methods.baselines import profile_wind_sd_m

    t = dr["t_s"].to_numpy(float)
    h = np.interp(t, clean.grid["t_s"].to_numpy(float), clean.grid["baro_alt_m"].to_numpy(float))
    x = profile_wind_sd_m(t, h, clean.phases.liftoff_t_s, t_end, shear_mps_per_km / 1000.0)
    tr = pd.DataFrame({"t_s": t, "joint_north_m": dr["north_m"].to_numpy(float) + x,
                       "joint_east_m": dr["east_m"].to_numpy(float),
                       "joint_north_sd_m": 300.0, "joint_east_sd_m": 300.0})
    return MethodResult(name="joint", track=tr, summary={})


def test_the_baseline_carries_its_one_wind_over_the_height_profile(regional_recorder_only):
    """A track that differs from dead reckoning as a shear of 9 m/s per km (3 sd of the
    baseline's shear) would make it differ (up to 16 km on the climb to 4.4 km) is the
    baseline's error, not the track's: not refused for leaving dead reckoning (before the
    baseline's height-profile sd: refused, 6.5 sd at worst). A shear of 30 m/s per km (10 sd;
    54 km) is still refused: overconfident."""
    clean, dr, t_end = regional_recorder_only
    h = method_health(_sheared(clean, dr, t_end, 9.0), clean)
    assert not [p for p in h["problems"] if p["check"] == "dead_reckoning"], h["problems"]
    h = method_health(_sheared(clean, dr, t_end, 30.0), clean)
    assert [p for p in h["problems"] if p["check"] == "dead_reckoning"], h["problems"]
