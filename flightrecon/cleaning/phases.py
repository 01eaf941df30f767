"""Flight phases: lift-off and touchdown detected in the cleaned grid.

The rules (``docs/signals.md``, section "Phase detection") use airspeed, pressure altitude and
the vertical kinematic acceleration ``a_up = -a_D`` from the load factors and attitude
(:func:`flightrecon.geo.kinematics.kinematic_acceleration_ned`), which is zero on the ground
(the wheel reaction is part of the measured specific force) and departs from zero when the
wheels leave or meet the runway:

* On the ground / possibly flying: airspeed below / above ``airborne_speed_mps`` (30 m/s);
  certainly on the ground below ``rolling_speed_mps`` (15 m/s, below any aircraft's lift-off
  speed: a Cessna 172 lifts off at 26-30 m/s).  The take-off run is searched from its last
  sample below 15 m/s, before the first at or above 30 m/s.
  The record *starts airborne* (*ends airborne*) when the airspeed over its first (last)
  second is above it.
* Field level: median pressure altitude over ``ground_window_s`` (20 s) of slow ground run
  before the take-off run (after the landing run).  *Certainly airborne*: more than
  ``airborne_height_m`` (15 m) above field level.
* Lift-off: the vertical velocity ``v_up`` is integrated from ``a_up`` (minus its mean over the
  ground window, the accelerometer/attitude bias) from the take-off run's last sample below
  15 m/s, with ``v_up = 0`` there; a linear drift fitted on the ground part is removed;
  lift-off is the knee of ``v_up`` (the point farthest below the chord) in the 6 s before
  ``v_up`` exceeds 0.6 m/s for ``climb_hold_s`` (3 s) or until certainly airborne (not its
  last crossing: a light aircraft can pause in ground effect after lift-off).
* Touchdown: between the last time the aircraft is certainly airborne and the end of the fast
  landing run, ``a_up`` is smoothed (0.5 s running mean); its quiet level and noise are taken
  from the last ``ground_window_s`` of the fast landing run; touchdown is the falling
  half-maximum of the *last* excursion above ``max(0.2 m/s^2, 5 sigma)``: the moment the
  wheels have arrested the sink rate, after which the vertical acceleration stays quiet.  A
  landing so smooth that no such excursion exists falls back to the last time the pressure
  altitude is 2 m above field level.  (Integrating ``a_up`` back from the end of the landing
  run was tried first: over 30-40 s of landing run the integrated noise and speed-dependent
  bias reach 0.3 m/s, the size of a gentle sink rate.)  The report says which rule was used.
* Taxi and take-off roll (a record that starts at the gate): the runway heading is the circular
  mean heading over the 2 s after the take-off run's last sample below ``rolling_speed_mps``
  (on the ground: after lift-off the aircraft crabs into the crosswind);
  the *line-up* is the start of the last stretch before it whose heading stays within
  ``lineup_deg`` (10 deg) of the runway heading: everything before is taxi (turns onto and
  along taxiways), never "at rest on the runway".  Within the lined-up stretch the ground speed
  is integrated back from the fast run's start, ``v(t) = V_fast - int_t a_along``, with the
  along-heading kinematic acceleration; the *roll start* is the last sample with
  ``v <= rest_mps`` (3 m/s), or the line-up itself for a rolling take-off.  A "rolling
  take-off" that is a swerve (the heading swinging more than ``lineup_deg`` in the roll's first
  seconds): where the speed integrated back along each sample's own heading was at most
  ``rest_mps`` before the line-up found, and no faster than ``taxi_mps`` (10 m/s) since, the
  roll starts there and the line-up is the stretch within ``lineup_deg`` of the heading there.
  The joint smoother takes its "at rest, lined up" stretch only after the line-up.
* Lift-off ground velocity: the runway direction is the mean heading over the last 10 s of the
  ground run; airspeed over those 10 s is fitted as ``V(t) = c + integral of a_along`` (the
  along-runway kinematic acceleration), which averages the airspeed noise with the
  accelerometer's shape; the wind component along the runway is subtracted when the log has a
  wind channel (otherwise wind is unmodelled and the report says so); the vertical component is
  zero at lift-off.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pandas as pd

from flightrecon.cleaning.ground_roll import speed_integrated_back
from flightrecon.cleaning.report import report_entry
from flightrecon.errors import ValidationError
from flightrecon.geo.kinematics import kinematic_acceleration_ned
from flightrecon.types import FlightPhases

__all__ = ["PhaseSettings", "detect_phases", "detect_phases_with_report"]

_NAN3 = (float("nan"), float("nan"), float("nan"))
_LOAD_CHANNELS = ("n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg", "heading_deg")


@dataclass(frozen=True)
class PhaseSettings:
    """Thresholds of the phase detector (module docstring).

    Attributes
    ----------
    airborne_speed_mps : airspeed below which the aircraft is on the ground [m/s]
    rolling_speed_mps : airspeed below which the aircraft is certainly on the ground (below
        any aircraft's lift-off speed): where the take-off run is searched for lift-off [m/s]
    airborne_height_m : pressure height above field level that proves flight [m]
    ground_window_s : ground stretch used for field level and accelerometer bias [s]
    roll_fit_s : end of the ground run used for the lift-off velocity [s]
    v_up_high_mps : vertical speed that proves the climb has begun [m/s]
    climb_hold_s : for at least this long (or until certainly airborne) [s]
    knee_window_s : window before that crossing searched for the lift-off knee [s]
    sink_mps : vertical speed below which the aircraft is still descending [m/s]
    td_smooth_s : running mean applied to the vertical acceleration at touchdown [s]
    td_accel_mps2 : smallest touchdown excursion of the vertical acceleration [m/s^2]
    lineup_deg : heading within this of the take-off runway's heading counts as lined up [deg]
    rest_mps : ground speed at or below which the aircraft is at rest (roll start) [m/s]
    taxi_mps : ground speed above which a heading change is a swerve on the take-off roll, not
        a turn onto the runway [m/s]
    """

    airborne_speed_mps: float = 30.0
    rolling_speed_mps: float = 15.0
    airborne_height_m: float = 15.0
    ground_window_s: float = 20.0
    roll_fit_s: float = 10.0
    v_up_high_mps: float = 0.6
    climb_hold_s: float = 3.0
    knee_window_s: float = 6.0
    sink_mps: float = 0.2
    td_smooth_s: float = 0.5
    td_accel_mps2: float = 0.2
    lineup_deg: float = 10.0
    rest_mps: float = 3.0
    taxi_mps: float = 10.0


def _filled(grid: pd.DataFrame, name: str) -> np.ndarray | None:
    """A grid column with its NaN filled linearly in the row index, and held at the ends
    (what ``Series.interpolate(limit_direction="both")`` gives, without pandas' overhead);
    ``None`` if the column is absent or has no value."""
    if name not in grid.columns:
        return None
    v = grid[name].to_numpy(dtype=float, copy=True)
    bad = np.isnan(v)
    if bad.all():
        return None
    if bad.any():
        idx = np.arange(len(v))
        v[bad] = np.interp(idx[bad], idx[~bad], v[~bad])
    return v


def _speed(filled) -> tuple[np.ndarray, str]:
    for name in ("tas_mps", "cas_mps", "ias_mps"):
        v = filled(name)
        if v is not None:
            return v, name
    raise ValidationError("phase detection needs an airspeed channel (tas_mps, cas_mps or "
                          "ias_mps)")


def _cumint(a: np.ndarray, dt: float) -> np.ndarray:
    """Trapezoidal running integral, zero at the first sample."""
    out = np.zeros(len(a))
    if len(a) > 1:
        out[1:] = np.cumsum(0.5 * (a[1:] + a[:-1])) * dt
    return out


def _take_off_run(speed: np.ndarray, s: PhaseSettings) -> tuple[int, int]:
    """``(i_run, i_fast)``: the last sample below ``rolling_speed_mps`` before the first at or
    above ``airborne_speed_mps`` (where the take-off run is certainly still on the ground), and
    that first fast sample; ``(-1, -1)`` where the airspeed never reaches the latter.

    A light aircraft lifts off below 30 m/s (a Cessna 172 at 26-30 m/s): the fast run's start
    can be after the lift-off, so the lift-off, the runway heading and the line-up are looked
    for from ``i_run``, which is on the ground for any aircraft."""
    fast = np.flatnonzero(speed >= s.airborne_speed_mps)
    if len(fast) == 0:
        return -1, -1
    i_fast = int(fast[0])
    slow = np.flatnonzero(speed[:i_fast + 1] < s.rolling_speed_mps)
    # never that slow (a strong wind at rest): the first fast sample, as before
    return (int(slow[-1]) if len(slow) else i_fast), i_fast


def _climb_onset(v: np.ndarray, thr: float, n_hold: int) -> int:
    """First sample of the first stretch of ``v >= thr`` lasting ``n_hold`` samples or running
    to the end of ``v`` (certainly airborne there), -1 if none; not the last upward crossing,
    which a light aircraft's pause in ground effect after lift-off made 5-7 s late."""
    above = np.r_[v >= thr, np.ones(n_hold, dtype=bool)]
    c = np.r_[0, np.cumsum(above)]
    ok = np.flatnonzero(c[n_hold:n_hold + len(v)] - c[:len(v)] == n_hold)
    return int(ok[0]) if len(ok) else -1


def _liftoff(t, dt, baro, accel, i_run: int, i_fast: int, s: PhaseSettings, rep: list
             ) -> tuple[float, int]:
    """Lift-off time and its index, or NaN, -1, searched from the take-off run ``i_run`` ..
    ``i_fast`` (:func:`_take_off_run`).

    ``accel(lo, hi)`` is the kinematic acceleration NED on grid rows ``lo:hi``."""
    if i_fast < 0:
        rep.append(report_entry("phases", "no_liftoff", "airspeed never reaches "
                                f"{s.airborne_speed_mps:g} m/s", count=0))
        return float("nan"), -1
    ng = max(int(round(s.ground_window_s / dt)), 1)
    i_b0 = max(i_run - ng, 0)
    h_dep = float(np.median(baro[i_b0:i_run + 1]))
    high = np.flatnonzero((baro[i_fast:] - h_dep) > s.airborne_height_m)
    if len(high) == 0:
        rep.append(report_entry("phases", "no_liftoff", f"pressure altitude never "
                                f"{s.airborne_height_m:g} m above field level after the "
                                "take-off run (rejected take-off or ground run only)", count=0))
        return float("nan"), -1
    i_air = i_fast + int(high[0])
    a_up = -accel(i_b0, i_air + 1)[:, 2]  # rows i_b0 .. i_air
    bias = float(np.mean(a_up[:i_run + 1 - i_b0]))
    v = _cumint(a_up[i_run - i_b0:] - bias, dt)
    tt = t[i_run:i_air + 1]
    n_hold = max(int(round(s.climb_hold_s / dt)), 1)
    i_hi = max(_climb_onset(v, s.v_up_high_mps, n_hold), 0)
    # remove a linear drift fitted on the ground part (up to 2 s before the climb is certain)
    i_g = max(i_hi - int(round(2.0 / dt)), 0)
    if i_g >= 10:
        coef = np.polyfit(tt[:i_g] - tt[0], v[:i_g], 1)
        v = v - np.polyval(coef, tt - tt[0])
    j_hi = _climb_onset(v, s.v_up_high_mps, n_hold)
    if j_hi <= 0:
        t_lo = float(t[i_fast])
        method = "start of the fast ground run (vertical speed never crosses the threshold)"
    else:
        j_w = max(j_hi - int(round(s.knee_window_s / dt)), 0)
        seg_t, seg_v = tt[j_w:j_hi + 1], v[j_w:j_hi + 1]
        chord = seg_v[0] + (seg_v[-1] - seg_v[0]) * (seg_t - seg_t[0]) / max(seg_t[-1] - seg_t[0],
                                                                            dt)
        t_lo = float(seg_t[int(np.argmax(chord - seg_v))])
        method = (f"vertical speed from the loads: knee (largest distance below the chord) in the "
                  f"{s.knee_window_s:g} s before it exceeds {s.v_up_high_mps:g} m/s for "
                  f"{s.climb_hold_s:g} s")
    i_lo = int(np.clip(np.searchsorted(t, t_lo), 0, len(t) - 1))
    rep.append(report_entry("phases", "liftoff", method, count=1, t_s=[t_lo],
                            field_pressure_alt_m=h_dep))
    return t_lo, i_lo


def _lineup_and_roll(t, dt, speed, hdg, accel, i_run: int, i_fast: int, s: PhaseSettings,
                     rep: list) -> tuple[float, float]:
    """Line-up time and roll-start time before the take-off run that starts at ``i_run``
    (:func:`_take_off_run`; module docstring, "Taxi and take-off roll"); NaN each where
    undecidable.  The runway heading is taken on the ground, from ``i_run``: after lift-off
    the aircraft crabs into the crosswind (10 deg and more for a light aircraft), which would
    put the line-up after the roll."""
    if hdg is None or i_run < 0:
        return float("nan"), float("nan")
    n2 = max(int(round(2.0 / dt)), 1)
    psi = np.radians(hdg)
    w = psi[i_run:i_run + n2]
    psi_rw = float(np.arctan2(np.mean(np.sin(w)), np.mean(np.cos(w))))
    off = np.degrees(np.abs(np.angle(np.exp(1j * (psi[:i_run + 1] - psi_rw)))))
    out = np.flatnonzero(off > s.lineup_deg)
    i_lu = int(out[-1]) + 1 if len(out) else 0
    a_ned = accel(i_lu, i_fast + 1)
    a_al = a_ned[:, 0] * np.cos(psi_rw) + a_ned[:, 1] * np.sin(psi_rw)
    a_al = np.where(np.isfinite(a_al), a_al, 0.0)
    v = speed_integrated_back(a_al, dt, float(speed[i_fast]))
    slow = np.flatnonzero(v <= s.rest_mps)
    if len(slow):
        i_rs = i_lu + int(slow[-1])
        how = f"last time the ground speed integrated back from the fast run is <= {s.rest_mps:g} m/s"
    else:
        i_rs = i_lu
        how = "rolling take-off: the roll starts at the line-up"
        swerve = _swerve_start(dt, speed, psi, accel, i_lu, i_fast, s)
        if swerve is not None:
            i_lu, i_rs = swerve
            how = (f"a swerve on the roll: the last time the ground speed integrated back "
                   f"along each sample's heading is <= {s.rest_mps:g} m/s, lined up with the "
                   "heading there")
    t_lu, t_rs = float(t[i_lu]), float(t[i_rs])
    taxi_s = t_lu - float(t[0])
    rep.append(report_entry("phases", "lineup", f"start of the last stretch within "
                            f"{s.lineup_deg:g} deg of the runway heading before the take-off run; "
                            f"{taxi_s:.0f} s of taxi or stand before it (never used as at rest "
                            "on the runway)", count=1, t_s=[t_lu],
                            runway_heading_deg=float(np.degrees(psi_rw) % 360.0),
                            taxi_s=taxi_s))
    rep.append(report_entry("phases", "roll_start", how, count=1, t_s=[t_rs]))
    return t_lu, t_rs


def _swerve_start(dt, speed, psi, accel, i_lu: int, i_fast: int, s: PhaseSettings
                  ) -> tuple[int, int] | None:
    """``(i_lu, i_rs)`` where the "rolling take-off" of :func:`_lineup_and_roll` is a swerve:
    the aircraft was at rest (ground speed integrated back from the fast run along each
    sample's own heading, the wheels rolling where the nose points, at most ``rest_mps``)
    before the line-up found, and no faster than ``taxi_mps`` from there to it (no taxi turn
    in between), so that the heading left the runway heading on the roll, not on a turn onto
    the runway (JSBSim's Cessna 310 swings 18 deg at 1-12 m/s: the line-up fell 2 s into the
    roll and the rest before it was lost).  The roll starts at the last such sample and the
    line-up is the start of the last stretch before it within ``lineup_deg`` of the heading
    there.  ``None`` where no rest is that close."""
    a = accel(0, i_fast + 1)
    p = psi[:i_fast + 1]
    a_own = np.where(np.isfinite(a[:, 0]) & np.isfinite(a[:, 1]),
                     a[:, 0] * np.cos(p) + a[:, 1] * np.sin(p), 0.0)
    v_own = speed_integrated_back(a_own, dt, float(speed[i_fast]))
    rest = np.flatnonzero(v_own[:i_lu + 1] <= s.rest_mps)
    if not len(rest) or np.any(v_own[int(rest[-1]):i_lu + 1] > s.taxi_mps):
        return None
    i_rs = int(rest[-1])
    off = np.degrees(np.abs(np.angle(np.exp(1j * (p[:i_rs + 1] - p[i_rs])))))
    out = np.flatnonzero(off > s.lineup_deg)
    return (int(out[-1]) + 1 if len(out) else 0), i_rs


def _touchdown(t, dt, speed, baro, accel, i_from: int, s: PhaseSettings, rep: list) -> float:
    """Touchdown time (module docstring) or NaN; ``accel`` as in :func:`_liftoff`."""
    fast = np.flatnonzero(speed[i_from:] >= s.airborne_speed_mps)
    if len(fast) == 0:
        return float("nan")
    i_slow = i_from + int(fast[-1])
    ng = max(int(round(s.ground_window_s / dt)), 1)
    i_b1 = min(i_slow + ng, len(t) - 1)
    h_arr = float(np.median(baro[i_slow:i_b1 + 1]))
    high = np.flatnonzero((baro[i_from:i_slow + 1] - h_arr) > s.airborne_height_m)
    if len(high) == 0:
        rep.append(report_entry("phases", "no_touchdown", "no airborne stretch before the "
                                "landing run", count=0))
        return float("nan")
    i_low = i_from + int(high[-1])
    seg = -accel(i_low, i_slow + 1)[:, 2]
    tt = t[i_low:i_slow + 1]
    k = max(int(round(s.td_smooth_s / dt)), 1)
    a_s = pd.Series(seg).rolling(k, center=True, min_periods=1).mean().to_numpy()
    # quiet level and noise of the smoothed vertical acceleration on the fast ground run
    n_g = max(int(round(s.ground_window_s / dt)), 3)
    ground = a_s[-n_g:]
    base = float(np.median(ground))
    noise = 1.4826 * float(np.median(np.abs(ground - base)))
    thr = max(s.td_accel_mps2, 5.0 * noise)
    exc = np.flatnonzero(a_s - base > thr)
    if len(exc) and exc[-1] + 1 < len(a_s):
        j_end = int(exc[-1])
        gaps = np.flatnonzero(np.diff(exc) > 1)
        j_start = int(exc[gaps[-1] + 1]) if len(gaps) else int(exc[0])
        peak = float(np.max(a_s[j_start:j_end + 1]) - base)
        below = np.flatnonzero(a_s[j_end:] - base < 0.5 * peak)
        j = max(j_end + int(below[0]) if len(below) else j_end, 1)
        y0, y1 = a_s[j - 1] - base, a_s[j] - base
        t_td = float(tt[j - 1] + (y0 - 0.5 * peak) / (y0 - y1) * dt) if y0 != y1 else float(tt[j])
        method = (f"end (falling half-maximum) of the last excursion of the vertical acceleration "
                  f"above {thr:.3g} m/s^2 before the quiet landing run: the sink rate arrested")
    else:
        above = np.flatnonzero(baro[i_low:i_slow + 1] - h_arr > 2.0)
        t_td = float(tt[int(above[-1])]) if len(above) else float(tt[0])
        method = "last time the pressure altitude is 2 m above field level (fallback)"
    rep.append(report_entry("phases", "touchdown", method, count=1, t_s=[t_td],
                            field_pressure_alt_m=h_arr))
    return t_td


def _liftoff_velocity(filled, t, dt, i_lo, i_first, accel, s: PhaseSettings, rep: list
                      ) -> tuple[float, float, float]:
    tas = filled("tas_mps")
    hdg = filled("heading_deg")
    if tas is None or hdg is None or i_lo <= 0:
        return _NAN3
    i0 = max(i_lo - int(round(s.roll_fit_s / dt)), i_first, 0)
    if i_lo - i0 < 2:
        i0 = max(i_lo - 2, 0)
    psi = np.radians(float(np.mean(hdg[i0:i_lo + 1])))
    a_ned = accel(i0, i_lo + 1)
    a_along = a_ned[:, 0] * np.cos(psi) + a_ned[:, 1] * np.sin(psi)
    A = _cumint(a_along, dt)
    c = float(np.mean(tas[i0:i_lo + 1] - A))
    v_air = c + A[-1]
    ws, wf = filled("wind_speed_mps"), filled("wind_from_deg")
    if ws is not None and wf is not None:
        head = float(np.mean(ws[i0:i_lo + 1] * np.cos(np.radians(wf[i0:i_lo + 1]) - psi)))
        why = "airspeed fitted with the along-runway acceleration, minus the headwind"
    else:
        head = 0.0
        why = "airspeed fitted with the along-runway acceleration; wind unmodelled (no wind channel)"
    vg = v_air - head
    vel = (float(vg * np.cos(psi)), float(vg * np.sin(psi)), 0.0)
    rep.append(report_entry("phases", "liftoff_velocity", why, count=i_lo + 1 - i0,
                            runway_heading_deg=float(np.degrees(psi) % 360.0),
                            headwind_mps=head, ground_speed_mps=float(vg)))
    return vel


def detect_phases_with_report(grid: pd.DataFrame, settings: PhaseSettings = PhaseSettings(), *,
                              lat_deg: float = 45.0) -> tuple[FlightPhases, list[dict]]:
    """Detect lift-off and touchdown (module docstring); also return the report entries.

    Parameters
    ----------
    grid : DataFrame
        The cleaned uniform grid (:attr:`flightrecon.types.CleanFlight.grid`): ``t_s``,
        an airspeed, ``baro_alt_m``, load factors and attitude.
    settings : PhaseSettings
    lat_deg : float
        Latitude for normal gravity (the departure airfield's where known).

    Raises
    ------
    ValidationError
        Fewer than two grid points, a non-uniform grid, or no airspeed / pressure altitude.
    """
    rep: list[dict] = []
    t = grid["t_s"].to_numpy(dtype=float) if "t_s" in grid.columns else np.empty(0)
    if len(t) < 2:
        raise ValidationError("phase detection needs at least two grid points")
    d = np.diff(t)
    dt = float(np.median(d))
    if not dt > 0 or np.max(np.abs(d - dt)) > 1e-6 * max(dt, 1.0):
        raise ValidationError("phase detection needs a uniform grid")
    cache: dict[str, np.ndarray | None] = {}

    def filled(name: str) -> np.ndarray | None:  # each filled column computed once
        if name not in cache:
            cache[name] = _filled(grid, name)
        return cache[name]

    speed, _ = _speed(filled)
    baro = filled("baro_alt_m")
    if baro is None:
        raise ValidationError("phase detection needs baro_alt_m")
    n1 = max(int(round(1.0 / dt)), 1)
    starts_air = bool(np.median(speed[:n1]) >= settings.airborne_speed_mps)
    ends_air = bool(np.median(speed[-n1:]) >= settings.airborne_speed_mps)
    cols = [filled(c) for c in _LOAD_CHANNELS]
    if any(c is None for c in cols):
        raise ValidationError("phase detection needs load factors and attitude")

    def accel(lo: int, hi: int) -> np.ndarray:
        # a_NED on rows lo:hi only: the rules look at a few windows around lift-off and
        # touchdown, and the conversion is row by row, so this equals slicing the whole record
        return kinematic_acceleration_ned(*(c[lo:hi] for c in cols), lat_deg=lat_deg,
                                          h_m=baro[lo:hi])

    t_lo, i_lo, vel = float("nan"), -1, _NAN3
    t_lu = t_rs = float("nan")
    if not starts_air:
        i_run, i_fast = _take_off_run(speed, settings)
        t_lo, i_lo = _liftoff(t, dt, baro, accel, i_run, i_fast, settings, rep)
        if np.isfinite(t_lo):
            t_lu, t_rs = _lineup_and_roll(t, dt, speed, filled("heading_deg"), accel, i_run,
                                          i_fast, settings, rep)
            vel = _liftoff_velocity(filled, t, dt, i_lo, i_run + 1, accel, settings, rep)
    t_td = float("nan")
    if not ends_air and (starts_air or np.isfinite(t_lo)):
        t_td = _touchdown(t, dt, speed, baro, accel, max(i_lo, 0), settings, rep)
    if starts_air:
        rep.append(report_entry("phases", "starts_airborne", "airspeed over the first second "
                                f">= {settings.airborne_speed_mps:g} m/s", count=1))
    if ends_air:
        rep.append(report_entry("phases", "ends_airborne", "airspeed over the last second "
                                f">= {settings.airborne_speed_mps:g} m/s", count=1))
    return FlightPhases(liftoff_t_s=t_lo, touchdown_t_s=t_td, starts_airborne=starts_air,
                        ends_airborne=ends_air, liftoff_velocity_ned_mps=vel,
                        lineup_t_s=t_lu, roll_start_t_s=t_rs), rep


def detect_phases(grid: pd.DataFrame, settings: PhaseSettings = PhaseSettings(), *,
                  lat_deg: float = 45.0) -> FlightPhases:
    """Lift-off and touchdown (:func:`detect_phases_with_report` without the report)."""
    return detect_phases_with_report(grid, settings, lat_deg=lat_deg)[0]
