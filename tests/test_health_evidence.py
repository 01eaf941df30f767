"""Health that cannot be fooled (issue #35): a track is ``ok`` only if its estimated states are
physically plausible and it agrees with the evidence.

Each defect met on the real Citation II records (docs/realflights.md) is reproduced on the
shipped simulated circuit, whose truth is known: the true track with the true wind passes every
check (a good flight judged unhealthy is as bad as a bad one judged ok), and the same track with
one defect added fails with that defect named.
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
from flightrecon.methods.baselines import bridge_sd_m
from flightrecon.pipeline import method_health
from flightrecon.track_evidence import Evidence, evidence_problems
from flightrecon.types import MethodResult, PositionFix

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"


@pytest.fixture(scope="module")
def circuit():
    """The cleaned circuit (GNSS, both airfields) and its truth in the output plane."""
    clean = clean_flight(load_flight(SAMPLES / "circuit.parquet"))
    truth = pd.read_parquet(SAMPLES / "circuit.truth.parquet")
    e, n, u = output_plane(clean.meta).forward(truth["lat_deg"].to_numpy(),
                                               truth["lon_deg"].to_numpy(),
                                               truth["alt_m"].to_numpy())
    truth = truth.assign(north_m=n, east_m=e, up_m=u)
    return clean, truth


@pytest.fixture(scope="module")
def recorder_only(circuit):
    """The same flight without its GNSS: the departure and arrival are its only positions."""
    clean, truth = circuit
    return replace(clean, gnss=clean.gnss.iloc[0:0]), truth


def _track(truth: pd.DataFrame, name: str = "joint", sd_m: float = 20.0,
           wind: bool = True) -> pd.DataFrame:
    tr = pd.DataFrame({"t_s": truth["t_s"], f"{name}_north_m": truth["north_m"],
                       f"{name}_east_m": truth["east_m"],
                       f"{name}_north_sd_m": sd_m, f"{name}_east_sd_m": sd_m,
                       f"{name}_alt_m": truth["alt_m"]})
    if wind:
        tr[f"{name}_wind_n_mps"] = truth["wind_n_mps"]
        tr[f"{name}_wind_e_mps"] = truth["wind_e_mps"]
    return tr


def _checks(res: MethodResult, clean) -> set[str]:
    return {p["check"] for p in evidence_problems(res, clean)}


def test_the_true_track_with_the_true_wind_passes_every_check(circuit, recorder_only):
    for clean, truth in (circuit, recorder_only):
        res = MethodResult("joint", _track(truth), {
            "corrections": {"heading_bias_deg": {"value": 1.5, "sd": 0.5}}})
        assert evidence_problems(res, clean) == []
        assert method_health(res, clean)["healthy"]
    # a method without sd (the deterministic Sabziev fusion) is held to the same evidence
    clean, truth = recorder_only
    tr = _track(truth, "sabziev", wind=False)
    tr[["sabziev_north_sd_m", "sabziev_east_sd_m"]] = np.nan
    assert evidence_problems(MethodResult("sabziev", tr, {}), clean) == []


def test_an_implausible_wind_is_unhealthy_with_its_reason(circuit):
    """The real 'ref' flight's joint wind of 63-94 m/s at 2 km: a wind forced to 80 m/s below
    2 km (the circuit flies under 1 km) is beyond the 40 m/s + 10 m/s per km limit."""
    clean, truth = circuit
    tr = _track(truth)
    tr["joint_wind_e_mps"] = 80.0
    h = method_health(MethodResult("joint", tr, {}), clean)
    assert not h["healthy"]
    what = [p["what"] for p in h["problems"] if p["check"] == "wind_speed"]
    assert what and "80 m/s" in what[0] and "beyond" in what[0]
    # 35 m/s is a gale, not impossible: inside the limit at any height
    tr["joint_wind_e_mps"] = 35.0
    assert "wind_speed" not in _checks(MethodResult("joint", tr, {}), clean)


def test_a_wind_that_jumps_faster_than_any_front_is_unhealthy(circuit):
    clean, truth = circuit
    tr = _track(truth)
    t = tr["t_s"].to_numpy()
    # 30 m/s back and forth every 20 s: a change of 30 m/s within 60 s (limit 25 + shear)
    tr["joint_wind_n_mps"] = truth["wind_n_mps"] + 15.0 * np.sign(np.sin(2 * np.pi * t / 40.0))
    assert "wind_change" in _checks(MethodResult("joint", tr, {}), clean)


def test_a_ground_speed_no_wind_explains_is_unhealthy(circuit):
    """A track flown three times as fast as the air data say (the wind states not involved:
    the Sabziev fusion has none)."""
    clean, truth = circuit
    tr = _track(truth, "sabziev", wind=False)
    tr["sabziev_north_m"] *= 3.0
    tr["sabziev_east_m"] *= 3.0
    probs = evidence_problems(MethodResult("sabziev", tr, {}), clean)
    ag = [p for p in probs if p["check"] == "air_ground"]
    assert ag and ag[0]["worst"] > ag[0]["limit"]


def test_a_heading_bias_of_26_deg_is_implausible_whatever_its_prior(circuit):
    clean, truth = circuit
    corr = {"heading_bias_deg": {"value": -26.0, "sd": 3.0, "prior_mean": 0.0,
                                 "prior_sd": 84.0}}
    h = method_health(MethodResult("joint", _track(truth), {"corrections": corr}), clean)
    assert not h["healthy"] and any("heading bias" in p["what"] for p in h["problems"])
    corr["heading_bias_deg"]["value"] = 5.6     # the B22 flight's: large, but possible
    assert "heading_bias" not in _checks(MethodResult("joint", _track(truth),
                                                      {"corrections": corr}), clean)


def test_a_track_ending_far_from_the_given_arrival_is_unhealthy(circuit):
    """A track that drifts linearly to 10 km off by the end: 4 combined sd of the 1500 m
    reference-point sd and the track's 20 m is 6 km."""
    clean, truth = circuit
    tr = _track(truth)
    t = tr["t_s"].to_numpy()
    tr["joint_east_m"] += 10000.0 * (t - t[0]) / (t[-1] - t[0])
    probs = [p for p in evidence_problems(MethodResult("joint", tr, {}), clean)
             if p["check"] == "arrival"]
    assert probs and 9000.0 < probs[0]["worst"] < 11000.0
    # 3 km off is within the reference point's sd: not a problem
    tr = _track(truth)
    tr["joint_east_m"] += 3000.0 * (t - t[0]) / (t[-1] - t[0])
    assert "arrival" not in _checks(MethodResult("joint", tr, {}), clean)


