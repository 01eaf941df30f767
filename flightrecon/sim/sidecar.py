"""The sidecar of a simulated flight: its metadata as TOML (:func:`meta_toml`, the format
``flightrecon`` reads beside a log: docs/schema.md) and the names of the files written beside
a log (:func:`sibling`)."""

from __future__ import annotations

import json
import math
from pathlib import Path

from flightrecon.errors import OutputError
from flightrecon.types import FlightMeta, Position


def _toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, (list, tuple)):
        return "[" + ", ".join(_toml_value(x) for x in v) + "]"
    f = float(v)
    if not math.isfinite(f):
        raise OutputError(f"metadata value {v!r} is not finite")
    return repr(f)


def meta_toml(meta: FlightMeta) -> str:
    """The sidecar text for ``meta`` (tables ``flight``, ``departure``, ``arrival``,
    ``station``; a missing position or value is left out)."""
    flight = {
        "aircraft_id": meta.aircraft_id, "flight_id": meta.flight_id,
        "epoch_utc": meta.epoch_utc, "gnss_alt_datum": meta.gnss_alt_datum,
        "baro_datum": meta.baro_datum, "geoid_undulation_m": meta.geoid_undulation_m,
        "gnss_lever_arm_m": [float(x) for x in meta.gnss_lever_arm_m],
        "qnh_departure_hpa": meta.qnh_departure_hpa, "qnh_arrival_hpa": meta.qnh_arrival_hpa,
        "attitude_source": meta.attitude_source,
    }
    lines = ["[flight]"]
    lines += [f"{k} = {_toml_value(v)}" for k, v in flight.items() if v is not None]
    for name in ("departure", "arrival", "station"):
        p: Position | None = getattr(meta, name)
        if p is None:
            continue
        lines += ["", f"[{name}]", f"lat_deg = {_toml_value(p.lat_deg)}",
                  f"lon_deg = {_toml_value(p.lon_deg)}", f"elev_m = {_toml_value(p.elev_m)}"]
        if p.runway_true_deg is not None:
            lines.append(f"runway_true_deg = {_toml_value(p.runway_true_deg)}")
        if p.threshold is not None:
            lines += [f"threshold_lat_deg = {_toml_value(p.threshold_lat_deg)}",
                      f"threshold_lon_deg = {_toml_value(p.threshold_lon_deg)}"]
    return "\n".join(lines) + "\n"


def sibling(path: str | Path, suffix: str) -> Path:
    """``<stem><suffix>`` beside ``path`` (``x.parquet`` -> ``x.meta.toml``)."""
    path = Path(path)
    return path.with_name(path.name[: -len(path.suffix)] + suffix if path.suffix else
                          path.name + suffix)
