"""Where a reconstruction's memory peaks: resident memory over time with the stage running.

Usage::

    python benchmarks/memory_profile.py [--traced] -- reconstruct LOG -o OUT.parquet

Runs the command line (:func:`flightrecon.cli.main.main`) in this process, as the console
command does, while a thread samples the resident set (``/proc/self/statm``, every 20 ms) and
the innermost frames of the package on the other threads.  Prints the peak, the stage under
it, and a line every half second.  With ``--traced``, Python's ``tracemalloc`` also records
every allocation (numpy's arrays included; not those made inside compiled kernels) and the
live memory at its own peak is summed by where it was allocated (the stages are then not
sampled): the method's package under
``flightrecon/methods/``, else the allocating lines.  The tracer makes the run minutes long
and adds its own records to the resident memory: read the resident peak from a run without
``--traced``.  Linux only (``/proc``).
"""

from __future__ import annotations

import argparse
import collections
import os
import sys
import threading
import time
import traceback
import tracemalloc

PAGE = os.sysconf("SC_PAGE_SIZE")
MIB = 2**20


def rss_bytes() -> int:
    with open("/proc/self/statm", encoding="ascii") as f:
        return int(f.read().split()[1]) * PAGE


def stages() -> list[str]:
    """The innermost package frames of every other thread (what each is doing)."""
    out = []
    for tid, frame in sys._current_frames().items():
        if tid == threading.get_ident():
            continue
        st = [f"{f.filename.split('flightrecon/')[-1]}:{f.name}:{f.lineno}"
              for f in traceback.extract_stack(frame) if "flightrecon/" in f.filename]
        if st:
            out.append(" > ".join(st[-4:]))
    return out


def origin(tb: tracemalloc.Traceback) -> str:
    names = [f"{f.filename.split('flightrecon/')[-1]}:{f.lineno}" for f in tb
             if "flightrecon/" in f.filename]
    for n in names:
        if n.startswith("methods/"):
            return "/".join(n.split("/")[:2])
    return " > ".join(names[-3:]) if names else "imports and libraries"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--traced", action="store_true", help="also sum tracemalloc's live memory")
    ap.add_argument("argv", nargs="+", help="the command line's arguments (after --)")
    a = ap.parse_args()
    if a.traced:
        tracemalloc.start(25)
    samples: list[tuple[float, int, list[str]]] = []
    best: list = [0, None]
    done = threading.Event()

    def sample() -> None:
        t0 = time.perf_counter()
        while not done.is_set():
            # with --traced the stages are not sampled (walking the frames under the tracer
            # is what slows it most)
            samples.append((time.perf_counter() - t0, rss_bytes(), [] if a.traced else stages()))
            if a.traced:
                cur = tracemalloc.get_traced_memory()[0]
                # a snapshot copies every live trace: only past 100 MiB (not during the
                # imports) and every 25 MiB more
                if cur > max(best[0] + 25 * MIB, 100 * MIB):
                    best[:] = [cur, tracemalloc.take_snapshot()]
            time.sleep(0.05 if a.traced else 0.02)

    thread = threading.Thread(target=sample, daemon=True)
    thread.start()
    os.environ["FLIGHTRECON_FAST_EXIT"] = "0"   # return here after the command
    from flightrecon.cli.main import main as command

    try:
        command(["--quiet", *a.argv])
    except SystemExit as exc:
        if exc.code not in (0, None):
            raise
    done.set()
    thread.join()
    t_pk, rss_pk, where = max(samples, key=lambda s: s[1])
    print(f"peak resident {rss_pk / MIB:.0f} MiB at {t_pk:.2f} s, under:")
    for w in where:
        print(f"    {w}")
    last = -1.0
    for t, r, w in samples:
        if t - last >= 0.5:
            last = t
            print(f"{t:6.2f} s {r / MIB:6.0f} MiB  {w[0] if w else ''}"[:200])
    if a.traced and best[1] is not None:
        by: collections.Counter[str] = collections.Counter()
        for tr in best[1].traces:
            by[origin(tr.traceback)] += tr.size
        print(f"traced live memory at its peak: {best[0] / MIB:.0f} MiB, by origin:")
        for k, v in by.most_common(12):
            print(f"{v / MIB:8.1f} MiB  {k}")


if __name__ == "__main__":
    main()
