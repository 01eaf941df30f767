"""Estimation health: a method whose covariance or track breaks is reported unhealthy, with
the affected time spans, and the default result falls back to the healthy sources."""

import numpy as np
import pandas as pd

from flightrecon.pipeline import method_health
from flightrecon.types import MethodResult


def _result(name="sns", n=100):
    t = np.arange(n, dtype=float)
    return pd.DataFrame({"t_s": t, f"{name}_north_m": t * 10, f"{name}_east_m": t,
                         f"{name}_north_sd_m": np.ones(n), f"{name}_east_sd_m": np.ones(n)})


def test_healthy_track():
    h = method_health(MethodResult("sns", _result(), {"converged": True}))
    assert h["healthy"] and h["problems"] == []


def test_broken_covariance_and_positions_are_located():
    tr = _result()
    tr.loc[40:44, "sns_east_sd_m"] = -1.0       # covariance lost positive definiteness
    tr.loc[70:71, "sns_north_m"] = np.inf       # diverged
    h = method_health(MethodResult("sns", tr, {}))
    assert not h["healthy"]
    spans = {p["what"]: p["spans_s"] for p in h["problems"]}
    assert spans["sns_east_sd_m missing or not positive"] == [[40.0, 44.0]]
    assert spans["non-finite position inside the coverage"] == [[70.0, 71.0]]


def test_non_convergence_is_unhealthy_and_outside_coverage_is_not():
    tr = _result()
    tr.loc[:9, ["sns_north_m", "sns_east_m", "sns_north_sd_m", "sns_east_sd_m"]] = np.nan
    assert method_health(MethodResult("sns", tr, {}))["healthy"]
    assert not method_health(MethodResult("sns", tr, {"converged": False}))["healthy"]
