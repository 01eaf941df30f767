"""Routes of the point-mass scenarios: each builds a :class:`~flightrecon.sim.plan.PlanBuilder`
from a :class:`~flightrecon.sim.scenarios.ScenarioConfig` (docs/simulator.md, "Scenarios")."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.geo.frames import offset_latlon
from flightrecon.sim.plan import PlanBuilder
from flightrecon.sim.weather import Atmosphere
from flightrecon.types import Position

if TYPE_CHECKING:
    from flightrecon.sim.scenarios import ScenarioConfig

__all__ = ["ARP_OFFSET_M", "circuit_touchdown_m"]

ARP_OFFSET_M = 800.0
"""Airfield reference point: this far down the runway from the start of the take-off roll
(departure) or from the touchdown point (arrival)."""


def offset_point(p: Position, north_m: float, east_m: float) -> tuple[float, float]:
    """Lat/lon of a point ``north_m, east_m`` from ``p`` in its tangent plane (at ground)."""
    return offset_latlon(p.lat_deg, p.lon_deg, north_m, east_m)


def _builder(cfg: ScenarioConfig, atmosphere: Atmosphere, start: tuple[float, float, float],
             track_deg: float, airborne_tas: float | None) -> PlanBuilder:
    a = cfg.aircraft
    return PlanBuilder(lat_deg=start[0], lon_deg=start[1], elev_msl_m=start[2],
                       track_deg=track_deg, wind=cfg.wind, atmosphere=atmosphere,
                       geoid_undulation_m=cfg.geoid_undulation_m,
                       alpha_ref_deg=a.alpha_ref_deg, alpha_ref_tas_mps=a.alpha_ref_tas_mps,
                       airborne_tas_mps=airborne_tas)


def _takeoff_start(cfg: ScenarioConfig) -> tuple[float, float, float]:
    r = np.radians(cfg.runway_deg)
    lat, lon = offset_point(cfg.airfield, -ARP_OFFSET_M * np.cos(r), -ARP_OFFSET_M * np.sin(r))
    return lat, lon, cfg.airfield.elev_m


def circuit_touchdown_m(cfg: ScenarioConfig) -> float:
    """Circuit touchdown point: this far along the runway from the airfield reference point
    (``cfg.touchdown_m`` past the threshold, which is ``cfg.lineup_m`` before the start of the
    take-off roll), on the centre line."""
    return cfg.touchdown_m - ARP_OFFSET_M - cfg.lineup_m


def threshold_latlon(cfg: ScenarioConfig) -> tuple[float, float]:
    """Lat/lon of the departure runway's threshold: ``lineup_m`` before the roll's start."""
    r = np.radians(cfg.runway_deg)
    d = ARP_OFFSET_M + cfg.lineup_m
    return offset_point(cfg.airfield, -d * np.cos(r), -d * np.sin(r))


def route_circuit(cfg: ScenarioConfig, atm: Atmosphere, extra_s: float,
                   legs: tuple[float, float] = (215.0, 60.0)) -> PlanBuilder:
    """Left-hand pattern at 450 m AGL: upwind, crosswind, downwind, base, final, landing.

    ``legs`` = (downwind, base) times [s]; :func:`close_circuit` adjusts them so that the
    final approach lies on the runway centre line and touches down at
    :func:`circuit_touchdown_m`.
    """
    a, s = cfg.aircraft, cfg.leg_scale
    b = _builder(cfg, atm, _takeoff_start(cfg), cfg.runway_deg, None)
    pattern = cfg.airfield.elev_m + (cfg.cruise_alt_msl_m or 450.0)
    b.hold(extra_s)  # lined up, standing still: the scenario's duration is exact
    b.takeoff(rotate_tas_mps=a.rotate_tas_mps, climb_rate_mps=a.climb_rate_mps)
    b.set_tas(a.climb_tas_mps)
    b.level_off(pattern, wait=False)
    b.hold(90 * s).turn(-90, 3.0).hold(60 * s).turn(-90, 3.0)
    b.set_tas(a.cruise_tas_mps).hold(legs[0] * s).turn(-90, 3.0)
    b.set_tas(a.approach_tas_mps).hold(legs[1]).turn(-90, 3.0).hold(10)
    b.land(elev_msl_m=cfg.arrival_elev_m, glide_rate_mps=a.glide_rate_mps)
    return b


def _touchdown_offset(cfg: ScenarioConfig, b: PlanBuilder) -> tuple[float, float]:
    """(along, cross) runway position of the touchdown relative to the airfield reference
    point, flat-earth integration of the ground velocity on a 0.25 s grid (planning only)."""
    from flightrecon.sim.trajectory import kinematics

    plan = b.plan()
    t = np.arange(0.0, plan.touchdown_s + 0.25, 0.25)
    k = kinematics(plan, t)
    n = np.sum(0.5 * (k.vn_mps[1:] + k.vn_mps[:-1]) * 0.25)
    e = np.sum(0.5 * (k.ve_mps[1:] + k.ve_mps[:-1]) * 0.25)
    r = np.radians(cfg.runway_deg)
    along = n * np.cos(r) + e * np.sin(r) - ARP_OFFSET_M
    cross = -n * np.sin(r) + e * np.cos(r)
    return float(along), float(cross)


def close_circuit(cfg: ScenarioConfig, atm: Atmosphere, extra_s: float) -> tuple[float, float]:
    """Downwind and base leg times that put the touchdown on the centre line at
    :func:`circuit_touchdown_m` (fixed-point iteration; the downwind leg moves the touchdown
    along the runway, the base leg across it)."""
    legs = np.array([215.0, 60.0])
    target = circuit_touchdown_m(cfg)
    for _ in range(6):
        b = route_circuit(cfg, atm, extra_s, tuple(legs))
        along, cross = _touchdown_offset(cfg, b)
        g = cfg.aircraft.cruise_tas_mps
        legs = legs + np.array([(along - target) / (g * cfg.leg_scale),
                                -cross / cfg.aircraft.approach_tas_mps])
        if abs(along - target) < 1.0 and abs(cross) < 1.0:
            break
    if legs.min() <= 20.0:
        raise ValidationError("the circuit cannot be closed in this wind (a leg would vanish)")
    return float(legs[0]), float(legs[1])


def route_regional(cfg: ScenarioConfig, atm: Atmosphere, extra_s: float) -> PlanBuilder:
    """About 300 km: climb to 4500 m with turns, cruise with heading changes, descent,
    approach turns, landing (about 1 h)."""
    a, s = cfg.aircraft, cfg.leg_scale
    b = _builder(cfg, atm, _takeoff_start(cfg), cfg.runway_deg, None)
    cruise = cfg.cruise_alt_msl_m or 4500.0
    b.takeoff(rotate_tas_mps=a.rotate_tas_mps, climb_rate_mps=a.climb_rate_mps)
    b.set_tas(a.climb_tas_mps)
    b.level_off(cfg.airfield.elev_m + 1500.0, wait=False)
    b.hold(60).turn(60, 3.0).hold(120)
    b.change_altitude(cruise, a.climb_rate_mps, wait=False)
    b.set_tas(a.cruise_tas_mps, wait=False)
    b.hold(500 * s).turn(-35, 1.5).hold(700 * s).turn(25, 1.5).hold(600 * s + extra_s)
    b.change_altitude(1200.0, a.descent_rate_mps)
    b.set_tas(a.approach_tas_mps + 15.0, wait=True)
    b.turn(-70, 2.5).hold(90).turn(80, 3.0).hold(40)
    b.set_tas(a.approach_tas_mps)
    b.change_altitude(cfg.arrival_elev_m + 450.0, 4.0).hold(30)
    b.land(elev_msl_m=cfg.arrival_elev_m, glide_rate_mps=a.glide_rate_mps)
    return b


def route_landing(cfg: ScenarioConfig, atm: Atmosphere, extra_s: float) -> PlanBuilder:
    """Approach from 2500 m, 40 km out: descending turns, base, final, landing (about 12 min)."""
    a = cfg.aircraft
    lat, lon = offset_point(cfg.airfield, 22e3, -30e3)
    b = _builder(cfg, atm, (lat, lon, 2500.0), cfg.runway_deg + 70.0, a.cruise_tas_mps)
    b.hold(40).change_altitude(1500.0, 8.0, wait=False)
    b.turn(-40, 2.0).hold(60 + extra_s)
    b.set_tas(a.approach_tas_mps + 20.0, wait=True).turn(-60, 3.0).hold(50).turn(100, 3.0).hold(40)
    b.change_altitude(cfg.arrival_elev_m + 500.0, 6.0, wait=False)
    b.hold(30).turn(-70, 3.0).hold(30)
    b.set_tas(a.approach_tas_mps).hold(60)
    b.land(elev_msl_m=cfg.arrival_elev_m, glide_rate_mps=a.glide_rate_mps)
    return b


def route_seed_ads_arms(cfg: ScenarioConfig, atm: Atmosphere, extra_s: float) -> PlanBuilder:
    """Straight and level at 100 m/s, 1000 m, passing the station (docs/arms.md)."""
    lat, lon = offset_point(cfg.airfield, 15e3, -60e3)
    b = _builder(cfg, atm, (lat, lon, 1000.0), 90.0, 100.0)
    b.hold(cfg.duration_s or 1200.0)
    return b


def route_longhaul(cfg: ScenarioConfig, atm: Atmosphere, extra_s: float) -> PlanBuilder:
    """10 h: climb to 10 500 m, cruise with course changes, descent, landing."""
    a = cfg.aircraft
    b = _builder(cfg, atm, _takeoff_start(cfg), cfg.runway_deg, None)
    cruise = cfg.cruise_alt_msl_m or 10500.0
    b.takeoff(rotate_tas_mps=a.rotate_tas_mps, climb_rate_mps=a.climb_rate_mps)
    b.set_tas(a.climb_tas_mps)
    b.level_off(cfg.airfield.elev_m + 3000.0, wait=False)
    b.hold(90).turn(40, 2.0).hold(300)
    b.change_altitude(cruise, a.climb_rate_mps, wait=False)
    b.set_tas(a.cruise_tas_mps, wait=False)
    # shorter flights (``duration_s``, for benchmarks of the growth with length) shorten the
    # cruise legs; the last leg absorbs the rest of the exact duration
    # (about 3200 s of the route is climb, descent and approach)
    leg = 3000.0 if not cfg.duration_s else min(3000.0, max(30.0, (cfg.duration_s - 3400.0) / 8))
    for k, d in enumerate((20, -30, 15, -25, 30, -10, 20, -15)):
        b.hold(leg + (extra_s if k == 7 else 0.0)).turn(d, 1.0)
    b.hold(600)
    b.change_altitude(1500.0, a.descent_rate_mps)
    b.set_tas(a.approach_tas_mps + 20.0, wait=True).turn(-50, 2.0).hold(60)
    b.set_tas(a.approach_tas_mps)
    b.change_altitude(cfg.arrival_elev_m + 500.0, 5.0).hold(30)
    b.land(elev_msl_m=cfg.arrival_elev_m, glide_rate_mps=a.glide_rate_mps)
    return b
