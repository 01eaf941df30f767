"""Is a reconstructed track physically possible?  The envelope check behind method health.

A solver that converged can still return a track no aircraft could fly: a Sabziev vertical
coefficient of -3 gives vertical speeds of kilometres per second, a boundary condition at the
wrong elevation puts a cruise at 1000 m on the ground.  Every method's track is therefore held
against the physics of the recorded flight before it may be called healthy (docs/output.md,
"Method health"):

==================  =========================================================================
check               rule (defaults of :class:`Envelope`)
==================  =========================================================================
ground_speed        horizontal speed of the track, by central differences of its positions
                    over ``speed_window_s`` = 1 s, at most the highest recorded true airspeed
                    plus ``wind_margin_mps`` = 120 m/s (the strongest jet streams); 400 m/s
                    when the record has no airspeed
vertical_speed      vertical speed of the track (same differences) at most the highest recorded
                    true airspeed plus ``vertical_wind_margin_mps`` = 30 m/s: an aircraft
                    cannot climb or sink faster than it flies through the air, and vertical
                    winds beyond 30 m/s are not met outside the strongest storm cells
acceleration        magnitude of the track's acceleration, by second differences over
                    ``accel_window_s`` = 2 s, at most ``max_accel_g`` = 10 g (beyond any
                    aircraft's structural limit over two seconds)
pressure_altitude   the track's height differs from the recorded pressure altitude by more than
                    ``alt_tol_m`` = 300 m + ``alt_tol_frac`` = 15 % of the height above the
                    departure field, for at least ``alt_min_span_s`` = 30 s in all (an
                    oscillation about the right height counts as well).  The tolerance
                    covers a QNH that is off by 30 hPa (250 m) and an air mass 40 K off the
                    standard atmosphere (15 %); beyond it the track's vertical is not the
                    aircraft's.
==================  =========================================================================

The limits are deliberately wide: they are there to catch the impossible, not the unusual.
An upset (a spiral dive to the ground) stays inside them; a diverged solver does not.  After a
ground impact detected by the cleaning (``phases.impact_t_s``, :mod:`flightrecon.cleaning.impact`)
nothing is checked: the crash sequence's decelerations are the structure's (tens to hundreds
of g) and the recorder's loads are clipped at their range.  The plausibility of the estimated
states and the track's agreement with the evidence are :mod:`flightrecon.track_evidence`'s.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.cleaning.plausibility import time_spans
from flightrecon.constants import G0
from flightrecon.types import CleanFlight, MethodResult


@dataclass(frozen=True)
class Envelope:
    """Limits of a physically possible track (see the module docstring for each rule)."""

    wind_margin_mps: float = 120.0
    no_airspeed_max_ground_speed_mps: float = 400.0
    vertical_wind_margin_mps: float = 30.0
    max_accel_g: float = 10.0
    speed_window_s: float = 1.0
    accel_window_s: float = 2.0
    alt_tol_m: float = 300.0
    alt_tol_frac: float = 0.15
    alt_min_span_s: float = 30.0


def horizontal_track(res: Any
                     ) -> tuple[pd.DataFrame, str, np.ndarray, np.ndarray, np.ndarray] | None:
    """A method's track, its column prefix, times and horizontal position (north, east), or
    ``None`` for a track with no position or fewer than 3 samples."""
    tr = res.track
    p = res.name + "_"
    if f"{p}north_m" not in tr.columns or len(tr) < 3:
        return None
    return (tr, p, tr["t_s"].to_numpy(float), tr[f"{p}north_m"].to_numpy(float),
            tr[f"{p}east_m"].to_numpy(float))

def half_window(t: np.ndarray, window_s: float) -> int:
    """Samples on each side of a centre that span about ``window_s`` (at least one)."""
    if len(t) < 2:
        return 1
    dt = float(np.median(np.diff(t)))
    return max(1, int(round(0.5 * window_s / dt))) if dt > 0 else 1


def central_rate(t: np.ndarray, x: np.ndarray, window_s: float) -> np.ndarray:
    """Rate of ``x`` by central differences over about ``window_s`` (NaN at the ends and
    wherever either neighbour is missing)."""
    k = half_window(t, window_s)
    out = np.full(len(t), np.nan)
    if len(t) > 2 * k:
        out[k:-k] = (x[2 * k:] - x[:-2 * k]) / (t[2 * k:] - t[:-2 * k])
    return out


def second_rate(t: np.ndarray, x: np.ndarray, window_s: float) -> np.ndarray:
    """Second derivative of ``x`` by the three-point difference over about ``window_s``."""
    k = half_window(t, window_s)
    out = np.full(len(t), np.nan)
    if len(t) > 2 * k:
        h1 = t[k:-k] - t[:-2 * k]
        h2 = t[2 * k:] - t[k:-k]
        out[k:-k] = 2.0 * ((x[2 * k:] - x[k:-k]) / h2 - (x[k:-k] - x[:-2 * k]) / h1) / (h1 + h2)
    return out


def _field_pressure_altitude_m(clean: CleanFlight) -> float | None:
    """Pressure altitude of the departure field under its QNH (as the Sabziev adapter and the
    pipeline's pressure fallback use), ``None`` without a departure."""
    from flightrecon.geo.atmosphere import field_pressure_altitude_m

    dep = clean.meta.departure
    if dep is None:
        return None
    return field_pressure_altitude_m(dep.elev_m, clean.meta.qnh_departure_hpa)


def _height_above_departure(res: MethodResult, clean: CleanFlight, tr_t: np.ndarray
                            ) -> np.ndarray | None:
    """The method's height above the departure field (m), or ``None`` when it has none.

    Only the methods that estimate the vertical are checked: the Sabziev fusion gives its
    height above the departure field (``sabziev_height_m``), the joint smoother its ellipsoidal
    height (``joint_alt_m``: ``alt - (elev_dep + N)``).  The others' heights are the recorded
    pressure altitude or GNSS height they were given (their ``<p>alt_m`` since every prefix
    carries one, flightrecon/tracks.py): not an estimate to check.
    """
    tr = res.track
    p = res.name + "_"
    dep = clean.meta.departure
    if res.name == "sabziev" and f"{p}height_m" in tr.columns:
        return tr[f"{p}height_m"].to_numpy(float)
    if res.name == "joint" and f"{p}alt_m" in tr.columns and dep is not None:
        return tr[f"{p}alt_m"].to_numpy(float) - (dep.elev_m + clean.meta.geoid_undulation_m)
    return None


def envelope_problems(res: MethodResult, clean: CleanFlight,
                      env: Envelope = Envelope()) -> list[dict[str, Any]]:
    """Where a method's track leaves the physical envelope of the recorded flight.

    Parameters
    ----------
    res : the method's result (prefixed columns on its own ``t_s``)
    clean : the cleaned flight (recorded airspeed, pressure altitude, departure field)
    env : the limits

    Returns
    -------
    list of dict
        One item per violated rule: ``what`` (the rule, the worst value and its limit, in
        words), ``check`` (rule name), ``worst`` and ``limit`` (SI), ``spans_s``.
    """
    hz = horizontal_track(res)
    if hz is None:
        return []
    tr, p, t, north, east = hz
    out: list[dict[str, Any]] = []
    grid = clean.grid
    tas_max = float(np.nanmax(grid["tas_mps"])) if (
        "tas_mps" in grid.columns and np.isfinite(grid["tas_mps"]).any()) else None
    # after a detected ground impact (cleaning/impact.py) the record is a crash sequence, not
    # flight: its decelerations are the structure's, and the loads are clipped at their range
    t_imp = getattr(clean.phases, "impact_t_s", float("nan")) if clean.phases else float("nan")
    flight = ~(t > t_imp) if np.isfinite(t_imp) else np.ones(len(t), bool)

    def add(check: str, words: str, value: np.ndarray, limit: float, min_span: float = 0.0):
        bad = np.isfinite(value) & (value > limit) & flight
        spans = time_spans(t, bad, min_span)
        if spans:
            worst = float(np.nanmax(np.where(bad, value, np.nan)))
            out.append({"check": check, "worst": worst, "limit": float(limit), "spans_s": spans,
                        "what": f"{words} {worst:.0f} beyond the envelope's {limit:.0f}"})

    with np.errstate(invalid="ignore"):
        gs = np.hypot(central_rate(t, north, env.speed_window_s),
                      central_rate(t, east, env.speed_window_s))
        gs_limit = (tas_max + env.wind_margin_mps if tas_max is not None
                    else env.no_airspeed_max_ground_speed_mps)
        add("ground_speed", "ground speed [m/s]", gs, gs_limit)
        h = _height_above_departure(res, clean, t)
        acc2 = (second_rate(t, north, env.accel_window_s) ** 2
                + second_rate(t, east, env.accel_window_s) ** 2)
        if h is not None:
            vs = np.abs(central_rate(t, h, env.speed_window_s))
            vs_limit = ((tas_max if tas_max is not None else env.no_airspeed_max_ground_speed_mps)
                        + env.vertical_wind_margin_mps)
            add("vertical_speed", "vertical speed [m/s]", vs, vs_limit)
            acc2 = acc2 + second_rate(t, h, env.accel_window_s) ** 2
        add("acceleration", "acceleration [g]", np.sqrt(acc2) / G0, env.max_accel_g)
        h_field = _field_pressure_altitude_m(clean)
        if h is not None and h_field is not None and "baro_alt_m" in grid.columns:
            baro = np.interp(t, grid["t_s"].to_numpy(float), grid["baro_alt_m"].to_numpy(float),
                             left=np.nan, right=np.nan) - h_field
            diff = np.abs(h - baro)
            tol = env.alt_tol_m + env.alt_tol_frac * np.abs(baro)
            bad = np.isfinite(diff) & (diff > tol) & flight
            spans = time_spans(t, bad)
            dt = np.diff(t, append=t[-1])
            if spans and float(dt[bad].sum()) >= env.alt_min_span_s:
                worst = float(np.nanmax(np.where(bad, diff, np.nan)))
                out.append({"check": "pressure_altitude", "worst": worst,
                            "limit": float(env.alt_tol_m), "spans_s": spans,
                            "what": f"height {worst:.0f} m away from the recorded pressure "
                                    f"altitude (tolerance {env.alt_tol_m:.0f} m + "
                                    f"{100 * env.alt_tol_frac:.0f} % of the height)"})
    return out
