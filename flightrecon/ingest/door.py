"""The door's shared state: the declared units, the checks' records and refusal, the
unit tables and bands, and the helpers the physics checks share
(:mod:`flightrecon.ingest.physics` runs the checks of :mod:`flightrecon.ingest.unit_checks`).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any
from dataclasses import asdict, dataclass, field
from functools import cached_property

import numpy as np
import pandas as pd

from flightrecon.constants import FOOT_M, KNOT_MPS
from flightrecon.errors import ValidationError
from flightrecon.ingest.evidence import (
    Fit,
    correlation,
    own_samples,
)


#: input channels the estimators need (the joint smoother's inputs)
RECONSTRUCT_INPUTS = ("n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg",
                      "heading_deg", "tas_mps")

#: SI size of the units a channel may really be in, per dimension
UNIT_SIZES: dict[str, dict[str, float]] = {
    "length": {"m": 1.0, "ft": FOOT_M},
    "speed": {"m/s": 1.0, "kt": KNOT_MPS, "km/h": 1.0 / 3.6, "mph": 0.44704,
              "ft/s": FOOT_M},
    "angle": {"deg": 1.0, "rad": float(np.degrees(1.0))},
}
#: a unit is named when the factor lies within this relative band of the unit's factor: wide
#: enough for the atmosphere (pressure altitude against height, +-15 % over ISA +-40 K) and a
#: sensor's scale error, far from the physical band around 1
UNIT_BAND = 0.25
#: factors inside this band are physically possible for a right unit
PHYSICAL_BAND = (0.7, 1.4)
#: a fit is of good quality with this many independent windows (and its kind's agreement,
#: :attr:`flightrecon.ingest.evidence.Fit.r_min`)
N_MIN = 4.0
#: and certain when its factor is this many standard errors out of the physical band
SE_MARGIN = 3.0


@dataclass(frozen=True)
class DeclaredUnit:
    """The unit a channel's source column is read in, and where that unit comes from.

    Attributes
    ----------
    unit : its name (``"ft"``, ``"kt"``; the canonical unit for a canonical column)
    explicit : declared with ``unit = ...`` in a mapping file (the user's word: it wins over
        a doubt, not over a certain contradiction unless ``confirmed``)
    table : the mapping file and its table for the channel (``m.toml [channels.baro_alt_m]``)
        when a mapping maps it, for messages
    location : where in the mapping the unit comes from, with its line (``mapping file m.toml
        line 37, [channels.baro_alt_m] unit``; the ``column`` key when no unit is written)
    confirmed : ``unit_confirmed = true`` beside it: used as declared even against a certain
        contradiction, which is then recorded (verdict ``overridden``)
    """

    unit: str
    explicit: bool = False
    table: str | None = None
    location: str | None = None
    confirmed: bool = False

    @property
    def where(self) -> str:
        """Where the unit comes from, for messages: the mapping's file, line and key, or the
        canonical column name."""
        if self.location is None and self.table is None:
            return "the canonical column name"
        at = self.location or self.table
        return (f"{at} = \"{self.unit}\"" if self.explicit else
                f"{at} (no unit written: the channel's {self.unit})")


@dataclass(frozen=True)
class DoorCheck:
    """One check of the door and its outcome (``flightrecon info`` lists them).

    Attributes
    ----------
    check : what was checked (``"baro_alt_m unit"``)
    channel : the channel judged
    verdict : ``"passed"``, ``"warned"``, ``"refused"``, ``"skipped"`` or ``"overridden"`` (a
        certain contradiction of a unit the mapping confirms with ``unit_confirmed = true``)
    figure : the number behind the verdict (a factor; ``None`` when skipped)
    detail : the evidence in words
    """

    check: str
    channel: str
    verdict: str
    figure: float | None = None
    detail: str = ""

    def as_dict(self) -> dict:
        """JSON-ready dict (the summary's and ``info --json``'s ``door``)."""
        return asdict(self)


@dataclass
class Door:
    """What the checks share: the table, its provenance, the declared units, the records."""

    data: pd.DataFrame
    prov: Any
    declared: Mapping[str, DeclaredUnit]
    checks: list[DoorCheck] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)

    def col(self, name: str) -> str:
        return column_label(self.prov, name)

    def file(self, name: str | None = None) -> str:
        return file_label(self.prov, name)

    def where(self, name: str) -> str:
        return f"{self.file(name)}: column '{self.col(name)}'"

    @cached_property
    def _slope(self) -> tuple[float, float] | None:
        return _gnss_baro_slope(self)

    def gnss_baro_slope(self) -> tuple[float, float] | None:
        """GNSS height against pressure altitude (:func:`_gnss_baro_slope`), computed once
        for the checks that use it."""
        return self._slope

    def unit_of(self, name: str, canonical: str) -> DeclaredUnit:
        return self.declared.get(name, DeclaredUnit(canonical))

    def record(self, check: str, channel: str, verdict: str, figure: float | None = None,
               detail: str = "") -> None:
        self.checks.append(DoorCheck(check, channel, verdict,
                                     None if figure is None else float(figure), detail))

    def warn(self, check: str, channel: str, figure: float | None, text: str) -> None:
        self.record(check, channel, "warned", figure, text)
        self.warnings.append(text)

    def refuse(self, check: str, channel: str, figure: float | None, message: str,
               file: str, column: str) -> None:
        self.record(check, channel, "refused", figure, message)
        raise DoorRefusal(message, file=file, column=column, checks=self.checks)


class DoorRefusal(ValidationError):
    """A refusal of the door, carrying the checks made up to it (for ``info``'s report)."""

    def __init__(self, message: str, *, file: str | None = None, column: str | None = None,
                 checks: list[DoorCheck] | None = None) -> None:
        super().__init__(message, file=file, column=column)
        self.checks = list(checks or [])


#: a channel computed at ingest is named by the column it was computed from
_COMPUTED_FROM = {"tas_mps": ("cas_mps", "ias_mps")}


def column_label(prov, name: str) -> str:
    try:
        for n in (name, *_COMPUTED_FROM.get(name, ())):
            for cols in prov.source_column:
                if n in cols:
                    return cols[n] if n == name else f"{cols[n]}' -> '{name}"
    except (AttributeError, TypeError):
        pass
    return name


def file_label(prov, name: str | None = None) -> str:
    """The file a channel came from (the log unless only a companion file has it)."""
    try:
        if name is not None:
            for i, cols in enumerate(prov.source_column):
                if name in cols:
                    return prov.files[i]
        return prov.files[0]
    except (AttributeError, IndexError):
        return "the log"


def nearest_unit(factor: float, table: dict[str, float], tol: float) -> str | None:
    """The entry of ``table`` within ``tol`` (relative, in log) of ``factor``."""
    if not np.isfinite(factor) or factor <= 0:
        return None
    best, err = None, np.inf
    for name, f in table.items():
        e = abs(np.log(factor / f))
        if e < err:
            best, err = name, e
    return best if err < np.log(1 + tol) else None


def candidate_units(dimension: str, declared: str) -> dict[str, float]:
    """Real unit -> the factor by which values in it, read as ``declared``, are too large."""
    sizes = UNIT_SIZES[dimension]
    d = sizes.get(declared)
    if d is None:
        return {}
    return {u: d / s for u, s in sizes.items() if u != declared}


def certain_unit(fit: Fit | None, table: dict[str, float]) -> str | None:
    """The unit a good-quality fit names with certainty (module docstring), else ``None``."""
    if fit is None or not fit.good(N_MIN):
        return None
    unit = nearest_unit(fit.factor, table, UNIT_BAND)
    if unit is None:
        return None
    lo, hi = fit.factor - SE_MARGIN * fit.se, fit.factor + SE_MARGIN * fit.se
    if lo <= PHYSICAL_BAND[1] and hi >= PHYSICAL_BAND[0]:
        return None
    return unit


def plausible_fit(fit: Fit | None) -> bool:
    return fit is not None and PHYSICAL_BAND[0] <= fit.factor <= PHYSICAL_BAND[1]


def _gnss_baro_slope(door: Door) -> tuple[float, float] | None:
    """Slope and correlation of the GNSS height against the pressure altitude over the
    flight, at the GNSS fixes; ``None`` without 150 m of climb or descent."""
    sg, sb = own_samples(door.data, "gnss_alt_m", 16), own_samples(door.data, "baro_alt_m")
    if sg is None or sb is None:
        return None
    t, g = sg
    inside = (t >= sb[0][0]) & (t <= sb[0][-1])
    if inside.sum() < 16:
        return None
    b = np.interp(t[inside], *sb)
    g = g[inside]
    if (np.ptp(b) < 150.0 and np.ptp(g) < 150.0) or min(np.ptp(b), np.ptp(g)) == 0.0:
        return None
    # robust: the fixes in the middle 98 % of the residuals (a spike in either channel)
    slope, icpt = np.polyfit(b, g, 1)
    res = g - (slope * b + icpt)
    keep = np.abs(res - np.median(res)) <= max(5 * 1.4826 * np.median(np.abs(res - np.median(
        res))), 1.0)
    if keep.sum() >= 16:
        slope = np.polyfit(b[keep], g[keep], 1)[0]
        b, g = b[keep], g[keep]
    return float(slope), correlation(b, g)
