"""Airwork and upsets as phases of a JSBSim schedule (docs/jsbsim.md, "Stress schedules"):
the upsets :class:`SpiralDive` and :class:`StallSpin`, which last until the ground (or, the
spiral dive, for a set time), and the airwork :class:`SteepTurn`, :class:`Chandelle` and
:class:`Stall`, each handing over to the next leg bumplessly.  Each has the ``update`` of the
phases of :mod:`flightrecon.sim.jsbsim_flight`, whose :func:`~flightrecon.sim.jsbsim_flight.fly`
runs them."""

from __future__ import annotations

import math

from flightrecon.sim.autopilot import wrap180
from flightrecon.sim.jsbsim_flight import Context

__all__ = ["Chandelle", "SpiralDive", "Stall", "StallSpin", "SteepTurn"]


class SpiralDive:
    """Loss of control in a spiral dive: the bank grows at ``roll_rate_dps`` to ``bank_deg``
    and is held there by the ailerons, the elevator held at ``pull`` above its last trim, the
    throttle left where it was; until the ground, or for ``duration_s`` (then the next phase
    recovers: airwork)."""

    ground = False
    upset = True

    def __init__(self, bank_deg: float = 70.0, roll_rate_dps: float = 2.0,
                 pull: float = 0.05, left: bool = False,
                 duration_s: float | None = None) -> None:
        self.bank, self.rate, self.pull = bank_deg, roll_rate_dps, pull
        self.sign = -1.0 if left else 1.0
        self.duration_s = duration_s
        self.t0: float | None = None
        self.elev0 = 0.0

    def update(self, c: Context, s: dict) -> bool:
        if self.t0 is None:
            self.t0 = s["t"]
            self.elev0 = c.fdm.f["fcs/elevator-cmd-norm"]
            c.events.setdefault("upset_t_s", s["t"])
        if self.duration_s is not None and s["t"] - self.t0 >= self.duration_s:
            _recovered(c, s)
            return True
        bank = self.sign * min(self.bank, self.rate * (s["t"] - self.t0))
        ail, rud = c.ap.lateral(s, c.dt, bank_deg=bank)
        c.surfaces(ail, self.elev0 - self.pull, rud, c.ap.throttle_cmd)
        return False


class StallSpin:
    """Stall and spin: idle thrust, the nose raised at ``pitch_rate_dps`` until the speed
    falls to ``stall_fraction`` of the entry speed, then full aft elevator and full rudder
    (left), ailerons neutral, held until the ground."""

    ground = False
    upset = True

    def __init__(self, pitch_deg: float = 25.0, pitch_rate_dps: float = 2.0,
                 stall_fraction: float = 0.55) -> None:
        self.pitch, self.rate, self.frac = pitch_deg, pitch_rate_dps, stall_fraction
        self.t0: float | None = None
        self.v0 = 0.0
        self.spinning = False

    def update(self, c: Context, s: dict) -> bool:
        if self.t0 is None:
            self.t0, self.v0 = s["t"], s["vc"]
            c.events.setdefault("upset_t_s", s["t"])
        if not self.spinning and s["vc"] < self.frac * self.v0:
            self.spinning = True
            c.events.setdefault("spin_entry_t_s", s["t"])
        if self.spinning:
            c.surfaces(0.0, -1.0, 1.0, 0.0)
            return False
        pitch = min(self.pitch, c.ap.pitch_cmd + self.rate * c.dt)
        ail, rud = c.ap.lateral(s, c.dt, bank_deg=0.0)
        c.surfaces(ail, c.ap.hold_pitch(s, c.dt, pitch), rud, 0.0)
        return False


def _recovered(c: Context, s: dict) -> None:
    """End of a manoeuvre: the next leg starts here, its loops taking over bumplessly."""
    c.wp = (s["lat"], s["lon"])
    c.ap.mode = ""
    c.ap.pitch_cmd = s["theta"]
    c.ap._pitch.preset(-c.fdm.f["fcs/elevator-cmd-norm"])
    c.ap._thr.preset(c.ap.throttle_cmd)


