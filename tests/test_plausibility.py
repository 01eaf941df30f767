"""Plausibility checks on cleaned flights: each defect found, a clean flight passes."""

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from flightrecon.cleaning import clean_flight
from flightrecon.cleaning.plausibility import plausibility_checks
from flightrecon.ingest import load_flight
from flightrecon.types import Position

LOG = Path(__file__).resolve().parents[1] / "sample_logs" / "circuit.parquet"


@pytest.fixture(scope="module")
def clean():
    return clean_flight(load_flight(LOG))


def _checks(findings):
    return {(f["check"], f["channel"]) for f in findings}


def test_clean_sample_has_no_findings(clean):
    assert plausibility_checks(clean) == []


def _airborne_slice(clean, t0, t1):
    t = clean.grid["t_s"].to_numpy()
    return (t >= clean.phases.liftoff_t_s + t0) & (t < clean.phases.liftoff_t_s + t1)


def test_frozen_and_dead_channels(clean):
    g = clean.grid.copy()
    sel = _airborne_slice(clean, 100, 300)
    g.loc[sel, "roll_deg"] = g.loc[sel, "roll_deg"].iloc[0]
    g["pitch_deg"] = 2.0
    f = plausibility_checks(replace(clean, grid=g))
    assert ("frozen_channel", "roll_deg") in _checks(f)
    assert ("dead_channel", "pitch_deg") in _checks(f)
    span = next(x for x in f if x["check"] == "frozen_channel")["spans_s"][0]
    # the span found is the one injected (to one grid step)
    assert abs(span[0] - (clean.phases.liftoff_t_s + 100)) < 1.0
    assert abs(span[1] - (clean.phases.liftoff_t_s + 300)) < 1.0


def test_below_stall_and_envelope(clean):
    g = clean.grid.copy()
    g.loc[_airborne_slice(clean, 200, 220), "tas_mps"] = 12.0
    g.loc[_airborne_slice(clean, 400, 402), "roll_deg"] = 85.0
    f = _checks(plausibility_checks(replace(clean, grid=g)))
    assert ("below_stall", "tas_mps") in f
    assert ("out_of_envelope", "roll_deg") in f


def test_departure_far_from_data(clean):
    far = Position(clean.meta.departure.lat_deg + 0.2, clean.meta.departure.lon_deg, 3.0)
    f = _checks(plausibility_checks(replace(clean, meta=replace(clean.meta, departure=far))))
    assert ("endpoint_far", "departure") in f
    high = Position(clean.meta.departure.lat_deg, clean.meta.departure.lon_deg, 900.0)
    f = _checks(plausibility_checks(replace(clean, meta=replace(clean.meta, departure=high))))
    assert ("endpoint_far", "baro_alt_m") in f


def test_time_jump(clean):
    g = clean.grid.copy()
    t = g["t_s"].to_numpy()
    sel = (t > 300) & (t < 330)
    for c in [c for c in g.columns if c.endswith("_valid")]:
        g.loc[sel, c] = False
    f = _checks(plausibility_checks(replace(clean, grid=g)))
    assert ("time_jump", "t_s") in f
    assert np.isfinite(t).all()
