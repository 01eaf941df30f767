"""A first run on a cold kernel cache: the estimators compile in two processes at once.

Compiling the numba kernels (``cache=True``) is most of a first run's time on a fresh
installation, and numba compiles one kernel at a time per process (its compiler lock), so two
estimator threads gain nothing while they compile.  When the kernels of more than one chosen
method are not in the cache yet, :func:`run_in_child` runs every chosen method except the
joint smoother in one spawned child process while the parent compiles and runs the joint
smoother: both compile at once, on two cores, and write the cache that every later run loads.
The results are the same as in one process (the same functions on the same inputs; the child's
warnings are re-issued in the parent), so only the first run's wall time changes.  Anything
that goes wrong with the child itself (it cannot start, a result cannot be sent back) falls back
to running that method in the parent.  The child is started before the log is read
(:class:`EarlyChild`), so that it imports the package while the parent reads and cleans the log,
and the Sabziev method, whose kernels compile in a few seconds, stays in the parent beside the
joint smoother when another method goes to the child (the two processes then finish closer
together: docs/performance.md).  A warm cache changes nothing: the methods run on
threads as before, and so does a busy machine (no core to spare: :func:`spare_core`).
``FLIGHTRECON_COMPILE_IN_CHILD=0`` in the environment turns the child off (the test suite
does, so that a test's monkeypatched method runs where the test put it, whatever the state of
the cache); ``=1`` uses it whatever the machine's load.
"""

from __future__ import annotations

import importlib
import multiprocessing
import os
import threading
import time
import warnings
from concurrent.futures import Future, ProcessPoolExecutor
from typing import Any

from flightrecon.types import CleanFlight, MethodResult

#: per method, the compiled kernel whose cache entry tells whether the method's kernels are
#: compiled (its largest kernel, compiled on every run of the method; for a method on the
#: estimation core's shared loops, whose cache holds every model's, a kernel of its own, or a
#: third element naming the model class whose specialisation of the shared loop must be among
#: that loop's cache entries)
KERNEL_SENTINELS: dict[str, tuple[str, ...]] = {
    "joint": ("flightrecon.estimation.filtering", "forward_pass", "JointModel"),
    "sns": ("flightrecon.methods.sns.output", "_densify_kernel"),
    "sabziev": ("flightrecon.methods.sabziev.discrete", "_run_end"),
    "arms": ("flightrecon.estimation.filtering", "forward_pass", "ArmsTrackModel"),
    "azimuth": ("flightrecon.estimation.filtering", "forward_pass", "AzimuthModel"),
}


def _cached(spec: tuple[str, ...]) -> bool:
    """True when the kernel ``(module, name[, model class])`` has a compiled entry in numba's
    cache for this source (numba's index file exists and its source stamp matches; with a
    model class, that class's specialisation), or when that cannot be told."""
    try:
        dispatcher = getattr(importlib.import_module(spec[0]), spec[1])
        # numba's own index: empty when missing or written for another version of the source
        index = dispatcher._cache._cache_file._load_index()
        if len(spec) > 2:  # keys (signature, codegen magic): the model's own specialisation
            return any(str(key[0][0]).startswith(spec[2] + "(") for key in index)
        return bool(index)
    except Exception:  # noqa: BLE001 - numba internals changed, caching off: do as when warm
        return True


def kernels_cached(method: str) -> bool:
    """True when ``method``'s sentinel kernel has a compiled entry in numba's cache for this
    source, or when that cannot be told (then nothing changes: the method runs as on a warm
    cache)."""
    spec = KERNEL_SENTINELS.get(method)
    return True if spec is None else _cached(spec)


#: a compiled kernel every reconstruction with the joint smoother calls early, with
#: arguments of the types it is called with (a float array and a float): the tilt evidence's
#: lag (the cleaning's running median, the first kernel of a run before, is plain numpy on
#: short flights: cleaning/despike.py)
FIRST_KERNEL = ("flightrecon.methods.joint.tilt", "_first_order_lag")


def _load_first_kernel() -> None:
    try:
        import numpy as np

        getattr(importlib.import_module(FIRST_KERNEL[0]), FIRST_KERNEL[1])(np.zeros(3), 0.5)
    except Exception:  # noqa: BLE001 - only a head start: the cleaning calls it itself
        pass