class SteepTurn:
    """A level turn at ``bank_deg`` (negative: left) through ``turn_deg`` of heading at the
    entry altitude, full power; the speed is what the power gives."""

    ground = False
    upset = False

    def __init__(self, bank_deg: float = 60.0, turn_deg: float = 360.0) -> None:
        self.bank, self.turn = bank_deg, turn_deg
        self.alt: float | None = None
        self.turned = 0.0
        self.last = 0.0

    def update(self, c: Context, s: dict) -> bool:
        if self.alt is None:
            self.alt, self.last = s["h"], s["psi"]
            c.events.setdefault("steep_turn_t_s", s["t"])
            c.ap._vs.preset(c.ap.pitch_cmd)
        self.turned += abs(wrap180(s["psi"] - self.last))
        self.last = s["psi"]
        if self.turned >= self.turn:
            _recovered(c, s)
            return True
        # the bank comes in at 10 deg/s; the pitch holds the altitude
        bank = math.copysign(min(abs(self.bank), 10.0 * self.turned / 15.0 + 10.0), self.bank)
        ail, rud = c.ap.lateral(s, c.dt, bank_deg=bank)
        pitch = c.ap._vs(max(-3.0, min(3.0, 0.1 * (self.alt - s["h"]))) + s["vd"], 0.0, c.dt)
        c.ap.mode = "vs"
        c.surfaces(ail, c.ap.elevator(s, c.dt, pitch), rud, c.fdm.airframe.climb_throttle)
        return False


class Chandelle:
    """A climbing turn through ``turn_deg`` at full power: ``bank_deg`` (negative: left), the
    nose raised at 1 deg/s to ``pitch_deg``; done at the end of the turn or when the speed
    has fallen to the approach speed (the next phase rolls out)."""

    ground = False
    upset = False

    def __init__(self, bank_deg: float = 30.0, pitch_deg: float = 10.0,
                 turn_deg: float = 180.0) -> None:
        self.bank, self.pitch, self.turn = bank_deg, pitch_deg, turn_deg
        self.turned: float | None = None
        self.last = 0.0

    def update(self, c: Context, s: dict) -> bool:
        if self.turned is None:
            self.turned, self.last = 0.0, s["psi"]
            c.events.setdefault("chandelle_t_s", s["t"])
        self.turned += abs(wrap180(s["psi"] - self.last))
        self.last = s["psi"]
        # done at the turn, or when the speed falls to the approach speed
        if self.turned >= self.turn or s["vc"] < c.fdm.airframe.approach_mps:
            _recovered(c, s)
            return True
        ail, rud = c.ap.lateral(s, c.dt, bank_deg=self.bank)
        pitch = min(self.pitch, c.ap.pitch_cmd + 1.0 * c.dt)   # the nose comes up at 1 deg/s
        c.surfaces(ail, c.ap.hold_pitch(s, c.dt, pitch), rud, c.fdm.airframe.climb_throttle)
        return False


class Stall:
    """A power-off stall and its recovery: idle, wings level, the nose raised at
    ``pitch_rate_dps`` (to at most ``pitch_deg``) until the speed falls to ``stall_fraction``
    of the airframe's approach speed (about its clean stall speed) or it sinks faster than
    4 m/s, then the nose lowered to
    ``recover_pitch_deg`` at full power until the speed is back to ``recover_fraction`` of the
    approach speed (the next leg climbs back)."""

    ground = False
    upset = False

    def __init__(self, pitch_deg: float = 25.0, pitch_rate_dps: float = 2.0,
                 stall_fraction: float = 0.75, recover_pitch_deg: float = -5.0,
                 recover_fraction: float = 1.2) -> None:
        self.pitch, self.rate, self.frac = pitch_deg, pitch_rate_dps, stall_fraction
        self.recover_pitch, self.recover_frac = recover_pitch_deg, recover_fraction
        self.started = False
        self.stalled = False

    def update(self, c: Context, s: dict) -> bool:
        a = c.fdm.airframe
        if not self.started:
            self.started = True
            c.events.setdefault("stall_entry_t_s", s["t"])
        # the stall: the speed gone, or the aircraft sinking nose-high (a mushing stall at
        # full aft stick: the T-6 at 45 m/s, 20 deg angle of attack)
        if not self.stalled and (s["vc"] < self.frac * a.approach_mps or -s["vd"] < -4.0):
            self.stalled = True
            c.events.setdefault("stall_t_s", s["t"])
        ail, rud = c.ap.lateral(s, c.dt, bank_deg=0.0)
        if self.stalled:
            if s["vc"] > self.recover_frac * a.approach_mps:
                _recovered(c, s)
                return True
            pitch = max(self.recover_pitch, c.ap.pitch_cmd - 5.0 * c.dt)
            c.surfaces(ail, c.ap.hold_pitch(s, c.dt, pitch), rud, a.climb_throttle)
            return False
        pitch = min(self.pitch, c.ap.pitch_cmd + self.rate * c.dt)
        c.surfaces(ail, c.ap.hold_pitch(s, c.dt, pitch), rud, a.idle_throttle)
        return False
