"""The cleaning report: one JSON-serialisable dict per action.

Every change the cleaning makes to the data (a dropped row, a despiked sample, an interpolated
or unfilled gap, an anti-alias filter) and every decision it takes (the grid rate, the detected
phases) is recorded as ``{"channel", "action", "count", "why"}`` plus ``"t_s"`` (times, seconds
from the flight's epoch) and/or ``"rows"`` (0-based row positions in the table the step
received: :attr:`Flight.data` for the time-stamp step, the time-resolved table for the later
steps; ``t_s`` is the unambiguous reference).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

__all__ = ["report_entry"]


def report_entry(channel: str, action: str, why: str, *, count: int,
                 t_s: Sequence[float] | np.ndarray | None = None,
                 rows: Sequence[int] | np.ndarray | None = None,
                 **extra: float | str | bool) -> dict[str, Any]:
    """One report entry (plain Python types only, ready for JSON).

    Parameters
    ----------
    channel : channel name, measurement group (``"gnss"``), ``"t_s"`` or ``"*"`` (all)
    action : what was done (``"despike"``, ``"drop_duplicate_rows"``, ``"long_gap"``, ...)
    why : the rule that triggered it, with its numbers
    count : number of samples / rows / gaps concerned
    t_s, rows : where (times [s] or 0-based row positions in the input table)
    extra : further scalar facts (a rate, a threshold)
    """
    entry: dict[str, Any] = {"channel": channel, "action": action, "count": int(count)}
    if t_s is not None:
        entry["t_s"] = [float(x) for x in np.asarray(t_s, float).ravel()]
    if rows is not None:
        entry["rows"] = [int(x) for x in np.asarray(rows).ravel()]
    entry["why"] = why
    for k, v in extra.items():
        entry[k] = v.item() if isinstance(v, np.generic) else v
    return entry
