"""A first run on a cold kernel cache compiles in two processes (flightrecon/pipeline/coldstart.py):
the methods other than the joint smoother run in a spawned child process.  What is guarded: the
results are those of one process, the child's warnings reach the parent, a method's own error
stays that method's error, a failure of the child itself falls back to the parent, and the
sentinel kernels that tell a cold cache exist."""

import importlib
import warnings
from concurrent.futures import Future
from concurrent.futures.process import BrokenProcessPool
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flightrecon.cleaning import clean_flight
from flightrecon.ingest import load_flight
from flightrecon.pipeline import ReconstructSettings, coldstart, reconstruct_clean
from flightrecon.pipeline import run as pipeline_run

LOG = Path(__file__).resolve().parents[1] / "sample_logs" / "circuit.parquet"


@pytest.fixture(scope="module")
def clean():
    return clean_flight(load_flight(LOG))


def test_every_sentinel_is_a_cached_kernel_of_its_method():
    """A sentinel that moved or lost ``cache=True`` would leave a cold cache undetected."""
    from flightrecon.pipeline.registry import ALL_METHODS

    assert set(coldstart.KERNEL_SENTINELS) == set(ALL_METHODS)
    for mod, name, *_ in coldstart.KERNEL_SENTINELS.values():
        d = getattr(importlib.import_module(mod), name)
        assert d._cache._cache_file._index_path.endswith(".nbi"), (mod, name)


def test_the_child_is_used_only_when_it_helps(monkeypatch):
    monkeypatch.setenv("FLIGHTRECON_COMPILE_IN_CHILD", "1")
    cold = {"joint": False, "sns": False, "sabziev": True}
    monkeypatch.setattr(coldstart, "kernels_cached", lambda m: cold.get(m, True))
    # Sabziev compiles in seconds: it stays beside the joint smoother when the SNS goes
    assert coldstart.child_methods(["joint", "sabziev", "sns"], 2) == ["sns"]
    assert coldstart.child_methods(["joint", "sabziev"], 2) == []         # Sabziev is warm
    cold["sabziev"] = False
    assert coldstart.child_methods(["joint", "sabziev"], 2) == ["sabziev"]  # alone: it goes
    assert coldstart.child_methods(["joint", "sabziev", "sns"], 1) == []   # one worker
    assert coldstart.child_methods(["sabziev", "sns"], 2) == []           # no joint beside
    assert coldstart.child_methods(["joint"], 2) == []
    cold["sns"] = True
    assert coldstart.child_methods(["joint", "sabziev", "sns"], 2) == []  # all warm
    cold["sns"] = False
    monkeypatch.setenv("FLIGHTRECON_COMPILE_IN_CHILD", "0")
    assert coldstart.child_methods(["joint", "sabziev", "sns"], 2) == []  # turned off


def test_the_early_child_starts_only_when_a_cold_method_may_need_it(monkeypatch):
    """Started before the log is read when a method that would go to the child is cold; taken
    by the methods' child (then theirs to shut down), or shut down unused."""
    monkeypatch.setenv("FLIGHTRECON_COMPILE_IN_CHILD", "1")
    monkeypatch.setattr(coldstart, "kernels_cached", lambda m: m not in ("sns", "joint"))
    with coldstart.EarlyChild(2) as early:
        pool = early.take()
        assert pool is not None and early.take() is None
    pool.shutdown(wait=True)
    monkeypatch.setattr(coldstart, "kernels_cached", lambda m: m != "sns")
    with coldstart.EarlyChild(2) as early:                      # the joint warm: not a first run
        assert early.take() is None
    with coldstart.EarlyChild(1) as early:                      # one worker: no child
        assert early.take() is None
    monkeypatch.setattr(coldstart, "kernels_cached", lambda m: m not in ("sabziev", "joint"))
    with coldstart.EarlyChild(2) as early:                      # only Sabziev cold: parent
        assert early.take() is None
    monkeypatch.setattr(coldstart, "kernels_cached", lambda m: False)
    monkeypatch.setenv("FLIGHTRECON_COMPILE_IN_CHILD", "0")
    with coldstart.EarlyChild(2) as early:                      # turned off
        assert early.take() is None


