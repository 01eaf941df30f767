"""Gap policy and resampling of input channels (flightrecon.cleaning.gaps / resample)."""

import numpy as np
import pandas as pd
import pytest

from flightrecon.cleaning import CleaningSettings, clean_flight, interpolate_with_gaps
from flightrecon.cleaning.resample import boxcar, resample_inputs
from flightrecon.types import Flight, FlightMeta


def _log(t16, **cols):
    return pd.DataFrame({"t_s": t16, **cols})


def test_short_gap_interpolated_long_gap_flagged():
    t = np.arange(0, 60, 1 / 16)
    x = 2.0 * t  # linear: interpolation across a short gap is exact
    keep = ~(((t > 10) & (t < 11.5)) | ((t > 30) & (t < 35)))
    vals, valid = interpolate_with_gaps(t[keep], x[keep], t, 1 / 16, max_gap_s=2.0)
    assert valid[(t > 10) & (t < 11.5)].all()
    np.testing.assert_allclose(vals[(t > 10) & (t < 11.5)], x[(t > 10) & (t < 11.5)], atol=1e-12)
    long = (t > 30) & (t < 35)
    assert not valid[long].any() and np.isnan(vals[long]).all()
    assert valid[~long].all()


def test_edges_held_half_a_period_only():
    t = np.arange(2.0, 10.0, 1.0)
    grid = np.arange(0.0, 12.0, 0.25)
    vals, valid = interpolate_with_gaps(t, t * 0 + 5.0, grid, 1.0, 2.0)
    assert valid[(grid >= 1.5) & (grid <= 9.5)].all()
    assert not valid[(grid < 1.5) | (grid > 9.5)].any()


def test_grid_has_valid_masks_and_long_gap_report():
    t = np.arange(0, 40, 1 / 16)
    tas = np.where((t > 10) & (t < 20), np.nan, 50.0 + t)
    d = _log(t, tas_mps=tas, n_norm_g=np.ones_like(t))
    clean = clean_flight(Flight(d, FlightMeta()), settings=CleaningSettings(phases=None))
    g = clean.grid
    assert clean.rate_hz == 16.0 and len(g) == len(t)
    assert g["tas_mps_valid"].dtype == bool
    inside = (g["t_s"] > 10) & (g["t_s"] < 20)
    assert not g.loc[inside, "tas_mps_valid"].any() and g.loc[inside, "tas_mps"].isna().all()
    assert g.loc[~inside, "tas_mps_valid"].all()
    gap = [r for r in clean.report if r["action"] == "long_gap" and r["channel"] == "tas_mps"]
    assert len(gap) == 1 and gap[0]["t_s"] == pytest.approx([10.0, 20.0])


def test_slow_channel_upsampled_heading_unwrapped():
    t16 = np.arange(0, 20, 1 / 16)
    hdg = np.full_like(t16, np.nan)
    t1 = np.arange(0, 20, 1.0)
    hdg[::16] = (355.0 + 2.0 * t1) % 360.0  # 1 Hz heading through north
    d = _log(t16, n_norm_g=np.ones_like(t16), heading_deg=hdg)
    g = clean_flight(Flight(d, FlightMeta()), settings=CleaningSettings(phases=None)).grid
    # interpolated on the unwrapped series: 355 + 2 t (never a 360 deg swing through 180)
    ok = g["heading_deg_valid"].to_numpy() & (g["t_s"].to_numpy() <= 19.0)  # last sample: 19 s
    np.testing.assert_allclose(g["heading_deg"][ok], 355.0 + 2.0 * g["t_s"][ok], atol=1e-9)


def test_downsampling_boxcar_antialias():
    """16 Hz -> 4 Hz: a 3.9 Hz vibration (which would alias to 0.1 Hz) is attenuated by the
    boxcar by at least 16 dB (|H| <= 0.16), while a 0.05 Hz manoeuvre passes (|H| > 0.999)."""
    t = np.arange(0, 200, 1 / 16)
    slow = np.sin(2 * np.pi * 0.05 * t)
    vib = np.sin(2 * np.pi * 3.9 * t)
    d = _log(t, n_norm_g=1.0 + slow + vib)
    grid, rate, rep = resample_inputs(d, 4.0, 2.0)
    assert rate == 4.0
    assert any(r["action"] == "antialias" for r in rep)
    gt = grid["t_s"].to_numpy()
    resid = grid["n_norm_g"].to_numpy() - 1.0 - np.sin(2 * np.pi * 0.05 * gt)
    inner = (gt > 5) & (gt < 195)
    # boxcar gain at 3.9 Hz over 4 samples at 16 Hz is 0.155; the slow term loses < 1e-3
    assert np.max(np.abs(resid[inner])) < 0.16 + 1e-3
    assert boxcar(np.arange(5.0), 1).tolist() == [0, 1, 2, 3, 4]


def _reference_interpolation(t, x, grid, period_s, max_gap_s):
    """The gap rule evaluated grid point by grid point (each one located among the samples)."""
    hold = 0.5 * period_s
    values = np.interp(grid, t, x)
    valid = (grid >= t[0] - hold) & (grid <= t[-1] + hold)
    j = np.clip(np.searchsorted(t, grid, side="right") - 1, 0, len(t) - 2)
    inside = (grid > t[j]) & (grid < t[j + 1])
    valid &= ~inside | (t[j + 1] - t[j] <= max(max_gap_s, 1.5 * period_s))
    values[~valid] = np.nan
    return values, valid


def test_gap_search_equals_pointwise_rule():
    """Locating only the long intervals in the grid gives exactly the pointwise rule, for
    gaps at the edges, back to back, on grid points and between them, and for a shuffled
    grid."""
    rng = np.random.default_rng(21)
    for trial in range(20):
        t = np.arange(0, 120, 0.25)
        drop = np.zeros(len(t), bool)
        for _ in range(rng.integers(0, 6)):
            a = rng.integers(0, len(t))
            drop[a:a + rng.integers(1, 40)] = True
        t = t[~drop] + (0.0 if trial % 2 else 0.1)
        x = rng.normal(0, 1, len(t))
        grid = np.arange(-1.0, 122.0, 1 / 16 if trial % 3 else 0.25)
        for max_gap in (0.0, 0.5, 2.0, 5.0):
            vals, valid = interpolate_with_gaps(t, x, grid, 0.25, max_gap)
            ref_v, ref_ok = _reference_interpolation(t, x, grid, 0.25, max_gap)
            np.testing.assert_array_equal(valid, ref_ok)
            np.testing.assert_array_equal(vals, ref_v)
            perm = rng.permutation(len(grid))
            v2, ok2 = interpolate_with_gaps(t, x, grid[perm], 0.25, max_gap)
            np.testing.assert_array_equal(ok2, ref_ok[perm])
            np.testing.assert_array_equal(v2, ref_v[perm])
