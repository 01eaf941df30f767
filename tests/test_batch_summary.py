"""The batch's summary table as Parquet (``batch_summary.parquet``, docs/batch.md "Tables"): one
typed column per CSV column, the same rows as ``batch_summary.csv``, for ok, failed and
skipped flights; the number of flights told before any runs (the progress bar's total)."""

from __future__ import annotations

import csv
import math
from pathlib import Path

import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from flightrecon.batch import SUMMARY_COLUMNS, SUMMARY_TYPES, batch, write_summary_parquet
from flightrecon.batch.discover import is_log_name
from flightrecon.sim.io import write_simulation
from flightrecon.sim.scenarios import simulate_fleet

ARROW = {"string": pa.string(), "float64": pa.float64(), "int64": pa.int64(), "bool": pa.bool_()}


def test_every_column_typed():
    assert set(SUMMARY_TYPES) == set(SUMMARY_COLUMNS)


def test_the_parquet_table_is_not_a_log():
    """A batch's output folder given as the next batch's input: its table is not a flight."""
    assert not is_log_name(Path("batch_summary.parquet"))


def test_rows_written_with_their_types(tmp_path):
    ok = {"input": "/x/a.csv", "name": "a", "status": "ok", "error": "", "exit_code": 0,
          "aircraft_id": "N1", "flight_id": None, "duration_s": 2838.0, "k1": None,
          "sabziev_converged": None, "stored": "not stored (calibration)", "sources": "joint:2839",
          "joint_mean_nis": 0.1889, "warnings": 8, "elapsed_s": 4.5, "result": "a.recon.parquet"}
    failed = {"input": "/x/b.csv", "name": "b", "status": "failed", "error": "truncated",
              "exit_code": 3, "elapsed_s": None}
    skipped = {**ok, "status": "skipped", "sabziev_converged": True, "k1": 1.25}
    path = write_summary_parquet(tmp_path / "s.parquet", [ok, failed, skipped])
    table = pq.read_table(path)
    assert table.column_names == list(SUMMARY_COLUMNS)
    assert {c: table.schema.field(c).type for c in SUMMARY_COLUMNS} == {
        c: ARROW[SUMMARY_TYPES[c]] for c in SUMMARY_COLUMNS}
    rows = table.to_pylist()
    assert rows[0]["duration_s"] == 2838.0 and rows[0]["warnings"] == 8
    assert rows[0]["k1"] is None and rows[0]["sabziev_converged"] is None
    assert rows[0]["error"] == ""                        # a string column keeps an empty text
    assert rows[1]["error"] == "truncated" and rows[1]["exit_code"] == 3
    assert rows[1]["aircraft_id"] is None and rows[1]["elapsed_s"] is None
    assert rows[2]["sabziev_converged"] is True and rows[2]["k1"] == 1.25
    assert not list(tmp_path.glob(".*")), "written atomically, no temporary file left"


def _csv_text(v) -> str:
    """A Parquet cell as ``batch_summary.csv`` writes it."""
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return ""
    return repr(v) if isinstance(v, float) else str(v)


@pytest.fixture(scope="module")
def two_batches(tmp_path_factory):
    """One short simulated flight and one truncated log, in an in-process Dask client; run
    twice (the second run skips the finished flight)."""
    distributed = pytest.importorskip("distributed")
    logs = tmp_path_factory.mktemp("logs")
    (sim,) = simulate_fleet("A1", 1, seed=5, scenario="circuit")
    write_simulation(sim, logs / "A1_F01.parquet")
    raw = (logs / "A1_F01.parquet").read_bytes()
    (logs / "cut.parquet").write_bytes(raw[: len(raw) // 3])
    out = tmp_path_factory.mktemp("out")
    with distributed.Client(processes=False, n_workers=1, threads_per_worker=1,
                            dashboard_address=None) as client:
        totals: list[int] = []
        r1 = batch([logs], out, client=client, started=totals.append)
        assert totals == [2], "the number of flights is told once, before any flight runs"
        t1 = pq.read_table(out / "batch_summary.parquet")
        r2 = batch([logs], out, client=client)
        t2 = pq.read_table(out / "batch_summary.parquet")
    return out, r1, t1, r2, t2


def test_parquet_matches_csv(two_batches):
    out, r1, t1, r2, t2 = two_batches
    assert r2.summary_parquet == out / "batch_summary.parquet"
    assert [o.status for o in r1.outcomes] == ["ok", "failed"]
    assert [o.status for o in r2.outcomes] == ["skipped", "failed"]
    with open(out / "batch_summary.csv", newline="", encoding="utf-8") as fh:
        csv_rows = list(csv.DictReader(fh))
    pq_rows = t2.to_pylist()
    assert [r["status"] for r in pq_rows] == ["skipped", "failed"]
    for c_row, p_row in zip(csv_rows, pq_rows, strict=True):
        assert {c: _csv_text(p_row[c]) for c in SUMMARY_COLUMNS} == c_row
    ok = t1.to_pylist()[0]
    assert ok["status"] == "ok" and ok["duration_s"] > 600 and ok["joint_mean_nis"] > 0
    assert t1.schema == t2.schema          # a skipped row (from its manifest) keeps the types
    assert pq_rows[1]["exit_code"] == 3 and "Parquet" in pq_rows[1]["error"]
