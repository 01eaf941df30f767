"""Test configuration.

Tests marked ``shared_data`` need the independent corpus beside the clone
(``../shared/corpus``, tests/_shared.py): skipped with one line where it is absent, an error
under CI (``CI`` or ``FLIGHTRECON_REQUIRE_SHARED`` set), which must run them.

Under CI (``CI`` set in the environment) hypothesis runs derandomised: the same thousands of
fuzzed examples on every run, so a CI result is reproducible; on developer machines it explores
new examples every run (and keeps failures in .hypothesis/ to replay them).
"""

import os

import pytest
from _shared import CORPUS, corpus_present
from hypothesis import settings

# a first run on a cold kernel cache sends the methods other than the joint smoother to a child
# process (flightrecon/pipeline/coldstart.py); the tests run them in-process whatever the cache
# holds, so that a monkeypatched method runs where its test put it (tests/test_coldstart.py
# turns the child on where it tests it)
os.environ["FLIGHTRECON_COMPILE_IN_CHILD"] = "0"
# the kernels compile at the command line's LLVM level (flightrecon/cli/entry.py), so that the
# tests run the code the CLI runs and a cold cache compiles faster; numba reads it at import
os.environ.setdefault("NUMBA_OPT", "1")

settings.register_profile("ci", derandomize=True, database=None)
if os.environ.get("CI"):
    settings.load_profile("ci")


def pytest_collection_modifyitems(config, items):
    """Skip the ``shared_data`` tests where ``../shared/corpus`` is absent; under CI, fail."""
    marked = [item for item in items if item.get_closest_marker("shared_data")]
    if not marked or corpus_present():
        return
    if os.environ.get("CI") or os.environ.get("FLIGHTRECON_REQUIRE_SHARED"):
        raise pytest.UsageError(f"{len(marked)} tests need the independent corpus, missing at "
                                f"{CORPUS} (CI lays ../shared beside the clone)")
    skip = pytest.mark.skip(reason=f"needs ../shared/corpus beside the clone (absent: {CORPUS})")
    for item in marked:
        item.add_marker(skip)
