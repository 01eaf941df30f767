"""A record that ends in the air with an arrival airfield given (issue #35 item 7: the PH-LAB
reference flight ends airborne 16 km from its airfield; given the airfield as its arrival, the
joint smoother took it as the last known position, 100 m sd, and bent the whole track onto it:
8.8 km RMS reported with NEES 38 / 93).  An arrival with a runway is an airfield, where the
flight was to land, not where the record ends: the joint smoother does not use it as the end
point and says so; a last known position (no runway) is still the end point."""

from __future__ import annotations

import dataclasses
import warnings

from test_cleaning_synth import synthetic_flight

from flightrecon.cleaning import clean_flight
from flightrecon.filters.joint_method import joint_inputs
from flightrecon.types import Flight, Position


def _cut_in_the_air(arrival: Position):
    flight, _ = synthetic_flight(5)
    d = flight.data
    cut = d[d["t_s"] <= 300.0].reset_index(drop=True)   # lift-off at 65 s, touchdown 500 s on
    meta = dataclasses.replace(flight.meta, arrival=arrival)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        clean = clean_flight(Flight(cut, meta))
    assert clean.phases.ends_airborne and not clean.phases.starts_airborne
    return joint_inputs(clean)


def test_an_arrival_airfield_is_not_the_end_of_a_record_ending_airborne():
    airfield = Position(45.1, 10.1, 100.0, runway_true_deg=90.0)
    inp = _cut_in_the_air(airfield)
    assert inp.ends_airborne
    assert inp.arrival is None and inp.runway_rad[1] is None and inp.thresholds[1] is None
    (note,) = [n for n in inp.notes if "ends in the air" in n]
    assert "runway 90 deg" in note and "not used" in note


def test_a_last_known_position_still_ends_it():
    last = Position(45.1, 10.1, 100.0)
    inp = _cut_in_the_air(last)
    assert inp.arrival is not None and abs(inp.arrival[0] - 45.1) < 1e-12
    assert not any("ends in the air" in n for n in inp.notes)