def load_first_kernel_early(workers: int) -> threading.Thread | None:
    """Load the first kernel of a run (:data:`FIRST_KERNEL`) from the cache on a thread while
    the log is read.  numba sets up its CPU target when a process loads its first kernel (0.2
    to 0.4 s), which the cleaning would otherwise wait for; reading a log spends part of its
    time outside the interpreter (Arrow's readers), where the thread runs (docs/performance.md:
    reading and cleaning the 10-hour flight 0.2 s less).  Only with two ``workers`` and the
    kernel in the cache (compiling it there would hold the interpreter against the reading; a
    cold cache has :class:`EarlyChild`).  Returns the thread (a daemon nobody waits for: the
    cleaning's own call waits on numba's lock where they meet) or None."""
    if workers < 2 or not _cached(FIRST_KERNEL):
        return None
    thread = threading.Thread(target=_load_first_kernel, name="first-kernel", daemon=True)
    thread.start()
    return thread


#: child processes this process started (the command line's fast exit leaves them to the
#: interpreter's usual exit, which releases the semaphores of their queues)
_started: list[int] = []


def child_was_started() -> bool:
    """Whether this process started a child process for the methods (:class:`EarlyChild`,
    :class:`ChildMethods`)."""
    return bool(_started)


def _new_pool() -> ProcessPoolExecutor:
    pool = ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("spawn"))
    _started.append(1)
    return pool


#: idle cores, measured over :data:`IDLE_SAMPLE_S`, that count as a core to spare (the
#: parent's own core is busy while it measures)
SPARE_IDLE_CORES = 0.75
IDLE_SAMPLE_S = 0.1


def idle_cores(interval_s: float = IDLE_SAMPLE_S) -> float | None:
    """Cores idle over the next ``interval_s`` seconds, from the kernel's CPU counters
    (``/proc/stat``: idle and I/O-wait time against all time, times the number of cores); None
    where they cannot be read (not Linux)."""
    def sample() -> tuple[float, float]:
        with open("/proc/stat", encoding="ascii") as fh:
            v = [float(x) for x in fh.readline().split()[1:9]]
        return v[3] + v[4], sum(v)

    try:
        idle0, all0 = sample()
        time.sleep(interval_s)
        idle1, all1 = sample()
    except (OSError, ValueError, IndexError):
        return None
    if all1 <= all0:
        return None
    return (os.cpu_count() or 1) * (idle1 - idle0) / (all1 - all0)


def spare_core() -> bool:
    """True when the machine has a core that nobody else uses: the one-minute load average
    below the number of cores less one (the parent's own), or, where the average still
    remembers a minute that is over (a first run right after ``pip install``, the README's),
    at least :data:`SPARE_IDLE_CORES` cores idle now (:func:`idle_cores`).  A child on a busy
    machine only adds work: it imports the package and compiles the shared kernels a second
    time, on a core it must share (docs/performance.md: 75 s against 61 s in one process at a
    load of 4-5 on two cores).  True where neither can be read."""
    try:
        load = os.getloadavg()[0]
    except (AttributeError, OSError):
        load = None
    if load is not None and load < (os.cpu_count() or 1) - 1:
        return True
    idle = idle_cores()
    if idle is None:
        return load is None
    return idle >= SPARE_IDLE_CORES


#: methods whose kernels compile in a few seconds (Sabziev: 2.7 s against the joint's and the
#: SNS's 19-23 s, docs/performance.md): they stay in the parent, beside the joint smoother,
#: when another method goes to the child
QUICK_TO_COMPILE = ("sabziev",)


def _mode() -> str:
    return os.environ.get("FLIGHTRECON_COMPILE_IN_CHILD", "").strip()


def child_methods(chosen: list[str], workers: int, early_started: bool = False) -> list[str]:
    """The methods to run in a child process: every chosen method but the joint smoother (and
    but the :data:`QUICK_TO_COMPILE` ones when another goes), when two workers are allowed, the
    joint smoother is among ``chosen`` (it keeps the parent busy), at least one of them is not
    compiled yet and the machine has a :func:`spare_core` (not asked again when
    ``early_started``: an :class:`EarlyChild` was started on it at the run's start); otherwise
    none.  ``FLIGHTRECON_COMPILE_IN_CHILD``: ``0`` never, ``1`` whatever the load."""
    others = [m for m in chosen if m != "joint"]
    if any(m not in QUICK_TO_COMPILE for m in others):
        others = [m for m in others if m not in QUICK_TO_COMPILE]
    mode = _mode()
    if mode == "0":
        return []
    if workers < 2 or "joint" not in chosen or not others:
        return []
    if all(kernels_cached(m) for m in others):
        return []
    # an early child (EarlyChild) was started on the machine's state at the run's start: the
    # two processes now busy would read as no core to spare
    if mode != "1" and not early_started and not spare_core():
        return []
    return others


