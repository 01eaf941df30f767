"""The Sabziev adapter's vertical channel (docs/sabziev.md, "The vertical reference"): the
pressure height's datum at lift-off, the hypsometric height, its consistency with the end
points, and the pressure altitude's scale against the accelerometer."""

from __future__ import annotations

from typing import Any

import numpy as np

from flightrecon.geo.atmosphere import isa_temperature_k
from flightrecon.types import CleanFlight

LIFTOFF_DATUM_S = 2.0
"""The pressure height's datum is its mean over this long [s] before lift-off (after the first
sample when the record starts airborne)."""

SCALE_MAX = 0.15
"""Largest relative pressure-height scale error explained by the air mass
(:func:`end_consistent_height`: 15 %, an air mass 40 K off the standard atmosphere)."""


def liftoff_datum(clean: CleanFlight, t_all: np.ndarray, sl: slice,
                   baro: np.ndarray) -> tuple[np.ndarray, dict[str, Any]]:
    """The pressure height relative to its recorded value at lift-off (the paper's ``h``,
    "relative to the lift-off point"; seed 001 section IV): the mean of the recorded pressure
    altitude over :data:`LIFTOFF_DATUM_S` before lift-off, or after the first sample of a
    record that starts airborne.  No QNH is needed: the datum is the aircraft's own reading."""
    g = clean.grid["baro_alt_m"].to_numpy(dtype=np.float64)
    t0 = t_all[sl.start]
    ph = clean.phases
    if ph is not None and not ph.starts_airborne:
        win = (t_all >= t0 - LIFTOFF_DATUM_S) & (t_all <= t0)
    else:
        win = (t_all >= t0) & (t_all <= t0 + LIFTOFF_DATUM_S)
    vals = g[win][np.isfinite(g[win])]
    ref = float(np.mean(vals)) if len(vals) else float(baro[0])
    info: dict[str, Any] = {"datum": "recorded pressure altitude at lift-off",
                            "liftoff_pressure_alt_m": ref, "hypsometric": False}
    h = baro - ref
    if "sat_degc" in clean.grid.columns:
        sat = clean.grid["sat_degc"].to_numpy(dtype=np.float64)[sl]
        ok = np.isfinite(sat)
        if ok.sum() >= 0.9 * len(sat):
            idx = np.arange(len(sat))
            sat = np.interp(idx, idx[ok], sat[ok])
            # from the lift-off reading: the first sample's offset from it scaled alike
            h = hypsometric_height(baro, sat) + (baro[0] - ref) * (sat[0] + 273.15) / float(
                isa_temperature_k(baro[0]))
            info["hypsometric"] = True
    return h, info


def hypsometric_height(h_p: np.ndarray, sat_degc: np.ndarray) -> np.ndarray:
    """Geometric height gained along a record from pressure altitude and static air temperature.

    The hypsometric equation ``dz = (T / T_ISA(h_p)) dh_p`` (the standard atmosphere's pressure
    altitude scaled by the ratio of the actual to the standard temperature at the same
    pressure; ICAO Doc 7488), integrated by the trapezoidal rule from the first sample.

    Parameters
    ----------
    h_p : (N,) pressure altitude [m] (1013.25 hPa datum)
    sat_degc : (N,) static air temperature [degC]

    Returns
    -------
    (N,) geometric height relative to the first sample [m]
    """
    ratio = (np.asarray(sat_degc, dtype=np.float64) + 273.15) / isa_temperature_k(h_p)
    dz = 0.5 * (ratio[1:] + ratio[:-1]) * np.diff(h_p)
    return np.concatenate([[0.0], np.cumsum(dz)])


