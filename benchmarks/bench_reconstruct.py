"""Speed and memory of a whole reconstruction, stage by stage, against filterpy in the same run.

Usage::

    python benchmarks/bench_reconstruct.py                 # 1 h, 3 h and 10 h longhaul flights
    python benchmarks/bench_reconstruct.py --hours 1 --hours 10 --repeat 3 --out docs/benchmark.md

Each flight size runs in a fresh subprocess (so peak memory, read from ``ru_maxrss``, is that
size's own).  The log is generated with the simulator (``longhaul`` scenario: 16 Hz inputs, 1 Hz
GNSS) and written to Parquet first; generation is not timed.  Its sidecar has no departure and
no arrival airfield (a GNSS-only flight, as a cruise segment comes: the frame's origin is the
first fix, ``--departure`` is not needed), so the Sabziev fusion, which needs the end points,
does not run; the joint smoother and SNS do.  Stages timed: ingest, cleaning,
kinematics, each estimator (filter + smoother), combine, export; then the whole
``python -m flightrecon reconstruct`` command in another subprocess (the console command, with
its own start-up, kernel compilation level and exit; its peak RSS that child's own).

The reference: filterpy's ``KalmanFilter.batch_filter`` + ``rts_smoother`` on a 4-state
constant-velocity model with as many steps as the 10-hour flight has samples, timed in the same
run; the last line printed is the ratio (our whole reconstruction / filterpy's filter+smoother).
Numba compilation is cached on disk (``cache=True``); a warm-up run on a short flight compiles
everything first and its time is reported separately.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import resource
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent


def _child(hours: float, workdir: str) -> dict:
    """Run the stages on a ``hours``-long flight; return timings (s) and peak RSS (MB)."""
    import numpy as np

    from flightrecon.cli.main import _tune_memory

    _tune_memory()  # the memory settings the CLI uses, so the stages are comparable

    from flightrecon.cleaning import clean_flight
    from flightrecon.export.writers import write_summary, write_track
    from flightrecon.geo.kinematics import kinematic_acceleration_ned
    from flightrecon.ingest import load_flight
    from flightrecon.pipeline import (
        ALL_METHODS,
        ReconstructSettings,
        available_methods,
        build_summary,
        combine,
        run_method,
    )
    from flightrecon.sim import simulate, write_simulation

    work = Path(workdir)
    log = work / f"longhaul_{hours:g}h.parquet"
    if not log.exists():
        import dataclasses

        from flightrecon.sim.io import meta_toml, sibling

        sim = simulate("longhaul", seed=1, duration_s=hours * 3600.0)
        write_simulation(sim, log)
        # GNSS-only: no airfield in the metadata (no --departure either)
        sibling(log, ".meta.toml").write_text(meta_toml(dataclasses.replace(
            sim.meta, departure=None, arrival=None)))
    times: dict[str, float] = {}

    def timed(name, fn, *a, **k):
        t0 = time.perf_counter()
        r = fn(*a, **k)
        times[name] = time.perf_counter() - t0
        return r

    flight = timed("ingest", load_flight, log)
    clean = timed("cleaning", clean_flight, flight)
    g = clean.grid
    timed("kinematics", kinematic_acceleration_ned, g["n_long_g"].to_numpy(),
          g["n_lat_g"].to_numpy(), g["n_norm_g"].to_numpy(), g["roll_deg"].to_numpy(),
          g["pitch_deg"].to_numpy(), g["heading_deg"].to_numpy(),
          lat_deg=np.full(len(g), clean.meta.origin.lat_deg), h_m=g["baro_alt_m"].to_numpy())
    settings = ReconstructSettings()
    avail = available_methods(clean, settings)
    results = {}
    for m in ALL_METHODS:  # one after the other here (the CLI runs them on two threads)
        if avail[m] is None:
            results[m] = timed(m, run_method, m, clean, settings)
    track = timed("combine", combine, clean, results)
    summary = build_summary(clean, settings, {m: r.summary for m, r in results.items()})
    out = work / f"out_{hours:g}h.parquet"
    timed("export", lambda: (write_track(out, track, summary),
                             write_summary(out.with_suffix(".json"), summary)))
    if clean.meta.departure is not None or clean.meta.origin is None:
        raise SystemExit("the benchmark flight must have no departure and a GNSS origin")
    if not {"joint", "sns"} <= set(results):
        raise SystemExit(f"joint and SNS must run on the GNSS-only flight: {avail}")
    return {"hours": hours, "samples": len(g), "gnss_fixes": len(clean.gnss),
            "times_s": times, "methods": sorted(results),
            "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0}


def _cli_time(hours: float, workdir: str) -> tuple[float, float]:
    """Wall time [s] and peak RSS [MiB] of the console command ``python -m flightrecon
    --quiet reconstruct`` on the ``hours``-long log: what a user runs (its start-up, its
    compilation level, its exit), the peak from the kernel's accounting of that one child
    (``os.wait4``)."""
    log = Path(workdir) / f"longhaul_{hours:g}h.parquet"
    out = Path(workdir) / f"cli_{hours:g}h.parquet"
    cmd = [sys.executable, "-m", "flightrecon", "--quiet", "reconstruct", str(log),
           "-o", str(out)]
    with tempfile.TemporaryFile() as err:
        t0 = time.perf_counter()
        p = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(p.pid, 0)
        dt = time.perf_counter() - t0
        p.returncode = os.waitstatus_to_exitcode(status)
        if p.returncode != 0:
            err.seek(0)
            raise SystemExit(f"reconstruct failed on {log}:\n{err.read().decode()}")
    return dt, usage.ru_maxrss / 1024.0


def filterpy_reference(n_steps: int, dt: float = 1 / 16) -> float:
    """Seconds for filterpy's batch_filter + rts_smoother, 4-state CV model, ``n_steps`` steps."""
    import numpy as np
    from filterpy.kalman import KalmanFilter

    kf = KalmanFilter(dim_x=4, dim_z=2)
    f1 = np.array([[1.0, dt], [0.0, 1.0]])
    kf.F = np.kron(np.eye(2), f1)
    kf.H = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0]])
    q1 = np.array([[dt**3 / 3, dt**2 / 2], [dt**2 / 2, dt]])
    kf.Q = np.kron(np.eye(2), q1) * 0.1
    kf.R = np.eye(2) * 25.0
    kf.P *= 1e4
    rng = np.random.default_rng(0)
    zs = (np.cumsum(rng.standard_normal((n_steps, 2)), axis=0) + 5 * rng.standard_normal(
        (n_steps, 2)))[:, :, None]
    t0 = time.perf_counter()
    mu, cov, _, _ = kf.batch_filter(zs)
    kf.rts_smoother(mu, cov)
    return time.perf_counter() - t0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--hours", type=float, action="append")
    ap.add_argument("--out", type=Path, help="write the Markdown table here")
    ap.add_argument("--repeat", type=int, default=3,
                    help="runs of the CLI per size (the fastest counts); the filterpy reference "
                         "runs repeat - 1 times (at least once)")
    ap.add_argument("--child", type=float, help=argparse.SUPPRESS)
    ap.add_argument("--workdir", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child is not None:
        print(json.dumps(_child(a.child, a.workdir)))
        return
    hours = a.hours or [1.0, 3.0, 10.0]
    work = tempfile.mkdtemp(prefix="flightrecon-bench-")
    env = dict(os.environ)

    def child(h: float) -> dict:
        p = subprocess.run([sys.executable, __file__, "--child", str(h), "--workdir", work],
                           capture_output=True, text=True, env=env)
        if p.returncode != 0:
            raise SystemExit(p.stderr)
        return json.loads(p.stdout.strip().splitlines()[-1])

    t0 = time.perf_counter()
    warm = child(1.0)  # compiles (or loads the cached) numba kernels; not in the table
    compile_s = time.perf_counter() - t0
    rows = [child(h) for h in hours]
    # the machines are shared and noisy: each timing is the fastest of ``repeat`` runs (as
    # timeit does), for our command and for the reference alike
    cli_runs = {h: [_cli_time(h, work) for _ in range(a.repeat)] for h in hours}
    cli = {h: min(runs) for h, runs in cli_runs.items()}
    n_ref = rows[-1]["samples"]
    ref_runs = [filterpy_reference(n_ref) for _ in range(max(1, a.repeat - 1))]
    ref_s = min(ref_runs)
    stages = list(rows[-1]["times_s"])
    lines = [
        f"Machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"Python {platform.python_version()}; warm-up (numba compile or cache load) "
        f"{compile_s:.1f} s on a {warm['hours']} h flight.",
        "",
        "| flight | samples | GNSS fixes | " + " | ".join(stages)
        + " | stages total | `reconstruct` CLI | peak RSS stages | peak RSS CLI |",
        "|---" * (len(stages) + 7) + "|",
    ]
    for r in rows:
        tot = sum(r["times_s"].values())
        c, crss = cli[r["hours"]]
        lines.append(f"| {r['hours']:g} h | {r['samples']} | {r['gnss_fixes']} | "
                     + " | ".join(f"{r['times_s'].get(s, float('nan')):.2f}" for s in stages)
                     + f" | {tot:.2f} | {c:.2f} | {r['peak_rss_mb']:.0f} MB | {crss:.0f} MB |")
    cli_last = cli[rows[-1]["hours"]][0]
    last = rows[-1]["hours"]
    lines += ["", f"`reconstruct` CLI runs of the {last:g} h flight: "
              + ", ".join(f"{t:.2f} s" for t, _ in cli_runs[last]) + " (fastest counts)",
              "", f"filterpy batch_filter + rts_smoother, 4-state CV, {n_ref} steps: {ref_s:.2f} s "
              f"({ref_s / n_ref * 1e6:.1f} us/step; runs: "
              + ", ".join(f"{t:.2f} s" for t in ref_runs) + ")", "",
              f"ratio (whole `flightrecon reconstruct` of the {rows[-1]['hours']:g} h flight / "
              f"filterpy 4-state filter+smoother): {cli_last / ref_s:.3f}"]
    text = "\n".join(lines)
    if a.out:
        a.out.write_text(text + "\n", encoding="utf-8")
    print(text)


if __name__ == "__main__":
    main()
