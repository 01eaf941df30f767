"""Mapping the Sabziev method's summary onto a store record (flightrecon.store.adapt)."""

import copy
import math

import pytest

from flightrecon.errors import StoreError
from flightrecon.store import from_sabziev_summary

# the fields of run_sabziev's summary that the adapter reads, with the solver's own key names
SUMMARY = {
    "converged": True, "mode": "boundary-value", "k1": -0.012, "k2": -2.0e-4, "k3": -0.021,
    "axes": {
        "x": {"converged": True, "k": -0.012, "residual_m": 0.3, "iterations": 5,
              "branch": "negative"},
        "y": {"converged": True, "k": -2.0e-4, "residual_m": -0.4, "iterations": 9,
              "branch": "negative"},
        "z": {"converged": True, "k": -0.021, "residual_m": 1.2, "iterations": 6,
              "branch": "negative"},
    },
    "end_residual_m": {"north": 3.0, "up": 4.0, "east": 12.0},
    "interval_s": [120.0, 5520.0],
}
IDS = dict(aircraft_id="4K-AZ01", flight_id="F0412", flight_date_utc="2024-05-01T10:00:00Z")


def test_boundary_value_fit():
    r = from_sabziev_summary(SUMMARY, **IDS, settings={"rate_hz": 16.0},
                             input_hashes={"log": "ab"})
    assert r.k == (-0.012, -2.0e-4, -0.021) and r.branch == ("negative",) * 3
    assert r.converged and r.axis_converged == (True, True, True)
    assert r.residual_m == 13.0            # |(3, 4, 12)|, exact in floating point
    assert r.iterations == 20 and r.duration_s == 5400.0
    assert r.settings == {"rate_hz": 16.0} and r.input_hashes == {"log": "ab"}


def test_failed_axis_is_recorded_as_such():
    s = copy.deepcopy(SUMMARY)
    s["converged"] = False
    s["axes"]["z"].update(converged=False, k=None, branch="none", iterations=40)
    s["end_residual_m"]["east"] = None
    r = from_sabziev_summary(s, **IDS)
    assert r.axis_converged == (True, True, False) and not r.converged
    assert math.isnan(r.k3) and r.branch[2] == "none" and math.isnan(r.residual_m)


def test_refuses_initial_value_mode_and_malformed_summaries():
    s = copy.deepcopy(SUMMARY)
    s["mode"] = "initial-value"
    with pytest.raises(StoreError, match="nothing to record"):
        from_sabziev_summary(s, **IDS)
    s = copy.deepcopy(SUMMARY)
    del s["axes"]["y"]["branch"]
    with pytest.raises(StoreError, match="'branch' missing in axis 'y'"):
        from_sabziev_summary(s, **IDS)
    with pytest.raises(StoreError, match="'mode' missing"):
        from_sabziev_summary({}, **IDS)
