"""The multi-rate recorder: truth -> canonical log (docs/simulator.md, "Recorder").

Every channel is sampled on a sub-grid of the truth grid (its rate must divide the truth rate);
the log's rows are the union of all channels' stamp times, NaN where a channel is not sampled.
Random numbers: one ``numpy.random.Generator(PCG64)`` stream per sensor group, seeded by
``SeedSequence(seed, spawn_key=(k,))`` with a fixed ``k`` per group, so the same seed gives the
same numbers and adding a sensor does not change the others.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.errors import ValidationError
from flightrecon.schema import CHANNELS
from flightrecon.sim.sensors import Faults, SensorSuite

__all__ = ["STREAM_KEYS", "Recording", "channel_samples", "record_log", "sample_rows",
           "stream"]

STREAM_KEYS = {"loads": 1, "attitude": 2, "airspeed": 3, "baro": 4, "gnss": 5, "radar": 6,
               "doppler": 7, "wind": 8, "faults": 20, "airdata": 21, "wind_gm": 22,
               "touchdown": 23, "lineup": 24}
"""Fixed spawn key per random stream."""


def stream(seed: int, name: str) -> np.random.Generator:
    """The random generator of stream ``name`` for ``seed`` (PCG64)."""
    return np.random.Generator(np.random.PCG64(
        np.random.SeedSequence(int(seed), spawn_key=(STREAM_KEYS[name],))))


def sample_rows(n: int, truth_rate_hz: float, rate_hz: float) -> np.ndarray:
    """Truth rows at which a channel of ``rate_hz`` is sampled (every ``truth/rate`` rows).

    Raises
    ------
    ValidationError
        When the channel rate does not divide the truth rate.
    """
    k = truth_rate_hz / rate_hz
    if rate_hz <= 0 or abs(k - round(k)) > 1e-9 or round(k) < 1:
        raise ValidationError(f"channel rate {rate_hz} Hz must divide the truth rate "
                              f"{truth_rate_hz} Hz")
    return np.arange(0, n, round(k))


@dataclass(frozen=True)
class Recording:
    """Output of :func:`record_log`.

    Attributes
    ----------
    log : canonical multi-rate log (``t_s`` first, schema column names)
    truth_extra : extra truth series on the truth grid (Gauss-Markov error series)
    faults : injected faults, one dict each (kind, column, t_s, size / length)
    """

    log: pd.DataFrame
    truth_extra: dict[str, np.ndarray]
    faults: tuple[dict[str, Any], ...]


def record_log(truth: pd.DataFrame, suite: SensorSuite, seed: int, truth_rate_hz: float,
               faults: Faults | None = None, airdata_truth: pd.DataFrame | None = None
               ) -> Recording:
    """Record every fitted sensor of ``suite`` from ``truth``.

    Parameters
    ----------
    truth : truth DataFrame on the uniform truth grid
    suite : sensors
    seed : noise seed
    truth_rate_hz : truth grid rate
    faults : spikes, gaps and clock offsets to inject
    airdata_truth : replaces ``truth`` for the airspeed and attitude sensors (the
        ``seed-ads-arms`` scenario records air data that include a Gauss-Markov error)
    """
    faults = Faults() if faults is None else faults
    n = truth.shape[0]
    dt = 1.0 / truth_rate_hz
    t = truth["t_s"].to_numpy()
    offsets = dict(faults.clock_offsets)
    unknown = set(offsets) - {s.group for s in suite.fitted()}
    if unknown:
        raise ValidationError(f"clock offset for a channel group that is not fitted: "
                              f"{sorted(unknown)}")
    cols: dict[str, np.ndarray] = {}
    extra: dict[str, np.ndarray] = {}
    for sensor in suite.fitted():
        rows = sample_rows(n, truth_rate_hz, sensor.rate_hz)
        if hasattr(sensor, "keep"):
            rows = rows[sensor.keep(t[rows])]
        shift = round(offsets.get(sensor.group, 0.0) * truth_rate_hz)
        src = np.clip(rows - shift, 0, n - 1)
        rng = stream(seed, sensor.group)
        src_truth = truth
        if airdata_truth is not None and sensor.group in ("airspeed", "attitude"):
            src_truth = airdata_truth
        if sensor.group == "wind":
            gm = sensor.gm_series(n, dt, stream(seed, "wind_gm"))
            extra["wind_speed_err_gm_mps"], extra["wind_from_err_gm_deg"] = gm
            values = sensor.record(src_truth, src, rng, dt, gm=gm)
        else:
            values = sensor.record(src_truth, src, rng, dt)
        for name, v in values.items():
            full = np.full(n, np.nan)
            full[rows] = v
            cols[name] = full
    events: list[dict[str, Any]] = []
    frng = stream(seed, "faults")
    for column, start, length in faults.gaps:
        if column not in cols:
            raise ValidationError(f"gap in a channel that is not recorded: {column}")
        gap = (t >= start) & (t < start + length) & np.isfinite(cols[column])
        cols[column][gap] = np.nan
        events.append({"kind": "gap", "column": column, "t_s": float(start),
                       "length_s": float(length)})
    for column, size in faults.spike_channels:
        if column not in cols:
            raise ValidationError(f"spike in a channel that is not recorded: {column}")
        ok = np.flatnonzero(np.isfinite(cols[column]))
        picks = np.sort(frng.choice(ok, size=min(faults.spikes, ok.size), replace=False))
        signs = frng.choice(np.array([-1.0, 1.0]), size=picks.size)
        cols[column][picks] += signs * size
        for p, s in zip(picks, signs):
            events.append({"kind": "spike", "column": column, "t_s": float(t[p]),
                           "size": float(s * size)})
    for group, off in faults.clock_offsets:
        events.append({"kind": "clock_offset", "group": group, "offset_s":
                       round(off * truth_rate_hz) / truth_rate_hz})
    order = [c.name for c in CHANNELS if c.name in cols]
    data = {"t_s": t}
    data.update({c: cols[c] for c in order})
    log = pd.DataFrame(data)
    any_value = np.zeros(n, bool)
    for c in order:
        any_value |= np.isfinite(log[c].to_numpy())
    log = log.loc[any_value].reset_index(drop=True)
    return Recording(log=log, truth_extra=extra, faults=tuple(events))


def channel_samples(log: pd.DataFrame, channel: str, what: str = "this export"
                    ) -> tuple[np.ndarray, np.ndarray]:
    """Times and values of ``channel`` at its own samples in a multi-rate canonical log (the
    rows where it is not NaN), for the exports that resample a log.

    Raises
    ------
    ValidationError
        Fewer than two samples of the channel.
    """
    v = log[channel].to_numpy(dtype=float)
    ok = np.isfinite(v)
    if ok.sum() < 2:
        raise ValidationError(f"{what} needs this channel sampled", column=channel)
    return log["t_s"].to_numpy(dtype=float)[ok], v[ok]
