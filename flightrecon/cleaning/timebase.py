"""Time base: one UTC epoch per flight, each channel at its own sample times.

* ``t_s`` is seconds from the flight's UTC epoch (``FlightMeta.epoch_utc``).
* A channel's samples are the rows where its column is not NaN; nothing is shared between
  channels except the epoch.
* Measurement groups (``gnss``, ``radar``) can carry a clock offset [s] that is *added* to their
  sample times (``clock_offsets_s={"gnss": 0.0, "radar": 0.0}``).
* Row order (:func:`resolve_timestamps`; a log read by ``load_flight`` is already in time
  order, repaired or refused by :mod:`flightrecon.ingest.timestamps`, so this rule is for
  tables made another way, e.g. ``allow_unsorted=True``): rows whose ``t_s`` is smaller than an earlier row's
  (a backward jump) are dropped (the later, out-of-order row loses); rows repeating a time stamp
  with identical values are dropped; rows repeating a time stamp with other values are merged
  column by column (first non-missing value wins), and each column where they disagree is
  reported.  A non-finite ``t_s`` is a :class:`flightrecon.errors.ValidationError`.
"""

from __future__ import annotations

from collections.abc import Mapping

import numpy as np
import pandas as pd

from flightrecon.cleaning.report import report_entry
from flightrecon.errors import ValidationError
from flightrecon.schema import GROUPS


#: columns that say where a row came from, not what it measured (ingest adds them)
BOOKKEEPING = ("row", "src_file")

__all__ = [
    "CLOCK_SOURCES",
    "channel_samples",
    "check_clock_offsets",
    "estimate_rate_hz",
    "measurement_table",
    "nominal_period_s",
    "rate_from_period_hz",
    "resolve_timestamps",
    "uniform_grid",
]

MAX_GRID_POINTS = 50_000_000
"""Largest grid accepted (36 days at 16 Hz): a larger one means broken time stamps."""

CLOCK_SOURCES: tuple[str, ...] = tuple(GROUPS)
"""Sources whose clock offset can be set: the measurement groups."""


def check_clock_offsets(clock_offsets_s: Mapping[str, float]) -> dict[str, float]:
    """Validate ``{"gnss": s, "radar": s}`` (unknown sources and non-finite values raise)."""
    out = {}
    for k, v in clock_offsets_s.items():
        if k not in CLOCK_SOURCES:
            raise ValidationError(f"unknown clock source '{k}' (choose from "
                                  f"{', '.join(CLOCK_SOURCES)})")
        try:
            f = float(v)
        except (TypeError, ValueError) as exc:
            raise ValidationError(f"clock offset of '{k}' must be a number, got {v!r}") from exc
        if not np.isfinite(f):
            raise ValidationError(f"clock offset of '{k}' must be finite, got {v!r}")
        out[k] = f
    return out


def resolve_timestamps(data: pd.DataFrame) -> tuple[pd.DataFrame, list[dict]]:
    """Make ``t_s`` strictly increasing by the documented rule (module docstring).

    Returns a new DataFrame (the input is not modified) with a fresh RangeIndex, and the report
    entries; ``rows`` in the entries are 0-based positions in ``data``.

    Raises
    ------
    ValidationError
        If ``t_s`` is missing, not numeric or not finite.
    """
    if "t_s" not in data.columns:
        raise ValidationError("the log has no t_s column", column="t_s")
    try:
        t = data["t_s"].to_numpy(dtype=float)
    except (TypeError, ValueError) as exc:
        raise ValidationError("t_s is not numeric", column="t_s") from exc
    bad = ~np.isfinite(t)
    if bad.any():
        raise ValidationError("t_s must be finite", column="t_s", rows=np.flatnonzero(bad) + 1)
    report: list[dict] = []
    n = len(t)
    if n == 0:
        return data.reset_index(drop=True).copy(), report
    prev_max = np.maximum.accumulate(np.concatenate([[-np.inf], t[:-1]]))
    backward = t < prev_max
    keep = ~backward
    if backward.any():
        idx = np.flatnonzero(backward)
        report.append(report_entry("t_s", "drop_backward_rows",
                                   "time stamp earlier than a previous row's: the later, "
                                   "out-of-order row is dropped", count=len(idx), rows=idx,
                                   t_s=t[idx]))
    # nothing dropped (the usual case): a lazy copy-on-write view, not a copy of every column
    out = (data.reset_index(drop=True) if not backward.any()
           else data.iloc[np.flatnonzero(keep)].reset_index(drop=True))
    t2 = t[keep]
    dup = np.concatenate([[False], np.diff(t2) == 0.0])
    if not dup.any():
        return out, report
    orig_rows = np.flatnonzero(keep)
    # identical repeats: dropped
    same_as_prev = np.zeros(len(out), dtype=bool)
    # the bookkeeping columns ``row`` / ``src_file`` (where a row came from) never make rows
    # different
    vals = out.drop(columns=[c for c in ("t_s", *BOOKKEEPING) if c in out.columns])
    prev = vals.shift(1)
    eq = (vals == prev) | (vals.isna() & prev.isna())
    same_as_prev[1:] = (eq.all(axis=1).to_numpy() & dup)[1:]
    if same_as_prev.any():
        idx = np.flatnonzero(same_as_prev)
        report.append(report_entry("*", "drop_duplicate_rows",
                                   "row repeats the previous row's time stamp and values",
                                   count=len(idx), rows=orig_rows[idx], t_s=t2[idx]))
        out = out.loc[~same_as_prev].reset_index(drop=True)
        orig_rows = orig_rows[~same_as_prev]
    t3 = out["t_s"].to_numpy(dtype=float)
    if np.all(np.diff(t3) > 0.0):
        return out.copy(), report
    # conflicting or complementary rows sharing a time stamp: merge (first non-missing wins)
    grp = out.groupby("t_s", sort=False)
    nunique = grp.nunique(dropna=True).drop(columns=list(BOOKKEEPING), errors="ignore")
    sizes = grp.size()
    multi = sizes[sizes > 1].index
    for col in nunique.columns:
        conflict = nunique.loc[multi, col] > 1
        if conflict.any():
            times = conflict.index[conflict.to_numpy()].to_numpy(dtype=float)
            report.append(report_entry(col, "merge_conflicting_duplicates",
                                       "rows share a time stamp with different values: the first "
                                       "row's value is kept", count=len(times), t_s=times))
    merged = grp.first().reset_index()
    n_merged = len(out) - len(merged)
    report.append(report_entry("*", "merge_duplicate_time_rows",
                               "rows sharing a time stamp merged column by column (first "
                               "non-missing value)", count=n_merged,
                               t_s=np.asarray(multi, dtype=float)))
    return merged[list(out.columns)].copy(), report


