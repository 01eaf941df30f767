"""The averaging rule (flightrecon.store.stats), checked against numbers computed independently
with the standard library's ``statistics`` module on a small hand-made fixture."""

import math
import statistics
from datetime import datetime

import numpy as np
import pytest

from flightrecon.errors import StoreError
from flightrecon.store import CoefficientStore, FlightCoefficients
from flightrecon.store.stats import aircraft_stats, drift, fleet_mean, majority_branch

N, P = "negative", "positive"

# flight id, date (UTC), k1, k2, k3, branches, converged
FIXTURE = [
    ("F1", "2024-01-03T08:00:00Z", -0.0110, 2.0e-4, -0.030, (N, P, N), True),
    ("F2", "2024-01-10T14:30:00Z", -0.0125, 2.6e-4, 0.004, (N, P, P), True),
    ("F3", "2024-01-11T06:15:00Z", -0.0090, -1.0e-4, -0.027, (N, N, N), True),
    ("F4", "2024-02-01T09:00:00Z", -0.0131, 2.2e-4, 0.006, (N, P, P), True),
    ("F5", "2024-02-05T20:45:00Z", 0.0500, 9.0e-4, 0.500, (P, P, P), False),  # not converged
    ("F6", "2024-02-20T11:00:00Z", 0.0020, 3.1e-4, -0.033, (P, P, N), True),
    ("F7", "2024-03-02T07:30:00Z", -0.0102, 2.9e-4, 0.005, (N, P, P), True),
]
# Expected selection per axis, worked out by hand from the rule
# (converged only; majority branch; tie -> negative):
#   k1: converged F1-F4, F6, F7 -> branches N N N N P N -> negative; used F1 F2 F3 F4 F7;
#       excluded F5 (not converged), F6 (branch positive)
#   k2: converged branches P P N P P P -> positive; used F1 F2 F4 F6 F7; excluded F5, F3
#   k3: converged branches N P N P N P -> 3 : 3 tie -> negative; used F1 F3 F6;
#       excluded F5, F2, F4, F7
USED = {"k1": ["F1", "F2", "F3", "F4", "F7"], "k2": ["F1", "F2", "F4", "F6", "F7"],
        "k3": ["F1", "F3", "F6"]}
BRANCH = {"k1": N, "k2": P, "k3": N}
EXCLUDED = {
    "k1": {"F5": "not converged", "F6": "branch positive, majority negative"},
    "k2": {"F5": "not converged", "F3": "branch negative, majority positive"},
    "k3": {"F5": "not converged", "F2": "branch positive, majority negative",
           "F4": "branch positive, majority negative", "F7": "branch positive, majority negative"},
}


def records(aircraft="4K-AZ01"):
    return [FlightCoefficients(aircraft_id=aircraft, flight_id=f, flight_date_utc=d,
                               duration_s=3000.0, k1=k1, k2=k2, k3=k3, branch=b, converged=c,
                               residual_m=5.0, iterations=6, software_version="0.1.0")
            for f, d, k1, k2, k3, b, c in FIXTURE]


def _days(text):
    return datetime.fromisoformat(text.replace("Z", "+00:00")).timestamp() / 86400.0


def expected(axis):
    """Mean, median, stdev, slope and its standard error from the standard library alone."""
    col = {"k1": 2, "k2": 3, "k3": 4}[axis]
    rows = [r for r in FIXTURE if r[0] in USED[axis]]
    k = [r[col] for r in rows]
    t = [_days(r[1]) for r in rows]
    slope, intercept = statistics.linear_regression(t, k)
    n = len(k)
    tm = statistics.fmean(t)
    sxx = math.fsum((ti - tm) ** 2 for ti in t)
    ssr = math.fsum((ki - (intercept + slope * ti)) ** 2 for ti, ki in zip(t, k))
    se = math.sqrt(ssr / (n - 2) / sxx)
    return statistics.mean(k), statistics.median(k), statistics.stdev(k), slope, se


