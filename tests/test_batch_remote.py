"""The batch command against a scheduler and a worker started as separate processes on the
loopback interface, and a batch whose client is killed mid-way then re-run."""

from __future__ import annotations

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from flightrecon.sim.io import write_simulation
from flightrecon.sim.scenarios import simulate_fleet
from flightrecon.store import CoefficientStore

NAMES = ("A1_F01", "A1_F02", "A1_F03")
#: seconds to wait for processes to start on a loaded 2-core machine (normally about 2 s)
START_TIMEOUT_S = 90.0


def _stop(proc: subprocess.Popen) -> None:
    if proc.poll() is None:
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(timeout=15)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait(timeout=15)


@pytest.fixture(scope="module")
def scheduler_file(tmp_path_factory):
    """``dask scheduler`` and one ``dask worker`` (1 process, 1 thread), terminated afterwards."""
    d = tmp_path_factory.mktemp("dask")
    sfile = d / "scheduler.json"
    env = {**os.environ, "NUMBA_NUM_THREADS": "1", "OMP_NUM_THREADS": "1"}
    procs = []
    try:
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
             "--port", "0", "--no-dashboard", "--scheduler-file", str(sfile)],
            cwd=d, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        procs.append(subprocess.Popen(
            [sys.executable, "-m", "distributed.cli.dask_worker", "--scheduler-file", str(sfile),
             "--nworkers", "1", "--nthreads", "1", "--host", "127.0.0.1", "--no-dashboard"],
            cwd=d, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        from distributed import Client

        deadline = time.monotonic() + START_TIMEOUT_S
        while not sfile.is_file():
            assert time.monotonic() < deadline, "scheduler did not start"
            time.sleep(0.1)
        with Client(scheduler_file=str(sfile), timeout=START_TIMEOUT_S) as c:
            c.wait_for_workers(1, timeout=START_TIMEOUT_S)
        yield sfile
    finally:
        for p in reversed(procs):
            _stop(p)


@pytest.fixture(scope="module")
def fleet(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("fleet")
    for r in simulate_fleet("A1", 3, seed=5, scenario="circuit"):
        write_simulation(r, d / f"A1_{r.meta.flight_id}.parquet")
    return d


def _cli(*args: str) -> list[str]:
    return [sys.executable, "-m", "flightrecon.cli.main", "-q", "batch", *args]


def _statuses(out: Path) -> dict[str, str]:
    with open(out / "batch_summary.csv", newline="", encoding="utf-8") as fh:
        return {r["name"]: r["status"] for r in csv.DictReader(fh)}


def test_killed_client_then_rerun_finishes_the_rest(scheduler_file, fleet, tmp_path):
    """Kill the client (SIGKILL) once its first flight is finished; the re-run skips exactly the
    flights with a manifest and does the others; the store ends with one row per flight."""
    out, store = tmp_path / "out", tmp_path / "k.sqlite"
    args = _cli(str(fleet), "--out", str(out), "--scheduler", str(scheduler_file),
                "--store", str(store))
    proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + START_TIMEOUT_S
        while not list(out.glob("*.manifest.json")):
            assert proc.poll() is None, "the batch ended before it could be interrupted"
            assert time.monotonic() < deadline, "no flight finished"
            time.sleep(0.02)
        proc.kill()
        proc.wait(timeout=15)
    finally:
        _stop(proc)
    done = sorted(p.name.split(".")[0] for p in out.glob("*.manifest.json"))
    # one worker does the flights one after the other, each over a second: the kill lands
    # before the last one
    assert 1 <= len(done) < len(NAMES)
    mtimes = {n: (out / f"{n}.manifest.json").stat().st_mtime_ns for n in done}
    assert not (out / "batch_summary.csv").exists()
    res = subprocess.run(args, check=False, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    st = _statuses(out)
    assert sorted(n for n, s in st.items() if s == "skipped") == done
    assert sorted(n for n, s in st.items() if s == "ok") == sorted(set(NAMES) - set(done))
    for n in done:
        assert (out / f"{n}.manifest.json").stat().st_mtime_ns == mtimes[n]
    # every flight whose Sabziev fit is healthy has its row, once (an unhealthy fit, here
    # F02's unconverged one, is not recorded)
    with open(out / "batch_summary.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    healthy = sorted(r["flight_id"] for r in rows if r["stored"] in ("yes", ""))
    with CoefficientStore(store, create=False) as db:
        assert sorted(r.flight_id for r in db.list_flights("A1")) == healthy
    assert len(healthy) >= 2
    assert "3 skipped" in subprocess.run(args, check=False, capture_output=True, text=True,
                                         timeout=300).stdout
    # --force redoes every flight, in CSV this time
    res = subprocess.run(_cli(str(fleet), "--out", str(out), "--scheduler", str(scheduler_file),
                              "--store", str(store), "--force", "--format", "csv"),
                         check=False, capture_output=True, text=True, timeout=300)
    assert res.returncode == 0, res.stderr
    assert set(_statuses(out).values()) == {"ok"}
    assert all((out / f"{n}.recon.csv").is_file() for n in NAMES)


def test_workers_option_conflicts_with_scheduler(scheduler_file, fleet, tmp_path):
    res = subprocess.run(_cli(str(fleet), "--out", str(tmp_path), "--scheduler",
                              str(scheduler_file), "--workers", "2"),
                         check=False, capture_output=True, text=True, timeout=120)
    assert res.returncode == 7 and "--workers" in res.stderr
