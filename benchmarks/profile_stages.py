"""Where one ``flightrecon reconstruct`` of a glass-cockpit export spends its time, stage by stage.

Usage::

    python benchmarks/profile_stages.py                    # the shipped Garmin export, 3 runs
    python benchmarks/profile_stages.py EXPORT.csv --runs 5 [--json FILE]

Each run is a fresh process (``python benchmarks/profile_stages.py --child ...``) that imports
the command's modules, wraps the functions that make up each stage with a timer and calls the
command line (:func:`flightrecon.cli.main.main`) in the same process, as the user's command
does; the parent times the whole process.  Two cases, as the speed benchmark
(``benchmarks/bench_glass_cockpit.py``): the export with its GPS, and ``--no-gnss`` with
``--departure``/``--arrival`` from the export's first and last GPS fix.

Stages (seconds; the median over the runs):

* ``interpreter start/exit``: the whole process less what the child's script measured (the
  child leaves with ``os._exit``, as the command does);
* ``imports``: the command's modules, numba, pandas, pyarrow and the estimators' modules;
* ``reading`` (``load_flight``), with its parts: the sidecar and the raw file read
  (``read_log``), derived channels, the door's checks and the frame (``validated_frame``), the
  geoid; ``reconstructable`` (the minimum-length check);
* ``cleaning``, ``plausibility``;
* each method (``run_method``; the estimators run on two threads, so these overlap), and inside
  the joint smoother its GNSS gap calibration (``calibrate_gaps``);
* ``health`` (per-method health checks), ``combine``, ``summary``, ``events``;
* ``writing`` (the track and the summary JSON).

``other`` is the command's wall time less the stages that do not overlap (set-up, argument
parsing, the printed outcome, publication).  The functions are wrapped by name, so a renamed
one is reported as missing rather than silently left out.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

T_SCRIPT = time.perf_counter()

HERE = Path(__file__).resolve().parent
DEFAULT_EXPORT = HERE.parent / "sample_logs" / "g1000_sr22_LFQA_20220417.csv"

#: (module, function, stage label, parent stage or "" for a top-level stage)
WRAPPED: tuple[tuple[str, str, str, str], ...] = (
    ("flightrecon.ingest", "load_flight", "reading", ""),
    ("flightrecon.ingest.api", "load_sidecar", "sidecar", "reading"),
    ("flightrecon.ingest.api", "read_log", "raw file", "reading"),
    ("flightrecon.ingest.api", "derived_channels", "derived channels", "reading"),
    ("flightrecon.ingest.api", "validated_frame", "door checks + frame", "reading"),
    ("flightrecon.ingest.api", "with_flight_geoid", "geoid", "reading"),
    ("flightrecon.ingest.physics", "check_reconstructable", "reconstructable", ""),
    ("flightrecon.cleaning", "clean_flight", "cleaning", ""),
    ("flightrecon.cleaning.plausibility", "plausibility_checks", "plausibility", ""),
    ("flightrecon.pipeline.run", "run_method", "method", ""),
    ("flightrecon.methods.joint.method", "calibrate_gaps", "gap calibration", "joint"),
    ("flightrecon.pipeline.run", "method_health", "health", ""),
    ("flightrecon.pipeline.run", "combine", "combine", ""),
    ("flightrecon.pipeline.run", "build_summary", "summary", ""),
    ("flightrecon.events", "detect_events", "events", ""),
    ("flightrecon.export.writers", "write_track", "writing", ""),
    ("flightrecon.export.writers", "write_summary", "writing", ""),
)

#: modules imported (and timed) before the command runs
IMPORTS = ("flightrecon.cli.main", "flightrecon.pipeline", "flightrecon.ingest",
           "flightrecon.cleaning", "flightrecon.events", "flightrecon.export.writers",
           "flightrecon.methods.joint.method", "flightrecon.methods.sns",
           "flightrecon.methods.sabziev")


def _wrap(times: dict[str, float], lock: threading.Lock, mod, name: str, label: str):
    fn = getattr(mod, name)

    def timed(*a, **k):
        t0 = time.perf_counter()
        try:
            return fn(*a, **k)
        finally:
            dt = time.perf_counter() - t0
            key = f"method {a[0]}" if label == "method" else label
            with lock:
                times[key] = times.get(key, 0.0) + dt

    setattr(mod, name, timed)


def child(argv: list[str]) -> dict[str, float]:
    """Run the command ``argv`` in this process with every stage timed."""
    import importlib

    from flightrecon.cli.entry import process_settings

    process_settings()
    times: dict[str, float] = {}
    t0 = time.perf_counter()
    for m in IMPORTS:
        importlib.import_module(m)
    times["imports"] = time.perf_counter() - t0
    lock = threading.Lock()
    for modname, fn, label, _ in WRAPPED:
        _wrap(times, lock, importlib.import_module(modname), fn, label)
    from flightrecon.cli.main import main

    t0 = time.perf_counter()
    try:
        main(argv)
    except SystemExit as exc:
        if exc.code not in (0, None):
            raise
    times["command"] = time.perf_counter() - t0
    times["script"] = time.perf_counter() - T_SCRIPT
    return times


def run_case(argv: list[str]) -> dict[str, float]:
    """One fresh process running ``argv`` under the timers; its times and the process's."""
    with tempfile.NamedTemporaryFile(suffix=".json", delete=False) as fh:
        out = Path(fh.name)
    cmd = [sys.executable, __file__, "--child", str(out), "--", *argv]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} exited {r.returncode}:\n{r.stderr[-2000:]}")
    times = json.loads(out.read_text())
    out.unlink()
    times["process"] = wall
    times["interpreter start/exit"] = wall - times["script"]
    return times


