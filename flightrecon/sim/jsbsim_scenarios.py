"""JSBSim truth scenarios: ``simulate("jsbsim-circuit", seed)`` and the others (docs/jsbsim.md).

Every scenario starts at rest, lined up on the departure runway's threshold (JSBSim settles
the aircraft on its gear before ``t = 0``), and is flown by the autopilot of
:mod:`flightrecon.sim.autopilot` through a schedule (:mod:`flightrecon.sim.jsbsim_flight`):

* ``jsbsim-circuit``: Cessna 172 (JSBSim ``c172p``), left-hand pattern at 300 m above the
  field, landing back on the runway, roll-out to rest (about 8 minutes);
* ``jsbsim-xc``: the Cessna on a cross-country of about an hour (about 190 km): climbs to
  1500 m and 2500 m, course changes, a descent, landing at a second airfield;
* ``jsbsim-jet``: Boeing 737 (JSBSim ``737``), climb to 10 700 m, cruise with course changes,
  descent, landing about 2000 km away (about 3 hours);
* ``jsbsim-spiral``: the Cessna climbs to 1800 m, cruises, then a loss of control in a spiral
  dive to the ground; ``jsbsim-spin``: the same to 1500 m, then a stall and spin to the ground.
  Both records end at the impact; the wreckage is the sidecar's arrival;
* ``jsbsim-airwork``: steep turns at 60 deg, a stall and its recovery, a spiral, chandelles,
  then the landing; ``jsbsim-holding``: four laps of a racetrack in 20-25 m/s of wind that
  turns (by the time sinusoid and the veer with height: 105 deg in 29 minutes on seed 1),
  then the landing; ``jsbsim-goaround``: the circuit with a go-around from
  60 m on the first approach.

Any scenario flies any aircraft of :data:`AIRFRAMES` (``airframe=``): the Cessna 172, the
Cessna 310 twin, the 737, the T-6 Texan II and the PC-7 trainers, the Global 5000 business jet
and the 747.

Per seed: the wind (speed, direction, shear, veer, a slow change in time and random walks in
time and height), JSBSim's turbulence (seeded, light to moderate), the temperature offset, the
sea-level pressure and its drift, the persistent sensor errors, and the recorder's noise.
``scale`` < 1 shortens the en-route legs (short versions for tests).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.geo.frames import offset_latlon
from flightrecon.sim.aircraft import JET, LIGHT, draw_aircraft
from flightrecon.sim.fdm import AirframeModel, FdmWeather
from flightrecon.sim.jsbsim_flight import (
    Approach,
    GoAround,
    Leg,
    Rest,
    Runway,
    TakeOff,
    Wait,
)
from flightrecon.sim.manoeuvres import Chandelle, SpiralDive, Stall, StallSpin, SteepTurn
from flightrecon.sim.sensors import Faults
from flightrecon.sim.weather import WindField
from flightrecon.types import Position

__all__ = ["AIRFRAMES", "JSBSIM_SCENARIOS", "JsbsimConfig", "draw_weather", "schedule"]

AIRFRAMES = {
    "c172p": AirframeModel(model="c172p", engines=1, rest_agl_ft=4.36, vr_mps=28.0,
                           climb_mps=36.0, cruise_mps=51.0, approach_mps=34.0,
                           rotate_pitch_deg=8.0, takeoff_flaps=0.0, landing_flaps=0.66,
                           flare_ft=20.0, climb_throttle=1.0, idle_throttle=0.25,
                           gains="light", brake=0.6, flare_pitch_deg=5.0),
    "737": AirframeModel(model="737", engines=2, rest_agl_ft=3.69, vr_mps=78.0,
                         climb_mps=150.0, cruise_mps=135.0, approach_mps=75.0,
                         rotate_pitch_deg=8.0, takeoff_flaps=0.2, landing_flaps=0.6,
                         flare_ft=60.0, climb_throttle=0.95, idle_throttle=0.0,
                         gains="jet", brake=0.5, flare_pitch_deg=8.0,
                         circuit_mps=(90.0, 90.0, 85.0, 80.0), circuit_scale=2.0,
                         sensor_class="jet", aircraft_class="airliner"),
    "c310": AirframeModel(model="c310", engines=2, rest_agl_ft=3.32, vr_mps=42.0,
                          climb_mps=46.0, cruise_mps=75.0, approach_mps=45.0,
                          rotate_pitch_deg=8.0, takeoff_flaps=0.0, landing_flaps=1.0,
                          flare_ft=20.0, climb_throttle=1.0, idle_throttle=0.25,
                          gains="light", brake=0.5, flare_pitch_deg=7.0,
                          circuit_mps=(55.0, 58.0, 50.0, 48.0), circuit_scale=1.3,
                          aircraft_class="twin piston", start_each_engine=True,
                          prop_advance=1.0, climb_at_climb_speed=True),
    "t6texan2": AirframeModel(model="t6texan2", engines=1, rest_agl_ft=6.09, vr_mps=40.0,
                              climb_mps=72.0, cruise_mps=100.0, approach_mps=50.0,
                              rotate_pitch_deg=8.0, takeoff_flaps=0.5, landing_flaps=1.0,
                              flare_ft=20.0, climb_throttle=1.0, idle_throttle=0.0,
                              gains="light", brake=0.3, flare_pitch_deg=5.0,
                              circuit_mps=(65.0, 70.0, 57.0, 54.0), circuit_scale=1.4,
                              aircraft_class="turboprop trainer", climb_at_climb_speed=True),
    "pc7": AirframeModel(model="pc7", engines=1, rest_agl_ft=2.71, vr_mps=40.0,
                         climb_mps=60.0, cruise_mps=90.0, approach_mps=46.0,
                         rotate_pitch_deg=8.0, takeoff_flaps=0.5, landing_flaps=1.0,
                         flare_ft=20.0, climb_throttle=1.0, idle_throttle=0.0,
                         gains="light", brake=0.25, flare_pitch_deg=5.0,
                         circuit_mps=(60.0, 62.0, 52.0, 50.0), circuit_scale=1.3,
                         aircraft_class="turboprop trainer", climb_at_climb_speed=True),
    "global5000": AirframeModel(model="global5000", engines=2, rest_agl_ft=8.79, vr_mps=65.0,
                                climb_mps=110.0, cruise_mps=130.0, approach_mps=68.0,
                                rotate_pitch_deg=8.0, takeoff_flaps=0.33, landing_flaps=0.66,
                                flare_ft=35.0, climb_throttle=0.95, idle_throttle=0.0,
                                gains="jet", brake=0.5, flare_pitch_deg=8.0,
                                circuit_mps=(100.0, 100.0, 85.0, 80.0), circuit_scale=2.0,
                                sensor_class="jet", aircraft_class="business jet",
                                climb_at_climb_speed=True),
    "B747": AirframeModel(model="B747", engines=4, rest_agl_ft=13.5, vr_mps=80.0,
                          climb_mps=120.0, cruise_mps=135.0, approach_mps=72.0,
                          rotate_pitch_deg=8.0, takeoff_flaps=0.33, landing_flaps=0.66,
                          flare_ft=45.0, climb_throttle=0.95, idle_throttle=0.0,
                          gains="jet", brake=0.5, flare_pitch_deg=8.0,
                          circuit_mps=(100.0, 100.0, 90.0, 85.0), circuit_scale=2.0,
                          sensor_class="jet", aircraft_class="wide-body airliner",
                          climb_at_climb_speed=True),
}
"""The JSBSim aircraft (docs/jsbsim.md, "Fleet"); ``rest_agl_ft`` measured (where each settles
on its gear, brakes on, no wind)."""


JSBSIM_AIRFIELD = Position(40.46, 50.05, 3.0)
"""Departure runway threshold of every JSBSim scenario (MSL elevation)."""


@dataclass(frozen=True)
class JsbsimConfig:
    """Settings of a JSBSim scenario (override any field by name in ``simulate``).

    ``weather`` = ``None`` draws it from the seed (:func:`draw_weather`); ``scale`` shortens
    the en-route legs; rates in Hz divide ``truth_rate_hz``; ``loads_range_g`` is the
    recorder's range per load factor (long, lat, norm): readings beyond it are clipped
    (saturation); ``tas_range_mps`` likewise for the airspeed.  ``full_tanks`` fills the
    fuel tanks for a full-length flight (``scale`` >= 0.5; short versions keep the model's
    default load).  ``spiral_bank_deg`` and ``spiral_roll_rate_dps`` shape ``jsbsim-spiral``'s
    loss of control (the bank it rolls to and how fast; beyond 90 deg the aircraft rolls past
    the knife edge into a steep, partly inverted dive: the any-attitude validation).
    """

    airframe: str = "c172p"
    flight_id: str = "F1"
    epoch_utc: str = "2026-01-01T10:00:00Z"
    airfield: Position = JSBSIM_AIRFIELD
    runway_deg: float = 160.0
    runway_length_m: float = 2000.0
    geoid_undulation_m: float = -22.0
    dt_s: float = 1.0 / 96.0
    control_hz: float = 16.0
    truth_rate_hz: float = 16.0
    loads_hz: float = 16.0
    attitude_hz: float = 8.0
    airspeed_hz: float = 4.0
    baro_hz: float = 4.0
    gnss_hz: float = 1.0
    scale: float = 1.0
    lineup_s: float = 20.0
    rest_s: float = 30.0
    weather: FdmWeather | None = None
    loads_range_g: tuple[tuple[float, float], ...] = ((-2.0, 2.0), (-2.0, 2.0), (-3.0, 6.0))
    tas_range_mps: tuple[float, float] = (15.0, 130.0)
    loads_quantum_g: float = 0.001
    attitude_quantum_deg: float = 0.05
    spikes: int = 2
    ideal_sensors: bool = False
    full_tanks: bool = False
    spiral_bank_deg: float = 75.0
    spiral_roll_rate_dps: float = 1.5


def _runway(cfg: JsbsimConfig, field: Position, heading: float) -> Runway:
    return Runway(field.lat_deg, field.lon_deg, heading, field.elev_m)


def draw_weather(name: str, seed: int) -> FdmWeather:
    """The weather of scenario ``name`` for ``seed`` (module docstring)."""
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([int(seed), 2121])))
    if name == "jsbsim-holding":
        return _holding_weather(rng)
    jet = name == "jsbsim-jet"
    speed0 = float(rng.uniform(4.0, 14.0) if jet else rng.uniform(2.0, 9.0))
    wind = WindField(
        speed0_mps=speed0, speed_gradient_per_s=float(rng.uniform(0.001, 0.003 if jet else 0.005)),
        from0_deg=float(rng.uniform(0.0, 360.0)), veer_deg_per_m=float(rng.uniform(-0.005, 0.015)),
        speed_amp_mps=float(rng.uniform(0.0, 2.0)), dir_amp_deg=float(rng.uniform(0.0, 10.0)),
        period_s=float(rng.uniform(3600.0, 3 * 3600.0)), rw_time_mps_sqrt_s=0.01,
        rw_alt_mps_sqrt_m=0.03, rw_seed=int(rng.integers(0, 2**31)))
    return FdmWeather(
        wind=wind, turbulence_severity=float(rng.choice([1.0, 2.0, 3.0], p=[0.5, 0.35, 0.15])),
        turbulence_wind_20ft_mps=speed0, temp_offset_k=float(rng.normal(0.0, 8.0)),
        p_sl_hpa=float(rng.normal(1013.0, 8.0)), p_sl_rate_hpa_per_h=float(rng.normal(0.0, 1.5)),
        turbulence_seed=int(rng.integers(1, 2**31 - 1)))


def _holding_weather(rng: np.random.Generator) -> FdmWeather:
    """Strong wind for ``jsbsim-holding``: 5-7 m/s at the surface, growing 10-12 (m/s)/km to
    20-25 m/s at the holding altitude (1500 m), from within 20 deg of the runway's direction
    (160) at the take-off and turning by 0.8 x (60-90) deg over the next 30 minutes (the time
    sinusoid's period 1.5 h, amplitude 60-90 deg)."""
    speed0 = float(rng.uniform(5.0, 7.0))
    amp = float(rng.uniform(60.0, 90.0))
    wind = WindField(
        speed0_mps=speed0, speed_gradient_per_s=float(rng.uniform(0.010, 0.012)),
        from0_deg=float(160.0 - amp * np.sin(1.0) + rng.uniform(-20.0, 20.0)),
        veer_deg_per_m=float(rng.uniform(0.0, 0.01)),
        speed_amp_mps=float(rng.uniform(0.0, 2.0)), dir_amp_deg=amp,
        period_s=1.5 * 3600.0, rw_time_mps_sqrt_s=0.01, rw_alt_mps_sqrt_m=0.03,
        rw_seed=int(rng.integers(0, 2**31)))
    return FdmWeather(
        wind=wind, turbulence_severity=float(rng.choice([1.0, 2.0], p=[0.6, 0.4])),
        turbulence_wind_20ft_mps=speed0, temp_offset_k=float(rng.normal(0.0, 8.0)),
        p_sl_hpa=float(rng.normal(1013.0, 8.0)), p_sl_rate_hpa_per_h=float(rng.normal(0.0, 1.5)),
        turbulence_seed=int(rng.integers(1, 2**31 - 1)))


# --------------------------------------------------------------------------------------------
# schedules: (phases, arrival runway or None, longest record [s], terrain(lat, lon) or None)


def _circuit(cfg: JsbsimConfig, rw: Runway):
    return _pattern(cfg, rw) + [Approach(rw, _aim_m(cfg)), Rest(cfg.rest_s)], rw, 1800.0, None


def _aim_m(cfg: JsbsimConfig) -> float:
    return 300.0 if AIRFRAMES[cfg.airframe].gains == "jet" else 250.0


def _pattern(cfg: JsbsimConfig, rw: Runway, climb: bool = True) -> list:
    """Line-up, take-off and a left-hand pattern at 300 m above the field to the final
    intercept (``climb`` = False: the pattern only, from the upwind end)."""
    a = AIRFRAMES[cfg.airframe]
    k = a.circuit_scale
    v1, v2, v3, v4 = a.circuit_mps
    pa = rw.elev_m + 300.0
    start = [Wait(cfg.lineup_s), TakeOff(rw, 150.0)] if climb else []
    return start + [
        Leg(*rw.point(2500.0 * k), pa, v1), Leg(*rw.point(2500.0 * k, -1500.0 * k), pa, v2),
        Leg(*rw.point(-2000.0 * k, -1500.0 * k), pa, v2),
        Leg(*rw.point(-3500.0 * k, -1500.0 * k), rw.elev_m + 200.0, v3,
            anticipate_m=500.0 * k, flaps=_part_flaps(a)),
        Leg(*rw.point(-3500.0 * k), rw.elev_m + 180.0, v4, anticipate_m=400.0 * k,
            flaps=_part_flaps(a))]


def _part_flaps(a: AirframeModel) -> float:
    """Flaps on base and final intercept: none on the Cessna (as flown before the fleet), half
    the landing flaps on the others."""
    return 0.0 if a.model == "c172p" else 0.5 * a.landing_flaps


def _destination(rw: Runway, north_m: float, east_m: float, heading: float,
                 elev_m: float) -> Runway:
    lat, lon = offset_latlon(rw.lat_deg, rw.lon_deg, north_m, east_m)
    return Runway(lat, lon, heading, elev_m)


def _arrival_legs(dest: Runway, a: AirframeModel, far_m: float, glide_m: float) -> list:
    """Onto the extended centre line ``far_m`` out (approach speed + 35 %, part flaps), then
    along it to ``glide_m`` out on the glide path (approach speed + 15 %, more flaps), then the
    approach."""
    t3 = np.tan(np.radians(3.0))
    jet = a.gains == "jet"
    return [Leg(*dest.point(-far_m), dest.elev_m + far_m * t3 + 150.0, 1.35 * a.approach_mps,
                anticipate_m=1500.0 if jet else 600.0, flaps=0.5 * a.landing_flaps),
            Leg(*dest.point(-glide_m), dest.elev_m + glide_m * t3, 1.15 * a.approach_mps,
                vs_min=-6.0, anticipate_m=300.0, cross_scale_m=600.0,
                flaps=0.75 * a.landing_flaps),
            Approach(dest, 300.0 if jet else 250.0)]


def _terrain(rw: Runway, dest: Runway, near_m: float):
    """Flat ground at the departure's elevation, at the destination's within ``near_m``."""
    def terrain(lat, lon):
        along, cross = dest.coords(lat, lon)
        return dest.elev_m if np.hypot(along, cross) < near_m else rw.elev_m
    return terrain


def _xc(cfg: JsbsimConfig, rw: Runway):
    s = cfg.scale
    dest = _destination(rw, 60e3 * s, 150e3 * s, 250.0, 120.0)

    def wp(n_km, e_km):
        return offset_latlon(rw.lat_deg, rw.lon_deg, n_km * 1e3 * s, e_km * 1e3 * s)
    a = AIRFRAMES[cfg.airframe]
    cr = a.cruise_mps
    phases = [Wait(cfg.lineup_s), TakeOff(rw, 150.0),
              Leg(*wp(-15, 25), rw.elev_m + 1500.0 * min(1.0, 2 * s), cr),
              Leg(*wp(10, 70), rw.elev_m + 2500.0 * min(1.0, 2 * s), cr),
              Leg(*wp(45, 95), rw.elev_m + 2500.0 * min(1.0, 2 * s), cr),
              Leg(*wp(40, 130), dest.elev_m + 1800.0 * min(1.0, 2 * s), cr, vs_min=-3.0),
              *_arrival_legs(dest, a, 9000.0, 4000.0), Rest(cfg.rest_s)]
    return phases, dest, 3 * 3600.0, _terrain(rw, dest, 30e3 * s)


def _jet(cfg: JsbsimConfig, rw: Runway):
    s = cfg.scale
    dest = _destination(rw, 900e3 * s, 1700e3 * s, 70.0, 250.0)

    def wp(n_km, e_km):
        return offset_latlon(rw.lat_deg, rw.lon_deg, n_km * 1e3 * s, e_km * 1e3 * s)
    a = AIRFRAMES[cfg.airframe]
    cruise = rw.elev_m + (10700.0 if s >= 0.5 else 4000.0)
    phases = [Wait(cfg.lineup_s), TakeOff(rw, 300.0),
              Leg(*wp(-60, 150), rw.elev_m + 3000.0, a.climb_mps, vs_max=15.0,
                  anticipate_m=3000.0),
              Leg(*wp(200, 650), cruise, a.climb_mps if s >= 0.5 else a.cruise_mps,
                  vs_max=12.0, anticipate_m=3000.0),
              Leg(*wp(500, 1150), cruise, a.cruise_mps, anticipate_m=3000.0),
              Leg(*wp(750, 1400), rw.elev_m + 3000.0, a.cruise_mps, vs_min=-15.0,
                  anticipate_m=3000.0),
              Leg(*dest.point(-60e3 * min(1.0, 2 * s)), dest.elev_m + 3000.0, 115.0,
                  vs_min=-12.0, anticipate_m=2500.0),
              *_arrival_legs(dest, a, 20000.0, 9000.0), Rest(cfg.rest_s)]
    return phases, dest, 8 * 3600.0, _terrain(rw, dest, 100e3 * s)


def _upset_climb(cfg: JsbsimConfig, rw: Runway, agl_m: float) -> list:
    s = cfg.scale
    a = AIRFRAMES[cfg.airframe]
    return [Wait(cfg.lineup_s), TakeOff(rw, 150.0),
            Leg(*rw.point(9000.0 * s + 3000.0, 2000.0), rw.elev_m + agl_m, a.climb_mps),
            Leg(*rw.point(9000.0 * s + 3000.0, 2000.0 + 12000.0 * s + 2000.0),
                rw.elev_m + agl_m, a.cruise_mps)]


def _spiral(cfg: JsbsimConfig, rw: Runway):
    return (_upset_climb(cfg, rw, 1800.0) + [SpiralDive(bank_deg=cfg.spiral_bank_deg,
                                                        roll_rate_dps=cfg.spiral_roll_rate_dps,
                                                        pull=0.04)], None, 3600.0, None)


def _spin(cfg: JsbsimConfig, rw: Runway):
    return _upset_climb(cfg, rw, 1500.0) + [StallSpin()], None, 3600.0, None


def _rejoin(cfg: JsbsimConfig, rw: Runway) -> list:
    """From anywhere near the field back to a left-hand downwind at 300 m and the landing."""
    a = AIRFRAMES[cfg.airframe]
    k = a.circuit_scale
    v1, v2, v3, v4 = a.circuit_mps
    pa = rw.elev_m + 300.0
    return [Leg(*rw.point(2500.0 * k, -1500.0 * k), pa, v2, vs_min=-5.0),
            Leg(*rw.point(-2000.0 * k, -1500.0 * k), pa, v2),
            Leg(*rw.point(-3500.0 * k, -1500.0 * k), rw.elev_m + 200.0, v3,
                anticipate_m=500.0 * k, flaps=_part_flaps(a)),
            Leg(*rw.point(-3500.0 * k), rw.elev_m + 180.0, v4, anticipate_m=400.0 * k,
                flaps=_part_flaps(a)),
            Approach(rw, _aim_m(cfg)), Rest(cfg.rest_s)]


def _airwork(cfg: JsbsimConfig, rw: Runway):
    """Climb to 1500 m in the practice area 8 km out; steep turns of 360 deg at 60 deg bank
    left and right, a power-off stall and recovery, a spiral (bank to 60 deg for 20 s), two
    chandelles, then back to the field and a landing (about 25 minutes)."""
    a = AIRFRAMES[cfg.airframe]
    area = rw.elev_m + 1500.0
    k = a.circuit_scale
    # manoeuvring at the downwind speed (at the cruise speed the level change after a
    # manoeuvre dived the trainers: pitch on a speed they could not climb at)
    v = a.circuit_mps[1]
    return ([Wait(cfg.lineup_s), TakeOff(rw, 150.0),
             Leg(*rw.point(6000.0 * k, 4000.0 * k), area, a.climb_mps),
             Leg(*rw.point(9000.0 * k, 8000.0 * k), area, a.climb_mps),
             SteepTurn(-60.0), Leg(*rw.point(6000.0 * k, 11000.0 * k), area, v),
             SteepTurn(60.0), Leg(*rw.point(9000.0 * k, 14000.0 * k), area, v),
             Stall(), Leg(*rw.point(12000.0 * k, 10000.0 * k), area, v),
             SpiralDive(bank_deg=60.0, roll_rate_dps=5.0, pull=0.02, duration_s=20.0),
             Leg(*rw.point(9000.0 * k, 6000.0 * k), area, v),
             Chandelle(-30.0), Leg(*rw.point(12000.0 * k, 6000.0 * k), area, v),
             Chandelle(30.0), Leg(*rw.point(8000.0 * k, 2000.0 * k), rw.elev_m + 600.0,
                                  v, vs_min=-5.0)]
            + _rejoin(cfg, rw), rw, 3 * 3600.0, None)


def _holding(cfg: JsbsimConfig, rw: Runway):
    """Climb to 1500 m, to a fix 15 km out on the extended centre line, four laps of a
    right-hand racetrack (legs 5 km, inbound towards the field), then the approach and landing.
    The weather (:func:`draw_weather`) puts 20-25 m/s of wind at the holding altitude, turning
    with the time sinusoid and the veer with height (105 deg in 29 minutes on seed 1)."""
    a = AIRFRAMES[cfg.airframe]
    alt = rw.elev_m + 1500.0
    s = cfg.scale
    leg_m = 5000.0 * max(s, 0.2)
    fix = -15000.0
    phases = [Wait(cfg.lineup_s), TakeOff(rw, 150.0),
              Leg(*rw.point(3000.0, 3000.0), alt, a.climb_mps),
              Leg(*rw.point(fix, 3000.0), alt, a.cruise_mps),
              Leg(*rw.point(fix), alt, a.cruise_mps, anticipate_m=200.0)]
    for _ in range(max(1, round(4 * s))):
        # inbound end at the fix; outbound on the right (the side away from the field)
        phases += [Leg(*rw.point(fix - 1500.0, 2500.0), alt, a.cruise_mps, anticipate_m=300.0),
                   Leg(*rw.point(fix - leg_m, 2500.0), alt, a.cruise_mps, anticipate_m=300.0),
                   Leg(*rw.point(fix - leg_m - 1500.0), alt, a.cruise_mps, anticipate_m=300.0),
                   Leg(*rw.point(fix), alt, a.cruise_mps, anticipate_m=200.0)]
    return phases + _arrival_legs(rw, a, 9000.0, 4000.0) + [Rest(cfg.rest_s)], rw, \
        3 * 3600.0, None


def _go_around(cfg: JsbsimConfig, rw: Runway):
    """The circuit, a go-around from 60 m on the first approach (climb straight ahead), a
    second circuit and the landing."""
    # the go-around climbs like the take-off (at the climb speed on a leg the pitch-on-speed
    # loop first dived to accelerate: the trainers and the business jet hit the ground)
    return (_pattern(cfg, rw) + [Approach(rw, _aim_m(cfg), go_around_agl_m=60.0),
                                 GoAround(rw, 200.0)]
            + _rejoin(cfg, rw), rw, 3600.0, None)


@dataclass(frozen=True)
class _JsbScenario:
    config: JsbsimConfig
    schedule: Any


JSBSIM_SCENARIOS: dict[str, _JsbScenario] = {
    "jsbsim-circuit": _JsbScenario(JsbsimConfig(), _circuit),
    "jsbsim-xc": _JsbScenario(JsbsimConfig(), _xc),
    "jsbsim-jet": _JsbScenario(JsbsimConfig(airframe="737", runway_deg=230.0,
                                            runway_length_m=3000.0, truth_rate_hz=8.0,
                                            loads_hz=8.0, attitude_hz=4.0, airspeed_hz=2.0,
                                            baro_hz=2.0, tas_range_mps=(30.0, 320.0),
                                            full_tanks=True), _jet),
    "jsbsim-spiral": _JsbScenario(JsbsimConfig(), _spiral),
    "jsbsim-spin": _JsbScenario(JsbsimConfig(), _spin),
    "jsbsim-airwork": _JsbScenario(JsbsimConfig(), _airwork),
    "jsbsim-holding": _JsbScenario(JsbsimConfig(), _holding),
    "jsbsim-goaround": _JsbScenario(JsbsimConfig(), _go_around),
}


def schedule(name: str, cfg: JsbsimConfig):
    """(phases, arrival runway or None, longest record, terrain) of scenario ``name``."""
    rw = _runway(cfg, cfg.airfield, cfg.runway_deg)
    return JSBSIM_SCENARIOS[name].schedule(cfg, rw)


def jsbsim_config(name: str, **overrides: Any) -> JsbsimConfig:
    """The configuration of JSBSim scenario ``name`` with ``overrides`` (unknown names are an
    error)."""
    if name not in JSBSIM_SCENARIOS:
        raise ValidationError(f"unknown JSBSim scenario '{name}'; choose one of "
                              f"{sorted(JSBSIM_SCENARIOS)}")
    cfg = config_with_overrides(JSBSIM_SCENARIOS[name].config, overrides)
    if cfg.airframe not in AIRFRAMES:
        raise ValidationError(f"unknown JSBSim aircraft '{cfg.airframe}'; choose one of "
                              f"{sorted(AIRFRAMES)}")
    return cfg


def config_with_overrides(config: Any, overrides: dict[str, Any]) -> Any:
    """The scenario configuration dataclass ``config`` with ``overrides`` applied (an unknown
    setting is a :class:`~flightrecon.errors.ValidationError` naming the valid ones); shared by
    both truth sources' scenario tables."""
    import dataclasses

    fields = {f.name for f in dataclasses.fields(config)}
    bad = sorted(set(overrides) - fields)
    if bad:
        raise ValidationError(f"unknown scenario setting(s) {bad}; valid: {sorted(fields)}")
    return replace(config, **overrides)


def persistent_aircraft(name: str, cfg: JsbsimConfig, seed: int):
    """The persistent sensor errors of this flight (drawn from the seed; the project's
    :func:`~flightrecon.sim.aircraft.draw_aircraft` spreads)."""
    base = JET if AIRFRAMES[cfg.airframe].sensor_class == "jet" else LIGHT
    return draw_aircraft(f"{name}:{cfg.airframe}", seed, base)


def recorder_faults(cfg: JsbsimConfig) -> Faults:
    """Spikes in the normal load factor, the airspeed and the baro altitude."""
    if cfg.spikes <= 0:
        return Faults()
    return Faults(spikes=cfg.spikes, spike_channels=(("n_norm_g", 1.0), ("tas_mps", 20.0),
                                                     ("baro_alt_m", 150.0)))
