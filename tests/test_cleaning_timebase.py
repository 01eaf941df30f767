"""Time base: duplicate / backward time stamps, clock offsets, measurements at their own times."""

import numpy as np
import pandas as pd
import pytest
from test_cleaning_synth import synthetic_flight

from flightrecon.cleaning import (
    CleaningSettings,
    clean_flight,
    estimate_rate_hz,
    measurement_table,
    resolve_timestamps,
    uniform_grid,
)
from flightrecon.errors import ValidationError
from flightrecon.types import Flight, FlightMeta


def test_identical_duplicates_dropped_conflicts_merged_backward_dropped():
    d = pd.DataFrame({
        "t_s":      [0.0, 1.0, 1.0, 2.0, 1.5, 3.0, 3.0, 4.0],
        "tas_mps":  [10., 11., 11., 12., 99., 13., 14., 15.],
        "baro_alt_m": [1., np.nan, np.nan, 2., 9., np.nan, 3., 4.],
    })
    before = d.copy()
    out, rep = resolve_timestamps(d)
    pd.testing.assert_frame_equal(d, before)
    np.testing.assert_array_equal(out["t_s"], [0.0, 1.0, 2.0, 3.0, 4.0])
    # the out-of-order row (t = 1.5 after 2.0) is dropped; conflict at t = 3: first row wins,
    # the missing baro of that row is taken from its twin
    np.testing.assert_array_equal(out["tas_mps"], [10., 11., 12., 13., 15.])
    np.testing.assert_array_equal(out["baro_alt_m"], [1., np.nan, 2., 3., 4.])
    actions = {r["action"]: r for r in rep}
    assert actions["drop_backward_rows"]["rows"] == [4]
    assert actions["drop_duplicate_rows"]["rows"] == [2]
    assert actions["merge_conflicting_duplicates"]["channel"] == "tas_mps"
    assert actions["merge_conflicting_duplicates"]["t_s"] == [3.0]


def test_non_finite_time_rejected():
    with pytest.raises(ValidationError):
        resolve_timestamps(pd.DataFrame({"t_s": [0.0, np.nan], "tas_mps": [1.0, 2.0]}))


def test_rate_estimate_and_grid_anchor():
    t = np.arange(100) / 16.0 + 0.01
    assert estimate_rate_hz(t) == 16.0
    g = uniform_grid(0.0, 6.0, 16.0, anchor_s=0.01)
    assert g[0] == pytest.approx(0.01) and np.allclose(np.diff(g), 1 / 16)
    assert g[-1] <= 6.0 and 6.0 - g[-1] < 1 / 16


def test_gnss_rows_equal_fixes_at_16hz():
    """Acceptance: a multi-rate log with 1 Hz GNSS (off the 16 Hz lattice) resampled to 16 Hz
    hands on exactly one GNSS row per fix, at the fix's own time (plus the clock offset)."""
    flight, _ = synthetic_flight(2, gnss_offset_s=0.37)
    n_fixes = int(flight.data["gnss_lat_deg"].notna().sum())
    n_plots = int(flight.data["arms_range_m"].notna().sum())
    s = CleaningSettings(clock_offsets_s={"gnss": -0.2, "radar": 0.05})
    clean = clean_flight(flight, rate_hz=16.0, settings=s)
    assert clean.rate_hz == 16.0
    assert len(clean.gnss) == n_fixes and len(clean.radar) == n_plots
    assert list(clean.gnss.columns)[0] == "t_s" and list(clean.radar.columns)[0] == "t_s"
    raw_t = flight.data.loc[flight.data["gnss_lat_deg"].notna(), "t_s"].to_numpy()
    np.testing.assert_allclose(clean.gnss["t_s"], raw_t - 0.2, atol=1e-12)
    np.testing.assert_array_equal(clean.gnss["gnss_lat_deg"],
                                  flight.data["gnss_lat_deg"].dropna().to_numpy())
    assert not any(c.startswith(("gnss_", "arms_")) for c in clean.grid.columns)
    assert any(r["action"] == "clock_offset" and r["channel"] == "gnss" for r in clean.report)


def test_unknown_clock_source_rejected():
    flight, _ = synthetic_flight(0)
    with pytest.raises(ValidationError):
        clean_flight(flight, settings=CleaningSettings(clock_offsets_s={"gps": 1.0}))


def test_measurement_table_absent_group():
    d = pd.DataFrame({"t_s": [0.0, 1.0], "tas_mps": [1.0, 2.0]})
    m = measurement_table(d, "radar")
    assert list(m.columns) == ["t_s"] and len(m) == 0
    clean = clean_flight(Flight(d, FlightMeta()))
    assert len(clean.radar) == 0 and len(clean.gnss) == 0


def test_absurd_grid_refused():
    """Guards against time stamps in the wrong unit (ms read as s): no 10^10-point grid."""
    t = np.append(np.arange(100) / 16.0, 3.6e7)
    d = pd.DataFrame({"t_s": t, "n_norm_g": np.ones_like(t)})
    with pytest.raises(ValidationError):
        clean_flight(Flight(d, FlightMeta()))


def test_same_row_from_two_files_is_a_plain_duplicate():
    """Regression: ingest's bookkeeping columns (row, src_file) made a GNSS fix repeated in the
    recorder file and the GNSS file look like a conflict instead of a duplicate."""
    d = pd.DataFrame({"t_s": [0.0, 1.0, 1.0, 2.0], "tas_mps": [10.0, 11.0, 11.0, 12.0],
                      "row": [1, 2, 1, 3], "src_file": [0, 0, 1, 0]})
    out, rep = resolve_timestamps(d)
    np.testing.assert_array_equal(out["t_s"], [0.0, 1.0, 2.0])
    assert [r["action"] for r in rep] == ["drop_duplicate_rows"]
