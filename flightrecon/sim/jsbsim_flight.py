"""Flying a JSBSim aircraft through a schedule of phases (docs/jsbsim.md, "Schedule").

A schedule is a list of phases, each a small object whose ``update`` sets the controls for one
control step and says when it is done: :class:`Wait` (lined up, brakes on), :class:`TakeOff`
(roll on the centre line, rotation, initial climb), :class:`Leg` (to a waypoint at an altitude
and a speed), :class:`Approach` (glide path to the touchdown aim point, flare, touchdown,
roll-out, braking to rest), :class:`Rest`, and the upsets and airwork of
:mod:`flightrecon.sim.manoeuvres`.  :func:`fly` runs the schedule and returns the
state at every truth sample; a flight that touches the ground other than on its runway phases
ends there (the impact).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from flightrecon.geo.wgs84 import WGS84_A, WGS84_E2
from flightrecon.errors import ValidationError
from flightrecon.geo.frames import offset_latlon
from flightrecon.sim.autopilot import GAINS, Autopilot, leg_geometry, wrap180
from flightrecon.sim.fdm import Fdm

# roll or pitch beyond this with the wheels on the ground is an overturned aircraft [deg]
GROUND_TILT_DEG = 30.0
# a climb faster than this from the ground on a ground phase is JSBSim's gear springs
# launching the aircraft (seen: the PC-7 rolling out, 62 m/s upwards in half a second) [m/s]
GROUND_LAUNCH_MPS = 10.0

__all__ = ["Approach", "GoAround", "Leg", "Rest", "Runway", "TakeOff", "Wait", "fly"]


@dataclass(frozen=True)
class Runway:
    """A runway: threshold (lat, lon), true direction, MSL elevation."""

    lat_deg: float
    lon_deg: float
    heading_deg: float
    elev_m: float

    def point(self, along_m: float, cross_m: float = 0.0) -> tuple[float, float]:
        """Lat/lon ``along_m`` past the threshold and ``cross_m`` right of the centre line."""
        r = math.radians(self.heading_deg)
        return offset_latlon(self.lat_deg, self.lon_deg,
                             along_m * math.cos(r) - cross_m * math.sin(r),
                             along_m * math.sin(r) + cross_m * math.cos(r))

    def coords(self, lat: float, lon: float) -> tuple[float, float]:
        """(along, cross) of a point near the runway [m] (local flat Earth with the WGS-84
        meridian and prime-vertical radii at the threshold)."""
        s2 = math.sin(math.radians(self.lat_deg)) ** 2
        w = math.sqrt(1.0 - WGS84_E2 * s2)
        n = math.radians(lat - self.lat_deg) * WGS84_A * (1.0 - WGS84_E2) / w**3
        e = math.radians(lon - self.lon_deg) * WGS84_A / w * math.cos(math.radians(self.lat_deg))
        r = math.radians(self.heading_deg)
        return n * math.cos(r) + e * math.sin(r), -n * math.sin(r) + e * math.cos(r)


@dataclass
class Context:
    """What the phases share: the model, the autopilot, the last waypoint, events."""

    fdm: Fdm
    ap: Autopilot
    dt: float
    wp: tuple[float, float] = (0.0, 0.0)
    events: dict = field(default_factory=dict)

    def surfaces(self, aileron=0.0, elevator=0.0, rudder=0.0, throttle=None, brake=0.0,
                 flaps=None, steer=None) -> None:
        f = self.fdm
        f.set("fcs/aileron-cmd-norm", aileron)
        f.set("fcs/elevator-cmd-norm", elevator)
        f.set("fcs/rudder-cmd-norm", rudder)
        f.set("fcs/steer-cmd-norm", -rudder if steer is None else steer)  # + steer: nose right
        for b in ("left", "right", "center"):
            f.set(f"fcs/{b}-brake-cmd-norm", brake)
        if throttle is not None:
            f.throttle(throttle)
            self.ap.throttle_cmd = throttle
        if flaps is not None:
            f.set("fcs/flap-cmd-norm", flaps)


class Wait:
    """At rest, lined up: brakes on, idle, for ``duration_s``."""

    ground = True

    def __init__(self, duration_s: float) -> None:
        self.duration_s = duration_s
        self.t0: float | None = None

    def update(self, c: Context, s: dict) -> bool:
        self.t0 = s["t"] if self.t0 is None else self.t0
        c.surfaces(throttle=c.ap.idle_throttle * 0.0, brake=1.0, elevator=0.0)
        return s["t"] - self.t0 >= self.duration_s


class TakeOff:
    """Roll on the centre line at take-off thrust, rotate at VR, climb straight ahead to
    ``agl_m`` above the runway at the climb speed."""

    ground = True

    def __init__(self, runway: Runway, agl_m: float) -> None:
        self.runway, self.agl_m = runway, agl_m
        self.rotated = False
        self.v_lo: tuple[float, float] | None = None

    def update(self, c: Context, s: dict) -> bool:
        a = c.fdm.airframe
        rw = self.runway
        _, cross = rw.coords(s["lat"], s["lon"])
        flaps = a.takeoff_flaps if s["agl"] < 150.0 else 0.0
        if not self.rotated and s["vc"] < a.vr_mps:
            hdg = rw.heading_deg - max(-5.0, min(5.0, 0.2 * cross))
            rud = c.ap.ground(s, hdg)
            c.ap.pitch_cmd = s["theta"]
            c.surfaces(rudder=rud, throttle=a.climb_throttle, flaps=flaps,
                       elevator=c.ap.elevator_trim)
            return False
        if not self.rotated:
            self.rotated = True
            c.events.setdefault("rotate_t_s", s["t"])
        if s["wow"]:
            # rotation: the stick comes aft at 0.3 per second until the nose rises, then the
            # pitch loop takes over
            self.elev = max(-0.8, getattr(self, "elev", c.ap.elevator_trim) - 0.3 * c.dt)
            if s["theta"] < a.rotate_pitch_deg - 2.0:
                elev = self.elev
                c.ap._pitch.preset(-elev)
                c.ap.pitch_cmd = s["theta"]
            else:
                elev = c.ap.hold_pitch(s, c.dt, a.rotate_pitch_deg)
            c.surfaces(rudder=c.ap.ground(s, rw.heading_deg), elevator=elev,
                       throttle=a.climb_throttle, flaps=flaps)
            return False
        c.events.setdefault("liftoff_t_s", s["t"])
        if self.v_lo is None:
            self.v_lo = (s["t"], s["vc"])
        # the climb speed is reached at 1 m/s per second from the lift-off speed
        cas = min(a.climb_mps, self.v_lo[1] + 1.0 * (s["t"] - self.v_lo[0]))
        track = rw.heading_deg - max(-10.0, min(10.0, 0.05 * cross))
        ail, rud = c.ap.lateral(s, c.dt, track_deg=track)
        elev, thr = c.ap.vertical(s, c.dt, alt_m=rw.elev_m + self.agl_m + 500.0, cas_mps=cas)
        c.surfaces(ail, elev, rud, thr, flaps=flaps)
        if s["agl"] >= self.agl_m:
            c.wp = (s["lat"], s["lon"])
            return True
        return False


class GoAround(TakeOff):
    """The climb-out of a go-around: :class:`TakeOff`'s airborne part (climb thrust at once,
    take-off flaps, the pitch holding the speed, which grows at 1 m/s per second to the climb
    speed, on the runway's centre line) from where the abandoned approach ends, to ``agl_m``
    above the runway."""

    ground = False

    def __init__(self, runway: Runway, agl_m: float) -> None:
        super().__init__(runway, agl_m)
        self.rotated = True


class Leg:
    """Fly from the last waypoint to (``lat``, ``lon``) at ``alt_m`` (MSL) and ``cas_mps``;
    done ``anticipate_m`` before the waypoint (the turn onto the next leg starts there)."""

    ground = False

    def __init__(self, lat: float, lon: float, alt_m: float, cas_mps: float,
                 vs_max: float = 4.0, vs_min: float = -4.0, anticipate_m: float = 600.0,
                 flaps: float = 0.0, cross_scale_m: float = 800.0) -> None:
        self.lat, self.lon, self.alt_m, self.cas = lat, lon, alt_m, cas_mps
        self.vs_max, self.vs_min, self.anticipate_m = vs_max, vs_min, anticipate_m
        self.flaps, self.cross_scale_m = flaps, cross_scale_m
        self.start: tuple[float, float] | None = None

    def update(self, c: Context, s: dict) -> bool:
        self.start = c.wp if self.start is None else self.start
        brg, xt, at, length = leg_geometry(*self.start, self.lat, self.lon, s["lat"], s["lon"])
        track = brg - math.degrees(math.atan2(xt, self.cross_scale_m))
        ail, rud = c.ap.lateral(s, c.dt, track_deg=track)
        cas = self.cas
        a = c.fdm.airframe
        if a.climb_at_climb_speed and self.alt_m - s["h"] > c.ap.gains.level_change_band_m:
            cas = min(cas, a.climb_mps)
        elev, thr = c.ap.vertical(s, c.dt, alt_m=self.alt_m, vs_max=self.vs_max,
                                  vs_min=self.vs_min, cas_mps=cas)
        c.surfaces(ail, elev, rud, thr, flaps=self.flaps)
        if at >= length - self.anticipate_m:
            c.wp = (self.lat, self.lon)
            return True
        return False


class Approach:
    """Centre line and a ``glide_deg`` glide path to the aim point ``aim_m`` past the
    threshold, flare at the airframe's flare height, touchdown, roll-out and braking; done at
    rest.  With ``go_around_agl_m`` the approach is abandoned when the gear descends through
    that height (done in the air: the next phase flies the go-around)."""

    ground = True

    def __init__(self, runway: Runway, aim_m: float = 300.0, glide_deg: float = 3.0,
                 go_around_agl_m: float | None = None) -> None:
        self.runway, self.aim_m, self.glide = runway, aim_m, math.radians(glide_deg)
        self.go_around_agl_m = go_around_agl_m
        self.stage = "air"
        self.t_td: float | None = None

    def update(self, c: Context, s: dict) -> bool:
        a = c.fdm.airframe
        rw = self.runway
        along, cross = rw.coords(s["lat"], s["lon"])
        if self.stage in ("air", "flare") and s["wow"]:
            self.stage = "roll"
            self.t_td = s["t"]
            c.events.setdefault("touchdown_t_s", s["t"])
        if self.stage == "roll":
            hdg = rw.heading_deg - max(-5.0, min(5.0, 0.2 * cross))
            slow = s["vc"] < 0.7 * a.vr_mps
            brake = a.brake if slow or s["t"] - self.t_td > 6.0 else 0.0
            ail, _ = c.ap.lateral(s, c.dt, bank_deg=0.0)
            # stick aft once slow (keeps the weight off the nose wheel), neutral before
            elev = -0.3 if slow else c.ap.elevator_trim
            c.surfaces(ail, elev, c.ap.ground(s, hdg), 0.0, brake, a.landing_flaps)
            return s["gs"] < 0.3
        track = rw.heading_deg - math.degrees(math.atan2(cross, 500.0))
        gear_agl = s["agl"] - a.rest_agl_ft * 0.3048
        if self.go_around_agl_m is not None and gear_agl < self.go_around_agl_m:
            # go-around: the approach is abandoned here; the next phase climbs away
            c.events.setdefault("go_around_t_s", s["t"])
            c.wp = (s["lat"], s["lon"])
            return True
        if self.stage == "flare" or gear_agl < a.flare_ft * 0.3048:
            if self.stage != "flare":
                self.stage, self.flare0 = "flare", (s["theta"], max(gear_agl, 0.5))
            th0, h0 = self.flare0
            frac = min(1.0, max(0.0, 1.0 - gear_agl / h0))
            ail, rud = c.ap.lateral(s, c.dt, track_deg=rw.heading_deg
                                    - max(-3.0, min(3.0, 0.05 * cross)))
            elev = c.ap.hold_pitch(s, c.dt, th0 + (a.flare_pitch_deg - th0) * frac)
            c.surfaces(ail, elev, rud, 0.0, flaps=a.landing_flaps)
            return False
        dist = self.aim_m - along
        h_gp = rw.elev_m + max(dist, 0.0) * math.tan(self.glide) + a.rest_agl_ft * 0.3048
        vs_ff = -s["gs"] * math.tan(self.glide)
        ail, rud = c.ap.lateral(s, c.dt, track_deg=track)
        vs_cmd = vs_ff + max(-2.0, min(2.0, 0.1 * (h_gp - s["h"])))
        elev, thr = c.ap.vertical(s, c.dt, vs_mps=vs_cmd, cas_mps=a.approach_mps)
        c.surfaces(ail, elev, rud, thr, flaps=a.landing_flaps)
        return False


class Rest:
    """At rest after the roll-out: brakes on, idle, for ``duration_s``."""

    ground = True

    def __init__(self, duration_s: float) -> None:
        self.duration_s = duration_s
        self.t0: float | None = None

    def update(self, c: Context, s: dict) -> bool:
        self.t0 = s["t"] if self.t0 is None else self.t0
        c.surfaces(throttle=0.0, brake=1.0)
        return s["t"] - self.t0 >= self.duration_s


def fly(fdm: Fdm, schedule: list, steps_per_control: int, controls_per_sample: int,
        max_s: float, terrain=None) -> tuple[dict[str, np.ndarray], dict]:
    """Run ``schedule`` on ``fdm``: controls every ``steps_per_control`` JSBSim steps, a truth
    sample every ``controls_per_sample`` controls, until the schedule is done, the ground is hit
    outside the runway phases (the impact: the record ends at the first sample in contact) or
    ``max_s``.  ``terrain(lat, lon) -> elevation`` moves the flat ground to the nearer airfield.

    Returns (columns of the state at the samples, events).

    Raises
    ------
    ValidationError
        When the ground is hit outside an upset (the autopilot lost the aircraft) or the
        schedule does not end within ``max_s``.
    """
    a = fdm.airframe
    ap = Autopilot(GAINS[a.gains], a.climb_throttle, a.idle_throttle)
    c = Context(fdm, ap, fdm.dt_s * steps_per_control)
    rows: dict[str, list] = {}
    k, i = 0, 0
    s = fdm.state()
    c.wp = (s["lat"], s["lon"])
    ap.elevator_trim = fdm.f["fcs/elevator-cmd-norm"]
    ap._pitch.i = ap.elevator_trim
    ap.pitch_cmd = s["theta"]

    def record(state: dict) -> None:
        for key, v in state.items():
            rows.setdefault(key, []).append(v)
        rows.setdefault("phase", []).append(i)

    fdm.mean_loads()  # the first sample keeps the instantaneous loads (at rest)
    record(s)
    while i < len(schedule):
        phase = schedule[i]
        if phase.update(c, s):
            i += 1
            continue
        fdm.apply_weather(s["t"], s["h"])
        if terrain is not None:
            fdm.set_terrain(terrain(s["lat"], s["lon"]))
        if not fdm.run(steps_per_control):  # pragma: no cover - JSBSim's own stop
            raise ValidationError("JSBSim stopped the simulation")
        s = fdm.state()
        k += 1
        if k % controls_per_sample:
            continue
        loads = fdm.mean_loads()
        s["n_long"], s["n_lat"], s["n_norm"] = loads
        landed = phase.ground and "touchdown_t_s" in c.events
        if landed and -s["vd"] > GROUND_LAUNCH_MPS:
            c.events["rollout_cut_t_s"] = s["t"]
            break
        if phase.ground and (s["wow"] or landed) and \
                max(abs(s["phi"]), abs(s["theta"])) > GROUND_TILT_DEG:
            # JSBSim's ground reactions can tip a light aircraft over at rest in a gusty wind
            # and then launch it (seen: roll 180 deg, then 48 m/s upwards): before take-off
            # that is not a flight; after the landing the record ends at the sample before
            if "touchdown_t_s" in c.events:
                c.events["rollout_cut_t_s"] = s["t"]
                break
            raise ValidationError(f"JSBSim's ground model overturned the aircraft on the ground: "
                                  f"roll {s['phi']:.0f} deg, pitch {s['theta']:.0f} deg at "
                                  f"t = {s['t']:.1f} s in phase {type(phase).__name__}")
        record(s)
        if s["wow"] and not phase.ground:
            if getattr(phase, "upset", False):
                c.events["impact_t_s"] = s["t"]
                break
            raise ValidationError(f"the JSBSim autopilot lost the aircraft: ground contact at "
                                  f"t = {s['t']:.1f} s in phase {type(phase).__name__}")
        if s["t"] >= max_s:
            raise ValidationError(f"the JSBSim schedule did not end within {max_s:.0f} s "
                                  f"(phase {i}: {type(phase).__name__})")
    return {key: np.asarray(v) for key, v in rows.items()}, c.events


def heading_error(a: float, b: float) -> float:
    """``a - b`` wrapped to [-180, 180)."""
    return wrap180(a - b)
