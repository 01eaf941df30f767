"""A batch of simulated flights on a 2-worker LocalCluster: results, failures, the store, the
averages and resuming (docs/batch.md)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest

from flightrecon.batch import batch, open_client
from flightrecon.export.writers import read_track
from flightrecon.sim.io import write_simulation
from flightrecon.sim.scenarios import simulate_fleet
from flightrecon.store import CoefficientStore

GOOD = ("A1_F01", "A1_F02", "B2_F01", "B2_F02")


@pytest.fixture(scope="module")
def fleet(tmp_path_factory) -> Path:
    """2 aircraft x 2 short circuits (15 min at 16 Hz, about a second each to reconstruct) and
    one truncated Parquet log."""
    d = tmp_path_factory.mktemp("fleet")
    for a in ("A1", "B2"):
        for r in simulate_fleet(a, 2, seed=3, scenario="circuit"):
            write_simulation(r, d / f"{a}_{r.meta.flight_id}.parquet")
    raw = (d / "A1_F01.parquet").read_bytes()
    (d / "bad.parquet").write_bytes(raw[: len(raw) // 3])
    return d


@pytest.fixture(scope="module")
def client():
    with open_client(workers=2) as c:
        yield c


@pytest.fixture(scope="module")
def first_subset_then_all(fleet, client, tmp_path_factory):
    """An interrupted batch (only the A1 flights done), then the full batch in the same folder."""
    out = tmp_path_factory.mktemp("out")
    store = out.parent / (out.name + ".sqlite")
    seen: list[tuple[str, int]] = []
    r1 = batch([str(fleet / "A1_*.parquet")], out, client=client, store=store)
    mtimes = {n: (out / f"{n}.manifest.json").stat().st_mtime_ns for n in ("A1_F01", "A1_F02")}
    r2 = batch([fleet], out, client=client, store=store,
               progress=lambda oc, total: seen.append((oc.status, total)))
    return out, store, r1, r2, mtimes, seen


def _read_csv(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def test_good_flights_reconstructed_bad_one_reported(first_subset_then_all):
    out, _, r1, r2, _, seen = first_subset_then_all
    assert [o.status for o in r1.outcomes] == ["ok", "ok"]
    status = {o.name: o.status for o in r2.outcomes}
    assert status == {"A1_F01": "skipped", "A1_F02": "skipped", "B2_F01": "ok", "B2_F02": "ok",
                      "bad": "failed"}
    bad = next(o for o in r2.outcomes if o.name == "bad")
    assert bad.row["exit_code"] == 3 and "Parquet" in bad.row["error"]
    assert r2.exit_code == 3
    assert sorted(seen) == sorted([(s, 5) for s in status.values()])
    for name in GOOD:
        track, _ = read_track(out / f"{name}.recon.parquet")
        summary = json.loads((out / f"{name}.recon.summary.json").read_text())
        assert len(track) == summary["grid"]["samples"] > 10_000
        assert np.isfinite(track[["north_m", "east_m", "up_m"]].to_numpy()).all()
        assert (out / f"{name}.manifest.json").is_file()
    assert not list(out.glob("bad.*")), "a failed flight leaves no result or manifest"
    assert not list(out.glob(".*")), "no temporary files left behind"


def test_summary_table(first_subset_then_all):
    out, *_ = first_subset_then_all
    rows = {r["name"]: r for r in _read_csv(out / "batch_summary.csv")}
    assert set(rows) == set(GOOD) | {"bad"}
    for name in GOOD:
        r = rows[name]
        # a 15-minute circuit: the grid spans 900 s within the simulated leg-scale spread
        assert 700.0 < float(r["duration_s"]) < 1200.0
        assert all(math.isfinite(float(r[k])) for k in ("k1", "k2", "k3", "joint_mean_nis",
                                                          "north_sd_m_median"))
        assert r["sources"].startswith("joint:") and r["stored"].startswith("yes")
    assert rows["bad"]["status"] == "failed" and rows["bad"]["k1"] == ""


def test_store_rows_and_averages_by_hand(first_subset_then_all):
    """One store row per good flight; the written averages equal the rule of
    flightrecon.store.stats (converged fits on the majority branch, tie -> negative) applied
    by hand to the recorded fits."""
    out, store, *_ = first_subset_then_all
    with CoefficientStore(store, create=False) as db:
        recs = db.list_flights()
    assert sorted((r.aircraft_id, r.flight_id) for r in recs) == [
        ("A1", "F01"), ("A1", "F02"), ("B2", "F01"), ("B2", "F02")]
    table = {r["aircraft_id"]: r for r in _read_csv(out / "aircraft_averages.csv")}
    assert set(table) == {"A1", "B2"}
    for ac in ("A1", "B2"):
        mine = [r for r in recs if r.aircraft_id == ac]
        for i, axis in enumerate(("k1", "k2", "k3")):
            conv = [r for r in mine if r.axis_converged[i]]
            neg = sum(r.branch[i] == "negative" for r in conv)
            branch = "negative" if 2 * neg >= len(conv) else "positive"
            k = np.array([getattr(r, axis) for r in conv if r.branch[i] == branch])
            row = table[ac]
            assert int(row[f"{axis}_n"]) == len(k)
            if len(k) == 0:  # no converged fit on this axis (stable policy: no root taken)
                assert row[f"{axis}_mean"] == ""
                continue
            # the CSV holds repr() of the float: only summation order can differ (1e-12)
            assert float(row[f"{axis}_mean"]) == pytest.approx(k.mean(), rel=1e-12)
            if len(k) > 1:
                assert float(row[f"{axis}_sd"]) == pytest.approx(k.std(ddof=1), rel=1e-12)
            else:
                assert row[f"{axis}_sd"] == ""
    # each fit equals the k the worker reported for that flight
    rows = {r["name"]: r for r in _read_csv(out / "batch_summary.csv")}
    for r in recs:
        row = rows[f"{r.aircraft_id}_{r.flight_id}"]
        assert [float(row[a]) for a in ("k1", "k2", "k3")] == pytest.approx(list(r.k), rel=1e-15)


def test_resume_does_not_redo_finished_flights(first_subset_then_all, fleet, client):
    out, store, _, r2, mtimes, _ = first_subset_then_all
    for n, t in mtimes.items():
        assert (out / f"{n}.manifest.json").stat().st_mtime_ns == t
    before = {n: (out / f"{n}.manifest.json").stat().st_mtime_ns for n in GOOD}
    r3 = batch([fleet], out, client=client, store=store)
    assert r3.count("skipped") == len(GOOD) == r2.count("ok") + r2.count("skipped")
    assert r3.count("failed") == 1  # a failed flight is retried on every run
    for n in GOOD:
        assert (out / f"{n}.manifest.json").stat().st_mtime_ns == before[n]
    # a changed sidecar redoes that flight only
    side = fleet / "B2_F02.meta.toml"
    side.write_text(side.read_text() + "\n# edited\n")
    r4 = batch([fleet], out, client=client, store=store)
    assert {o.name: o.status for o in r4.outcomes if o.status != "skipped"} == {
        "B2_F02": "ok", "bad": "failed"}
    with CoefficientStore(store, create=False) as db:
        assert db.count() == len(GOOD)  # re-recording a flight replaces its row
        db.remove("A1", "F02")
    # a store that lost a skipped flight's row gets it back without the flight being redone
    r5 = batch([fleet], out, client=client, store=store)
    assert r5.count("skipped") == len(GOOD)
    with CoefficientStore(store, create=False) as db:
        assert db.count() == len(GOOD) and db.get("A1", "F02").k == pytest.approx(
            [float(next(o.row[a] for o in r5.outcomes if o.name == "A1_F02"))
             for a in ("k1", "k2", "k3")], rel=1e-15)


def test_logs_sharing_a_flight_id_get_one_record_each(fleet, client, tmp_path):
    """Three logs whose sidecars all say flight F1 (as the shipped sample logs do): two
    different logs and a byte-identical copy of the first.  One record per distinct log: the
    first keeps F1, the other is recorded as F1~<its hash>, the copy updates the first; the
    table says so.  Without a store the averages count the two distinct logs."""
    import hashlib
    import shutil

    d = tmp_path / "logs"
    d.mkdir()
    for src, dst in (("A1_F01", "a"), ("A1_F02", "b"), ("A1_F01", "c_copy")):
        shutil.copy(fleet / f"{src}.parquet", d / f"{dst}.parquet")
        side = (fleet / f"{src}.meta.toml").read_text()
        (d / f"{dst}.meta.toml").write_text(side.replace(f'"{src[3:]}"', '"F1"'))
    h = {n: hashlib.sha256((d / f"{n}.parquet").read_bytes()).hexdigest() for n in ("a", "b")}
    store = tmp_path / "s.sqlite"
    r = batch([d], tmp_path / "out", client=client, store=store)
    assert r.count("ok") == 3
    with CoefficientStore(store, create=False) as db:
        ids = sorted(f.flight_id for f in db.list_flights("A1"))
        cal_ids = sorted(c.flight_id for c in db.list_calibrations("A1"))
        assert db.flight_id_of("A1", h["a"]) == "F1"
        assert db.flight_id_of("A1", h["b"]) == "F1~" + h["b"][:8]
    assert ids == cal_ids == ["F1", "F1~" + h["b"][:8]]
    stored = {o.name: o.row["stored"] for o in r.outcomes}
    assert "as F1~" in stored["b"] and "another log" in stored["b"]
    assert stored["a"].startswith("yes") and stored["c_copy"].startswith("yes")
    r2 = batch([d], tmp_path / "out2", client=client)   # no store: same identity rule
    assert {a["aircraft_id"]: a["k1_n"] for a in r2.averages}["A1"] <= 2
    assert r2.averages[0]["n_flights"] == 2


def test_a_batch_reads_frame_count_tables_at_its_frame_rate(client, tmp_path):
    """``--frame-rate`` reaches every flight of a batch (a table with no time column is refused
    without it, with the option named), and a re-run at a rate redoes the refused flight."""
    from flightrecon.errors import SchemaError
    from tests.test_folder_rate import RATE_HZ, SAMPLES, reference

    logs = tmp_path / "logs"
    logs.mkdir()
    reference().drop(columns=["t_s"]).to_csv(logs / "frames.csv", index=False)
    (logs / "frames.meta.toml").write_text((SAMPLES / "handmade.meta.toml").read_text())
    out = tmp_path / "out"
    r1 = batch([logs], out, client=client)
    (o1,) = r1.outcomes
    assert o1.status == "failed" and o1.row["exit_code"] == SchemaError.exit_code
    assert "--frame-rate" in o1.row["error"]
    r2 = batch([logs], out, client=client, frame_rate_hz=RATE_HZ)
    (o2,) = r2.outcomes
    assert o2.status == "ok", o2.row["error"]
    track, _ = read_track(out / "frames.recon.parquet")
    t = track["t_s"].to_numpy()
    assert t[-1] == pytest.approx(reference()["t_s"].iloc[-1], abs=1.0)
