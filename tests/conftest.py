"""Test configuration.

Under CI (``CI`` set in the environment) hypothesis runs derandomised: the same thousands of
fuzzed examples on every run, so a CI result is reproducible; on developer machines it explores
new examples every run (and keeps failures in .hypothesis/ to replay them).
"""

import os

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
