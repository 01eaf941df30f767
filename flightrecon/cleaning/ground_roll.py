"""The take-off roll and the rest before it, found in the recorded data by integrating the
ground speed back from lift-off (docs/signals.md, "Phase detection"; docs/joint.md).

The one detection of the roll: the joint smoother's zero-velocity stretch and roll start
(:func:`takeoff_roll`, refined there with its smoothed lift-off speed and accelerometer bias)
and the cleaning's line-up and roll start (:mod:`flightrecon.cleaning.phases`) integrate the
along-track kinematic acceleration back with :func:`speed_integrated_back`.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


def speed_integrated_back(a_along: np.ndarray, dt: np.ndarray | float, v_end: float
                          ) -> np.ndarray:
    """Ground speed integrated back from the last sample: ``v(t_i) = v_end - int_{t_i}^{t_end}
    a dt`` (trapezoidal; ``dt`` the interval lengths, (n - 1,), or one step).  The one
    integration both the line-up's roll start
    (:func:`flightrecon.cleaning.phases.detect_phases_with_report`) and :func:`takeoff_roll` use."""
    dv = 0.5 * (a_along[1:] + a_along[:-1]) * dt   # speed gained over each interval
    return v_end - np.r_[np.cumsum(dv[::-1])[::-1], 0.0]


@dataclass(frozen=True)
class TakeoffRoll:
    """The take-off roll found in the recorded data (:func:`takeoff_roll`).

    Attributes
    ----------
    start_t : start of the roll [s], NaN where not found
    rest_t : (first, last) time [s] of the rest before it (the aircraft lined up), NaN each where
        the aircraft was not seen at rest
    """

    start_t: float = np.nan
    rest_t: tuple[float, float] = (np.nan, np.nan)

    def same_as(self, other: TakeoffRoll) -> bool:
        """The same roll start and rest (NaN, not found, equal to NaN)."""
        return bool(np.array_equal([self.start_t, *self.rest_t],
                                   [other.start_t, *other.rest_t], equal_nan=True))


def takeoff_roll(t_in: np.ndarray, acc_ned: np.ndarray, heading_rad: np.ndarray,
                 tas: np.ndarray, liftoff_t: float, wind_ne: np.ndarray | None = None,
                 rest_mps: float = 3.0, max_rolling_mps: float = 10.0,
                 settle_s: float = 10.0, v_lo_mps: float | None = None,
                 accel_bias_mps2: float = 0.0, not_before_t: float = np.nan) -> TakeoffRoll:
    """Start of the take-off roll, and the rest before it, from the recorded data alone (the
    joint smoother's zero-velocity stretch and roll start; :mod:`flightrecon.cleaning.phases`,
    "Taxi and take-off roll").

    The ground speed is integrated backwards from lift-off, v(t) = v_lo - int_t^t_lo a dt,
    with a the measured kinematic acceleration along the recorded heading and v_lo the
    along-track ground speed at lift-off: ``v_lo_mps`` where given (the smoother passes its
    smoothed velocity), else the recorded airspeed minus the recorded head wind (where
    given).  The roll starts at the last sample with v <= ``rest_mps``; a record whose aircraft
    never slows that much (a rolling take-off from the taxiway) starts it at the end of the
    slowest stretch, if that is below ``max_rolling_mps``.  A speed error dv moves the time by
    dv / a but the position only by about v dv / a (metres: the aircraft is slow there).  The
    rest is the stretch of v <= ``rest_mps`` that ends at the roll start, less its last
    ``settle_s`` (the first metres of the roll, where the detection lags).
    ``accel_bias_mps2`` is subtracted from the along-track acceleration (the accelerometer's
    forward bias, once the smoother has estimated it: 0.003 g is 1.8 m/s over a minute's rest).
    ``not_before_t`` (the line-up on the runway, from the cleaning's phases): the search and the
    rest stretch start there, so taxiing from the gate is never taken as the roll or the rest.

    Returns
    -------
    TakeoffRoll
        NaN times where the record has no ground roll or no rest is found.
    """
    if not np.isfinite(liftoff_t):
        return TakeoffRoll()
    i_lo = int(np.searchsorted(t_in, liftoff_t)) - 1
    if i_lo < 1 or not np.isfinite(tas[i_lo]):
        return TakeoffRoll()
    psi = np.where(np.isfinite(heading_rad[:i_lo + 1]), heading_rad[:i_lo + 1], 0.0)
    a = acc_ned[:i_lo + 1, 0] * np.cos(psi) + acc_ned[:i_lo + 1, 1] * np.sin(psi)
    a = np.where(np.isfinite(a), a, 0.0) - accel_bias_mps2
    if v_lo_mps is not None:
        v_lo = float(v_lo_mps)
    else:
        v_lo = float(tas[i_lo])
        if wind_ne is not None and np.all(np.isfinite(wind_ne[i_lo])):
            v_lo += float(wind_ne[i_lo, 0] * np.cos(psi[i_lo])
                          + wind_ne[i_lo, 1] * np.sin(psi[i_lo]))
    v = speed_integrated_back(a, np.diff(t_in[:i_lo + 1]), v_lo)
    if np.isfinite(not_before_t):
        v = np.where(t_in[:i_lo + 1] >= not_before_t, v, np.inf)   # taxi: never at rest here
    slow = v <= rest_mps
    if not slow.any():
        if not np.isfinite(v.min()):
            return TakeoffRoll()
        # the end of the slowest stretch (within 0.5 m/s of the minimum)
        i_min = int(np.flatnonzero(v <= v.min() + 0.5)[-1])
        return TakeoffRoll(float(t_in[i_min]) if v.min() <= max_rolling_mps else np.nan)
    i_start = int(np.flatnonzero(slow)[-1])
    fast = np.flatnonzero(~slow[:i_start + 1])
    i_rest = int(fast[-1]) + 1 if len(fast) else 0
    t_end = t_in[i_start] - settle_s
    rest = (float(t_in[i_rest]), float(t_end)) if t_end > t_in[i_rest] else (np.nan, np.nan)
    return TakeoffRoll(float(t_in[i_start]), rest)
