"""Validation and normalisation of FlightCoefficients (flightrecon.store.records)."""

import math
from datetime import date, datetime, timedelta, timezone

import pytest

from flightrecon.errors import StoreError
from flightrecon.store import FlightCoefficients
from flightrecon.store.records import utc_days, utc_text


def fit(**kw):
    base = dict(aircraft_id="4K-AZ01", flight_id="F001", flight_date_utc="2024-05-01T10:00:00Z",
                duration_s=3600.0, k1=-0.01, k2=-1e-4, k3=-0.02,
                branch=("negative", "negative", "negative"), converged=True, residual_m=12.5,
                iterations=7, software_version="0.1.0")
    base.update(kw)
    return FlightCoefficients(**base)


def test_times_normalised_to_utc_text():
    """Equal instants written differently give the same stored text (a store shared across
    time zones must not split one flight into two dates)."""
    a = fit(flight_date_utc="2024-05-01T12:30:00+02:30")
    b = fit(flight_date_utc=datetime(2024, 5, 1, 10, 0, tzinfo=timezone.utc))
    c = fit(flight_date_utc=datetime(2024, 5, 1, 11, 0, tzinfo=timezone(timedelta(hours=1))))
    assert a.flight_date_utc == b.flight_date_utc == c.flight_date_utc == "2024-05-01T10:00:00Z"
    assert fit(flight_date_utc=date(2024, 5, 1)).flight_date_utc == "2024-05-01T00:00:00Z"
    assert fit(flight_date_utc="2024-05-01").flight_date_utc == "2024-05-01T00:00:00Z"
    # one day is exactly 1.0 in the drift regression's time axis
    assert utc_days("2024-05-02T00:00:00Z") - utc_days("2024-05-01T00:00:00Z") == 1.0
    assert utc_text("2024-05-01T10:00:00.250000Z", "t") == "2024-05-01T10:00:00.250000Z"


@pytest.mark.parametrize("bad", [
    dict(flight_date_utc="2024-05-01T10:00:00"),            # no timezone
    dict(flight_date_utc="yesterday"),
    dict(aircraft_id=""), dict(flight_id="  "),
    dict(k2=math.nan), dict(k1=math.inf), dict(k3="x"),
    dict(duration_s=0.0), dict(duration_s=-5.0),
    dict(branch=("negative", "negative")), dict(branch=("neg", "negative", "negative")),
    dict(converged=2), dict(residual_m=-1.0),
    dict(residual_m=math.nan),                               # a converged fit needs a residual
    dict(iterations=-1), dict(iterations=2.5), dict(settings=["a"]),
])
def test_bad_records_raise_store_error(bad):
    with pytest.raises(StoreError):
        fit(**bad)


def test_non_converged_fit_may_have_no_residual():
    """A diverged fit is still worth recording (it is reported, not hidden), residual unknown."""
    f = fit(converged=False, residual_m=math.inf)
    assert math.isnan(f.residual_m)
    assert f == fit(converged=False, residual_m=math.nan)
    assert f != fit(converged=False, residual_m=1.0)
    assert fit().k == (-0.01, -1e-4, -0.02)


def test_per_axis_convergence():
    """An axis that found no root: k unknown (NaN), branch 'none'; the others keep their k."""
    f = fit(converged=False, axis_converged=(True, True, False), k3=None, branch=(
        "negative", "negative", "none"))
    assert math.isnan(f.k3) and f.k1 == -0.01 and f.axis_converged == (True, True, False)
    assert fit().axis_converged == (True, True, True)
    assert fit(converged=False).axis_converged == (False, False, False)
    with pytest.raises(StoreError, match="converged is True"):
        fit(axis_converged=(True, False, True))          # overall flag contradicts the axes
    with pytest.raises(StoreError, match="converged is False"):
        fit(converged=False, axis_converged=(True, True, True))
    with pytest.raises(StoreError, match="must be a finite"):
        fit(converged=False, axis_converged=(False, True, True), k2=math.nan)  # k2 converged
    with pytest.raises(StoreError, match="has a root branch"):
        fit(branch=("negative", "none", "negative"))     # a converged axis has a branch
    with pytest.raises(StoreError):
        fit(axis_converged=(True, True))
