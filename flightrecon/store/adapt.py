"""Build store records from method summaries: a :class:`FlightCoefficients` from the Sabziev
method's, a :class:`FlightCalibration` from the joint smoother's (:func:`from_joint_summary`).

The Sabziev method (:func:`flightrecon.methods.sabziev.method.run_sabziev`) reports, in its
``MethodResult.summary``: ``mode`` (``"boundary-value"`` when k was fitted), ``converged``,
``axes`` = {``"x"``: k1, ``"y"``: k2, ``"z"``: k3 reports, each with ``converged``, ``k``,
``branch``, ``iterations``}, ``end_residual_m`` = {``north``, ``up``, ``east``} and
``interval_s`` = [lift-off, touchdown].  This module maps that onto a store record, so that the
pipeline records exactly what the solver found.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from datetime import date, datetime
from typing import Any

from flightrecon import __version__
from flightrecon.errors import StoreError
from flightrecon.store.calibration import FlightCalibration, SensorEstimate
from flightrecon.store.records import AXES, FlightCoefficients

#: Sabziev-frame axis of each coefficient (docs/sabziev.md: x north, y up, z east)
SUMMARY_AXES: tuple[str, str, str] = ("x", "y", "z")


def _get(d: Mapping[str, Any], key: str, where: str) -> Any:
    if not isinstance(d, Mapping) or key not in d:
        raise StoreError(f"not a Sabziev method summary: '{key}' missing in {where}")
    return d[key]


def _float(x: Any) -> float:
    return math.nan if x is None else float(x)


def from_sabziev_summary(summary: Mapping[str, Any], *, aircraft_id: str, flight_id: str,
                         flight_date_utc: str | datetime | date,
                         software_version: str = __version__,
                         settings: dict[str, Any] | None = None,
                         input_hashes: dict[str, Any] | None = None) -> FlightCoefficients:
    """The store record of one boundary-value Sabziev fit.

    Parameters
    ----------
    summary : ``MethodResult.summary`` of the Sabziev method
    aircraft_id, flight_id, flight_date_utc : identify the flight (date in UTC)
    software_version, settings, input_hashes : provenance (settings and hashes as in the
        reconstruction summary)

    Returns
    -------
    FlightCoefficients
        ``residual_m`` is the Euclidean norm of the end-point miss (north, up, east), NaN if a
        component is unknown; ``iterations`` the total over the three axes; ``duration_s`` the
        fitted interval.

    Raises
    ------
    StoreError
        The summary is not a boundary-value fit (coefficients given in the initial-value mode
        were not fitted on this flight and must not feed the averages), or lacks a field.
    """
    mode = _get(summary, "mode", "the summary")
    if mode != "boundary-value":
        raise StoreError(f"the Sabziev run was in {mode} mode: its coefficients were given, not "
                         "fitted on this flight, so there is nothing to record")
    axes = _get(summary, "axes", "the summary")
    k, branch, conv, iters, k_sd = [], [], [], 0, []
    for name, kname in zip(SUMMARY_AXES, AXES):
        ax = _get(axes, name, "'axes'")
        # the coefficient the track used: the root, or (stable policy, no root taken) the
        # fixed stable coefficient, recorded with the axis not converged so that it never
        # enters an average (flightrecon.store.stats uses converged fits only)
        k.append(_float(ax["k_used"] if "k_used" in ax
                        else _get(ax, "k", f"axis '{name}' ({kname})")))
        branch.append(_get(ax, "branch", f"axis '{name}' ({kname})"))
        conv.append(bool(_get(ax, "converged", f"axis '{name}' ({kname})")))
        iters += int(_get(ax, "iterations", f"axis '{name}' ({kname})"))
        k_sd.append(_float(ax.get("k_sd")))  # the root's conditioning (absent: unknown)
    res = _get(summary, "end_residual_m", "the summary")
    comps = [_float(_get(res, c, "'end_residual_m'")) for c in ("north", "up", "east")]
    residual = math.sqrt(sum(c * c for c in comps))  # NaN if any component is unknown
    t0, t1 = (float(x) for x in _get(summary, "interval_s", "the summary"))
    # a fit is converged when every axis found a root; the stable policy's summary says
    # "converged" when the track meets the end point (a root or the linear end correction of
    # an axis without one, docs/sabziev.md) and "roots_found" for the fit itself
    converged = bool(summary["roots_found"] if "roots_found" in summary
                     else _get(summary, "converged", "the summary"))
    return FlightCoefficients(
        aircraft_id=aircraft_id, flight_id=flight_id, flight_date_utc=flight_date_utc,
        duration_s=t1 - t0, k1=k[0], k2=k[1], k3=k[2], branch=tuple(branch),  # type: ignore[arg-type]
        converged=converged, residual_m=residual, iterations=iters,
        software_version=software_version, settings=dict(settings or {}),
        input_hashes=dict(input_hashes or {}), axis_converged=tuple(conv),  # type: ignore[arg-type]
        k_sd=(k_sd[0], k_sd[1], k_sd[2]))


def flight_conditions(clean: Any) -> dict[str, Any]:
    """The conditions that make a flight's sensor estimates comparable with another's, from a
    :class:`flightrecon.types.CleanFlight`: ``configuration`` (the sidecar's ``[flight]
    configuration``, kept in the metadata's ``extra``; ``""`` if not given), ``duration_s``
    (the record), ``tas_range_mps`` and ``alt_range_m`` (5th and 95th percentiles of the
    airborne true airspeed and pressure altitude; airborne = between lift-off and touchdown
    where the phases are known, else TAS >= 30 m/s)."""
    import numpy as np

    g = clean.grid
    t = g["t_s"].to_numpy(float)
    ph = clean.phases
    if ph is not None and math.isfinite(ph.liftoff_t_s) and math.isfinite(ph.touchdown_t_s):
        air = (t >= ph.liftoff_t_s) & (t <= ph.touchdown_t_s)
    elif "tas_mps" in g.columns:
        air = g["tas_mps"].to_numpy(float) >= 30.0
    else:
        air = np.ones(len(t), bool)

    def pct(col: str) -> tuple[float, float]:
        if col not in g.columns:
            return (math.nan, math.nan)
        v = g[col].to_numpy(float)[air]
        v = v[np.isfinite(v)]
        if not len(v):
            return (math.nan, math.nan)
        lo, hi = np.percentile(v, [5, 95])
        return (float(lo), float(hi))

    return {"configuration": clean.meta.configuration or "", "duration_s": float(t[-1] - t[0]) if len(t) > 1 else 1.0,
            "tas_range_mps": pct("tas_mps"), "alt_range_m": pct("baro_alt_m")}


def from_joint_summary(summary: Mapping[str, Any], *, aircraft_id: str, flight_id: str,
                       flight_date_utc: str | datetime | date,
                       conditions: Mapping[str, Any] | None = None,
                       software_version: str = __version__,
                       settings: dict[str, Any] | None = None,
                       input_hashes: dict[str, Any] | None = None,
                       log_sha256: str | None = None) -> FlightCalibration:
    """The sensor-calibration record of one joint-smoother run.

    Parameters
    ----------
    summary : ``MethodResult.summary`` of the joint smoother (or its status entry in the
        reconstruction summary): ``corrections`` {name: {value, sd, unit, prior_mean,
        prior_sd}}, ``converged``, ``sources`` {name: {count, ...}}
    conditions : :func:`flight_conditions` of the flight

    Raises
    ------
    StoreError
        The summary has no corrections, or they lack their prior (a summary written before the
        priors were reported).
    """
    corr = _get(summary, "corrections", "the joint summary")
    est = []
    for name, c in corr.items():
        for key in ("value", "sd", "prior_mean", "prior_sd"):
            _get(c, key, f"correction '{name}'")
        est.append(SensorEstimate(quantity=name, value=c["value"], sd=c["sd"],
                                  prior_mean=c["prior_mean"], prior_sd=c["prior_sd"],
                                  unit=str(c.get("unit", ""))))
    srcs = summary.get("sources") or {}
    used = "+".join(n for n, s in srcs.items() if (s or {}).get("count"))
    cond = dict(conditions or {})
    return FlightCalibration(
        aircraft_id=aircraft_id, flight_id=flight_id, flight_date_utc=flight_date_utc,
        estimates=tuple(est), configuration=str(cond.get("configuration", "")), sources=used,
        duration_s=float(cond.get("duration_s", 1.0)),
        tas_range_mps=tuple(cond.get("tas_range_mps", (math.nan, math.nan))),  # type: ignore[arg-type]
        alt_range_m=tuple(cond.get("alt_range_m", (math.nan, math.nan))),  # type: ignore[arg-type]
        converged=bool(summary.get("converged", False)), software_version=software_version,
        settings=dict(settings or {}), input_hashes=dict(input_hashes or {}),
        log_sha256=log_sha256)
