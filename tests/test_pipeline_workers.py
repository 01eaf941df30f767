"""The estimators run on a thread pool; the result must not depend on the number of threads."""

from pathlib import Path

import numpy as np
import pandas as pd

from flightrecon.cleaning import clean_flight
from flightrecon.ingest import load_flight
from flightrecon.pipeline import ReconstructSettings, reconstruct_clean

LOG = Path(__file__).resolve().parents[1] / "sample_logs" / "regional.parquet"


def test_one_and_two_threads_give_identical_tracks_and_statuses():
    clean = clean_flight(load_flight(LOG))
    t1, r1, s1 = reconstruct_clean(clean, ReconstructSettings(), workers=1)
    t2, r2, s2 = reconstruct_clean(clean, ReconstructSettings(), workers=2)
    assert list(r1) == list(r2) and len(r1) >= 3
    # same methods, same order, bit-identical numbers (each method is independent and
    # deterministic; threads change only when they run)
    pd.testing.assert_frame_equal(t1, t2, check_exact=True)
    assert {m: s["status"] for m, s in s1.items()} == {m: s["status"] for m, s in s2.items()}
    for m in r1:
        num = r1[m].track.select_dtypes("number").to_numpy()
        np.testing.assert_array_equal(num, r2[m].track.select_dtypes("number").to_numpy())


def test_a_numerical_failure_is_that_methods_error_not_the_runs(monkeypatch):
    """Regression: the pipeline caught FlightReconError only, so a LinAlgError (or another
    numerical breakdown) in one method aborted the whole reconstruction.  It is now that
    method's ``failed`` status, with the exception named, and the others' results stand;
    ``strict`` still raises."""
    import pytest

    import flightrecon.methods.sns.method as sns_method

    def broken(clean, **kwargs):
        raise np.linalg.LinAlgError("Matrix is singular to machine precision.")

    clean = clean_flight(load_flight(LOG))
    monkeypatch.setattr(sns_method, "run_sns", broken)
    track, results, status = reconstruct_clean(clean, ReconstructSettings(), workers=1)
    assert status["sns"]["status"] == "failed"
    assert "LinAlgError" in status["sns"]["reason"]
    assert "sns" not in results and "joint" in results and len(track)
    with pytest.raises(np.linalg.LinAlgError):
        reconstruct_clean(clean, ReconstructSettings(strict=True), workers=1)
