"""Trimming a record to the part an analyst wants (``--start`` / ``--end``).

A bound is seconds from the flight's UTC epoch (``t_s``, the log's own time axis) or a UTC
timestamp (ISO-8601; no zone means UTC), which needs the flight's ``epoch_utc``.  Rows outside
``[start, end]`` are dropped before cleaning: inputs and measurements alike (a fix outside the
window is not used).  The input file is never modified.  What was cut is reported as a cleaning
report entry (``trim``).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from flightrecon.cleaning.report import report_entry
from flightrecon.errors import MetadataError, ValidationError
from flightrecon.types import Flight

__all__ = ["parse_time_bound", "trim_flight"]


def parse_time_bound(value: float | str | None, epoch_utc: str | None,
                     what: str = "bound") -> float | None:
    """``value`` as seconds from ``epoch_utc``: a number (or numeric text) is taken as ``t_s``,
    other text as a UTC timestamp.

    Raises
    ------
    ValidationError
        Text that is neither a number nor a timestamp.
    MetadataError
        A timestamp for a flight without ``epoch_utc``.
    """
    if value is None:
        return None
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        v = float(value)
    else:
        txt = str(value).strip()
        try:
            v = float(txt)
        except ValueError:
            try:
                ts = np.datetime64(txt.rstrip("Z").replace(" ", "T"), "ns")
            except ValueError:
                raise ValidationError(f"--{what} '{txt}' is neither seconds (t_s) nor a UTC "
                                      "timestamp (ISO-8601, e.g. 2026-01-01T10:05:00Z)") from None
            if np.isnat(ts):
                raise ValidationError(f"--{what} '{txt}' is not a time") from None
            if epoch_utc is None:
                raise MetadataError(f"--{what} is a UTC time but the flight has no epoch_utc: "
                                    "give it in seconds (t_s) or set epoch_utc in the sidecar"
                                    ) from None
            ep = np.datetime64(str(epoch_utc).rstrip("Z"), "ns")
            v = float((ts - ep).astype(np.int64)) / 1e9
    if not np.isfinite(v):
        raise ValidationError(f"--{what} must be finite")
    return v


def trim_flight(flight: Flight, start: float | str | None = None,
                end: float | str | None = None) -> tuple[Flight, list[dict]]:
    """The flight restricted to ``start <= t_s <= end`` (either bound optional).

    Returns
    -------
    flight : a new :class:`Flight` (``data`` rows outside dropped; ``row``/``src_file`` kept, so
        messages still name the file's rows)
    report : one ``trim`` entry (empty when nothing was asked)

    Raises
    ------
    ValidationError
        ``end <= start``, or a window that keeps fewer than two rows of input data.
    """
    t0 = parse_time_bound(start, flight.meta.epoch_utc, "start")
    t1 = parse_time_bound(end, flight.meta.epoch_utc, "end")
    if t0 is None and t1 is None:
        return flight, []
    if t0 is not None and t1 is not None and t1 <= t0:
        raise ValidationError(f"--end ({t1:g} s) must be after --start ({t0:g} s)")
    d = flight.data
    t = d["t_s"].to_numpy()
    keep = np.ones(len(t), dtype=bool)
    if t0 is not None:
        keep &= t >= t0
    if t1 is not None:
        keep &= t <= t1
    if keep.sum() < 2:
        raise ValidationError(
            f"the window [{'-inf' if t0 is None else f'{t0:g}'}, "
            f"{'inf' if t1 is None else f'{t1:g}'}] s keeps {int(keep.sum())} row(s) of a record "
            f"spanning {t[0]:g} .. {t[-1]:g} s")
    out = d.loc[keep].reset_index(drop=True)
    rep = report_entry("*", "trim", "rows outside the requested window dropped before cleaning",
                       count=int((~keep).sum()),
                       start_s=float("nan") if t0 is None else t0,
                       end_s=float("nan") if t1 is None else t1,
                       kept_rows=int(keep.sum()))
    return dataclasses.replace(flight, data=out), [rep]
