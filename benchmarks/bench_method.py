"""Time one estimator on a log, in process, several calls: to compare two versions of the code.

Usage::

    python benchmarks/bench_method.py LOG [--method joint] [--calls 3]
    # two trees, alternating (each with its own warm kernel cache):
    for i in 1 2; do for tree in ../old ../new; do
        PYTHONPATH=$tree python benchmarks/bench_method.py LOG; done; done

The log is read and cleaned once (not timed); the method then runs ``--calls`` times
(``flightrecon.pipeline.run_method`` with the default settings, the memory settings of the
command line), and the wall and CPU time of each call are printed with the process's peak
RSS.  The first call of a process also loads the method's kernels from numba's cache: compare
the later calls (on a shared machine their CPU times).  The summary of the last call is the
same for every call (the method is deterministic); its iterations (for the joint smoother) are
printed so that two versions can be seen to do the same work.
"""

from __future__ import annotations

import argparse
import resource
import time


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("log")
    ap.add_argument("--method", default="joint")
    ap.add_argument("--calls", type=int, default=3)
    a = ap.parse_args()

    from flightrecon.cleaning import clean_flight
    from flightrecon.cli.main import _tune_memory
    from flightrecon.ingest import load_flight
    from flightrecon.pipeline import ReconstructSettings, run_method

    _tune_memory()
    clean = clean_flight(load_flight(a.log))
    settings = ReconstructSettings()
    times = []
    cpu = []
    res = None
    for _ in range(max(1, a.calls)):
        t0 = time.perf_counter()
        c0 = time.process_time()
        res = run_method(a.method, clean, settings)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    assert res is not None
    passes = [round(float(i.get("max_position_change_m", float("nan"))), 3)
              for i in res.summary.get("iterations", [])]
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(f"{a.method}: " + ", ".join(f"{t:.3f}" for t in times) + " s; CPU "
          + ", ".join(f"{t:.3f}" for t in cpu) + " s; "
          f"peak RSS {peak:.0f} MiB; passes' position changes [m] {passes}")


if __name__ == "__main__":
    main()
