"""The joint smoother's ground-row masks: the first sample of each rate bin, judged on a few
samples of a long record, is the whole record's answer (methods/joint/ground.py)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from flightrecon.methods.joint.measurements import decimate_mask, first_in_bin


def _first_of_each_bin(t: np.ndarray, rate_hz: float, origin: float | None) -> np.ndarray:
    """The definition: bin k = floor((t - origin) rate); a sample is kept when its bin differs
    from its predecessor's (the first sample always)."""
    b = np.floor((t - (t[0] if origin is None else origin)) * rate_hz + 1e-9).astype(np.int64)
    keep = np.ones(len(t), bool)
    keep[1:] = b[1:] != b[:-1]
    return keep


@settings(max_examples=200, deadline=None)
@given(st.lists(st.floats(0.0, 500.0), min_size=1, max_size=300),
       st.sampled_from([0.5, 1.0, 4.0, 16.0]), st.sampled_from([None, -0.25, 3.0]),
       st.integers(0, 2 ** 32 - 1))
def test_first_in_bin_on_a_subset_is_the_whole_records_answer(ts, rate, origin, seed):
    t = np.sort(np.asarray(ts, float))
    want = _first_of_each_bin(t, rate, origin)
    assert np.array_equal(decimate_mask(t, rate, origin), want)
    i = np.flatnonzero(np.random.default_rng(seed).random(len(t)) < 0.3)
    assert np.array_equal(first_in_bin(t, rate, i, origin), want[i])


def test_no_rate_keeps_nothing():
    t = np.arange(10.0)
    assert not decimate_mask(t, 0.0).any()
    assert not first_in_bin(t, 0.0, np.arange(3)).any()