@pytest.mark.parametrize("axis", ["k1", "k2", "k3"])
def test_axis_statistics_match_hand_computation(axis):
    st = aircraft_stats("4K-AZ01", records()).axis(axis)
    mean, median, sd, slope, se = expected(axis)
    assert st.branch == BRANCH[axis] and st.n == len(USED[axis])
    assert {e.flight_id: e.reason for e in st.excluded} == EXCLUDED[axis]
    # mean / median / std: the same few operations in another order; values ~1e-2, so
    # agreement to 1e-12 relative is a wide margin over double rounding (~1e-16)
    assert st.mean == pytest.approx(mean, rel=1e-12)
    assert st.median == pytest.approx(median, rel=1e-12)
    assert st.std == pytest.approx(sd, rel=1e-12)
    # drift: dates ~19 700 days spread over ~60 days, so centring loses ~3 of 16 digits and the
    # reference's intercept form (residuals k - a - b t at t ~ 2e4) loses a few more; observed
    # agreement ~2e-14, so 1e-10 relative leaves margin for other platforms yet would catch any
    # wrong formula (ddof, n - 2, uncentred sums)
    assert st.drift_per_day == pytest.approx(slope, rel=1e-10)
    assert st.drift_se_per_day == pytest.approx(se, rel=1e-10)


def test_excluded_counts_and_store_round_trip(tmp_path):
    """The store gives the same statistics as the pure function on the same records."""
    with CoefficientStore(tmp_path / "s.sqlite") as store:
        store.record_many(records())
        store.record_many(records("OTHER"))
        st = store.aircraft_stats("4K-AZ01")
        fm = store.fleet_mean("4K-AZ01")
    ref = aircraft_stats("4K-AZ01", records())
    assert st == ref and st.n_flights == 7
    assert st.axis("k3").excluded_counts() == {"not converged": 1,
                                               "branch positive, majority negative": 3}
    # the fleet mean is that of the property over the stable branch (k2: F3 alone, no spread)
    assert fm.k == tuple(a.prop.k for a in ref.axes) and fm.n == (5, 1, 3)
    assert fm.branch == (N, N, N) and math.isnan(fm.sd[1]) and fm.missing == ()


def test_majority_rule_and_degenerate_cases():
    assert majority_branch([]) is None
    assert majority_branch([P, N]) == N            # tie -> physical branch
    assert majority_branch([P, P, N]) == P
    assert all(math.isnan(v) for v in drift(np.array([1.0]), np.array([2.0])))
    s, se = drift(np.array([0.0, 2.0]), np.array([1.0, 2.0]))
    assert s == 0.5 and math.isnan(se)             # two points: slope exact, no error estimate
    s, se = drift(np.array([5.0, 5.0, 5.0]), np.array([1.0, 2.0, 3.0]))
    assert math.isnan(s) and math.isnan(se)        # one date: no slope
    # exact line -> zero standard error
    s, se = drift(np.array([0.0, 1.0, 3.0]), np.array([1.0, 3.0, 7.0]))
    assert s == pytest.approx(2.0, rel=1e-15) and se == pytest.approx(0.0, abs=1e-15)


def test_fleet_mean_refuses_too_few_usable_fits():
    recs = records()
    with pytest.raises(StoreError, match="k3: 3 usable"):
        fleet_mean(aircraft_stats("4K-AZ01", recs), min_flights=4)
    only_bad = [r for r in recs if r.flight_id == "F5"]
    with pytest.raises(StoreError, match="not converged"):
        fleet_mean(aircraft_stats("4K-AZ01", only_bad))
    one = [r for r in recs if r.flight_id == "F3"]
    fm = fleet_mean(aircraft_stats("4K-AZ01", one))
    assert fm.n == (1, 1, 1) and all(math.isnan(s) for s in fm.sd)  # spread unknown from 1 fit
    with pytest.raises(StoreError):
        aircraft_stats("X", recs)                  # records of another aircraft


def test_axis_convergence_is_per_axis():
    """A flight whose k3 found no root still counts for k1 and k2."""
    recs = [r for r in records() if r.flight_id in ("F1", "F3")]
    partial = FlightCoefficients(
        aircraft_id="4K-AZ01", flight_id="F9", flight_date_utc="2024-03-09T00:00:00Z",
        duration_s=3000.0, k1=-0.0200, k2=-3.0e-4, k3=math.nan, branch=(N, N, "none"),
        converged=False, axis_converged=(True, True, False), residual_m=math.nan, iterations=40,
        software_version="0.1.0")
    st = aircraft_stats("4K-AZ01", recs + [partial])
    k1 = st.axis("k1")
    # F1, F3 and F9: all converged on k1, all negative -> mean of the three (by hand)
    assert k1.n == 3 and k1.excluded == ()
    assert k1.mean == pytest.approx(statistics.mean([-0.0110, -0.0090, -0.0200]), rel=1e-12)
    k3 = st.axis("k3")
    assert k3.n == 2 and [(e.flight_id, e.reason) for e in k3.excluded] == [("F9", "not converged")]
    assert not math.isnan(k3.mean)                      # NaN k3 of F9 never enters the mean
