"""Units accepted at the boundary and their conversion to the canonical (SI) units.

Every canonical channel has one unit (``flightrecon.schema.Channel.unit``).  A source column may
be in any unit of the same *dimension*; :func:`to_canonical` converts it with an exact affine map
``value_canonical = scale * value + offset`` (docs/ingest.md, "Units").  Load factors given as an
acceleration in m/s^2 are divided by g0 = 9.80665 m/s^2 (docs/schema.md, "Conventions": g0 is a
unit, not the local gravity).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightrecon.constants import FOOT_M, FPM_MPS, G0, KNOT_MPS


@dataclass(frozen=True)
class Unit:
    """An accepted unit: its dimension and the affine map to the canonical unit of that dimension.

    Attributes
    ----------
    name : canonical spelling (``"ft"``, ``"kt"``, ...)
    dimension : ``"length"``, ``"speed"``, ``"load"``, ``"angle"``, ``"temperature"``, ``"time"``
    scale, offset : canonical value = ``scale * value + offset``
    """

    name: str
    dimension: str
    scale: float
    offset: float = 0.0


UNITS: dict[str, Unit] = {u.name: u for u in (
    Unit("m", "length", 1.0),
    Unit("ft", "length", FOOT_M),
    Unit("km", "length", 1000.0),
    Unit("m/s", "speed", 1.0),
    Unit("kt", "speed", KNOT_MPS),
    Unit("km/h", "speed", 1000.0 / 3600.0),
    Unit("ft/min", "speed", FPM_MPS),
    Unit("g", "load", 1.0),
    Unit("m/s^2", "load", 1.0 / G0),
    Unit("deg", "angle", 1.0),
    Unit("rad", "angle", 180.0 / np.pi),
    Unit("degC", "temperature", 1.0),
    Unit("K", "temperature", 1.0, -273.15),
    Unit("s", "time", 1.0),
    Unit("deg/s", "angular rate", 1.0),
    Unit("rad/s", "angular rate", 180.0 / np.pi),
    Unit("1", "ratio", 1.0),
)}

#: other spellings seen in recorder exports -> canonical spelling
ALIASES: dict[str, str] = {
    "meter": "m", "meters": "m", "metre": "m", "metres": "m",
    "feet": "ft", "foot": "ft",
    "mps": "m/s", "m s-1": "m/s",
    "kts": "kt", "knot": "kt", "knots": "kt", "kn": "kt",
    "kmh": "km/h", "kph": "km/h",
    "fpm": "ft/min",
    "m/s2": "m/s^2", "m/s**2": "m/s^2", "mps2": "m/s^2",
    "degree": "deg", "degrees": "deg",
    "radian": "rad", "radians": "rad",
    "c": "degC", "degc": "degC", "celsius": "degC",
    "k": "K", "kelvin": "K",
    "sec": "s", "second": "s", "seconds": "s",
    "dps": "deg/s", "deg/sec": "deg/s", "degrees/s": "deg/s", "rad/sec": "rad/s", "rps": "rad/s",
    "-": "1", "none": "1", "": "1",
}

#: dimension of each canonical unit string used in ``flightrecon.schema``
CANONICAL_DIMENSION: dict[str, str] = {
    "m": "length", "m/s": "speed", "g": "load", "deg": "angle", "degC": "temperature", "s": "time",
    "deg/s": "angular rate", "1": "ratio",
}


def lookup_unit(text: str) -> Unit | None:
    """The :class:`Unit` spelt ``text`` (case-insensitive for aliases), or ``None`` if unknown."""
    t = str(text).strip()
    if t in UNITS:
        return UNITS[t]
    a = ALIASES.get(t.lower())
    return UNITS[a] if a else None


def to_canonical(values: np.ndarray, unit: Unit) -> np.ndarray:
    """Convert ``values`` given in ``unit`` to the canonical unit of its dimension (float64)."""
    v = np.asarray(values, dtype=np.float64)
    if unit.scale == 1.0 and unit.offset == 0.0:
        return v
    return v * unit.scale + unit.offset
