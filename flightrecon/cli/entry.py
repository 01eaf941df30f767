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
"""

from __future__ import annotations

import os
import signal


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
    # before numba is imported (by the CLI's modules, below): read at its import
    os.environ.setdefault("NUMBA_OPT", "1")
    from flightrecon.cli.main import main

    main()