def table(runs: list[dict[str, float]]) -> list[str]:
    """The stage table: medians over the runs, sub-stages indented under their parent."""
    def med(k: str) -> float:
        return statistics.median(r.get(k, 0.0) for r in runs)

    keys = {k for r in runs for k in r}
    methods = sorted(k for k in keys if k.startswith("method "))
    top = ["interpreter start/exit", "imports", "reading", "reconstructable", "cleaning",
           "plausibility", *methods, "health", "combine", "summary", "events", "writing"]
    children: dict[str, list[str]] = {}
    for _, _, label, parent in WRAPPED:
        if parent:
            key = f"method {parent}" if f"method {parent}" in keys else parent
            children.setdefault(key, [])
            if label not in children[key]:
                children[key].append(label)
    lines = []
    for k in top:
        if k not in keys:
            lines.append(f"  {k:28s}      -  (not run)")
            continue
        lines.append(f"  {k:28s} {med(k):6.2f}")
        lines += [f"    {c:26s} {med(c):6.2f}" for c in children.get(k, []) if c in keys]
    def other(r: dict[str, float]) -> float:
        serial = sum(r.get(k, 0.0) for k in top if not k.startswith("method ")
                     and k not in ("interpreter start/exit", "imports"))
        return r["command"] - serial - max((r.get(m, 0.0) for m in methods), default=0.0)

    other_s = statistics.median(other(r) for r in runs)
    each = ", ".join(f"{r['process']:.2f}" for r in runs)
    lines += [f"  {'other (set-up, output)':28s} {other_s:6.2f}",
              f"  {'whole process':28s} {med('process'):6.2f}  (runs: {each})"]
    return lines


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("export", nargs="?", type=Path, default=DEFAULT_EXPORT)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--json", type=Path, help="write every run's stage times here")
    ap.add_argument("--child", type=Path, help=argparse.SUPPRESS)
    ap.add_argument("argv", nargs="*", help=argparse.SUPPRESS)
    a = ap.parse_args()
    if a.child is not None:
        a.child.write_text(json.dumps(child(a.argv)))
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(0)     # as the command leaves (flightrecon.cli.entry.leave): no tear-down
    sys.path.insert(0, str(HERE))
    from bench_glass_cockpit import compile_bytecode, export_ends

    compile_bytecode()      # as an installation from a wheel (bench_glass_cockpit.py)
    dep, arr = export_ends(a.export)
    with tempfile.TemporaryDirectory(prefix="profile_stages_") as tmp:
        cases = {
            "with GNSS": ["-q", "reconstruct", str(a.export), "-o", f"{tmp}/g.parquet"],
            "--no-gnss with its ends": ["-q", "reconstruct", str(a.export), "--no-gnss",
                                        "--departure", dep, "--arrival", arr,
                                        "-o", f"{tmp}/n.parquet"],
        }
        for argv in cases.values():     # warm-up: the kernel cache, the page cache
            run_case(argv)
        results = {name: [run_case(argv) for _ in range(a.runs)] for name, argv in cases.items()}
    load = os.getloadavg()[0]
    print(f"{a.export.name}: stage times [s], median of {a.runs} runs, load {load:.1f}")
    for name, runs in results.items():
        print(f"{name}:")
        print("\n".join(table(runs)))
    if a.json:
        a.json.write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
