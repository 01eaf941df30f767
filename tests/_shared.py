"""Data the tests read from outside the repository: ``../shared`` beside the clone (in CI),
with the independent simulated flights in ``../shared/corpus`` (or the folder
``FLIGHTRECON_SHARED`` names).

Tests that need it carry ``@pytest.mark.shared_data`` (registered in pyproject.toml);
``tests/conftest.py`` skips them with one line when the folder is absent (a public clone) and
refuses to skip them where ``CI`` or ``FLIGHTRECON_REQUIRE_SHARED`` is set.
"""

from __future__ import annotations

import os
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
#: the shared folder beside the clone, or where ``FLIGHTRECON_SHARED`` says (as the study
#: scripts read it: scripts/sabziev_flights.py)
SHARED = Path(os.environ.get("FLIGHTRECON_SHARED", ROOT.parent / "shared"))
#: the independent corpus: simulated flights made by a generator that is not the project's
CORPUS = SHARED / "corpus"


def corpus_present() -> bool:
    """True when the independent corpus lies beside the clone."""
    return CORPUS.is_dir() and any(CORPUS.glob("c*-fdr.parquet"))
