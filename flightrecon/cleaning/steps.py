"""Composable cleaning steps on the canonical multi-rate table.

Each step is a small frozen dataclass with one method, ``apply(data) -> (data, report)``, that
returns a *new* DataFrame and its report entries and never modifies its input (the pattern of
traffic's ``Filter`` protocol).  :func:`run_steps` chains them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np
import pandas as pd

from flightrecon.cleaning.despike import (
    DespikeSettings,
    hampel_candidates,
    isolated_runs,
)
from flightrecon.cleaning.report import report_entry
from flightrecon.cleaning.timebase import resolve_timestamps
from flightrecon.schema import BY_NAME, INPUTS

__all__ = ["CleaningStep", "Despike", "ResolveTimestamps", "UnwrapAngles", "run_steps"]


class CleaningStep(Protocol):
    """A cleaning step: returns a new table and its report entries; never mutates ``data``."""

    def apply(self, data: pd.DataFrame) -> tuple[pd.DataFrame, list[dict]]: ...


@dataclass(frozen=True)
class ResolveTimestamps:
    """Strictly increasing ``t_s`` (:func:`flightrecon.cleaning.timebase.resolve_timestamps`)."""

    def apply(self, data: pd.DataFrame) -> tuple[pd.DataFrame, list[dict]]:
        return resolve_timestamps(data)


#: input channels that wrap at 360 deg but are not heading-like in the schema (their canonical
#: range is [-180, 180]): unwrapped for despiking and interpolation, wrapped back on the grid
#: (:func:`flightrecon.cleaning.resample.wrap_roll`)
WRAPPED_INPUTS: tuple[str, ...] = ("roll_deg",)


def _angle_inputs(data: pd.DataFrame) -> list[str]:
    return [c for c in INPUTS if (BY_NAME[c].angle or c in WRAPPED_INPUTS) and c in data.columns]


@dataclass(frozen=True)
class UnwrapAngles:
    """Unwrap angle input channels (``heading_deg``, ``wind_from_deg``, ``roll_deg``) on their
    own samples.

    Consecutive samples never differ by more than 180 deg afterwards (``numpy.unwrap`` with a
    360 deg period); the first sample is brought into [0, 360) (roll into [-180, 180)).  The
    values become continuous and may leave that interval: a roll through +-180 deg (inverted
    flight, a spin) is then neither despiked as a 360 deg jump nor interpolated the long way
    through wings level.
    """

    channels: tuple[str, ...] | None = None

    def apply(self, data: pd.DataFrame) -> tuple[pd.DataFrame, list[dict]]:
        chans = self.channels if self.channels is not None else tuple(_angle_inputs(data))
        out = data.copy(deep=False)  # copy-on-write (pandas >= 3): the input is never changed
        rep = []
        for c in chans:
            if c not in out.columns:
                continue
            v = out[c].to_numpy(dtype=float)
            ok = np.isfinite(v)
            if ok.sum() == 0:
                continue
            u = np.unwrap(v[ok], period=360.0)
            lo = -180.0 if c in WRAPPED_INPUTS else 0.0
            u = u - 360.0 * np.floor((u[0] - lo) / 360.0)
            new = v.copy()
            new[ok] = u
            n_changed = int(np.count_nonzero(np.abs(new[ok] - v[ok]) > 0.0))
            out[c] = new
            rep.append(report_entry(c, "unwrap", "angle made continuous (steps of more than "
                                    "180 deg between samples taken as wraps)", count=n_changed))
        return out, rep


def _nearest_distance(ref: np.ndarray, query: np.ndarray) -> np.ndarray:
    """Distance from each ``query`` time to the nearest of the sorted ``ref`` times (inf if
    ``ref`` is empty)."""
    if len(ref) == 0:
        return np.full(len(query), np.inf)
    j = np.searchsorted(ref, query)
    right = np.abs(ref[np.clip(j, 0, len(ref) - 1)] - query)
    left = np.abs(ref[np.clip(j - 1, 0, len(ref) - 1)] - query)
    return np.minimum(left, right)


LOAD_FACTORS: tuple[str, ...] = ("n_long_g", "n_lat_g", "n_norm_g")
"""Channels that see the same physical events: a spike coinciding across them is kept."""


@dataclass(frozen=True)
class Despike:
    """Remove isolated spikes from input channels (:mod:`flightrecon.cleaning.despike`).

    Each channel is treated on its own samples; the removed samples become missing (NaN) and
    are reported with their times.  A spike in one of ``coincidence_group`` within one sample
    period of an outlier candidate in another channel of the group is kept (rule 5) and reported
    as ``keep_coincident_transient``.  Angles must be unwrapped first (:class:`UnwrapAngles`).
    """

    settings: DespikeSettings = field(default_factory=DespikeSettings)
    channels: tuple[str, ...] | None = None
    coincidence_group: tuple[str, ...] = LOAD_FACTORS

    def apply(self, data: pd.DataFrame) -> tuple[pd.DataFrame, list[dict]]:
        chans = self.channels if self.channels is not None else tuple(
            c for c in INPUTS if c in data.columns)
        out = data.copy(deep=False)  # copy-on-write (pandas >= 3): the input is never changed
        t = data["t_s"].to_numpy(dtype=float)
        rep = []
        s = self.settings
        # per channel: (rows sampled, their times, candidates, spikes, floor)
        found: dict[str, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, float]] = {}
        for c in chans:
            v = out[c].to_numpy(dtype=float)
            fin = np.isfinite(v)
            n_ok = int(np.count_nonzero(fin))
            if n_ok < 3:
                continue
            whole = n_ok == len(v)  # sampled on every row: no selection copies
            x = v if whole else v[fin]
            tc = t if whole else t[fin]
            cand, thr, floor = hampel_candidates(x, s, full_threshold=False)
            spikes = isolated_runs(x, cand, thr, s.max_run)
            found[c] = (fin, tc, cand, spikes, floor)
        for c, (fin, t_c, _cand, spikes, floor) in found.items():
            if not spikes.any():
                continue
            ok = np.flatnonzero(fin)
            if c in self.coincidence_group:
                period = float(np.median(np.diff(t_c)))  # only needed here
                others = [tc[cd] for name, (_, tc, cd, _, _) in found.items()
                          if name != c and name in self.coincidence_group]
                other_t = np.sort(np.concatenate(others)) if others else np.empty(0)
                ts = t[ok[spikes]]
                coincident = _nearest_distance(other_t, ts) <= 1.001 * period
                if coincident.any():
                    kept = ok[spikes][coincident]
                    rep.append(report_entry(
                        c, "keep_coincident_transient",
                        "outlier within one sample period of an outlier in another load-factor "
                        "channel: a physical event, kept", count=len(kept), t_s=t[kept],
                        rows=kept))
                    spikes = spikes.copy()
                    spikes[np.flatnonzero(spikes)[coincident]] = False
                if not spikes.any():
                    continue
            rows = ok[spikes]
            new = out[c].to_numpy(dtype=float).copy()
            new[rows] = np.nan
            out[c] = new
            rep.append(report_entry(
                c, "despike",
                f"isolated outlier (run of <= {s.max_run} samples) beyond {s.n_sigma:g} robust "
                f"sigma of the running median over {2 * s.half_window + 1} samples, away from "
                f"its neighbours; scale floor {floor:.6g}; removed, then interpolated",
                count=len(rows), t_s=t[rows], rows=rows))
        return out, rep


def run_steps(data: pd.DataFrame, steps: Sequence[CleaningStep]
              ) -> tuple[pd.DataFrame, list[dict]]:
    """Apply ``steps`` in order; return the final table and the concatenated report."""
    report: list[dict] = []
    for step in steps:
        data, rep = step.apply(data)
        report.extend(rep)
    return data, report
