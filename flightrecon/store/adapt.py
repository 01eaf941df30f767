"""Build a :class:`FlightCoefficients` record from the Sabziev method's summary.

The Sabziev method (:func:`flightrecon.fusion.method.run_sabziev`) reports, in its
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
    k, branch, conv, iters = [], [], [], 0
    for name, kname in zip(SUMMARY_AXES, AXES):
        ax = _get(axes, name, "'axes'")
        k.append(_float(_get(ax, "k", f"axis '{name}' ({kname})")))
        branch.append(_get(ax, "branch", f"axis '{name}' ({kname})"))
        conv.append(bool(_get(ax, "converged", f"axis '{name}' ({kname})")))
        iters += int(_get(ax, "iterations", f"axis '{name}' ({kname})"))
    res = _get(summary, "end_residual_m", "the summary")
    comps = [_float(_get(res, c, "'end_residual_m'")) for c in ("north", "up", "east")]
    residual = math.sqrt(sum(c * c for c in comps))  # NaN if any component is unknown
    t0, t1 = (float(x) for x in _get(summary, "interval_s", "the summary"))
    converged = bool(_get(summary, "converged", "the summary"))
    return FlightCoefficients(
        aircraft_id=aircraft_id, flight_id=flight_id, flight_date_utc=flight_date_utc,
        duration_s=t1 - t0, k1=k[0], k2=k[1], k3=k[2], branch=tuple(branch),  # type: ignore[arg-type]
        converged=converged, residual_m=residual, iterations=iters,
        software_version=software_version, settings=dict(settings or {}),
        input_hashes=dict(input_hashes or {}), axis_converged=tuple(conv))  # type: ignore[arg-type]