def _import_methods() -> None:
    """In the child, while the parent reads and cleans the log: import what the methods run
    (the package, numba, the methods' modules), so that their compilation starts at once."""
    from flightrecon.pipeline import registry  # noqa: F401 - imported for its side effect

    for name in KERNEL_SENTINELS:
        if name != "joint":
            importlib.import_module(f"flightrecon.methods.{name}.method")


class EarlyChild:
    """The child process started before the log is read, when a first run is likely to need
    it (two workers, a core to spare, the joint smoother and a method that may go to the child
    not compiled yet): it imports the package meanwhile.  :meth:`take` hands it to
    :class:`ChildMethods`; an early child nobody took is shut down on exit.  Use as a context
    manager."""

    def __init__(self, workers: int) -> None:
        self._pool: ProcessPoolExecutor | None = None
        mode = _mode()
        candidates = [m for m in KERNEL_SENTINELS if m != "joint" and m not in QUICK_TO_COMPILE]
        if (mode == "0" or workers < 2 or kernels_cached("joint")
                or all(kernels_cached(m) for m in candidates)):
            return
        if mode != "1" and not spare_core():
            return
        try:
            self._pool = _new_pool()
            self._pool.submit(_import_methods)
        except Exception:  # noqa: BLE001 - no child process here: ChildMethods starts one
            self.close()

    def __enter__(self) -> EarlyChild:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def take(self) -> ProcessPoolExecutor | None:
        """The started child process (then the caller's to shut down), or None."""
        pool, self._pool = self._pool, None
        return pool

    def close(self) -> None:
        """Shut the child down if nobody took it."""
        if self._pool is not None:
            self._pool.shutdown(wait=False, cancel_futures=True)
            self._pool = None


def _run_recording(name: str, clean: CleanFlight, settings: Any
                   ) -> tuple[str, Any, list[tuple[str, type[Warning]]]]:
    """In the child: run one method; returns ``("ok", result, warnings)`` or ``("error",
    exception, warnings)``, so that an error of the method itself crosses back as a value and
    any exception of the future is the child's or the transport's own."""
    from flightrecon.pipeline.registry import run_method

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            res: Any = run_method(name, clean, settings)
            kind = "ok"
        except Exception as exc:  # noqa: BLE001 - sent back and raised in the parent
            res, kind = exc, "error"
    return kind, res, [(str(w.message), w.category) for w in caught]


class ChildMethods:
    """The methods run in the child process; :meth:`result` waits for one of them.

    ``started``: a child process started earlier (:meth:`EarlyChild.take`), used instead of a
    new one (and shut down when no method goes to it).  Use as a context manager: the process
    is shut down on exit.
    """

    def __init__(self, names: list[str], clean: CleanFlight, settings: Any,
                 started: ProcessPoolExecutor | None = None) -> None:
        self.names = list(names)
        self._pool: ProcessPoolExecutor | None = started
        self._futures: dict[str, Future[Any]] = {}
        if not self.names:
            self.close()
            return
        try:
            if self._pool is None:
                self._pool = _new_pool()
            for name in self.names:
                self._futures[name] = self._pool.submit(_run_recording, name, clean, settings)
        except Exception:  # noqa: BLE001 - no child process here: run them in the parent
            self.close()
            self._futures = {}

    def __enter__(self) -> ChildMethods:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        """Shut the child process down (cancelling what it has not started)."""
        if self._pool is not None:
            self._pool.shutdown(wait=True, cancel_futures=True)
            self._pool = None

    def _release_when_done(self) -> None:
        """Once every method sent to the child has its result, let the child process exit
        now, while this one still works (its interpreter's exit took 0.9 s on the cold
        circuit run, after the joint smoother had finished, had it waited for :meth:`close`)."""
        if self._pool is not None and all(f.done() for f in self._futures.values()):
            self._pool.shutdown(wait=False)

    def handles(self, name: str) -> bool:
        """True when ``name`` was sent to the child process."""
        return name in self._futures

    def result(self, name: str, clean: CleanFlight, settings: Any) -> MethodResult:
        """The result of ``name`` from the child, its warnings re-issued here.  An error the
        method raised is raised here as it was; a failure of the child process itself (it died,
        or a result could not be sent back) runs the method in this process instead."""
        from flightrecon.pipeline.registry import run_method

        try:
            kind, payload, caught = self._futures[name].result()
        except Exception:  # noqa: BLE001 - the child's own failure, not the method's
            return run_method(name, clean, settings)
        finally:
            self._release_when_done()
        for message, category in caught:
            warnings.warn(message, category, stacklevel=2)
        if kind == "error":
            raise payload
        return payload
