"""An arrival given for a record cut in the air is not its end point
(flightrecon/cleaning/arrival_end.py): the simulated 'circuit' (arrival given in its sidecar,
field 3 m MSL, QNH 1006.51 hPa) cut at 450 s in the downwind leg, 450 m above the field at
70 m/s (its truth)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flightrecon.cleaning import CleaningSettings, clean_flight
from flightrecon.cleaning.arrival_end import MARGIN_QNH_M
from flightrecon.errors import MetadataError
from flightrecon.ingest import load_flight
from flightrecon.ingest.gnss_use import GnssUse
from flightrecon.pipeline import ReconstructSettings, reconstruct

SAMPLES = Path(__file__).resolve().parent.parent / "sample_logs"
CIRCUIT = SAMPLES / "circuit.csv"


@pytest.fixture(scope="module")
def circuit():
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_flight(CIRCUIT)


def _clean(flight, end):
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        c = clean_flight(flight, settings=CleaningSettings(end=end))
    return c, [str(x.message) for x in w]


def _truth_height_above_field(t_s: float, elev_m: float) -> float:
    truth = pd.read_parquet(SAMPLES / "circuit.truth.parquet")
    return float(np.interp(t_s, truth["t_s"], truth["alt_msl_m"])) - elev_m


def test_cut_in_the_air_the_arrival_is_dropped_with_the_evidence(circuit):
    """Cut at 450 s: the arrival is gone from the metadata (kept in extra with the evidence),
    a warning names the airspeed and the height; the height from the pressure altitude and the
    QNH is the true one within 30 m (a 15 K departure from the standard temperature is 5 % of
    the height, 23 m at 450 m; measured 2 m), the airspeed the true 70 m/s within 2 m/s (the
    simulated air-data noise and scale error; measured 71.4)."""
    arr = circuit.meta.arrival
    assert arr is not None
    c, warns = _clean(circuit, 450.0)
    assert c.phases.ends_airborne
    assert c.meta.arrival is None
    rec = c.meta.arrival_not_end
    assert rec is not None
    assert rec.arrival.lat_deg == arr.lat_deg
    assert rec.height_above_field_m == pytest.approx(
        _truth_height_above_field(450.0, arr.elev_m), abs=30.0)
    assert rec.height_above_field_m > MARGIN_QNH_M
    assert rec.tas_mps == pytest.approx(70.0, abs=2.0)
    msg = [w for w in warns if "is not where this record ends" in w]
    assert len(msg) == 1 and "m/s" in msg[0] and "above the arrival field" in msg[0]
    assert [r["action"] for r in c.report if r["channel"] == "arrival"] == ["arrival_not_end"]


def test_whole_record_and_a_low_end_keep_the_arrival(circuit):
    """The whole record ends on the ground: the arrival stays, no word.  Cut at 820 s on final
    (32 m above the field by the truth, 60 m/s): below the 150 m that proves it is elsewhere,
    the arrival stays the end point, with a warning saying the record ends fast."""
    c, warns = _clean(circuit, None)
    assert c.meta.arrival == circuit.meta.arrival
    assert not [r for r in c.report if r["channel"] == "arrival"]
    assert _truth_height_above_field(820.0, circuit.meta.arrival.elev_m) < MARGIN_QNH_M
    c, warns = _clean(circuit, 820.0)
    assert c.meta.arrival == circuit.meta.arrival
    assert [r["action"] for r in c.report if r["channel"] == "arrival"] == [
        "arrival_end_airborne"]
    assert any("the record ends fast" in w for w in warns)


def test_no_method_takes_the_airfield_as_the_end_of_a_record_cut_in_the_air():
    """Recorder only, cut at 450 s: Sabziev needs an end point and, the arrival dropped, has
    none: skipped by default, saying why (before this rule: run and refused, its height ending
    448 m from the end point's); asked for alone, refused (exit 7) with the same reason, never
    bending the track 450 m down to the airfield."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = reconstruct(CIRCUIT, settings=ReconstructSettings(
            methods=None, end=450.0, keep_unhealthy=True),
            gnss_use=GnssUse(withhold=True), record=False)
        st = rec.summary["methods"]["sabziev"]
        assert st["status"] == "skipped"
        assert "the arrival given is not where the record ends" in st["reason"]
        assert rec.summary["flight"]["arrival"] is None
        assert any("is not where this record ends" in w for w in rec.summary["warnings"])
        with pytest.raises(MetadataError, match="arrival given is not where the record ends"):
            reconstruct(CIRCUIT, settings=ReconstructSettings(methods=("sabziev",), end=450.0),
                        gnss_use=GnssUse(withhold=True), record=False)