def end_consistent_height(t: np.ndarray, h: np.ndarray,
                          y_T: float) -> tuple[np.ndarray, dict[str, Any]]:
    """The pressure height made consistent with the end point (policy ``stable``).

    The pressure height ``h`` (relative to lift-off) ends at ``h_T`` (mean of the last second),
    the end point is at ``y_T`` (geometric, relative to lift-off); their difference
    ``D = y_T - h_T`` is the pressure height's error at the end: an air mass off the standard
    atmosphere (a scale error, about 3.5 % per 10 K) and the change of sea-level pressure over
    the flight (a datum drift).  It is removed as

    * a scale error, ``h (1 + D/h_T)``, when the flight ends near its highest point (``|h_T|``
      at least half the largest ``|h|``) and ``|D| <= SCALE_MAX |h_T|``; or else
    * a drift linear in time, ``h + D (t - t_0)/T``.

    Without it the undamped baro-inertial loop cannot both follow the pressure height and meet
    the end point: ``F(k2)`` then has roots only where the loop lets the track stray from
    ``h`` by ``D`` (docs/sabziev.md, "Signs and branches").

    Parameters
    ----------
    t : (N,) grid [s]
    h : (N,) pressure height relative to lift-off [m]
    y_T : end height relative to lift-off [m]

    Returns
    -------
    h_c : (N,) the corrected reference [m]
    info : ``end_mismatch_m`` (D), ``model`` (``scale`` or ``drift``), ``scale`` (1 + D/h_T
        or 1)
    """
    n_end = max(1, int(round(1.0 / (t[1] - t[0]))))
    h_T = float(np.mean(h[-n_end:]))
    D = float(y_T - h_T)
    h_max = float(np.max(np.abs(h)))
    if abs(h_T) >= 0.5 * h_max and abs(h_T) > 0 and abs(D) <= SCALE_MAX * abs(h_T):
        scale = 1.0 + D / h_T
        h_c = h * scale
        # the mean of the last second now ends at y_T; the last sample exactly:
        h_c = h_c + (y_T - h_c[-1]) * (t - t[0]) / (t[-1] - t[0])
        return h_c, {"end_mismatch_m": D, "model": "scale", "scale": scale}
    h_c = h + (y_T - h[-1]) * (t - t[0]) / (t[-1] - t[0])
    return h_c, {"end_mismatch_m": D, "model": "drift", "scale": 1.0}


SCALE_WINDOW_S = 20.0
"""Window [s] of the second differences compared by :func:`baro_accelerometer_scale`."""

SCALE_BAND = (0.7, 1.4)
"""Ratio of the pressure height's to the accelerometers' height changes outside which the
vertical is unhealthy (a unit error: feet read as metres gives 3.28, metres as feet 0.30; an
air mass 40 K off standard 1.15; measured 0.92-1.06 on the corpus and JSBSim flights)."""


def baro_accelerometer_scale(t: np.ndarray, a_y: np.ndarray,
                             h: np.ndarray, window_s: float = SCALE_WINDOW_S
                             ) -> tuple[float, float, float]:
    """How much faster the pressure height changes than the vertical accelerometer says.

    Second differences over ``window_s`` of the pressure height,
    ``h(t+W) - 2 h(t) + h(t-W)``, against the same of the doubly integrated vertical
    acceleration (``int int a_y``, trapezoidal), on non-overlapping windows; the least-squares
    slope with an intercept (a constant accelerometer error ``b`` adds ``b W^2`` to every
    window).  A correct pressure height gives a slope near 1; an altitude in feet read as
    metres 3.28.

    Returns
    -------
    slope, r2, spread_m : the slope, the fit's coefficient of determination and the standard
        deviation of the accelerometer's second differences [m] (below a few metres the flight
        has too little vertical manoeuvring to tell; NaN with fewer than 4 windows)
    """
    dt = float(t[1] - t[0])
    v = np.concatenate([[0.0], np.cumsum(0.5 * (a_y[1:] + a_y[:-1]) * dt)])
    y = np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)])
    k = max(1, int(round(window_s / dt)))
    idx = np.arange(k, len(t) - k, k)
    if len(idx) < 4:
        return float("nan"), float("nan"), float("nan")
    dd_h = h[idx + k] - 2.0 * h[idx] + h[idx - k]
    dd_a = y[idx + k] - 2.0 * y[idx] + y[idx - k]
    A = np.column_stack([dd_a, np.ones_like(dd_a)])
    coef = np.linalg.lstsq(A, dd_h, rcond=None)[0]
    var = float(np.var(dd_h))
    r2 = 1.0 - float(np.var(dd_h - A @ coef)) / var if var > 0 else float("nan")
    return float(coef[0]), r2, float(np.std(dd_a))
