"""A 1 Hz glass-cockpit flight and a fleet's exports, timed against a bare script in one run.

Usage::

    python benchmarks/bench_glass_cockpit.py                       # the shipped export, 5 rounds
    python benchmarks/bench_glass_cockpit.py --rounds 3 --batch     # + 30 exports through batch
    python benchmarks/bench_glass_cockpit.py --cold --busy          # + a first run, empty cache,
                                                                    #   the other core kept busy

Every figure is a whole process (interpreter start-up, imports, reading, writing), timed with
``time.perf_counter`` around ``subprocess.run``; the commands of one round alternate so that the
machine's load falls on both sides of each ratio alike.  The reference is
``benchmarks/reference_glass_cockpit.py`` (pandas reads the export, filterpy's KF + RTS smooths
its GPS positions, pyarrow writes Parquet: the minimum a script does with the same file).

Cases (issue "speed where users feel it"):

* ``gnss``: ``flightrecon reconstruct EXPORT`` (its GPS used);
* ``no_gnss``: ``flightrecon reconstruct EXPORT --no-gnss --departure .. --arrival ..`` (the
  ends from the export's first and last GPS fix);
* ``batch`` (``--batch``): ten copies of each real export of ``../shared/realdata`` through
  ``flightrecon batch --workers 2`` against the reference run over the same files two at a time;
* ``cold`` (``--cold``): ``gnss`` with an empty numba cache (a new ``NUMBA_CACHE_DIR``), with
  ``--busy`` while a spinning process keeps one core busy.

The package's bytecode is compiled first (``compileall`` of the ``flightrecon`` the commands
import), as an installation from a wheel has it: where ``PYTHONDONTWRITEBYTECODE`` is set and
the checkout has no ``__pycache__``, every command would otherwise compile its 160 modules from
source (0.2-0.4 s a run) while the reference's libraries have theirs.

The ratios (median over the rounds of flightrecon / reference) are the last lines printed;
``--json FILE`` writes every run's time.
"""

from __future__ import annotations

import argparse
import json
import multiprocessing
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
REFERENCE = HERE / "reference_glass_cockpit.py"
DEFAULT_EXPORT = ROOT / "sample_logs" / "g1000_sr22_LFQA_20220417.csv"
REALDATA = ROOT.parent / "shared" / "realdata"
FOOT_M = 0.3048


def export_ends(path: Path) -> tuple[str, str]:
    """``LAT,LON,ELEV_M`` of the export's first and last GPS fix (``AltMSL`` as the elevation)."""
    df = pd.read_csv(path, skiprows=2, skipinitialspace=True, low_memory=False)
    df.columns = [str(c).strip() for c in df.columns]
    lat = pd.to_numeric(df["Latitude"], errors="coerce").to_numpy()
    lon = pd.to_numeric(df["Longitude"], errors="coerce").to_numpy()
    alt = pd.to_numeric(df["AltMSL"], errors="coerce").to_numpy()
    ok = np.flatnonzero(np.isfinite(lat) & np.isfinite(lon) & np.isfinite(alt))
    first, last = ok[0], ok[-1]
    return (f"{lat[first]:.7f},{lon[first]:.7f},{alt[first] * FOOT_M:.1f}",
            f"{lat[last]:.7f},{lon[last]:.7f},{alt[last] * FOOT_M:.1f}")


def compile_bytecode() -> Path:
    """Write the bytecode of the ``flightrecon`` package that ``python -m flightrecon`` imports
    here (``compileall``: what pip does when it installs a wheel); returns its folder."""
    find = "import flightrecon; print(flightrecon.__path__[0])"
    where = subprocess.run([sys.executable, "-c", find], capture_output=True, text=True,
                           check=True).stdout.strip()
    subprocess.run([sys.executable, "-m", "compileall", "-q", where], check=True,
                   stdout=subprocess.DEVNULL)
    return Path(where)


def timed(cmd: list[str], env: dict[str, str] | None = None) -> float:
    """Wall time [s] of one process; raises when it fails."""
    t0 = time.perf_counter()
    r = subprocess.run(cmd, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE,
                       text=True)
    dt = time.perf_counter() - t0
    if r.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)} exited {r.returncode}: {r.stderr[-400:]}")
    return dt


def flightrecon(*args: str) -> list[str]:
    return [sys.executable, "-m", "flightrecon", "-q", *args]


def reference(export: Path, out: Path) -> list[str]:
    return [sys.executable, str(REFERENCE), str(export), str(out)]


