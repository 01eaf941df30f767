"""Events of a flight on synthetic cleaned flights with known answers."""

from types import SimpleNamespace

import numpy as np
import pandas as pd
import pytest

from flightrecon.events import (
    Envelope,
    detect_events,
    end_of_record_events,
    events_from_summary,
    events_table,
    exceedance_events,
    measurement_gap_events,
    outage_events,
    source_change_events,
    utc_text,
)

EPOCH = "2026-01-01T10:00:00Z"


def grid(n_s=600, rate=4.0):
    t = np.arange(0, n_s * rate + 1) / rate
    return pd.DataFrame({"t_s": t, "n_norm_g": 1.0 + 0 * t, "roll_deg": 0 * t,
                         "pitch_deg": 3 + 0 * t, "tas_mps": 90 + 0 * t,
                         "baro_alt_m": 1000 + 0 * t})


def test_load_factor_exceedance_span_and_peak():
    g = grid()
    sel = (g["t_s"] >= 100) & (g["t_s"] <= 103)
    g.loc[sel, "n_norm_g"] = 2.7
    g.loc[g["t_s"] == 101.5, "n_norm_g"] = 3.1
    ev = exceedance_events(g)
    assert len(ev) == 1
    e = ev[0]
    assert e.channel == "n_norm_g" and e.t_s == 100.0 and e.end_t_s == 103.0
    assert e.value == pytest.approx(3.1) and e.severity == "alert"


def test_upset_attitude_and_short_blips_ignored():
    g = grid()
    g.loc[(g["t_s"] >= 200) & (g["t_s"] < 205), "roll_deg"] = -50.0
    g.loc[g["t_s"] == 300, "pitch_deg"] = 40.0  # one sample: below the minimum duration
    ev = exceedance_events(g)
    assert [(e.channel, e.t_s) for e in ev] == [("roll_deg", 200.0)]
    assert ev[0].value == pytest.approx(-50.0)
    assert exceedance_events(g, Envelope(bank_deg=60.0)) == []


def test_vmo_checked_only_when_given():
    g = grid()
    g.loc[g["t_s"].between(10, 20), "tas_mps"] = 200.0
    assert exceedance_events(g) == []
    ev = exceedance_events(g, Envelope(vmo_mps=180.0))
    assert len(ev) == 1 and ev[0].t_s == 10.0 and ev[0].end_t_s == 20.0


def test_outage_from_the_valid_mask():
    g = grid()
    valid = np.ones(len(g), bool)
    valid[(g["t_s"] >= 50) & (g["t_s"] <= 70)] = False
    g["tas_mps_valid"] = valid
    ev = outage_events(g)
    assert len(ev) == 1 and ev[0].channel == "tas_mps"
    assert (ev[0].t_s, ev[0].end_t_s) == (50.0, 70.0)


def test_gnss_gap():
    t = np.r_[np.arange(0, 100.0), np.arange(160, 300.0)]
    ev = measurement_gap_events(t, "GNSS fix")
    assert len(ev) == 1 and (ev[0].t_s, ev[0].end_t_s) == (99.0, 160.0)
    assert measurement_gap_events(np.arange(0, 300.0), "GNSS fix") == []


def test_source_changes():
    tr = pd.DataFrame({"t_s": np.arange(6.0),
                       "source": pd.array(["joint", "joint", "sns", "sns", "joint", "joint"],
                                          dtype="string")})
    ev = source_change_events(tr)
    assert [(e.t_s, e.label) for e in ev] == [
        (2.0, "horizontal position: joint -> sns"), (4.0, "horizontal position: sns -> joint")]


def test_steep_descent_at_the_end_of_record_is_no_impact_without_one_detected():
    g = grid(60)
    t = g["t_s"].to_numpy()
    g["baro_alt_m"] = np.where(t > 50, 1000 - 40 * (t - 50), 1000)
    ph = {"liftoff_t_s": float("nan"), "touchdown_t_s": float("nan"), "starts_airborne": True,
          "ends_airborne": True}
    ev = end_of_record_events(g, ph)
    # an impact is detected (cleaning/impact.py), never assumed from the descent alone
    assert len(ev) == 1 and ev[0].kind == "end_airborne" and ev[0].t_s == 60.0
    assert ev[0].severity == "alert" and "falling at 4" in ev[0].detail
    g["baro_alt_m"] = 1000.0
    ev = end_of_record_events(g, ph)
    assert [e.kind for e in ev] == ["end_airborne"] and ev[0].severity == "caution"
    assert end_of_record_events(g, {**ph, "ends_airborne": False}) == []


def test_detected_impact_is_the_event_with_its_time_and_peak_loads():
    g = grid(60)
    ph = {"liftoff_t_s": float("nan"), "touchdown_t_s": float("nan"), "starts_airborne": True,
          "ends_airborne": True, "impact_t_s": 59.5, "impact_peak_load_g": 6.63}
    rep = [{"channel": "phases", "action": "impact", "peak_n_long_g": -2.0,
            "peak_n_lat_g": 2.0, "peak_n_norm_g": 6.0, "saturated": "n_norm_g",
            "sink_rate_mps": 30.0, "tas_mps": 46.0}]
    ev = end_of_record_events(g, ph, rep)
    assert len(ev) == 1 and ev[0].kind == "impact"
    assert (ev[0].t_s, ev[0].end_t_s, ev[0].value) == (59.5, 60.0, 6.63)
    assert "n_norm_g +6.00 g" in ev[0].detail and "n_norm_g at the recorder's range" in ev[0].detail


def test_detect_events_sorted_with_utc_and_round_trip():
    g = grid()
    g.loc[g["t_s"].between(100, 102), "n_norm_g"] = -1.5
    gnss = pd.DataFrame({"t_s": np.r_[np.arange(0, 200.0), np.arange(300, 600.0)]})
    clean = SimpleNamespace(grid=g, gnss=gnss, radar=pd.DataFrame(),
                            phases={"liftoff_t_s": 30.0, "touchdown_t_s": 570.0,
                                    "starts_airborne": False, "ends_airborne": False},
                            report=())
    ev = detect_events(clean)
    kinds = [e.kind for e in ev]
    assert kinds == ["fixes", "liftoff", "exceedance", "gap", "touchdown"]
    assert all(np.diff([e.t_s for e in ev]) >= 0)
    rows = events_table(ev, EPOCH)
    assert rows[1]["utc"] == "2026-01-01T10:00:30.000Z"
    assert rows[3]["end_utc"] == "2026-01-01T10:05:00.000Z"
    back = events_from_summary({"events": rows})
    assert back == ev


def test_utc_text():
    assert utc_text(EPOCH, 3661.25) == "2026-01-01T11:01:01.250Z"
    assert utc_text(None, 1.0) is None and utc_text(EPOCH, float("nan")) is None