def channel_samples(data: pd.DataFrame, name: str, offset_s: float = 0.0
                    ) -> tuple[np.ndarray, np.ndarray]:
    """A channel's own samples: ``(t_s + offset_s, values)`` over its non-NaN rows."""
    v = data[name].to_numpy(dtype=float)
    ok = np.isfinite(v)
    t = data["t_s"].to_numpy(dtype=float)
    if ok.all():  # sampled on every row: plain copies instead of selections
        return t + offset_s, v.copy()
    return t[ok] + offset_s, v[ok]


def nominal_period_s(t: np.ndarray) -> float:
    """Median spacing of sample times [s] (NaN with fewer than two samples)."""
    if len(t) < 2:
        return float("nan")
    return float(np.median(np.diff(t)))


def estimate_rate_hz(t: np.ndarray) -> float:
    """Nominal sampling rate [Hz]: 1 / median spacing, rounded to 6 significant digits."""
    return rate_from_period_hz(nominal_period_s(t))


def rate_from_period_hz(period_s: float) -> float:
    """1 / ``period_s`` rounded to 6 significant digits (NaN for a non-positive period)."""
    if not np.isfinite(period_s) or period_s <= 0.0:
        return float("nan")
    return float(f"{1.0 / period_s:.6g}")


def measurement_table(data: pd.DataFrame, group: str, offset_s: float = 0.0) -> pd.DataFrame:
    """One row per fix / plot of a measurement group, at its own (offset) time, ``t_s`` first.

    A row belongs to the group when any of the group's columns is present there.  Values are
    never interpolated.  Returns an empty DataFrame with a ``t_s`` column if the group is absent.
    """
    cols = [c for c in GROUPS[group] if c in data.columns]
    if not cols:
        return pd.DataFrame({"t_s": pd.Series([], dtype=float)})
    block = data[cols]
    present = block.notna().any(axis=1).to_numpy()
    out = pd.DataFrame({"t_s": data["t_s"].to_numpy(dtype=float)[present] + offset_s})
    for c in cols:
        out[c] = block[c].to_numpy(dtype=float)[present]
    return out


def uniform_grid(t_first: float, t_last: float, rate_hz: float, anchor_s: float | None = None
                 ) -> np.ndarray:
    """Uniform grid ``t0 + k / rate_hz`` covering ``[t_first, t_last]``.

    With ``anchor_s`` (a sample time of the fastest channel) the grid passes through the anchor,
    so that channel's samples fall on grid points and are not smeared by interpolation.
    """
    if not (np.isfinite(rate_hz) and rate_hz > 0.0):
        raise ValidationError(f"grid rate must be a positive number, got {rate_hz!r}")
    dt = 1.0 / rate_hz
    t0 = t_first
    if anchor_s is not None:
        t0 = anchor_s - np.floor((anchor_s - t_first) / dt + 1e-9) * dt
    n_f = np.floor((t_last - t0) / dt + 1e-9) + 1
    if n_f > MAX_GRID_POINTS:
        raise ValidationError(f"a {rate_hz:g} Hz grid over {t_last - t_first:.6g} s would have "
                              f"{n_f:.3g} points (limit {MAX_GRID_POINTS:.0e}): check the time "
                              "stamps' unit or choose a lower --rate", column="t_s")
    return t0 + np.arange(max(int(n_f), 0)) * dt
