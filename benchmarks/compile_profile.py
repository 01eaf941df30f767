"""Where a cold start's compilation goes: numba's compile events around one command.

Usage (from a folder outside every checkout, a new kernel cache, one process)::

    FLIGHTRECON_COMPILE_IN_CHILD=0 NUMBA_CACHE_DIR=$(mktemp -d) \\
        python benchmarks/compile_profile.py --quiet reconstruct circuit.parquet -o out.parquet

runs ``flightrecon`` with the given arguments in this process with a listener on numba's
``numba:compile``, ``numba:llvm_lock`` and ``numba:run_pass`` events (every thread), then
prints: the wall time, the process's CPU time and the load (on a shared machine the CPU time
is the figure to compare: the wall times below stretch with the load); the time under numba's
LLVM lock (LLVM's optimisation and code generation); per top-level kernel (the estimation
core's loops per model class, ``[JointModel]``) its compilation with everything compiled
inside it, and the LLVM part of that; per function, every one compiled, its own compilation
(its span less the compilations nested in it), the LLVM part, and how many signatures were
compiled; and the functions compiled for more than one signature, with them
(docs/performance.md, "The first run").  With a warm cache nothing is compiled and the tables
are empty.
"""

from __future__ import annotations

import collections
import os
import resource
import sys
import threading
import time

os.environ.setdefault("FLIGHTRECON_COMPILE_IN_CHILD", "0")  # a child's compilations are unseen


def _name(event) -> str:
    """``module.qualname`` of a compile event's dispatcher (the package prefix dropped)."""
    f = event.data["dispatcher"].py_func
    return f"{f.__module__.replace('flightrecon.', '')}.{f.__qualname__}"


def _model(event) -> str:
    """`` [Model]`` when the compiled signature's first argument is a model of the estimation
    core's loops (a named tuple: one compilation of the loop per model class), else ``''``."""
    args = event.data.get("args") or ()
    cls = getattr(args[0], "instance_class", None) if args else None
    return f" [{cls.__name__}]" if cls is not None else ""


def _children_cpu() -> float:
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def main(argv: list[str]) -> None:
    from numba.core import event as ev

    import flightrecon
    from flightrecon.cli.main import main as cli_main

    print(f"flightrecon from {flightrecon.__file__}", file=sys.stderr)

    class Recorder(ev.Listener):
        def __init__(self) -> None:
            self.buf: list[tuple[float, int, ev.Event]] = []

        def on_start(self, event: ev.Event) -> None:
            self.buf.append((time.perf_counter(), threading.get_ident(), event))

        def on_end(self, event: ev.Event) -> None:
            self.buf.append((time.perf_counter(), threading.get_ident(), event))

    kinds = ("numba:compile", "numba:llvm_lock", "numba:run_pass")
    rec = {k: Recorder() for k in kinds}
    for k, listener in rec.items():
        ev.register(k, listener)
    t0 = time.perf_counter()
    cpu0 = time.process_time()
    try:
        cli_main(argv)
    except SystemExit:
        pass
    wall = time.perf_counter() - t0
    cpu = time.process_time() - cpu0
    for k, listener in rec.items():
        ev.unregister(k, listener)

    events = sorted((r for listener in rec.values() for r in listener.buf), key=lambda r: r[0])
    stacks: dict[int, list[list]] = collections.defaultdict(list)
    own: dict[str, float] = collections.defaultdict(float)
    own_llvm: dict[str, float] = collections.defaultdict(float)
    top: dict[str, float] = collections.defaultdict(float)
    top_llvm: dict[str, float] = collections.defaultdict(float)
    n_sig: collections.Counter[str] = collections.Counter()
    dispatchers = {}
    llvm_total = 0.0
    for ts, tid, e in events:
        st = stacks[tid]
        if e.is_start:
            name = _name(e) if e.kind == "numba:compile" else e.kind
            if e.kind == "numba:compile":
                dispatchers[name] = e.data["dispatcher"]
            st.append([e.kind, name, ts, 0.0, _model(e) if e.kind == "numba:compile" else ""])
            continue
        kind, name, t1, nested, model = st.pop()
        d = ts - t1
        if kind == "numba:llvm_lock":
            if not any(s[0] == kind for s in st):  # the outermost hold of the lock
                llvm_total += d
                comps = [s for s in st if s[0] == "numba:compile"]
                if comps:
                    own_llvm[comps[-1][1]] += d
                    top_llvm[comps[0][1] + comps[0][4]] += d
        elif kind == "numba:compile":
            own[name] += d - nested
            n_sig[name] += 1
            comps = [s for s in st if s[0] == "numba:compile"]
            if comps:
                comps[-1][3] += d
            else:
                top[name + model] += d
    load = os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    print(f"wall {wall:.1f} s; CPU time of this process {cpu:.1f} s "
          f"(its children {_children_cpu():.1f} s); load at the end {load:.1f}")
    print(f"compilation {sum(own.values()):.1f} s of {len(own)} functions "
          f"({sum(n_sig.values())} compilations); under the LLVM lock {llvm_total:.1f} s")
    print("\ntop-level kernels: compilation with what it compiled inside / of which LLVM [s]")
    for name, v in sorted(top.items(), key=lambda kv: -kv[1]):
        print(f"  {v:6.2f} {top_llvm[name]:6.2f}  {name}")
    print("\nown compilation / of which LLVM [s], signatures")
    for name, v in sorted(own.items(), key=lambda kv: -kv[1]):
        print(f"  {v:6.2f} {own_llvm[name]:6.2f}  x{n_sig[name]}  {name}")
    print("\nfunctions compiled for more than one signature")
    for name, disp in sorted(dispatchers.items()):
        sigs = disp.signatures
        if len(sigs) > 1:
            print(f"  {name}")
            for s in sigs:
                print(f"      {s}")


if __name__ == "__main__":
    main(sys.argv[1:])
