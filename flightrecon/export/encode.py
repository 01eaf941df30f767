"""What every writer shares: standard JSON (no NaN), XML escaping, UTC texts of the track's
times, the summary's flight block, and the track's rows with a position (thinned evenly for the
map formats).  Used by :mod:`flightrecon.export.writers` and :mod:`flightrecon.export.replay`.
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.errors import OutputError


def escape(text: str) -> str:
    """``&``, ``<`` and ``>`` as XML entities (:func:`xml.sax.saxutils.escape`, imported only
    when a KML is written: it pulls in ``urllib`` and ``ssl``)."""
    from xml.sax.saxutils import escape as xml_escape

    return xml_escape(text)


def _json_default(o: Any) -> Any:
    if isinstance(o, (np.floating,)):
        return None if not np.isfinite(o) else float(o)
    if isinstance(o, (np.integer,)):
        return int(o)
    if isinstance(o, np.bool_):
        return bool(o)
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, Path):
        return str(o)
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def clean_json(o: Any) -> Any:
    """Replace non-finite floats by None so the JSON is standard (RFC 8259)."""
    if isinstance(o, float):
        return o if math.isfinite(o) else None
    if isinstance(o, Mapping):
        return {str(k): clean_json(v) for k, v in o.items()}
    if isinstance(o, (list, tuple)):
        return [clean_json(v) for v in o]
    if isinstance(o, np.ndarray):
        return clean_json(o.tolist())
    if isinstance(o, np.floating):
        return clean_json(float(o))
    return o


def to_json(obj: Any) -> str:
    """Standard JSON (no NaN/Infinity), indented."""
    return json.dumps(clean_json(obj), indent=2, default=_json_default, allow_nan=False)

def flight_of(metadata: Mapping[str, Any] | None) -> Mapping[str, Any]:
    fl = metadata.get("flight") if isinstance(metadata, Mapping) else None
    return fl if isinstance(fl, Mapping) else {}


def utc_strings(t_s: np.ndarray, epoch_utc: str | None) -> np.ndarray | None:
    """ISO-8601 UTC texts (milliseconds, ``Z``) of ``t_s`` seconds after ``epoch_utc``."""
    from flightrecon.events import parse_epoch

    t0 = parse_epoch(epoch_utc)
    if t0 is None:
        return None
    base = np.datetime64(t0.replace(tzinfo=None), "ms")
    t = np.asarray(t_s, float)
    ok = np.isfinite(t)
    out = np.full(len(t), "", dtype=object)
    stamps = base + (t[ok] * 1000.0).round().astype("timedelta64[ms]")
    out[ok] = np.char.add(np.datetime_as_string(stamps, unit="ms"), "Z")
    return out


def thin_index(n: int, max_points: int) -> np.ndarray:
    if n <= max_points:
        return np.arange(n)
    return np.unique(np.linspace(0, n - 1, max_points).round().astype(int))


def sd_columns(track: pd.DataFrame) -> list[str]:
    return [c for c in track.columns if "_sd_" in c and not c.startswith(("sabziev_", "arms_",
                                                                            "azimuth_", "sns_"))]


def geo_rows(track: pd.DataFrame) -> pd.DataFrame:
    for c in ("lat_deg", "lon_deg", "alt_m"):
        if c not in track.columns:
            raise OutputError(f"the result has no '{c}' column: cannot write a map format")
    ok = np.isfinite(track[["lat_deg", "lon_deg", "alt_m"]].to_numpy()).all(axis=1)
    return track.loc[ok]

