"""An arrival given for a record that ends in the air is not the track's end point.

The estimators take the arrival airfield (``[arrival]``, ``--arrival``) as where the track
ends: the joint smoother as a position at touchdown, Sabziev as its end point (at the last
sample when the record ends airborne), dead reckoning's linear correction as its closing
point.  A record cut while the aircraft still flies (a recorder stopped in cruise, a partial
export) ends wherever the aircraft then was, kilometres from the airfield: imposing the
airfield there bends the whole track toward it.

The evidence (:func:`arrival_not_end`), over the record's last second (the grid after any
``--end`` trim):

* **airspeed**: its median at or above the phase detector's airborne threshold
  (``PhaseSettings.airborne_speed_mps``, 30 m/s: the record ``ends_airborne``);
* **height above the arrival field**: the pressure altitude's median less the field's pressure
  altitude (its elevation under the arrival's QNH, else the departure's, else the standard
  atmosphere; docs/signals.md) at least :data:`MARGIN_QNH_M` (150 m, 500 ft: 2.8 km before the
  threshold on a 3 deg approach, more than the QNH's rounding and the altimeter's errors) when
  a QNH is known, :data:`MARGIN_STANDARD_M` (300 m) when not (sea-level pressure spans about
  +-35 hPa about the standard 1013.25 hPa: 8.4 m/hPa x 35 hPa).

Both hold: the arrival is dropped from the flight's metadata (no estimator uses it), kept in
``meta.arrival_not_end`` with the evidence, and a warning and a cleaning-report entry
(``arrival_not_end``) name it.  The airspeed holds but not the height: the arrival is kept as the
end point, with a warning.  That is an arrival given at the aircraft's own height, where the
record ends (a radar hand-off: the joint smoother's ``last_position`` end point, docs/joint.md),
or an airfield on short final, in a low pass or on a fast landing roll.  The record's end is then not pinned anywhere: the
estimators end where their own evidence takes them (as without an arrival).
"""

from __future__ import annotations

import dataclasses
import warnings
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.cleaning.report import report_entry
from flightrecon.errors import FlightReconWarning
from flightrecon.geo.atmosphere import field_pressure_altitude_m
from flightrecon.types import ArrivalNotEnd, FlightMeta, FlightPhases

__all__ = ["MARGIN_QNH_M", "MARGIN_STANDARD_M", "arrival_not_end"]

#: height above the arrival field that proves the record ends away from it, QNH known [m]
MARGIN_QNH_M = 150.0
#: the same without any QNH (pressure altitude against the standard atmosphere) [m]
MARGIN_STANDARD_M = 300.0


def _last_second(grid: pd.DataFrame, ch: str) -> float:
    """Median of ``ch`` over the grid's last second (NaN when not there)."""
    if ch not in grid.columns or not len(grid):
        return float("nan")
    t = grid["t_s"].to_numpy(float)
    v = grid[ch].to_numpy(float)[t >= t[-1] - 1.0]
    v = v[np.isfinite(v)]
    return float(np.median(v)) if v.size else float("nan")


def arrival_not_end(grid: pd.DataFrame, phases: FlightPhases | None, meta: FlightMeta,
                    airborne_speed_mps: float) -> tuple[FlightMeta, list[dict[str, Any]]]:
    """``meta`` without its arrival when the record ends in the air away from it (module
    docstring), and the report entries; a warning each time the arrival and an airborne end
    meet.

    Parameters
    ----------
    grid : the cleaned grid (``t_s``, ``tas_mps``, ``baro_alt_m``)
    phases : the detected phases (``ends_airborne``, ``impact_t_s``)
    meta : the flight's metadata (``arrival``, ``qnh_arrival_hpa``, ``qnh_departure_hpa``)
    airborne_speed_mps : the phase detector's airborne threshold [m/s]

    Returns
    -------
    meta, report
        ``meta`` without ``arrival`` (and with ``arrival_not_end``) when the evidence
        holds, else ``meta`` itself; the cleaning-report entries (``arrival_not_end`` or
        ``arrival_end_airborne``; none when the record does not end fast with an arrival).
    """
    arr = meta.arrival
    if arr is None or phases is None or not phases.ends_airborne \
            or np.isfinite(phases.impact_t_s):
        return meta, []
    tas = _last_second(grid, "tas_mps")
    hp = _last_second(grid, "baro_alt_m")
    qnh = meta.qnh_arrival_hpa if meta.qnh_arrival_hpa is not None else meta.qnh_departure_hpa
    margin = MARGIN_QNH_M if qnh is not None else MARGIN_STANDARD_M
    height = hp - field_pressure_altitude_m(arr.elev_m, qnh)
    t_end = float(grid["t_s"].iloc[-1])
    qtxt = f"QNH {qnh:.1f} hPa" if qnh is not None else "no QNH: standard atmosphere"
    evidence = (f"airspeed {tas:.0f} m/s (airborne from {airborne_speed_mps:g} m/s) and "
                f"{height:.0f} m above the arrival field ({qtxt}) over the last second, at "
                f"t = {t_end:.1f} s")
    if not np.isfinite(height) or height < margin:
        msg = (f"the record ends fast ({evidence}): the arrival given is taken as the "
               "aircraft's position at the last sample (a hand-off point at its height, or the "
               "airfield on short final or a fast roll-out); if the record ends elsewhere, "
               "give no arrival")
        warnings.warn(msg, FlightReconWarning, stacklevel=4)
        return meta, [report_entry("arrival", "arrival_end_airborne", msg, count=1,
                                   t_s=[t_end])]
    msg = (f"the arrival given ({arr.lat_deg:.5f}, {arr.lon_deg:.5f}, {arr.elev_m:g} m) is not "
           f"where this record ends: it ends in the air ({evidence}; {margin:g} m proves it); "
           "not used as the track's end point by any method (docs/signals.md, 'An arrival "
           "for a record that ends airborne')")
    warnings.warn(msg, FlightReconWarning, stacklevel=4)
    rec = ArrivalNotEnd(arrival=arr, t_end_s=t_end, tas_mps=tas,
                        height_above_field_m=float(height), margin_m=margin, qnh_hpa=qnh)
    meta = dataclasses.replace(meta, arrival=None, arrival_not_end=rec)
    return meta, [report_entry("arrival", "arrival_not_end", msg, count=1, t_s=[t_end],
                               height_above_field_m=float(height), tas_mps=tas)]
