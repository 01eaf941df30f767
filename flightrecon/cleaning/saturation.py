"""Recorder saturation: samples stuck at the end of a channel's range (docs/signals.md,
"Saturation").

A recorder channel has a range (an accelerometer's +-2 g, an airspeed indicator's top of
scale, a rate gyro's +-500 deg/s); beyond it the reading stays at the bound.  The range is
rarely in the metadata, so the bound is found in the data.  For each saturable channel the
record's largest value ``L`` (and likewise its smallest) is a *saturation level* when

1. at least ``min_samples`` (2) samples read exactly ``L`` (within ``1e-9 max(1, |L|)``: a
   clipped reading is the bound itself, the quantised noise of a real signal rarely repeats its
   extreme), and
2. ``L`` lies far from the channel's bulk: ``|L - median| >= MIN_EXCURSION`` of the channel's
   unit (0.5 g, 5 m/s, 10 deg/s; a level near the median is quantised flight at rest, not a
   range limit), and
3. one of: ``L`` is the channel's physical bound of the schema (validation clipped readings
   just beyond it to the bound, :data:`flightrecon.ingest.validate.CLIP_MARGIN`); a run of at
   least ``min_run`` (3) consecutive samples reads ``L`` (a flat top: a real signal at its
   extreme is not constant to the last bit for three samples); or ``L`` stands apart from
   every other value by at least ``gap_factor`` (10) robust standard deviations of the
   sample-to-sample change (and at least a quarter of ``MIN_EXCURSION``): the signal jumps
   onto the bound (an impact's load spike clipped at the accelerometer's range).

A single sample at ``-L`` where ``L`` is a detected level is flagged too (a symmetric range,
the lateral accelerometer's +-2 g: the impact may reach the other end only once), and so is a
load factor's lone extreme sample that stands apart by the gap rule of 3. when another load
factor saturates within one sample period, or has a lone extreme of the same magnitude there
(the triad's common range, +-2 g on both horizontal axes): an impact drives the accelerometers
to their range in one sample.  (A touchdown's lone extremes, 3.2 g and -1.4 g, differ: not
flagged.)

The airspeed channels' level 0 is not a saturation (the indicator's floor at rest on the
ground, a true reading of "slow").  Every sample at a saturation level is flagged: on the
grid ``<channel>_saturated`` is True wherever the value was interpolated from (or is) a
saturated sample.  The values are kept (they are the recorder's), and the consumers decide:
the joint smoother treats a saturated load factor as missing (acceleration noise added over
the step, :mod:`flightrecon.methods.joint.linearisation`), the true value being at least the bound;
Sabziev's fit and the dead reckoning integrate the readings as recorded (the error is the
excess beyond the bound, over the saturated samples only; docs/signals.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
import pandas as pd

from flightrecon.cleaning.report import report_entry
from flightrecon.schema import BY_NAME

__all__ = ["SATURABLE", "Level", "SaturationSettings", "detect_saturation", "saturated_loads",
           "saturation_levels", "saturation_on_grid"]

#: channels a recorder's range can clip (load factors, air data speeds, body rates)
SATURABLE: tuple[str, ...] = ("n_long_g", "n_lat_g", "n_norm_g", "tas_mps", "ias_mps",
                              "cas_mps", "doppler_gs_mps", "p_dps", "q_dps", "r_dps")
#: smallest distance of a saturation level from the channel's median, per unit
MIN_EXCURSION: dict[str, float] = {"g": 0.5, "m/s": 5.0, "deg/s": 10.0}
#: at most this many samples for the median and the robust scale (10 h at 16 Hz: every 6th)
ROBUST_SAMPLES = 100_000
_SPEEDS = ("tas_mps", "ias_mps", "cas_mps", "doppler_gs_mps")
LOAD_FACTORS: tuple[str, ...] = ("n_long_g", "n_lat_g", "n_norm_g")


@dataclass(frozen=True)
class SaturationSettings:
    """Thresholds of the saturation rule (module docstring)."""

    min_samples: int = 2
    min_run: int = 3
    gap_factor: float = 10.0


def _longest_run(mask: np.ndarray) -> int:
    if not mask.any():
        return 0
    m = np.concatenate(([0], mask.astype(np.int8), [0]))
    d = np.diff(m)
    return int(np.max(np.flatnonzero(d == -1) - np.flatnonzero(d == 1)))


class Level(NamedTuple):
    """One saturation level of a channel: ``end`` ``"low"`` / ``"high"``, its ``value``, the
    samples at it (``mask``), the evidence (``why``); ``single``: a lone sample that stands
    apart, a saturation only where another load factor saturates at the same time."""

    end: str
    value: float
    mask: np.ndarray
    why: str
    single: bool = False


def saturation_levels(name: str, x: np.ndarray, settings: SaturationSettings = SaturationSettings()
                      ) -> list[Level]:
    """The saturation levels of channel ``name`` in its samples ``x`` (finite values, in time
    order; module docstring for the rule), and the lone extreme samples that stand apart
    (``single``)."""
    ch = BY_NAME[name]
    x = np.asarray(x, float)
    if len(x) < 2:
        return []
    floor = MIN_EXCURSION.get(ch.unit, 0.0)
    # the bulk's median and the robust sd of the sample-to-sample change from at most
    # ROBUST_SAMPLES evenly spread values (statistics of the bulk: a subsample is as good)
    stride = max(1, len(x) // ROBUST_SAMPLES)
    med = float(np.median(x[::stride]))
    dx = np.diff(x)[::stride]
    s = 1.4826 * float(np.median(np.abs(dx - np.median(dx)))) if len(dx) else 0.0
    out: list[Level] = []
    for end, level in (("low", float(np.min(x))), ("high", float(np.max(x)))):
        if name in _SPEEDS and level == 0.0:
            continue
        tol = 1e-9 * max(1.0, abs(level))
        at = np.abs(x - level) <= tol
        if abs(level - med) < floor:
            continue
        bound = ch.lo if end == "low" else ch.hi
        rest = x[~at]
        gap = float(np.min(np.abs(rest - level))) if len(rest) else 0.0
        apart = gap >= max(settings.gap_factor * s, 0.25 * floor) and gap > 0.0
        jump = (f"jumps onto the level: {gap:.3g} {ch.unit} from every other value "
                f"({gap / s if s > 0 else float('inf'):.3g} robust sd of the "
                "sample-to-sample change)")
        if int(at.sum()) < settings.min_samples:
            if apart:
                out.append(Level(end, level, at, "a lone sample that " + jump, single=True))
            continue
        if abs(level - bound) <= tol:
            why = f"at the physical bound {bound:g} {ch.unit}"
        elif _longest_run(at) >= settings.min_run:
            why = f"flat top: {_longest_run(at)} consecutive samples at the level"
        elif apart:
            why = jump
        else:
            continue
        out.append(Level(end, level, at, why))
    full = [lv for lv in out if not lv.single]
    if len(full) == 1:  # a symmetric range: one sample at the mirror of a detected limit
        level = full[0].value
        tol = 1e-9 * max(1.0, abs(level))
        out = [lv if not (lv.single and level != 0.0 and abs(lv.value + level) <= tol)
               else lv._replace(single=False, why=f"the mirror of the detected {level:g} "
                                "limit (a symmetric range)") for lv in out]
    return out


def detect_saturation(data: pd.DataFrame, settings: SaturationSettings = SaturationSettings()
                      ) -> tuple[dict[str, tuple[np.ndarray, np.ndarray]], list[dict]]:
    """Saturated samples of every saturable channel of ``data`` (the time-resolved table,
    each channel on its own samples).

    Returns
    -------
    masks : dict
        channel -> (sample times [s], saturated flag per sample), for the channels with a
        saturation level
    report : list of dict
        One ``saturation`` entry per level: its value, the evidence, the times of the samples.
    """
    t_all = data["t_s"].to_numpy(float)
    found: dict[str, tuple[np.ndarray, list[Level]]] = {}
    for c in SATURABLE:
        if c not in data.columns:
            continue
        v = data[c].to_numpy(float)
        ok = np.isfinite(v)
        if ok.sum() < 2:
            continue
        levels = saturation_levels(c, v[ok], settings)
        if levels:
            found[c] = (t_all[ok], levels)
    # a lone load-factor extreme counts where another load factor saturates within one sample
    # period, or has a lone extreme of the same magnitude there (a triad's common range: the
    # impact drove the accelerometers to it in one sample)
    conf = {c: np.concatenate([t[lv.mask] for lv in lvs if not lv.single] or [np.empty(0)])
            for c, (t, lvs) in found.items() if c in LOAD_FACTORS}
    lone = {c: [(float(t[lv.mask][0]), abs(lv.value)) for lv in lvs if lv.single]
            for c, (t, lvs) in found.items() if c in LOAD_FACTORS}

    def confirmed(c: str, t0: float, mag: float, period: float) -> bool:
        for o in conf:
            if o == c:
                continue
            if len(conf[o]) and np.min(np.abs(conf[o] - t0)) <= 1.001 * period:
                return True
            if any(abs(t1 - t0) <= 1.001 * period and abs(m1 - mag) <= 1e-9 * max(1.0, mag)
                   for t1, m1 in lone[o]):
                return True
        return False

    masks: dict[str, tuple[np.ndarray, np.ndarray]] = {}
    rep: list[dict] = []
    for c, (t, levels) in found.items():
        period = float(np.median(np.diff(t))) if len(t) > 1 else 0.0
        sat = np.zeros(len(t), bool)
        unit = BY_NAME[c].unit
        for lv in levels:
            why = lv.why
            if lv.single:
                if c not in LOAD_FACTORS or not confirmed(c, float(t[lv.mask][0]),
                                                          abs(lv.value), period):
                    continue
                why += "; at the same sample as another load factor's range limit"
            sat |= lv.mask
            n = int(lv.mask.sum())
            rep.append(report_entry(
                c, "saturation", f"{n} sample(s) at the recorder's {lv.end} range limit "
                f"{lv.value:g} {unit} ({why}); kept, flagged {c}_saturated: the true value is "
                "at least as far out", count=n, t_s=t[lv.mask], level=lv.value, end=lv.end))
        if sat.any():
            masks[c] = (t, sat)
    return masks, rep


def saturation_on_grid(grid: pd.DataFrame, masks: dict[str, tuple[np.ndarray, np.ndarray]]
                       ) -> pd.DataFrame:
    """``grid`` with a boolean ``<channel>_saturated`` column per channel of ``masks``: True
    at the grid points whose value is, or is interpolated from, a saturated sample."""
    if not masks:
        return grid
    g = grid.copy(deep=False)  # copy-on-write (pandas >= 3): the input is never changed
    tg = g["t_s"].to_numpy(float)
    for c, (t, sat) in masks.items():
        if c not in g.columns:
            continue
        # a grid point between two samples takes part of each: flagged if either is saturated
        f = np.interp(tg, t, sat.astype(float), left=float(sat[0]), right=float(sat[-1]))
        g[f"{c}_saturated"] = f > 0.0
    return g


def saturated_loads(grid: pd.DataFrame) -> np.ndarray:
    """Grid points where any load factor is at the recorder's range (``<channel>_saturated``
    of :func:`saturation_on_grid`); all False without saturation columns."""
    out = np.zeros(len(grid), bool)
    for c in LOAD_FACTORS:
        if f"{c}_saturated" in grid.columns:
            out |= grid[f"{c}_saturated"].to_numpy(bool)
    return out
