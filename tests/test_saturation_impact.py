"""Recorder saturation (cleaning/saturation.py) and the impact at a record's end
(cleaning/impact.py) on synthetic records whose answer is known by construction."""

from __future__ import annotations

import numpy as np
import pandas as pd

from flightrecon.cleaning.impact import ImpactSettings, detect_impact
from flightrecon.cleaning.saturation import (
    detect_saturation,
    saturated_loads,
    saturation_levels,
    saturation_on_grid,
)
from flightrecon.types import FlightPhases

RNG = np.random.default_rng(21)


def _quantised(x, q=0.001):
    return np.round(np.asarray(x) / q) * q


def test_clipped_impact_spike_is_saturated_and_a_smooth_peak_is_not():
    t = np.arange(0.0, 60.0, 1 / 16)
    n = _quantised(1.0 + 0.8 * np.exp(-((t - 30.0) / 3.0) ** 2) + 0.005 * RNG.standard_normal(
        len(t)))
    assert saturation_levels("n_norm_g", n) == []        # a manoeuvre's peak, noisy: no level
    n[-3:] = [6.0, 3.1, 6.0]                              # the impact clipped at +6 g
    lv = saturation_levels("n_norm_g", n)
    assert [(lv.end, lv.value, lv.single) for lv in lv] == [("high", 6.0, False)]
    assert np.flatnonzero(lv[0].mask).tolist() == [len(t) - 3, len(t) - 1]


def test_flat_top_run_and_the_mirror_of_a_symmetric_range():
    t = np.arange(0.0, 40.0, 0.25)
    v = np.minimum(50.0 + 3.0 * t, 130.0)                 # a dive into the top of the scale
    lv = saturation_levels("tas_mps", v + 0.0 * t)
    assert lv and lv[0].value == 130.0 and "flat top" in lv[0].why
    # the airspeed's floor at rest is the instrument's, not a saturation
    assert saturation_levels("tas_mps", np.r_[np.zeros(50), 30 + t]) == []
    lat = _quantised(0.02 * RNG.standard_normal(400))
    lat[-3:] = [2.0, -2.0, 2.0]                            # +-2 g: the -2 g reading once
    lv = saturation_levels("n_lat_g", lat)
    assert sorted((x.end, x.value, int(x.mask.sum()), x.single) for x in lv) == [
        ("high", 2.0, 2, False), ("low", -2.0, 1, False)]


def test_saturation_mask_on_the_grid():
    t = np.arange(0.0, 10.0, 0.25)
    x = np.r_[np.linspace(0.0, 1.0, len(t) - 2), [-2.0, -2.0]]
    data = pd.DataFrame({"t_s": t, "n_long_g": x})
    masks, rep = detect_saturation(data)
    assert rep[0]["action"] == "saturation" and rep[0]["count"] == 2 and rep[0]["level"] == -2.0
    grid = pd.DataFrame({"t_s": np.arange(0.0, 9.8, 0.125), "n_long_g": 0.0})
    g = saturation_on_grid(grid, masks)
    sat = g["n_long_g_saturated"].to_numpy()
    # flagged from the grid point after the last unsaturated sample (t = 9.25) on
    assert np.flatnonzero(sat).min() == np.searchsorted(g["t_s"], 9.25, side="right")
    assert saturated_loads(g).sum() == sat.sum()


def _grid(t, n_norm, baro, tas):
    z = np.zeros(len(t))
    return pd.DataFrame({"t_s": t, "n_long_g": z, "n_lat_g": z, "n_norm_g": n_norm,
                         "baro_alt_m": baro, "tas_mps": tas})


PH = FlightPhases(liftoff_t_s=10.0, touchdown_t_s=np.nan, starts_airborne=False,
                  ends_airborne=True, liftoff_velocity_ned_mps=(0.0, 0.0, 0.0))


def test_impact_detected_at_the_spike_with_its_peak():
    t = np.arange(0.0, 100.0, 1 / 16)
    n = 1.8 + 0.02 * RNG.standard_normal(len(t))
    n[-2:] = [6.0, 6.0]
    g = _grid(t, n, 1500.0 - 25.0 * np.maximum(t - 40.0, 0.0), np.full(len(t), 45.0))
    g["n_norm_g_saturated"] = n >= 6.0
    imp, rep = detect_impact(g, PH)
    assert imp is not None and imp.t_s == t[-2]
    assert imp.peak_load_g == 6.0 and imp.saturated == ("n_norm_g",)
    assert abs(imp.sink_rate_mps - 25.0) < 0.5 and rep[0]["action"] == "impact"


def test_firm_landing_and_a_spike_aloft_are_no_impact():
    t = np.arange(0.0, 200.0, 1 / 16)
    td = 150.0
    baro = np.where(t < td, 300.0 - 2.0 * (t - 100.0).clip(0), 200.0)
    n = np.ones(len(t))
    n[(t >= td) & (t < td + 0.25)] = 2.4                  # a firm touchdown at 2 m/s
    tas = np.where(t < td, 35.0, np.maximum(35.0 - 1.5 * (t - td), 0.0))   # then the roll-out
    imp, rep = detect_impact(_grid(t, n, baro, tas), PH)
    assert imp is None and rep == []
    # the record cut by a load spike at 1500 m (no descent onto it): not an impact
    n2 = np.ones(len(t))
    n2[-2:] = 4.5
    imp, rep = detect_impact(_grid(t, n2, np.full(len(t), 1500.0), np.full(len(t), 10.0)), PH)
    assert imp is None and rep[0]["action"] == "no_impact"
    # a steep dive onto a spike, but 1200 m above the wreckage's elevation: not an impact
    from flightrecon.types import FlightMeta, Position

    meta = FlightMeta(aircraft_id="A", flight_id="F", epoch_utc="2026-01-01T00:00:00Z",
                      departure=Position(40.0, 50.0, 0.0), arrival=Position(40.1, 50.1, 0.0))
    baro3 = 1200.0 + 30.0 * (t[-1] - t)
    baro3[t < 20] = 0.0
    imp, rep = detect_impact(_grid(t, n2, baro3, np.full(len(t), 60.0)), PH, meta,
                             ImpactSettings())
    assert imp is None and rep[0]["height_above_end_m"] > 1000.0
