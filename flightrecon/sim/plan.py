"""Building a point-mass :class:`~flightrecon.sim.trajectory.FlightPlan` phase by phase
(docs/simulator.md, "Trajectory"): :class:`PlanBuilder`, used by the scenarios' routes."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.sim.profiles import SmoothProfile
from flightrecon.sim.trajectory import FlightPlan
from flightrecon.sim.weather import Atmosphere, WindField

__all__ = ["PlanBuilder"]


@dataclass
class _Steps:
    initial: float
    steps: list = field(default_factory=list)

    def add(self, start: float, dur: float, delta: float) -> None:
        if delta != 0.0:
            self.steps.append((float(start), float(dur), float(delta)))

    def target(self) -> float:
        return self.initial + sum(s[2] for s in self.steps)

    def last_end(self) -> float:
        return max((s[0] + s[1] for s in self.steps), default=0.0)

    def profile(self) -> SmoothProfile:
        return SmoothProfile.build(self.initial, self.steps)


class PlanBuilder:
    """Build a :class:`FlightPlan` phase by phase (a builder used by the scenarios).

    The builder keeps a time cursor; each manoeuvre starts at the cursor and (unless
    ``wait=False``) moves it to the manoeuvre's end, so vertical and lateral manoeuvres can
    overlap.  Altitudes are MSL; level changes are exact (a vertical-speed step of duration
    ``tau`` contributes ``rate * tau / 2`` of height).

    Parameters
    ----------
    lat_deg, lon_deg, elev_msl_m : start point and height above MSL
    track_deg : initial ground track
    wind, atmosphere : weather
    geoid_undulation_m : ellipsoidal minus MSL height
    alpha_ref_deg, alpha_ref_tas_mps : aircraft angle of attack at a reference airspeed
    airborne_tas_mps : ``None`` to start at rest on the runway; else start airborne, level,
        at this true airspeed
    """

    def __init__(self, *, lat_deg: float, lon_deg: float, elev_msl_m: float, track_deg: float,
                 wind: WindField, atmosphere: Atmosphere, geoid_undulation_m: float = 0.0,
                 alpha_ref_deg: float = 3.0, alpha_ref_tas_mps: float = 70.0,
                 airborne_tas_mps: float | None = None) -> None:
        self.lat0, self.lon0, self.h0 = lat_deg, lon_deg, elev_msl_m
        self.track0 = track_deg
        self.wind, self.atmosphere = wind, atmosphere
        self.geoid = geoid_undulation_m
        self.alpha_ref_deg, self.alpha_ref_tas = alpha_ref_deg, alpha_ref_tas_mps
        air = airborne_tas_mps is not None
        self.t = 0.0
        self._gcmd = _Steps(0.0)
        self._tas = _Steps(float(airborne_tas_mps) if air else 0.0)
        self._turn = _Steps(0.0)
        self._vu = _Steps(0.0)
        self._bw = _Steps(1.0 if air else 0.0)
        self._aw = _Steps(1.0 if air else 0.0)
        self._cw = _Steps(1.0 if air else 0.0)
        self.liftoff = np.nan
        self.touchdown = np.nan

    # -- helpers ---------------------------------------------------------------------------
    def plan(self, t_end_s: float | None = None) -> FlightPlan:
        """The plan as built so far (``t_end_s`` defaults to the cursor)."""
        return FlightPlan(
            t_end_s=float(self.t if t_end_s is None else t_end_s), lat0_deg=self.lat0,
            lon0_deg=self.lon0, geoid_undulation_m=self.geoid, h0_msl_m=self.h0,
            track0_deg=self.track0, ground_speed=self._gcmd.profile(), tas=self._tas.profile(),
            turn_rate=self._turn.profile(), vertical_speed=self._vu.profile(),
            air_weight=self._bw.profile(), alpha_weight=self._aw.profile(),
            crab_weight=self._cw.profile(), alpha_ref_deg=self.alpha_ref_deg,
            alpha_ref_tas_mps=self.alpha_ref_tas, liftoff_s=self.liftoff,
            touchdown_s=self.touchdown, wind=self.wind, atmosphere=self.atmosphere)

    def altitude_at(self, t_s: float) -> float:
        """Height above MSL [m] at ``t_s`` with the vertical commands given so far."""
        return self.h0 + float(self._vu.profile().evaluate(np.array([t_s]))[2][0])

    def track_at(self, t_s: float) -> float:
        """Ground track [deg] at ``t_s`` with the turn commands given so far."""
        return self.track0 + float(np.degrees(self._turn.profile().evaluate(
            np.array([t_s]))[2][0]))

    def _air_ground_speed(self, t_s: float, tas_mps: float) -> float:
        h = self.altitude_at(t_s)
        chi = np.radians(self.track_at(t_s))
        wn, we = self.wind.velocity(h, t_s)
        w_par = wn * np.cos(chi) + we * np.sin(chi)
        w_perp = -wn * np.sin(chi) + we * np.cos(chi)
        return float(w_par + np.sqrt(tas_mps**2 - w_perp**2))

    # -- manoeuvres ------------------------------------------------------------------------
    def hold(self, seconds: float) -> PlanBuilder:
        """Keep the current commands for ``seconds``."""
        self.t += float(seconds)
        return self

    def takeoff(self, *, rotate_tas_mps: float, climb_rate_mps: float,
                accel_mps2: float = 2.0, rotate_s: float = 3.0) -> PlanBuilder:
        """Take-off roll from rest, rotation, lift-off at ``rotate_tas_mps`` and initial climb.

        The ground-speed command is one smooth step from 0 to 1.3x the lift-off ground speed
        (peak acceleration 1.875 x mean); lift-off is where it reaches the lift-off ground speed.
        """
        t0 = self.t
        g_lo = self._air_ground_speed(t0 + 30.0, rotate_tas_mps)
        for _ in range(3):  # the lift-off time enters only through the slowly varying wind
            g_top = 1.3 * g_lo
            dur = 1.875 * g_top / (1.875 * accel_mps2)
            lo, hi = 0.0, 1.0
            for _ in range(60):  # bisection for S(u) = 1 / 1.3
                mid = 0.5 * (lo + hi)
                if mid**3 * (10 + mid * (-15 + 6 * mid)) < 1.0 / 1.3:
                    lo = mid
                else:
                    hi = mid
            t_lo = t0 + lo * dur
            g_lo = self._air_ground_speed(t_lo, rotate_tas_mps)
        self._gcmd.add(t0, dur, g_top)
        self._tas.add(0.0, 1.0, rotate_tas_mps - self._tas.target())
        self.liftoff = t_lo
        self._aw.add(t_lo - rotate_s, rotate_s, 1.0)
        self._bw.add(t_lo, 4.0, 1.0)
        self._cw.add(t_lo + 2.0, 6.0, 1.0)
        self._vu.add(t_lo, 6.0, climb_rate_mps)
        self.t = t_lo + 6.0
        return self

    def set_tas(self, tas_mps: float, accel_mps2: float = 0.5, wait: bool = False) -> PlanBuilder:
        """Change the true-airspeed command (peak acceleration ``accel_mps2``)."""
        delta = tas_mps - self._tas.target()
        dur = max(1.875 * abs(delta) / accel_mps2, 1.0)
        self._tas.add(max(self.t, self._tas.last_end()), dur, delta)
        if wait:
            self.t = max(self.t, self._tas.last_end())
        return self

    def level_off(self, alt_msl_m: float, tau_s: float = 8.0, wait: bool = True) -> PlanBuilder:
        """End the current climb or descent exactly at ``alt_msl_m``."""
        c = self._vu.target()
        if c == 0.0:
            raise ValidationError("level_off: the aircraft is not climbing or descending")
        t_e = self._vu.last_end()
        h_e = self.altitude_at(t_e)
        t_s = t_e + (alt_msl_m - h_e - c * tau_s / 2.0) / c
        if t_s < self._vu.last_end() - 1e-9:
            raise ValidationError(f"level_off: {alt_msl_m} m is reached before the vertical "
                                  "manoeuvre in progress ends")
        self._vu.add(t_s, tau_s, -c)
        if wait:
            self.t = max(self.t, t_s + tau_s)
        return self

    def change_altitude(self, alt_msl_m: float, rate_mps: float, tau_s: float = 8.0,
                        wait: bool = True) -> PlanBuilder:
        """Climb or descend (``rate_mps`` > 0, sign from the target) and level off exactly."""
        h = self.altitude_at(max(self.t, self._vu.last_end()))
        if self._vu.target() != 0.0:
            raise ValidationError("change_altitude: level off first")
        c = abs(rate_mps) * np.sign(alt_msl_m - h)
        if c == 0.0:
            return self
        t0 = max(self.t, self._vu.last_end())
        if abs(alt_msl_m - h) < abs(c) * tau_s:
            raise ValidationError("change_altitude: the level change is too small for the rate")
        self._vu.add(t0, tau_s, c)
        cursor = self.t
        self.t = t0 + tau_s
        self.level_off(alt_msl_m, tau_s, wait=True)
        if not wait:
            self.t = cursor
        return self

    def turn(self, delta_deg: float, rate_dps: float = 3.0, tau_s: float = 4.0) -> PlanBuilder:
        """Turn the track by ``delta_deg`` (+ right) at ``rate_dps``; the cursor moves to the end."""
        if delta_deg == 0.0:
            return self
        r = np.radians(abs(rate_dps)) * np.sign(delta_deg)
        hold = np.radians(delta_deg) / r - tau_s
        if hold < 0.0:
            tau_s = np.radians(delta_deg) / r
            hold = 0.0
        t0 = max(self.t, self._turn.last_end())
        self._turn.add(t0, tau_s, r)
        self._turn.add(t0 + tau_s + hold, tau_s, -r)
        self.t = t0 + 2.0 * tau_s + hold
        return self

    def land(self, *, elev_msl_m: float, glide_rate_mps: float, flare_rate_mps: float = 0.4,
             tau_s: float = 6.0, flare_s: float = 5.0, touch_s: float = 1.0,
             decel_mps2: float = 2.0, taxi_mps: float = 10.0, rollout_s: float = 60.0
             ) -> PlanBuilder:
        """Descend from level flight, flare and touch down exactly at ``elev_msl_m``, roll out.

        Height lost: ``c tau/2 + c T + (c + c_f) flare/2 + c_f touch/2`` solves for the
        constant-descent time ``T``.
        """
        if self._vu.target() != 0.0:
            raise ValidationError("land: level off first")
        t0 = max(self.t, self._vu.last_end())
        c, cf = abs(glide_rate_mps), abs(flare_rate_mps)
        drop = self.altitude_at(t0) - elev_msl_m
        hold = (drop - c * tau_s / 2 - (c + cf) * flare_s / 2 - cf * touch_s / 2) / c
        if hold < 0:
            raise ValidationError("land: too low to start the approach")
        self._vu.add(t0, tau_s, -c)
        t_f = t0 + tau_s + hold
        self._vu.add(t_f, flare_s, c - cf)
        self._vu.add(t_f + flare_s, touch_s, cf)
        t_td = t_f + flare_s + touch_s
        self.touchdown = t_td
        self._cw.add(t_td - 5.0, 4.5, -self._cw.target())
        # ground-speed command meets the air-derived ground speed at touchdown (b = 1 before)
        g_td = self._air_ground_speed(t_td, self._tas.target())
        t_match = max(self._gcmd.last_end(), t0)
        self._gcmd.add(t_match, 1.0, g_td - self._gcmd.target())
        self._bw.add(t_td, 3.0, -self._bw.target())
        self._aw.add(t_td, 3.0, -self._aw.target())
        dg = taxi_mps - g_td
        self._gcmd.add(t_td + 1.0, max(1.875 * abs(dg) / decel_mps2, 1.0), dg)
        self.t = t_td + rollout_s
        return self
