"""The console entry point: catchable signals are handled from the first moment.

Python turns Ctrl-C into a ``KeyboardInterrupt`` traceback while modules are still being
imported, and SIGTERM ends a process without any clean-up.  Before the CLI's modules are
imported (a second or more), :func:`run` makes every catchable terminating signal end the
process quietly with 128 + its number; nothing has been written yet at that point.
:func:`flightrecon.cli.main.main` then installs the handlers that clean up
(:func:`flightrecon.cli.main.install_signal_handlers`).

The command line also compiles its kernels at LLVM optimisation level 1 (``NUMBA_OPT=1``,
unless the environment sets it): a first run on an empty kernel cache spends most of its time
in LLVM, and level 1 cuts the compilation by 10-15 % while the kernels run as fast as at
numba's default level 3 and give the same numbers to the bit (their loops are latency-bound
small-matrix arithmetic without fast-math, where the vectoriser and the unroller of level 3
find nothing to gain; measured on the 10-hour benchmark flight and the shipped samples,
docs/performance.md, sixth session).  The library itself changes no numba setting.

Once the command has finished (its outputs written and flushed, its child process joined), the
process leaves with ``os._exit`` instead of the interpreter's tear-down, which frees every
object and the JIT-compiled code one by one: 0.6 s of a 2.4 s warm run, 1.3 s after a cold one
(measured, docs/performance.md).  Not under a tracer or profiler (coverage, cProfile, whose
results are written at exit), nor after a first run that started a child process
(``pipeline/coldstart.py``: the interpreter's exit releases its queues' semaphores), nor with
``FLIGHTRECON_FAST_EXIT=0``.
"""

from __future__ import annotations

import os
import signal
import sys


def _quiet_exit(signum: int, frame) -> None:
    os._exit(128 + signum)


def run() -> None:
    """``flightrecon`` console script and ``python -m flightrecon``."""
    for name in ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT", "SIGUSR1", "SIGUSR2", "SIGALRM",
                 "SIGXCPU", "SIGXFSZ", "SIGVTALRM", "SIGPROF"):
        s = getattr(signal, name, None)
        if s is None:
            continue
        try:
            if signal.getsignal(s) != signal.SIG_IGN:
                signal.signal(s, _quiet_exit)
        except (OSError, ValueError):
            pass
    process_settings()
    from flightrecon.cli.main import main

    try:
        main()
    except SystemExit as exc:
        leave(exc.code)
        raise


def process_settings() -> None:
    """The command line's process-level settings, before numba is imported (by the CLI's
    modules; numba reads its environment at import): kernels at LLVM level 1."""
    os.environ.setdefault("NUMBA_OPT", "1")


def leave(code: object) -> None:
    """End the process now with ``code`` (an int, or None for 0), its standard streams
    flushed, skipping the interpreter's tear-down; returns (the caller exits the usual way)
    under a tracer or profiler, with ``FLIGHTRECON_FAST_EXIT=0``, for any other code, or
    when a stream cannot be flushed."""
    if code is not None and not isinstance(code, int):
        return
    if os.environ.get("FLIGHTRECON_FAST_EXIT", "").strip() == "0":
        return
    if sys.gettrace() is not None or sys.getprofile() is not None:
        return
    coldstart = sys.modules.get("flightrecon.pipeline.coldstart")
    if coldstart is not None and coldstart.child_was_started():
        return      # a first run's child process: its queues' semaphores are released at exit
    try:
        sys.stdout.flush()
        sys.stderr.flush()
    except (OSError, ValueError):
        return
    os._exit(code or 0)