def test_a_known_position_missed_is_unhealthy(circuit):
    clean, truth = circuit
    row = truth.iloc[len(truth) // 2]
    fix = PositionFix(float(row["t_s"]), float(row["lat_deg"]), float(row["lon_deg"]), None, 100.0)
    cl = replace(clean, meta=replace(clean.meta, fixes=(fix,)))
    assert "fix" not in _checks(MethodResult("joint", _track(truth), {}), cl)
    tr = _track(truth)
    tr["joint_north_m"] += 1000.0          # 10 sd of the fix
    probs = [p for p in evidence_problems(MethodResult("joint", tr, {}), cl)
             if p["check"] == "fix"]
    assert probs and probs[0]["worst"] == pytest.approx(1000.0 / np.hypot(100.0, 20.0), rel=0.01)


def test_a_track_far_from_dead_reckoning_between_known_ends_is_unhealthy(recorder_only, circuit):
    """The real 'B22' flight's joint track bowed 20 km from dead reckoning corrected to its
    ends: a bow of that shape on the recorder-only circuit, ends kept, is caught; a bow inside
    the combined sd is not."""
    clean, truth = recorder_only
    ph = clean.phases
    t = truth["t_s"].to_numpy()
    s = np.clip((t - ph.liftoff_t_s) / (ph.touchdown_t_s - ph.liftoff_t_s), 0.0, 1.0)
    tr = _track(truth, "sabziev", wind=False)
    tr[["sabziev_north_sd_m", "sabziev_east_sd_m"]] = np.nan
    tr["sabziev_north_m"] += 20000.0 * 4 * s * (1 - s)
    probs = [p for p in evidence_problems(MethodResult("sabziev", tr, {}), clean)
             if p["check"] == "dead_reckoning"]
    assert probs and probs[0]["worst"] > 4.0
    tr = _track(truth, "sabziev", wind=False)
    tr["sabziev_north_m"] += 1500.0 * 4 * s * (1 - s)
    assert "dead_reckoning" not in _checks(MethodResult("sabziev", tr, {}), clean)
    # with GNSS the track is not held against dead reckoning (the fixes are the evidence)
    cl_gnss = circuit[0]
    tr["sabziev_north_m"] += 20000.0 * 4 * s * (1 - s)
    assert "dead_reckoning" not in _checks(MethodResult("sabziev", tr, {}), cl_gnss)


def test_the_bridge_sd_is_zero_at_both_ends_and_q_t32_over_48_half_way():
    sd = bridge_sd_m(np.array([0.0, 50.0, 100.0]), 0.0, 100.0, 0.1)
    assert sd[0] == 0.0 and sd[2] == pytest.approx(0.0, abs=1e-9)
    assert sd[1] == pytest.approx(0.1 * 100.0 ** 1.5 / np.sqrt(48.0), rel=1e-12)


def test_the_wind_limit_grows_with_height_to_the_jet_stream_cap():
    ev = Evidence()
    assert ev.wind_limit_mps(np.array([0.0, 2000.0, 20000.0])).tolist() == [40.0, 60.0, 150.0]


def test_a_non_finite_position_is_never_ok(circuit):
    """Missing (NaN) between finite samples counts as well as infinite values."""
    clean, truth = circuit
    tr = _track(truth)
    tr.loc[100:120, ["joint_north_m", "joint_east_m"]] = np.nan
    h = method_health(MethodResult("joint", tr, {}), clean)
    assert not h["healthy"]
    assert any(p["what"] == "non-finite position inside the coverage" for p in h["problems"])
    tr = _track(truth)
    tr[["joint_north_m", "joint_east_m"]] = np.inf
    assert not method_health(MethodResult("joint", tr, {}))["healthy"]


def test_a_method_unhealthy_by_its_own_verdict_says_why():
    """SNS said "reports itself unhealthy" and nothing more; its summary holds the reason."""
    t = np.arange(50.0)
    tr = pd.DataFrame({"t_s": t, "sns_north_m": t, "sns_east_m": t, "sns_north_sd_m": 1.0,
                       "sns_east_sd_m": 1.0})
    h = method_health(MethodResult("sns", tr, {"healthy": False, "consistency": {
        "gross": True, "mean": 12.3, "count": 400}}))
    assert [p["what"] for p in h["problems"]] == [
        "its mean NIS per degree of freedom is 12.3 (expected 1, at most 5): its noise model "
        "does not fit the flight"]
    h = method_health(MethodResult("sns", tr, {"healthy": False, "consistency": {
        "gross": False, "mean": float("nan"), "count": 0}}))
    assert "no measurement reached its filter" in h["problems"][0]["what"]
    h = method_health(MethodResult("sns", tr, {"healthy": False}))
    assert h["problems"][0]["what"] == "it reports itself unhealthy and gives no reason"


def test_a_known_position_at_the_end_is_an_end_for_dead_reckoning(recorder_only):
    """The real 'ref' flight ends airborne; its last GPS position given as a fix left the
    Sabziev fusion 'ok' at 17 km RMS.  Without an arrival, a fix within 60 s of the record's
    end closes dead reckoning instead: the truth passes, a 20 km bow does not."""
    clean, truth = recorder_only
    last = truth.iloc[-1]
    fix = PositionFix(float(last["t_s"]), float(last["lat_deg"]), float(last["lon_deg"]), None,
                      100.0)
    cl = replace(clean, meta=replace(clean.meta, arrival=None, fixes=(fix,)))
    tr = _track(truth, "sabziev", wind=False)
    tr[["sabziev_north_sd_m", "sabziev_east_sd_m"]] = np.nan
    assert "dead_reckoning" not in _checks(MethodResult("sabziev", tr, {}), cl)
    ph = clean.phases
    t = truth["t_s"].to_numpy()
    s = np.clip((t - ph.liftoff_t_s) / (t[-1] - ph.liftoff_t_s), 0.0, 1.0)
    tr["sabziev_east_m"] += 20000.0 * 4 * s * (1 - s)
    assert "dead_reckoning" in _checks(MethodResult("sabziev", tr, {}), cl)
    # a fix in mid-flight is no end point: nothing to close dead reckoning with
    mid = truth.iloc[len(truth) // 2]
    cl_mid = replace(cl, meta=replace(cl.meta, fixes=(PositionFix(
        float(mid["t_s"]), float(mid["lat_deg"]), float(mid["lon_deg"]), None, 100.0),)))
    assert "dead_reckoning" not in _checks(MethodResult("sabziev", tr, {}), cl_mid)


def test_a_verdict_reaches_the_console_once_and_the_summary_top(tmp_path, capsys):
    """End to end on the shipped circuit: an arrival given 30 km from where the flight ends
    (its GNSS holds the track) makes the joint smoother unhealthy; the reason is on the
    console on the method's line and in the summary's top-level warnings; nothing healthy:
    exit 8."""
    import json
    import shutil

    from flightrecon.cli.main import main

    for f in SAMPLES.glob("circuit.*"):
        shutil.copy(f, tmp_path / f.name)
    out = tmp_path / "r.parquet"
    # 0.27 deg of latitude north of the field: 30 km
    args = ["reconstruct", str(tmp_path / "circuit.parquet"), "--methods", "joint",
            "--arrival", "40.73,50.05,3.0", "--keep-unhealthy", "-o", str(out)]
    try:
        main(args)
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    text = capsys.readouterr()
    console = text.out + text.err
    assert code == 8, console
    # on the method's line, not repeated as a warning of its own (the closing "no method
    # produced a physically possible track" line lists every method's reason once more)
    assert "joint    unhealthy: the track ends" in console, console
    assert "warning: joint unhealthy:" not in console, console
    summary = json.loads(out.with_name("r.summary.json").read_text())
    top = [w for w in summary["warnings"] if w.startswith("joint unhealthy:")]
    assert len(top) == 1 and "from the given arrival" in top[0]


def test_the_ground_speed_is_the_methods_own_velocity_far_from_the_plane_origin(circuit):
    """8000 km out on a 10-hour flight the tangent plane's north moved at 150 m/s where the
    aircraft flew 224 (the benchmark's longhaul flight, GNSS-aided, was refused by the
    air-ground check): a method's own local-level velocity is its ground speed. Reproduced on
    the circuit: its plane positions stretched three times (a plane rate no wind explains),
    its velocities true."""
    clean, truth = circuit
    tr = _track(truth, "joint")
    vn = np.gradient(truth["north_m"].to_numpy(), truth["t_s"].to_numpy())
    ve = np.gradient(truth["east_m"].to_numpy(), truth["t_s"].to_numpy())
    tr["joint_vn_mps"], tr["joint_ve_mps"] = vn, ve
    squeezed = tr.copy()
    squeezed["joint_north_m"] *= 3.0
    squeezed["joint_east_m"] *= 3.0
    assert "air_ground" not in _checks(MethodResult("joint", squeezed, {}), clean)
    # without the velocity the plane's rate is all there is: the check fires
    bare = squeezed.drop(columns=["joint_vn_mps", "joint_ve_mps"])
    assert "air_ground" in _checks(MethodResult("joint", bare, {}), clean)
