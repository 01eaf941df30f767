"""Averaging rules for the per-aircraft coefficients (docs/sabziev.md, last paragraph).

Sabziev (2020, Conclusions) proposes that the coefficients depend mainly on the aircraft, so that
their mean over several flights of one aircraft can reconstruct a flight whose arrival point is
unknown.  A mean only makes sense over fits of the same kind, hence the rule, applied to each
axis separately:

1. keep the fits converged on that axis (the others are excluded: ``"not converged"``; a flight
   whose k1 converged but whose k3 did not still counts for k1);
2. group them by root branch and keep the majority branch; a tie goes to ``"negative"``, the
   physical branch (the ``"positive"`` branch grows like exp(k T) and is not physical);
   the others are excluded: ``"branch positive, majority negative"`` (or the reverse);
3. over the fits kept: count, mean, median, sample standard deviation (ddof = 1), and the drift,
   the ordinary least-squares slope of k against the flight date in days with its standard error.

These are pure functions on lists of :class:`~flightrecon.store.records.FlightCoefficients`;
the store calls them on the rows it reads.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from flightrecon.errors import StoreError
from flightrecon.store.records import (AXES, AircraftStats, AxisStats, Exclusion, FleetMean,
                                       FlightCoefficients, utc_days)

#: branch chosen when both branches have the same number of converged fits
TIE_BRANCH = "negative"


def majority_branch(branches: Sequence[str]) -> str | None:
    """The most frequent branch; a tie gives :data:`TIE_BRANCH`; ``None`` for no branches."""
    if len(branches) == 0:
        return None
    n_neg = sum(1 for b in branches if b == "negative")
    n_pos = len(branches) - n_neg
    if n_neg == n_pos:
        return TIE_BRANCH
    return "negative" if n_neg > n_pos else "positive"


def drift(days: np.ndarray, k: np.ndarray) -> tuple[float, float]:
    """Least-squares slope of ``k`` against ``days`` and its standard error.

    slope = Sxy / Sxx and se = sqrt(s^2 / Sxx), s^2 = sum(residual^2) / (n - 2), with
    Sxx = sum((t - mean t)^2), Sxy = sum((t - mean t)(k - mean k)) (the textbook simple linear
    regression).  Times are centred before use, so dates near 20 000 days since 1970 lose no
    precision.

    Parameters
    ----------
    days : (n,) flight dates [days]
    k : (n,) coefficient values

    Returns
    -------
    slope, se : [unit of k per day]; slope NaN when n < 2 or all dates coincide, se NaN when
        the slope is NaN or n < 3 (no residual degree of freedom).
    """
    n = len(days)
    if n < 2:
        return math.nan, math.nan
    t = np.asarray(days, dtype=np.float64) - float(np.mean(days))
    y = np.asarray(k, dtype=np.float64)
    sxx = float(t @ t)
    if sxx == 0.0:
        return math.nan, math.nan
    slope = float(t @ (y - float(np.mean(y)))) / sxx
    if n < 3:
        return slope, math.nan
    resid = (y - float(np.mean(y))) - slope * t
    s2 = float(resid @ resid) / (n - 2)
    return slope, math.sqrt(s2 / sxx)


def axis_stats(records: Sequence[FlightCoefficients], axis: str) -> AxisStats:
    """Statistics of one coefficient under the averaging rule of this module.

    Parameters
    ----------
    records : the fits of one aircraft
    axis : ``"k1"``, ``"k2"`` or ``"k3"``
    """
    if axis not in AXES:
        raise StoreError(f"unknown coefficient '{axis}', expected one of {AXES}")
    i = AXES.index(axis)
    excluded = [Exclusion(r.flight_id, axis, "not converged")
                for r in records if not r.axis_converged[i]]
    conv = [r for r in records if r.axis_converged[i]]
    branch = majority_branch([r.branch[i] for r in conv])
    used = [r for r in conv if r.branch[i] == branch]
    excluded += [Exclusion(r.flight_id, axis, f"branch {r.branch[i]}, majority {branch}")
                 for r in conv if r.branch[i] != branch]
    k = np.array([getattr(r, axis) for r in used], dtype=np.float64)
    days = np.array([utc_days(r.flight_date_utc) for r in used], dtype=np.float64)
    n = len(used)
    mean = float(np.mean(k)) if n else math.nan
    median = float(np.median(k)) if n else math.nan
    std = float(np.std(k, ddof=1)) if n >= 2 else math.nan
    slope, se = drift(days, k)
    return AxisStats(axis=axis, branch=branch, n=n, mean=mean, median=median, std=std,
                     drift_per_day=slope, drift_se_per_day=se, excluded=tuple(excluded))


def aircraft_stats(aircraft_id: str, records: Sequence[FlightCoefficients]) -> AircraftStats:
    """Per-axis statistics of one aircraft's fits (all ``records`` must belong to it)."""
    others = {r.aircraft_id for r in records} - {aircraft_id}
    if others:
        raise StoreError(f"records of other aircraft given: {sorted(others)}")
    axes = tuple(axis_stats(records, ax) for ax in AXES)
    return AircraftStats(aircraft_id=aircraft_id, n_flights=len(records), axes=axes)  # type: ignore[arg-type]


def fleet_mean(stats: AircraftStats, min_flights: int = 1) -> FleetMean:
    """Averaged coefficients for the initial-value mode, from :func:`aircraft_stats`.

    Parameters
    ----------
    stats : statistics of the aircraft
    min_flights : fewest usable fits accepted per axis (>= 1)

    Raises
    ------
    StoreError
        An axis has fewer than ``min_flights`` usable fits (the message says how many were
        excluded and why).
    """
    if min_flights < 1:
        raise StoreError(f"min_flights must be >= 1, got {min_flights}")
    short = [a for a in stats.axes if a.n < min_flights]
    if short:
        parts = []
        for a in short:
            why = ", ".join(f"{c} {r}" for r, c in a.excluded_counts().items()) or "none recorded"
            parts.append(f"{a.axis}: {a.n} usable (excluded: {why})")
        raise StoreError(f"aircraft '{stats.aircraft_id}' has fewer than {min_flights} usable "
                         f"fit(s) per axis: " + "; ".join(parts))
    return FleetMean(
        aircraft_id=stats.aircraft_id,
        k=tuple(a.mean for a in stats.axes),  # type: ignore[arg-type]
        sd=tuple(a.std for a in stats.axes),  # type: ignore[arg-type]
        n=tuple(a.n for a in stats.axes),  # type: ignore[arg-type]
        branch=tuple(a.branch for a in stats.axes),  # type: ignore[arg-type]
    )
