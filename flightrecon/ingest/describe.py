"""A summary of a loaded flight: channels, rates, duration, gaps, metadata (``flightrecon info``)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from flightrecon.schema import BY_NAME
from flightrecon.types import Flight, declared_metadata

__all__ = ["GAP_FACTOR", "channel_stats", "describe_flight"]

#: an interval between two samples of a channel longer than GAP_FACTOR times its median interval
#: is a gap (a recorder dropping 4 samples in a row at its own rate)
GAP_FACTOR = 5.0


def channel_stats(t: np.ndarray, v: np.ndarray) -> dict[str, Any]:
    """Samples, median interval, rate and gaps of one channel (NaN = not sampled)."""
    ts = t[~np.isnan(v)]
    out: dict[str, Any] = {"samples": int(ts.size)}
    if ts.size < 2:
        out.update(median_interval_s=None, rate_hz=None, gaps=0, longest_gap_s=None)
        return out
    dt = np.diff(ts)
    med = float(np.median(dt))
    gaps = dt > GAP_FACTOR * med
    out.update(first_s=float(ts[0]), last_s=float(ts[-1]), median_interval_s=med,
               rate_hz=(1.0 / med) if med > 0 else None, gaps=int(gaps.sum()),
               longest_gap_s=float(dt.max()) if gaps.any() else None,
               min=float(np.nanmin(v)), max=float(np.nanmax(v)))
    return out


def _recorder(rec: Mapping[str, Any] | None) -> dict[str, str]:
    """The recorder's variant and each convention read with its evidence (a Garmin export:
    ``flightrecon.ingest.garmin``), as ``conventions`` entries."""
    if not rec:
        return {}
    out = {"recorder": str(rec.get("variant", ""))}
    out.update({f"recorded {k}": str(v) for k, v in rec.get("conventions", {}).items()})
    return out


def describe_flight(flight: Flight) -> dict[str, Any]:
    """JSON-serialisable description of ``flight`` (what ``flightrecon info`` prints)."""
    d = flight.data
    t = d["t_s"].to_numpy()
    chans = {}
    for name in d.columns:
        ch = BY_NAME.get(name)
        if ch is None or ch.kind == "time":
            continue
        chans[name] = {"unit": ch.unit, "kind": ch.kind, "group": ch.group or None,
                       **channel_stats(t, d[name].to_numpy())}
    record = flight.meta.ingest
    return {
        "sources": list(flight.sources),
        "rows": len(d),
        "start_s": float(t[0]) if t.size else None,
        "end_s": float(t[-1]) if t.size else None,
        "duration_s": float(t[-1] - t[0]) if t.size else 0.0,
        "channels": chans,
        "metadata": declared_metadata(flight.meta),
        "conventions": {
            "baro_alt_m": f"datum: {flight.meta.baro_datum}",
            "gnss_alt_m": f"datum: {flight.meta.gnss_alt_datum}",
            "heading_deg": "true, clockwise from north, [0, 360)",
            "body_axes": "FRD; n_norm_g = -f_z/g0 (+1 at rest)",
            **_recorder(record.recorder),
            "conversions": list(record.notes),
        },
        "repairs": list(record.repairs),
        "door": list(record.door),
        "mapping": record.mapping,
        "sidecar": record.sidecar,
        "warnings": list(flight.warnings),
    }
