"""Concurrent writers and interrupted writes: nothing lost, nothing half-written."""

import multiprocessing as mp
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time

import pytest

from flightrecon.store import CoefficientStore, FlightCoefficients

N_PROCS, N_EACH = 4, 25


def fit(aircraft, i):
    """A record whose fields all derive from ``i``: a half-written row would not be consistent."""
    return FlightCoefficients(
        aircraft_id=aircraft, flight_id=f"F{i:05d}", flight_date_utc="2024-05-01T10:00:00Z",
        duration_s=1000.0 + i, k1=-1e-3 * (i + 1), k2=-1e-6 * (i + 1), k3=-2e-3 * (i + 1),
        branch=("negative", "negative", "negative"), converged=True, residual_m=float(i),
        iterations=i, software_version="0.1.0", settings={"i": i}, input_hashes={"log": str(i)})


def consistent(f):
    i = int(f.flight_id[1:])
    return (f.duration_s == 1000.0 + i and f.k1 == -1e-3 * (i + 1) and f.k3 == -2e-3 * (i + 1)
            and f.iterations == i and f.settings == {"i": i} and f.residual_m == float(i))


def _writer(path, aircraft, start_evt):
    start_evt.wait()
    with CoefficientStore(path) as store:
        for i in range(N_EACH):
            store.record(fit(aircraft, i))


def test_concurrent_writers_lose_nothing(tmp_path):
    """4 processes x 25 records, one transaction each, racing from the first use of the store
    (so creation of the file and schema is raced too): all 100 rows present."""
    path = tmp_path / "s.sqlite"
    ctx = mp.get_context("fork" if "fork" in mp.get_all_start_methods() else "spawn")
    evt = ctx.Event()
    procs = [ctx.Process(target=_writer, args=(path, f"AC{p}", evt)) for p in range(N_PROCS)]
    for p in procs:
        p.start()
    evt.set()
    for p in procs:
        p.join(timeout=120)
    assert [p.exitcode for p in procs] == [0] * N_PROCS
    with CoefficientStore(path) as store:
        fits = store.list_flights()
        assert store.aircraft() == [(f"AC{p}", N_EACH) for p in range(N_PROCS)]
    assert len(fits) == N_PROCS * N_EACH and all(consistent(f) for f in fits)


def test_exception_inside_transaction_leaves_nothing(tmp_path):
    """Ctrl-C (KeyboardInterrupt) in the middle of a batch: the whole batch is rolled back and
    the store stays writable."""
    path = tmp_path / "s.sqlite"

    def batch():
        for i in range(10):
            if i == 6:
                raise KeyboardInterrupt
            yield fit("A", i)

    with CoefficientStore(path) as store:
        store.record(fit("A", 100))
        with pytest.raises(KeyboardInterrupt):
            store.record_many(batch())
        assert [f.flight_id for f in store.list_flights()] == ["F00100"]
        store.record_many([fit("A", 1), fit("A", 2)])   # lock released: writable again
        assert store.count() == 3


_CHILD = textwrap.dedent("""
    import sys, time
    sys.path.insert(0, {tests!r})
    from test_store_concurrency import fit
    from flightrecon.store import CoefficientStore

    BATCH = 40
    def batch(b):
        for j in range(BATCH):
            if b == 2 and j == BATCH // 2:
                print("inside", flush=True)   # half of batch 2 inserted, transaction open
                time.sleep(60)
            yield fit("K", b * BATCH + j)

    with CoefficientStore({path!r}) as store:
        for b in range(3):
            store.record_many(batch(b))
            print("committed", b, flush=True)
""")


@pytest.mark.skipif(not hasattr(signal, "SIGKILL"), reason="needs SIGKILL")
def test_process_killed_mid_transaction_leaves_no_partial_rows(tmp_path):
    """A writer killed (SIGKILL: no cleanup at all) with a transaction open and half a batch
    inserted: on reopening, the integrity check passes and exactly the committed batches are
    there."""
    path = tmp_path / "s.sqlite"
    code = _CHILD.format(tests=os.path.dirname(__file__), path=str(path))
    child = subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.PIPE, text=True)
    try:
        lines = []
        deadline = time.monotonic() + 60
        while time.monotonic() < deadline:
            line = child.stdout.readline()
            if not line:
                break
            lines.append(line.strip())
            if line.strip() == "inside":
                break
        assert lines == ["committed 0", "committed 1", "inside"]
        os.kill(child.pid, signal.SIGKILL)
        child.wait(timeout=30)
    finally:
        if child.poll() is None:
            child.kill()
            child.wait()
        child.stdout.close()
    assert child.returncode == -signal.SIGKILL
    with CoefficientStore(path) as store:
        fits = store.list_flights()
        assert store.con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    assert len(fits) == 80 and all(consistent(f) for f in fits)
    assert sorted(int(f.flight_id[1:]) for f in fits) == list(range(80))
    con = sqlite3.connect(path)
    assert con.execute("SELECT count(*) FROM flights").fetchone()[0] == 80
    con.close()
