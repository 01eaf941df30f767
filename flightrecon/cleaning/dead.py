"""Dead and stuck input channels dropped before the estimators (issue #50).

A channel whose every sample has the same value says nothing about the flight: a heading of
0 from start to end is a disconnected synchro, not a flight due north; used as data it gave a
track 8-12 km off with exit 0.  Such a channel is **treated as absent**: it is dropped from the
cleaned flight, so that each method sees it missing and either uses what replaces it (the
heading propagated from the body rates and anchored on the runway or the GNSS track,
:mod:`flightrecon.cleaning.attitude`) or is skipped with that reason.

Rules (on the channel's own samples, before resampling):

* **dead**: the same value on every sample of the record;
* **stuck**: the same value on every sample while the true airspeed is above
  :data:`AIRBORNE_TAS_MPS` over at least :data:`STUCK_MIN_S` of such flight (a value held
  from the ground roll on: a turning, climbing aircraft changes every channel of the list; a
  12-bit heading word steps every 0.09 deg).

A channel constant only for a while is not dropped: the plausibility check
``frozen_channel`` reports it (:mod:`flightrecon.cleaning.plausibility`).
"""

from __future__ import annotations

from collections.abc import Collection

import numpy as np
import pandas as pd

from flightrecon.cleaning.report import report_entry

__all__ = ["AIRBORNE_TAS_MPS", "CHANNELS", "STUCK_MIN_S", "drop_dead_channels", "missing_inputs"]

#: the input channels judged: the methods' inputs and the pressure altitude
CHANNELS = ("n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg", "heading_deg",
            "tas_mps", "baro_alt_m")
#: a true airspeed above this is flight [m/s]
AIRBORNE_TAS_MPS = 30.0
#: a channel is stuck when constant over at least this much flight [s]
STUCK_MIN_S = 60.0


def _constant(v: np.ndarray) -> bool:
    f = v[np.isfinite(v)]
    return f.size >= 2 and bool(f.max() == f.min())


def _why_dead(work: pd.DataFrame, name: str) -> str | None:
    """Why ``name`` is dead or stuck (module docstring), else ``None``."""
    t = work["t_s"].to_numpy(float)
    v = work[name].to_numpy(float)
    ok = np.isfinite(v)
    if ok.sum() < 2:
        return None
    if _constant(v):
        return (f"{name} never changes over the whole record (value {v[ok][0]:g}, "
                f"{int(ok.sum())} samples): a dead or disconnected sensor")
    if name == "tas_mps" or "tas_mps" not in work.columns:
        return None
    s = work["tas_mps"].to_numpy(float)
    sk = np.isfinite(s)
    if sk.sum() < 2 or _constant(s):
        return None
    tas = np.interp(t[ok], t[sk], s[sk])
    air = tas > AIRBORNE_TAS_MPS
    if air.sum() < 2 or t[ok][air][-1] - t[ok][air][0] < STUCK_MIN_S:
        return None
    if _constant(v[ok][air]):
        return (f"{name} holds {v[ok][air][0]:g} on every sample in flight (true airspeed "
                f"above {AIRBORNE_TAS_MPS:g} m/s, {t[ok][air][-1] - t[ok][air][0]:.0f} s): "
                "a stuck sensor")
    return None


def drop_dead_channels(work: pd.DataFrame, derived: Collection[str] = ()
                       ) -> tuple[pd.DataFrame, list[dict]]:
    """``work`` without its dead or stuck input channels, and a report entry for each
    (action ``dead_channel``: treated as absent).  The channels ``derived`` at ingest (not
    recorded: e.g. the lateral load of coordinated flight, constant by construction) are not
    judged."""
    report = []
    drop = []
    for name in CHANNELS:
        if name not in work.columns or name in derived:
            continue
        why = _why_dead(work, name)
        if why is not None:
            drop.append(name)
            report.append(report_entry(
                name, "dead_channel", f"{why}: treated as absent (not used as data; the "
                "methods that need it use what replaces it or are skipped)",
                count=int(work[name].notna().sum())))
    return (work.drop(columns=drop) if drop else work), report


def missing_inputs(grid: pd.DataFrame, report, names) -> str | None:
    """Why a method needing ``names`` cannot run on the cleaned grid: the channels missing,
    each dead or stuck one with the reason it was dropped; ``None`` when all are there."""
    dead = {e["channel"]: e["why"].split(": treated")[0] for e in report
            if e.get("action") == "dead_channel"}
    gone = [c for c in names if c not in grid.columns]
    if not gone:
        return None
    return "missing input channels " + ", ".join(
        f"{c} (dropped: {dead[c]})" if c in dead else c for c in gone)
