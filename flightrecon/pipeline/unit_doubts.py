"""The doubt a method's result carries when a channel it leans on has a unit the door doubts,
or was used against a certain contradiction the mapping confirmed (``unit_confirmed = true``;
docs/door.md, issue #50).

The door (:mod:`flightrecon.ingest.physics`) leaves each unit check's verdict in the flight's
metadata (``door``).  A ``warned`` unit check is evidence against the unit that is not certain;
an ``overridden`` one a certain contradiction used as declared.  Either way a method whose
inputs include that channel is not ``ok``: its status is ``doubtful`` and its reason gives the
channel, the verdict and the figure; its track is still combined and written.
"""

from __future__ import annotations

from collections.abc import Iterable, Mapping
from typing import Any

__all__ = ["DOUBTFUL", "METHOD_INPUTS", "doubt", "unit_doubts"]

#: the status of a result built on a doubted or overridden unit
DOUBTFUL = "doubtful"

_LOADS = ("n_long_g", "n_lat_g", "n_norm_g")
_ATTITUDE = ("roll_deg", "pitch_deg", "heading_deg")
#: the channels each method's track leans on (its inputs)
METHOD_INPUTS: dict[str, tuple[str, ...]] = {
    "joint": (*_LOADS, *_ATTITUDE, "tas_mps", "baro_alt_m", "gnss_alt_m"),
    "sabziev": (*_LOADS, *_ATTITUDE, "tas_mps", "baro_alt_m"),
    "arms": ("heading_deg", "tas_mps", "baro_alt_m"),
    "azimuth": (*_LOADS, *_ATTITUDE, "baro_alt_m"),
    "sns": (*_ATTITUDE, "tas_mps", "baro_alt_m", "gnss_alt_m"),
}
_GROUPS = {"roll/pitch/heading": _ATTITUDE, "t_s": (*_LOADS, *_ATTITUDE, "tas_mps",
                                                     "baro_alt_m", "gnss_alt_m")}


def _channels(channel: str) -> tuple[str, ...]:
    """The channels a door record is about (``heading_deg/tas_mps``: both)."""
    if channel in _GROUPS:
        return _GROUPS[channel]
    return tuple(channel.split("/"))


def unit_doubts(door: Iterable[Mapping[str, Any]]) -> dict[str, str]:
    """Channel -> why its unit is in doubt, from the door's unit checks (module docstring)."""
    out: dict[str, str] = {}
    # an overridden contradiction first: it is certain, a doubt is not
    for c in sorted(door, key=lambda c: c.get("verdict") != "overridden"):
        if not str(c.get("check", "")).endswith(" unit"):
            continue
        if c.get("verdict") not in ("warned", "overridden"):
            continue
        fig = c.get("figure")
        what = ("used against a certain contradiction (unit_confirmed)"
                if c["verdict"] == "overridden" else "its unit doubted")
        text = (f"{c['channel']} {what}" + (f", factor {fig:.3g}" if fig is not None else ""))
        for ch in _channels(str(c["channel"])):
            out.setdefault(ch, text)
    return out


def doubt(method: str, door: Iterable[Mapping[str, Any]]) -> str | None:
    """Why ``method``'s result is doubtful (the door's checks of the flight,
    ``FlightMeta.ingest.door``), else ``None``."""
    doubts = unit_doubts(door)
    inputs = METHOD_INPUTS.get(method, ())
    hits = dict.fromkeys(text for c, text in doubts.items() if c in inputs)
    return "; ".join(hits) if hits else None
