"""Resampling policy (docs/schema.md, "Two kinds of channel").

* **Input channels** (load factors, attitude, airspeeds, pressure altitude, temperature, Doppler,
  drift, wind) are brought onto one uniform grid, by default at the rate of the fastest input
  channel and anchored on its samples (so they are copied, not interpolated).  Slower channels
  are linearly interpolated (angles, roll included, on their unwrapped series, so an
  interpolation across the wrap goes the short way: 179 -> -179 deg passes through 180, not
  through 0) with the gap policy of
  :mod:`flightrecon.cleaning.gaps`.  A channel faster than the grid (``rate > 1.2 * grid rate``)
  is first averaged over ``L = round(rate / grid rate)`` of its own samples (a boxcar, whose
  first spectral zero falls on the new sampling rate, so the band that would alias onto low
  frequencies is attenuated; for 16 -> 4 Hz the band 3.5-4.5 Hz, which folds onto 0-0.5 Hz, is attenuated by at least 16 dB,
  and 0 Hz passes unchanged).
* **Measurements** (``gnss_*``, ``arms_*``) are never interpolated: see
  :func:`flightrecon.cleaning.timebase.measurement_table`.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from flightrecon.cleaning.gaps import find_gaps, interpolate_with_gaps
from flightrecon.cleaning.report import report_entry
from flightrecon.cleaning.timebase import (
    channel_samples,
    nominal_period_s,
    rate_from_period_hz,
    uniform_grid,
)
from flightrecon.errors import ValidationError
from flightrecon.schema import INPUTS

__all__ = ["ANTIALIAS_RATIO", "boxcar", "default_rate_hz", "input_channels", "resample_inputs",
           "wrap_roll"]

ANTIALIAS_RATIO = 1.2
"""A channel is pre-filtered when its rate exceeds the grid rate by more than this factor."""


def input_channels(data: pd.DataFrame) -> list[str]:
    """Input channels of the schema present in ``data`` with at least one sample."""
    return [c for c in INPUTS if c in data.columns and data[c].notna().any()]


def default_rate_hz(data: pd.DataFrame) -> tuple[float, str]:
    """Rate [Hz] of the fastest input channel and its name.

    Raises
    ------
    ValidationError
        If no input channel has two samples.
    """
    return _fastest({c: nominal_period_s(channel_samples(data, c)[0])
                     for c in input_channels(data)})


def _fastest(periods: dict[str, float]) -> tuple[float, str]:
    """:func:`default_rate_hz` from the channels' nominal periods (name -> period [s])."""
    best, name = float("nan"), ""
    for c, p in periods.items():
        r = rate_from_period_hz(p)
        if np.isfinite(r) and (not np.isfinite(best) or r > best):
            best, name = r, c
    if not np.isfinite(best):
        raise ValidationError("no input channel has two samples: cannot choose a grid rate")
    return best, name


def boxcar(x: np.ndarray, length: int) -> np.ndarray:
    """Centred moving average over ``length`` samples (shorter at the ends)."""
    if length <= 1:
        return x.copy()
    return pd.Series(x).rolling(length, center=True, min_periods=1).mean().to_numpy()


def resample_inputs(data: pd.DataFrame, rate_hz: float | None, max_gap_s: float
                    ) -> tuple[pd.DataFrame, float, list[dict]]:
    """Bring every input channel onto one uniform grid (module docstring for the policy).

    ``data`` must already have strictly increasing ``t_s``, despiked channels and unwrapped
    angles.  Returns the grid table (``t_s``, then each channel followed by ``<channel>_valid``),
    the grid rate and the report entries.
    """
    report: list[dict] = []
    chans = input_channels(data)
    if not chans:
        raise ValidationError("the log has no input channel with samples")
    samples = {c: channel_samples(data, c) for c in chans}  # each channel extracted once
    periods = {c: nominal_period_s(samples[c][0]) for c in chans}
    fast_rate, fast_name = _fastest(periods)
    if rate_hz is None:
        rate_hz = fast_rate
        why = f"fastest input channel {fast_name} at {fast_rate:g} Hz"
    else:
        if not (np.isfinite(rate_hz) and rate_hz > 0.0):
            raise ValidationError(f"grid rate must be a positive number, got {rate_hz!r}")
        why = "requested"
    t_first = min(samples[c][0][0] for c in chans)
    t_last = max(samples[c][0][-1] for c in chans)
    anchor = samples[fast_name][0][0]
    grid_t = uniform_grid(t_first, t_last, float(rate_hz), anchor_s=anchor)
    report.append(report_entry("*", "grid", why, count=len(grid_t), rate_hz=float(rate_hz),
                               t0_s=float(grid_t[0]) if len(grid_t) else float("nan")))
    cols: dict[str, np.ndarray] = {"t_s": grid_t}
    for c in chans:
        t, x = samples[c]
        period = periods[c]
        rate_c = 1.0 / period if np.isfinite(period) and period > 0 else float("nan")
        if np.isfinite(rate_c) and rate_c > ANTIALIAS_RATIO * rate_hz:
            length = min(int(round(rate_c / rate_hz)), len(x))
            x = boxcar(x, length)
            report.append(report_entry(c, "antialias", f"boxcar mean over {length} samples "
                                       f"before resampling {rate_c:g} Hz -> {rate_hz:g} Hz",
                                       count=len(x)))
        g0, g1 = find_gaps(t, period)
        length_g = g1 - g0
        short = length_g <= max_gap_s
        if short.any():
            report.append(report_entry(c, "interpolate_short_gaps",
                                       f"gaps of at most {max_gap_s:g} s bridged linearly",
                                       count=int(short.sum()), t_s=g0[short]))
        vals, valid = interpolate_with_gaps(t, x, grid_t, period, max_gap_s)
        if (~short).any():
            report.append(report_entry(c, "long_gap",
                                       f"gap longer than {max_gap_s:g} s left unfilled (NaN, "
                                       f"{c}_valid False); t_s are start/end pairs",
                                       count=int((~short).sum()),
                                       t_s=np.column_stack([g0[~short], g1[~short]]).ravel()))
        cols[c] = vals
        cols[f"{c}_valid"] = valid
    # the arrays are this function's own: the table takes them without a consolidating copy
    return pd.DataFrame(cols, copy=False), float(rate_hz), report


def wrap_roll(grid: pd.DataFrame) -> pd.DataFrame:
    """``grid`` with ``roll_deg`` (unwrapped for despiking and interpolation) wrapped back to
    its canonical range [-180, 180) (docs/schema.md, "Conventions"): the envelope checks and the
    plots read the bank as recorded; the rotations take either."""
    if "roll_deg" not in grid.columns:
        return grid
    g = grid.copy(deep=False)  # copy-on-write (pandas >= 3): the input is never changed
    r = g["roll_deg"].to_numpy(float)
    out = (r < -180.0) | (r >= 180.0)   # in-range values untouched (bit for bit)
    if out.any():
        g["roll_deg"] = np.where(out, (r + 180.0) % 360.0 - 180.0, r)
    return g