def reference_pair(files: list[Path], work: Path) -> float:
    """Wall time [s] of the reference over ``files``, two processes at a time."""
    def one(i_f: tuple[int, Path]) -> None:
        i, f = i_f
        timed(reference(f, work / f"ref{i}.parquet"))
    t0 = time.perf_counter()
    with ThreadPoolExecutor(max_workers=2) as pool:
        list(pool.map(one, enumerate(files)))
    return time.perf_counter() - t0


def spin() -> None:  # pragma: no cover - a busy core, killed by the parent
    while True:
        pass


def single_flight(export: Path, rounds: int, work: Path) -> dict[str, list[float]]:
    dep, arr = export_ends(export)
    cases = {
        "reference": reference(export, work / "ref.parquet"),
        "gnss": flightrecon("reconstruct", str(export), "-o", str(work / "g.parquet")),
        "no_gnss": flightrecon("reconstruct", str(export), "--no-gnss", "--departure", dep,
                               "--arrival", arr, "-o", str(work / "n.parquet")),
    }
    for cmd in cases.values():  # warm-up: the kernel cache, the page cache
        timed(cmd)
    times: dict[str, list[float]] = {k: [] for k in cases}
    for _ in range(rounds):
        for k, cmd in cases.items():
            times[k].append(timed(cmd))
    return times


def fleet(rounds: int, work: Path, copies: int = 10) -> dict[str, list[float]]:
    files = sorted(REALDATA.glob("*.csv"))
    if not files:
        raise SystemExit(f"--batch needs the real exports of {REALDATA}")
    inputs = work / "fleet"
    inputs.mkdir()
    fleet_files = []
    for i in range(copies):
        for f in files:
            dst = inputs / f"{f.stem}_{i:02d}.csv"
            shutil.copyfile(f, dst)
            fleet_files.append(dst)
    times: dict[str, list[float]] = {"batch_reference": [], "batch": []}
    for r in range(rounds):
        times["batch_reference"].append(reference_pair(fleet_files, work))
        out = work / f"batch{r}"
        times["batch"].append(timed(flightrecon("batch", str(inputs), "--workers", "2",
                                                "--out", str(out))))
    return times


def cold(export: Path, rounds: int, work: Path, busy: bool) -> dict[str, list[float]]:
    times: dict[str, list[float]] = {"cold_reference": [], "cold": []}
    spinner = multiprocessing.Process(target=spin, daemon=True) if busy else None
    if spinner is not None:
        spinner.start()
    try:
        for r in range(rounds):
            times["cold_reference"].append(timed(reference(export, work / "ref.parquet")))
            env = dict(os.environ, NUMBA_CACHE_DIR=str(work / f"numba{r}"))
            times["cold"].append(timed(flightrecon("reconstruct", str(export), "-o",
                                                   str(work / "c.parquet")), env=env))
    finally:
        if spinner is not None:
            spinner.kill()
    return times


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("export", nargs="?", type=Path, default=DEFAULT_EXPORT)
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--batch", action="store_true", help="also time 30 exports through batch")
    ap.add_argument("--cold", action="store_true", help="also time a first run, empty cache")
    ap.add_argument("--busy", action="store_true", help="keep one core busy during --cold")
    ap.add_argument("--json", type=Path, help="write every run's time here")
    a = ap.parse_args()
    print(f"bytecode compiled: {compile_bytecode()}")
    with tempfile.TemporaryDirectory(prefix="bench_gc_") as tmp:
        work = Path(tmp)
        times = single_flight(a.export, a.rounds, work)
        if a.batch:
            times |= fleet(max(1, a.rounds // 2), work)
        if a.cold:
            times |= cold(a.export, max(1, a.rounds // 2), work, a.busy)
    for k, v in times.items():
        print(f"{k:16s} median {statistics.median(v):7.2f} s  min {min(v):7.2f}  "
              f"max {max(v):7.2f}  ({len(v)} runs)")
    ratios = {"gnss": "reference", "no_gnss": "reference", "batch": "batch_reference",
              "cold": "cold_reference"}
    for k, ref in ratios.items():
        if k in times:
            r = statistics.median(times[k]) / statistics.median(times[ref])
            print(f"ratio {k} / {ref}: {r:.2f}")
    if a.json:
        a.json.write_text(json.dumps(times, indent=1) + "\n")


if __name__ == "__main__":
    main()
