"""The fleet mean of an aircraft property (flightrecon.store.stats.property_stats, docs/store.md
"The fleet mean"): the transform, the stable branch only, the conditioning weights, and the
schema-v4 column that carries each root's conditioning; numbers worked out by hand."""

import math
import sqlite3

import pytest

from flightrecon.errors import StoreError
from flightrecon.store import CoefficientStore, FlightCoefficients, db, schema
from flightrecon.store.stats import aircraft_stats, fleet_mean, from_property, to_property

N, P, NONE = "negative", "positive", "none"


def fit(fid, k, sd, branch=(N, N, N), conv=(True, True, True)):
    return FlightCoefficients(aircraft_id="A", flight_id=fid,
                              flight_date_utc="2026-01-01T00:00:00Z", duration_s=900.0,
                              k1=k[0], k2=k[1], k3=k[2], branch=branch, converged=all(conv),
                              residual_m=0.01 if all(conv) else math.nan, iterations=5,
                              software_version="t", axis_converged=conv, k_sd=sd)


def fixture():
    return [
        # k1: tau 10 s (sd 0.001/0.01 = 0.1 s), tau 20 s (sd 0.0005/0.0025 = 0.2 s)
        # k2: w 0.2 (sd 0.004/0.4 = 0.01), w 0.3 (sd 0.009/0.6 = 0.015)
        fit("F1", (-0.1, -0.04, -0.02), (0.001, 0.004, None)),
        fit("F2", (-0.05, -0.09, -0.04), (0.0005, 0.009, None)),
        # positive branch on k1 (not the stable branch) and an axis without a root on k3
        fit("F3", (0.01, -0.0625, math.nan), (0.0001, 0.005, None), branch=(P, N, NONE),
            conv=(True, True, False)),
    ]


def test_transform_round_trip_and_its_first_order_sd():
    assert to_property("k1", -0.1, 0.001) == pytest.approx((10.0, 0.1), rel=1e-12)
    assert to_property("k2", -0.04, 0.004) == pytest.approx((0.2, 0.01), rel=1e-12)
    for axis, k, sd in (("k1", -0.03, 1e-4), ("k2", -0.05, 2e-3), ("k3", -0.2, 0.01)):
        assert from_property(axis, *to_property(axis, k, sd)) == pytest.approx((k, sd), rel=1e-12)
    with pytest.raises(StoreError):
        to_property("k1", 0.01, 0.001)   # the positive branch has no time constant


def test_weighted_mean_of_the_property_on_the_stable_branch():
    st = aircraft_stats("A", fixture())
    p1 = st.axis("k1").prop
    # F3 excluded (positive); weights 1/0.1^2 = 100 and 1/0.2^2 = 25: (100*10 + 25*20)/125 = 12
    assert p1.n == 2 and p1.weighted and p1.quantity == "tau_s"
    assert p1.mean == pytest.approx(12.0, rel=1e-12)
    assert p1.se == pytest.approx(1 / math.sqrt(125.0), rel=1e-12)
    assert p1.spread == pytest.approx(math.sqrt(50.0), rel=1e-12)     # sd of (10, 20)
    # chi2/dof = (100 * 4 + 25 * 64) / 1 = 2000: the flights differ far beyond their conditioning
    assert p1.chi2_dof == pytest.approx(2000.0, rel=1e-12)
    assert p1.k == pytest.approx(-1 / 12.0, rel=1e-12)
    assert p1.k_sd == pytest.approx(math.sqrt(50.0) / 144.0, rel=1e-12)
    p2 = st.axis("k2").prop
    # w = 0.2, 0.3, 0.25 with sd 0.01, 0.015, 0.005/0.5 = 0.01: weights 10000, 4444.4, 10000
    w = [1e4, 1 / 0.015**2, 1e4]
    mean = (w[0] * 0.2 + w[1] * 0.3 + w[2] * 0.25) / sum(w)
    assert p2.n == 3 and p2.weighted and p2.mean == pytest.approx(mean, rel=1e-12)
    assert p2.k == pytest.approx(-mean**2, rel=1e-12)
    p3 = st.axis("k3").prop
    # k3 conditioning unknown: equal weights, tau 50 and 25 s; F3 has no root
    assert p3.n == 2 and not p3.weighted and p3.mean == pytest.approx(37.5, rel=1e-12)
    assert math.isnan(p3.chi2_dof) and p3.se == pytest.approx(p3.spread / math.sqrt(2))
    fm = fleet_mean(st, min_flights=2)
    assert fm.k == (p1.k, p2.k, p3.k) and fm.branch == (N, N, N) and fm.n == (2, 3, 2)


def test_an_axis_without_enough_fits_is_missing_only_when_allowed():
    recs = fixture()[:1] + fixture()[2:]          # k1: one stable root (F1), F3 positive
    st = aircraft_stats("A", recs)
    with pytest.raises(StoreError, match="k1: 1 usable on the stable branch"):
        fleet_mean(st, min_flights=2)
    fm = fleet_mean(st, min_flights=2, allow_missing=True)
    assert fm.missing == ("k1", "k3") and math.isnan(fm.k[0]) and fm.branch[0] == NONE
    assert fm.k[1] < 0 and fm.n[1] == 2
    with pytest.raises(StoreError):               # nothing usable on any axis: refused
        fleet_mean(aircraft_stats("A", recs[1:]), min_flights=2, allow_missing=True)


def test_conditioning_round_trips_and_a_v3_store_is_upgraded(tmp_path):
    path = tmp_path / "v3.sqlite"
    con = sqlite3.connect(path, isolation_level=None)
    with db.write_transaction(con):
        schema.create_schema(con, schema.SCHEMA_V3_DDL, 3)
        cols = schema.FLIGHT_COLUMNS[:-3]
        con.execute(f"INSERT INTO flights ({', '.join(cols)}) VALUES "
                    f"({', '.join('?' for _ in cols)})",
                    ("A", "OLD", "2026-01-01T00:00:00Z", 900.0, -0.1, -0.04, -0.02, N, N, N,
                     1, 1, 1, 1, 0.01, 5, "t", "{}", "{}", "2026-01-01T00:00:00Z", None))
    con.close()
    with CoefficientStore(path) as st:
        old = st.get("A", "OLD")
        assert all(math.isnan(x) for x in old.k_sd)   # not recorded before v4: unknown
        new = st.record(fixture()[0])
        assert st.get("A", "F1") == new and new.k_sd[:2] == (0.001, 0.004)
        # one fit without conditioning: the k1 mean falls back on equal weights
        assert not st.aircraft_stats("A").axis("k1").prop.weighted
    con = sqlite3.connect(path)
    assert con.execute("PRAGMA user_version").fetchone()[0] == schema.SCHEMA_VERSION == 4
    with pytest.raises(sqlite3.IntegrityError):       # a conditioning is positive
        con.execute("UPDATE flights SET k1_sd = -1.0")
    con.close()
