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

These describe the raw coefficients.  The fleet mean the initial-value mode uses
(:func:`fleet_mean`) is that of the candidate aircraft property instead
(:func:`property_stats`): the time constant ``tau = -1/k`` of k1, k3 and the loop frequency
``w = sqrt(-k2)`` of k2, over the fits on the stable branch only, weighted by the inverse
variance of the transform from each fit's conditioning (``k_sd``); docs/store.md.

These are pure functions on lists of :class:`~flightrecon.store.records.FlightCoefficients`;
the store calls them on the rows it reads.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from flightrecon.errors import StoreError
from flightrecon.store.records import (AXES, AircraftStats, AxisStats, Exclusion, FleetMean,
                                       FlightCoefficients, PropertyStats, utc_days)

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


#: the branch a candidate aircraft property is averaged on (docs/sabziev.md: the stable policy)
STABLE_BRANCH = "negative"


def to_property(axis: str, k: float, k_sd: float) -> tuple[float, float]:
    """A coefficient on the stable branch as its candidate property, with its sd to first
    order: ``tau = -1/k``, ``sd_tau = k_sd / k^2`` (k1, k3) or ``w = sqrt(-k2)``,
    ``sd_w = k_sd / (2 w)`` (k2).  ``k`` must be negative."""
    if not k < 0.0:
        raise StoreError(f"{axis} = {k}: a property is defined on the stable branch (k < 0)")
    if axis == "k2":
        w = math.sqrt(-k)
        return w, k_sd / (2.0 * w)
    return -1.0 / k, k_sd / (k * k)


def from_property(axis: str, p: float, p_sd: float) -> tuple[float, float]:
    """Inverse of :func:`to_property`: ``k = -1/tau``, ``sd_k = sd_tau / tau^2`` (k1, k3) or
    ``k2 = -w^2``, ``sd_k = 2 w sd_w``."""
    if axis == "k2":
        return -p * p, 2.0 * p * p_sd
    return -1.0 / p, p_sd / (p * p)


def property_stats(records: Sequence[FlightCoefficients], axis: str) -> PropertyStats:
    """The candidate aircraft property behind ``axis`` over ``records`` (docs/store.md).

    Fits converged on the axis and on the stable branch only; each transformed by
    :func:`to_property`; weighted by ``1 / sd_p^2`` when every fit carries a finite ``k_sd``
    (its conditioning), else equally.
    """
    i = AXES.index(axis)
    used = [r for r in records if r.axis_converged[i] and r.branch[i] == STABLE_BRANCH]
    quantity = "w_radps" if axis == "k2" else "tau_s"
    n = len(used)
    if n == 0:
        nan = math.nan
        return PropertyStats(axis, quantity, 0, False, nan, nan, nan, nan, nan, nan)
    sds = [(r.k_sd or (math.nan,) * 3)[i] for r in used]
    pairs = [to_property(axis, getattr(r, axis), sd) for r, sd in zip(used, sds)]
    p = np.array([x for x, _ in pairs], dtype=np.float64)
    psd = np.array([x for _, x in pairs], dtype=np.float64)
    weighted = bool(np.all(np.isfinite(psd)) and np.all(psd > 0.0))
    w = 1.0 / psd**2 if weighted else np.ones(n)
    mean = float(w @ p / w.sum())
    spread = float(np.std(p, ddof=1)) if n >= 2 else math.nan
    if weighted:
        se = float(1.0 / math.sqrt(w.sum()))
        chi2 = float(w @ (p - mean) ** 2 / (n - 1)) if n >= 2 else math.nan
    else:
        se = spread / math.sqrt(n) if n >= 2 else math.nan
        chi2 = math.nan
    k, k_sd = from_property(axis, mean, spread)
    return PropertyStats(axis=axis, quantity=quantity, n=n, weighted=weighted, mean=mean, se=se,
                         spread=spread, chi2_dof=chi2, k=k, k_sd=k_sd)


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
                     drift_per_day=slope, drift_se_per_day=se, excluded=tuple(excluded),
                     prop=property_stats(records, axis))


def aircraft_stats(aircraft_id: str, records: Sequence[FlightCoefficients]) -> AircraftStats:
    """Per-axis statistics of one aircraft's fits (all ``records`` must belong to it)."""
    others = {r.aircraft_id for r in records} - {aircraft_id}
    if others:
        raise StoreError(f"records of other aircraft given: {sorted(others)}")
    axes = tuple(axis_stats(records, ax) for ax in AXES)
    return AircraftStats(aircraft_id=aircraft_id, n_flights=len(records), axes=axes)  # type: ignore[arg-type]


def fleet_mean(stats: AircraftStats, min_flights: int = 1, *,
               allow_missing: bool = False) -> FleetMean:
    """Fleet coefficients for the initial-value mode, from :func:`aircraft_stats`: per axis the
    coefficient of the weighted mean property over the stable-branch fits
    (:class:`~flightrecon.store.records.PropertyStats`), with the flight-to-flight spread as its
    sd.

    Parameters
    ----------
    stats : statistics of the aircraft
    min_flights : fewest usable fits accepted per axis (>= 1)
    allow_missing : give an axis with too few fits as NaN (named in ``missing``; the Sabziev
        adapter then takes the stable policy's fixed coefficient there) instead of raising,
        as long as one axis has enough

    Raises
    ------
    StoreError
        An axis has fewer than ``min_flights`` usable fits (every axis, with ``allow_missing``;
        the message says how many were excluded and why).
    """
    if min_flights < 1:
        raise StoreError(f"min_flights must be >= 1, got {min_flights}")
    props = [a.prop if a.prop is not None else property_stats((), a.axis) for a in stats.axes]
    short = [(a, p) for a, p in zip(stats.axes, props) if p.n < min_flights]
    if short and (not allow_missing or len(short) == len(stats.axes)):
        parts = []
        for a, p in short:
            why = ", ".join(f"{c} {r}" for r, c in a.excluded_counts().items()) or "none recorded"
            n_pos = a.n - p.n if a.branch == "positive" else 0
            extra = f", {n_pos} on the positive branch" if n_pos else ""
            parts.append(f"{a.axis}: {p.n} usable on the stable branch (excluded: {why}{extra})")
        raise StoreError(f"aircraft '{stats.aircraft_id}' has fewer than {min_flights} usable "
                         f"fit(s) per axis: " + "; ".join(parts))
    missing = tuple(a.axis for a, _ in short)
    nan = math.nan
    return FleetMean(
        aircraft_id=stats.aircraft_id,
        k=tuple(nan if p.axis in missing else p.k for p in props),  # type: ignore[arg-type]
        sd=tuple(nan if p.axis in missing else p.k_sd for p in props),  # type: ignore[arg-type]
        n=tuple(p.n for p in props),  # type: ignore[arg-type]
        branch=tuple("none" if p.axis in missing else STABLE_BRANCH  # type: ignore[arg-type]
                     for p in props),
        missing=missing,
    )
