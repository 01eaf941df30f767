"""A small autopilot for the JSBSim truth flights: PID loops on JSBSim properties.

Loops (docs/jsbsim.md, "Autopilot"), all at the control rate:

* lateral: ground track -> bank command (proportional, limited), bank -> aileron (PD + I);
  rudder from the sideslip (turn coordination); on the ground, heading -> rudder and nose-wheel
  steering (PD on heading and yaw rate);
* vertical: altitude -> vertical speed (proportional, limited) -> pitch (PI) -> elevator
  (PID on pitch and pitch rate); far from the target altitude, "level change": climb or idle
  thrust with the pitch holding the speed (PI), so that a climb never bleeds the speed away;
* speed: calibrated airspeed -> throttle (PI with anti-windup).

Mode changes are bumpless: the integrator of the loop that takes over is set so that its
output equals the command it replaces.  Guidance on a leg from A to B: the leg's great-circle
bearing at the aircraft minus ``atan(cross-track / L)`` (the cross-track error pulls the track
back to the line), spherical Earth (navigation only needs to be good, not exact).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

__all__ = ["GAINS", "Autopilot", "Gains", "Pid", "leg_geometry", "wrap180"]

R_NAV_M = 6371000.0


def wrap180(x: float) -> float:
    """Angle in [-180, 180)."""
    return (x + 180.0) % 360.0 - 180.0


def leg_geometry(lat_a, lon_a, lat_b, lon_b, lat, lon) -> tuple[float, float, float, float]:
    """(bearing of the leg at the aircraft [deg], cross-track [m, + right of A->B],
    along-track [m from A], leg length [m]) on a sphere."""
    la, oa, lb, ob, lp, op = map(math.radians, (lat_a, lon_a, lat_b, lon_b, lat, lon))

    def bearing(l1, o1, l2, o2):
        y = math.sin(o2 - o1) * math.cos(l2)
        x = math.cos(l1) * math.sin(l2) - math.sin(l1) * math.cos(l2) * math.cos(o2 - o1)
        return math.atan2(y, x)

    def dist(l1, o1, l2, o2):
        h = (math.sin((l2 - l1) / 2) ** 2
             + math.cos(l1) * math.cos(l2) * math.sin((o2 - o1) / 2) ** 2)
        return 2.0 * math.asin(min(1.0, math.sqrt(h)))

    d13 = dist(la, oa, lp, op)
    t13 = bearing(la, oa, lp, op)
    t12 = bearing(la, oa, lb, ob)
    xt = math.asin(max(-1.0, min(1.0, math.sin(d13) * math.sin(t13 - t12))))
    at = math.acos(max(-1.0, min(1.0, math.cos(d13) / max(math.cos(xt), 1e-12))))
    if math.cos(t13 - t12) < 0.0:
        at = -at
    # bearing of the great circle A->B abeam the aircraft (the abeam point interpolated in
    # latitude and longitude; at B, the final bearing of the leg)
    d12 = dist(la, oa, lb, ob)
    frac = 0.0 if d12 <= 0 else min(max(at / d12, 0.0), 1.0)
    if frac < 0.99:
        brg = bearing(la + frac * (lb - la), oa + frac * (ob - oa), lb, ob)
    else:
        brg = bearing(lb, ob, la, oa) + math.pi
    return math.degrees(brg) % 360.0, xt * R_NAV_M, at * R_NAV_M, d12 * R_NAV_M


@dataclass
class Pid:
    """``u = kp e + ki int(e) - kd rate`` limited to [lo, hi]; the integral stops where the
    output saturates in the direction it would push (anti-windup)."""

    kp: float
    ki: float
    kd: float
    lo: float
    hi: float
    i: float = 0.0

    def __call__(self, e: float, rate: float, dt: float) -> float:
        u = self.kp * e + self.i - self.kd * rate
        if (u < self.hi or e < 0.0) and (u > self.lo or e > 0.0):
            self.i += self.ki * e * dt
        return min(self.hi, max(self.lo, self.kp * e + self.i - self.kd * rate))

    def preset(self, u: float, e: float = 0.0, rate: float = 0.0) -> None:
        """Set the integral so that the output is ``u`` now (bumpless transfer)."""
        self.i = u - self.kp * e + self.kd * rate


@dataclass(frozen=True)
class Gains:
    """Loop gains of one airframe (angles in degrees, speeds in m/s, surfaces normalised)."""

    track_to_bank: float
    bank_max_deg: float
    bank: tuple[float, float, float]       # aileron per deg bank error: kp, ki, kd (per deg/s)
    beta_to_rudder: float
    ground_heading: tuple[float, float]    # rudder per deg heading error, per deg/s yaw rate
    pitch: tuple[float, float, float]      # elevator per deg pitch error (sign: + nose down)
    vs_to_pitch: tuple[float, float]       # deg pitch per m/s vertical-speed error: kp, ki
    alt_to_vs: float                       # m/s per m altitude error
    speed_to_pitch: tuple[float, float]    # deg pitch per m/s speed excess: kp, ki
    speed_to_throttle: tuple[float, float]
    level_change_band_m: float
    pitch_limits_deg: tuple[float, float]
    pitch_rate_dps: float = 3.0


GAINS = {
    "light": Gains(track_to_bank=1.5, bank_max_deg=25.0, bank=(0.03, 0.005, 0.012),
                   beta_to_rudder=0.05, ground_heading=(0.05, 0.08),
                   pitch=(0.02, 0.005, 0.01), vs_to_pitch=(0.4, 0.05), alt_to_vs=0.05,
                   speed_to_pitch=(0.8, 0.08), speed_to_throttle=(0.05, 0.01),
                   level_change_band_m=120.0, pitch_limits_deg=(-12.0, 15.0),
                   pitch_rate_dps=4.0),
    "twin": Gains(track_to_bank=1.5, bank_max_deg=25.0, bank=(0.03, 0.005, 0.012),
                  beta_to_rudder=0.05, ground_heading=(0.05, 0.08),
                  pitch=(0.010, 0.0025, 0.008), vs_to_pitch=(0.3, 0.04), alt_to_vs=0.05,
                  speed_to_pitch=(0.4, 0.04), speed_to_throttle=(0.05, 0.01),
                  level_change_band_m=120.0, pitch_limits_deg=(-12.0, 15.0),
                  pitch_rate_dps=3.0),
    "jet": Gains(track_to_bank=1.0, bank_max_deg=25.0, bank=(0.04, 0.005, 0.02),
                 beta_to_rudder=0.08, ground_heading=(0.08, 0.08),
                 pitch=(0.10, 0.05, 0.08), vs_to_pitch=(0.3, 0.05), alt_to_vs=0.03,
                 speed_to_pitch=(0.5, 0.01), speed_to_throttle=(0.04, 0.006),
                 level_change_band_m=300.0, pitch_limits_deg=(-10.0, 18.0),
                 pitch_rate_dps=2.0),
}


@dataclass
class Autopilot:
    """The loops of the module docstring; :meth:`step` returns the surface and throttle
    commands for a set of targets.

    Targets: ``track_deg`` or ``bank_deg`` (lateral), ``alt_m`` (with ``vs_max``/``vs_min``) or
    ``vs_mps`` or ``pitch_deg`` (vertical), ``cas_mps`` or ``throttle`` (speed); ``ground``:
    the ground roll (``heading_deg``, rudder and steering on the heading).
    """

    gains: Gains
    climb_throttle: float
    idle_throttle: float
    elevator_trim: float = 0.0
    mode: str = ""
    _bank: Pid = field(init=False)
    _pitch: Pid = field(init=False)
    _vs: Pid = field(init=False)
    _spd_pitch: Pid = field(init=False)
    _thr: Pid = field(init=False)

    def __post_init__(self) -> None:
        g = self.gains
        self._bank = Pid(g.bank[0], g.bank[1], g.bank[2], -1.0, 1.0)
        self._pitch = Pid(g.pitch[0], g.pitch[1], g.pitch[2], -1.0, 1.0, self.elevator_trim)
        lo, hi = g.pitch_limits_deg
        self._vs = Pid(g.vs_to_pitch[0], g.vs_to_pitch[1], 0.0, lo, hi)
        self._spd_pitch = Pid(g.speed_to_pitch[0], g.speed_to_pitch[1], 0.0, lo, hi)
        self._thr = Pid(g.speed_to_throttle[0], g.speed_to_throttle[1], 0.0, 0.0, 1.0)
        self.pitch_cmd = 0.0
        self.throttle_cmd = 0.0

    def lateral(self, s: dict, dt: float, track_deg=None, bank_deg=None) -> tuple[float, float]:
        """(aileron, rudder) for a track or bank target."""
        g = self.gains
        if bank_deg is None:
            err = wrap180(track_deg - s["track"])
            bank_deg = max(-g.bank_max_deg, min(g.bank_max_deg, g.track_to_bank * err))
        ail = self._bank(bank_deg - s["phi"], math.degrees(s["p"]), dt)
        rud = -g.beta_to_rudder * s["beta"]
        return ail, max(-1.0, min(1.0, rud))

    def ground(self, s: dict, heading_deg: float) -> float:
        """Rudder / nose-wheel steering on the ground roll (+ rudder: nose left)."""
        kh, kr = self.gains.ground_heading
        u = -kh * wrap180(heading_deg - s["psi"]) + kr * math.degrees(s["r"])
        return max(-1.0, min(1.0, u))

    def elevator(self, s: dict, dt: float, pitch_deg: float) -> float:
        """Elevator for a pitch target (positive elevator: nose down)."""
        r = self.gains.pitch_rate_dps * dt
        pitch_deg = min(self.pitch_cmd + r, max(self.pitch_cmd - r, pitch_deg))
        self.pitch_cmd = pitch_deg
        return -self._pitch(pitch_deg - s["theta"], math.degrees(s["q"]), dt)

    def vertical(self, s: dict, dt: float, alt_m=None, vs_mps=None, vs_max=5.0, vs_min=-5.0,
                 cas_mps=None) -> tuple[float, float | None]:
        """(elevator, throttle or None) for an altitude or vertical-speed target; far from the
        altitude, level change: climb / idle thrust and the pitch on the speed."""
        vs = -s["vd"]
        g = self.gains
        if alt_m is not None and cas_mps is not None and abs(alt_m - s["h"]) > \
                g.level_change_band_m:
            if self.mode != "level_change":
                self._spd_pitch.preset(self.pitch_cmd)
                self.mode = "level_change"
            pitch = self._spd_pitch(-(cas_mps - s["vc"]), 0.0, dt)
            if s["vc"] < 0.85 * cas_mps:  # stall protection: the nose comes down at 1 deg/s
                pitch = min(pitch, self.pitch_cmd - 1.0 * dt)
                self._spd_pitch.preset(pitch)
            thr = self.climb_throttle if alt_m > s["h"] else self.idle_throttle
            self._thr.preset(thr)
            return self.elevator(s, dt, pitch), thr
        if alt_m is not None:
            vs_mps = max(vs_min, min(vs_max, g.alt_to_vs * (alt_m - s["h"])))
        if self.mode != "vs":
            self._vs.preset(self.pitch_cmd)
            self.mode = "vs"
        pitch = self._vs(vs_mps - vs, 0.0, dt)
        thr = None if cas_mps is None else self._thr(cas_mps - s["vc"], 0.0, dt)
        return self.elevator(s, dt, pitch), thr

    def hold_pitch(self, s: dict, dt: float, pitch_deg: float) -> float:
        """Elevator for a pitch target, the vertical loops following (bumpless)."""
        self.mode = "pitch"
        return self.elevator(s, dt, pitch_deg)
