"""Test configuration.

Under CI (``CI`` set in the environment) hypothesis runs derandomised: the same thousands of
fuzzed examples on every run, so a CI result is reproducible; on developer machines it explores
new examples every run (and keeps failures in .hypothesis/ to replay them).
"""

import os

from hypothesis import settings

settings.register_profile("ci", derandomize=True, database=None)
if os.environ.get("CI"):
    settings.load_profile("ci")