def test_the_child_is_used_only_with_a_core_to_spare(monkeypatch):
    """Unforced, the child runs only while the load leaves a core beside the parent's."""
    monkeypatch.delenv("FLIGHTRECON_COMPILE_IN_CHILD", raising=False)
    monkeypatch.setattr(coldstart, "kernels_cached", lambda m: m == "joint")
    monkeypatch.setattr(coldstart.os, "cpu_count", lambda: 2)
    monkeypatch.setattr(coldstart, "idle_cores", lambda: 0.1)   # busy now
    for load, used in ((0.4, True), (0.99, True), (1.0, False), (4.2, False)):
        monkeypatch.setattr(coldstart.os, "getloadavg", lambda v=load: (v, v, v))
        assert coldstart.child_methods(["joint", "sns"], 2) == (["sns"] if used else []), load
    # the average still remembers a busy minute that is over (the README's first run, right
    # after pip install): a core idle now is a core to spare
    monkeypatch.setattr(coldstart, "idle_cores", lambda: 0.95)
    assert coldstart.child_methods(["joint", "sns"], 2) == ["sns"]
    monkeypatch.setattr(coldstart, "idle_cores", lambda: 0.5)
    assert coldstart.child_methods(["joint", "sns"], 2) == []
    # an early child started at the run's start is used whatever the machine reads now (the
    # parent and the child themselves keep both cores busy)
    assert coldstart.child_methods(["joint", "sns"], 2, early_started=True) == ["sns"]
    monkeypatch.setenv("FLIGHTRECON_COMPILE_IN_CHILD", "1")  # forced: whatever the load
    assert coldstart.child_methods(["joint", "sns"], 2) == ["sns"]


def test_idle_cores_is_a_share_of_the_machine():
    """Measured from the kernel's counters where they exist: between 0 and the core count."""
    import os
    import sys

    idle = coldstart.idle_cores(0.05)
    if not sys.platform.startswith("linux"):
        assert idle is None
        return
    assert idle is not None and 0.0 <= idle <= (os.cpu_count() or 1) + 1e-9


def test_methods_in_the_child_give_the_results_of_one_process(clean, monkeypatch):
    t1, r1, s1 = reconstruct_clean(clean, ReconstructSettings(), workers=1)
    sent = []

    def all_others(chosen, workers, early_started=False):
        sent[:] = [m for m in chosen if m != "joint"]
        return list(sent)

    monkeypatch.setattr(pipeline_run, "child_methods", all_others)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        t2, r2, s2 = reconstruct_clean(clean, ReconstructSettings(), workers=2)
    assert set(sent) >= {"sabziev", "sns"}
    pd.testing.assert_frame_equal(t1, t2, check_exact=True)
    assert list(r1) == list(r2)
    for m in r1:
        np.testing.assert_array_equal(r1[m].track.select_dtypes("number").to_numpy(),
                                      r2[m].track.select_dtypes("number").to_numpy())
        assert s1[m]["status"] == s2[m]["status"]
    # Sabziev warns (no wind channel on this log): the warning crossed back from the child
    assert any(str(w.message).startswith("sabziev:") for w in caught)


def test_a_failed_child_falls_back_and_a_methods_error_stays_its_own(clean):
    from flightrecon.pipeline.registry import run_method

    settings = ReconstructSettings()
    kids = coldstart.ChildMethods([], clean, settings)
    broken: Future = Future()
    broken.set_exception(BrokenProcessPool("the child died"))
    kids._futures["sabziev"] = broken
    res = kids.result("sabziev", clean, settings)    # re-run in this process
    ref = run_method("sabziev", clean, settings)
    np.testing.assert_array_equal(res.track.select_dtypes("number").to_numpy(),
                                  ref.track.select_dtypes("number").to_numpy())
    own: Future = Future()
    own.set_result(("error", np.linalg.LinAlgError("singular"), []))
    kids._futures["sns"] = own
    with pytest.raises(np.linalg.LinAlgError, match="singular"):
        kids.result("sns", clean, settings)


def test_the_first_kernel_loads_on_a_thread_only_from_a_warm_cache(monkeypatch):
    """numba's first kernel of a run is loaded beside the log's reading only with two workers
    and only from the cache (compiling it there would hold the interpreter against the
    reading); the thread is a daemon that ends, and the kernel it names is a cached one, loaded
    for the argument types a run calls it with (no second signature)."""
    mod, name = coldstart.FIRST_KERNEL
    d = getattr(importlib.import_module(mod), name)
    assert d._cache._cache_file._index_path.endswith(".nbi")   # a cached kernel
    assert coldstart.load_first_kernel_early(1) is None
    monkeypatch.setattr(coldstart, "_cached", lambda spec: False)
    assert coldstart.load_first_kernel_early(2) is None
    monkeypatch.setattr(coldstart, "_cached", lambda spec: True)
    thread = coldstart.load_first_kernel_early(2)
    assert thread is not None and thread.daemon
    thread.join(timeout=60)
    assert not thread.is_alive()
    assert len(d.signatures) >= 1       # loaded (or compiled, here) in this process
    from flightrecon.methods.joint.tilt import remembered

    n_sig = len(d.signatures)
    remembered(np.arange(5.0), np.ones(5), 2.0)   # the run's own call: the same signature
    assert len(d.signatures) == n_sig
