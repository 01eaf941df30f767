"""Named scenarios and the public entry points :func:`simulate` and :func:`simulate_fleet`.

Scenarios (docs/simulator.md, "Scenarios"): ``circuit``, ``regional``, ``seed-ads-arms``,
``landing``, ``longhaul``.  Each is a :class:`ScenarioConfig` (weather, rates, radar, faults)
plus a route builder; ``simulate(name, seed, **overrides)`` replaces config fields by name
(an unknown name is an error, never ignored).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.errors import ValidationError
from flightrecon.geo.frames import output_plane
from flightrecon.sim.aircraft import (
    JET,
    LIGHT,
    TURBOPROP,
    aircraft_seed,
    draw_aircraft,
)
from flightrecon.sim.jsbsim_scenarios import JSBSIM_SCENARIOS, config_with_overrides
from flightrecon.sim.plan import PlanBuilder
from flightrecon.sim.recorder import record_log, stream
from flightrecon.sim.scenario_config import ScenarioConfig
from flightrecon.sim.routes import (  # noqa: F401 - ARP_OFFSET_M, circuit_touchdown_m: API
    ARP_OFFSET_M,
    close_circuit,
    offset_point,
    route_circuit,
    route_landing,
    route_longhaul,
    route_regional,
    route_seed_ads_arms,
    threshold_point,
    circuit_touchdown_m,
)
from flightrecon.sim.scenario_sensors import json_ready, scenario_sensor_models, scenario_sensor_truth
from flightrecon.sim.result import SimResult
from flightrecon.sim.sensors import Faults, gauss_markov, wrap360
from flightrecon.sim.trajectory import FlightPlan, simulate_truth
from flightrecon.sim.weather import Atmosphere, WindField, qnh_hpa
from flightrecon.types import FlightMeta, Position

__all__ = [
    "SCENARIOS",
    "ScenarioConfig",
    "SimResult",
    "build_plan",
    "scenario_config",
    "simulate",
    "simulate_fleet",
]

@dataclass(frozen=True)
class _Scenario:
    config: ScenarioConfig
    route: Callable[[ScenarioConfig, Atmosphere, float], PlanBuilder]
    target_s: float = 0.0          # exact duration (the last cruise leg absorbs the difference)
    airborne: bool = False


SCENARIOS: dict[str, _Scenario] = {
    "circuit": _Scenario(ScenarioConfig(
        aircraft=LIGHT, wind=WindField(6.0, 0.004, 230.0, 0.02, 1.0, 5.0, 1800.0),
        temp_offset_k=6.0, p_sl_departure_hpa=1006.0, p_sl_arrival_hpa=1006.5,
    ), route_circuit, target_s=900.0),
    "regional": _Scenario(ScenarioConfig(
        aircraft=TURBOPROP, runway_deg=300.0, arrival_elev_m=25.0,
        wind=WindField(8.0, 0.004, 250.0, 0.006, 3.0, 10.0, 3.0 * 3600.0),
        temp_offset_k=8.0, p_sl_departure_hpa=1008.0, p_sl_arrival_hpa=1016.0,
        truth_rate_hz=8.0, loads_hz=8.0, attitude_hz=4.0, airspeed_hz=4.0, baro_hz=2.0,
        gnss_hz=1.0, doppler_hz=2.0, wind_hz=1.0, gnss_dropouts=((1500.0, 600.0),),
        faults=Faults(spikes=3, spike_channels=(("n_norm_g", 1.5), ("tas_mps", 40.0),
                                                ("baro_alt_m", 300.0)),
                      gaps=(("tas_mps", 2000.0, 20.0),)),
    ), route_regional, target_s=3600.0),
    "seed-ads-arms": _Scenario(ScenarioConfig(
        aircraft=TURBOPROP, airfield=Position(40.0, 49.0, 0.0), arrival_elev_m=0.0,
        truth_rate_hz=4.0, loads_hz=4.0, attitude_hz=1.0, airspeed_hz=1.0, baro_hz=1.0,
        gnss_hz=0.0, radar_scan_s=1.0, radar_range_sd_m=50.0, radar_azimuth_sd_deg=0.25,
        airdata_gm_sigma_mps=20.0, airdata_gm_tau_s=360.0, duration_s=1200.0,
    ), route_seed_ads_arms, airborne=True),
    "landing": _Scenario(ScenarioConfig(
        aircraft=TURBOPROP, airfield=Position(40.0, 49.0, 0.0), runway_deg=100.0,
        arrival_elev_m=-20.0, wind=WindField(5.0, 0.003, 30.0, 0.01, 1.0, 5.0, 1800.0),
        temp_offset_k=-5.0, p_sl_departure_hpa=1021.0, p_sl_arrival_hpa=1021.0,
        truth_rate_hz=8.0, loads_hz=8.0, attitude_hz=8.0, airspeed_hz=4.0, baro_hz=4.0,
        gnss_hz=1.0, radar_scan_s=4.0, radar_range_sd_m=50.0, radar_azimuth_sd_deg=0.15,
        radar_outages=((400.0, 60.0),), station_offset_m=(-1500.0, 1000.0),
    ), route_landing, airborne=True),
    "longhaul": _Scenario(ScenarioConfig(
        aircraft=JET, runway_deg=230.0, arrival_elev_m=120.0,
        wind=WindField(6.0, 0.002, 260.0, 0.004, 4.0, 15.0, 4.0 * 3600.0),
        temp_offset_k=-4.0, p_sl_departure_hpa=1011.0, p_sl_arrival_hpa=1019.0,
        doppler_hz=4.0, wind_hz=1.0, gnss_dropouts=((12000.0, 900.0),),
    ), route_longhaul, target_s=36000.0 - 1.0 / 16.0),
}


def scenario_config(name: str, **overrides: Any) -> ScenarioConfig:
    """The configuration of scenario ``name`` with ``overrides`` applied.

    Raises
    ------
    ValidationError
        Unknown scenario or unknown override name.
    """
    if name not in SCENARIOS:
        raise ValidationError(f"unknown scenario '{name}'; choose one of "
                              f"{sorted(SCENARIOS) + sorted(JSBSIM_SCENARIOS)}")
    return config_with_overrides(SCENARIOS[name].config, overrides)


# --------------------------------------------------------------------------------------------
# running


def build_plan(name: str, cfg: ScenarioConfig) -> tuple[FlightPlan, Atmosphere]:
    """The flight plan and atmosphere of scenario ``name`` under ``cfg`` (exact duration for
    scenarios with a target; the circuit closed on the runway centre line)."""
    sc = SCENARIOS[name]
    atm = Atmosphere(cfg.temp_offset_k, 100.0 * cfg.p_sl_departure_hpa,
                     100.0 * cfg.p_sl_arrival_hpa, 1.0)

    def route_for(atm_: Atmosphere, extra_: float):
        if name != "circuit":
            return lambda c, a, x: sc.route(c, a, x)
        legs = close_circuit(cfg, atm_, extra_)
        return lambda c, a, x: route_circuit(c, a, x, legs)

    target_s = sc.target_s
    if name == "longhaul" and cfg.duration_s > 0.0:
        target_s = cfg.duration_s - 1.0 / cfg.truth_rate_hz
    if name == "circuit" and cfg.duration_s > 0.0:
        target_s = cfg.duration_s  # the record's length: the circuit waits lined up the longer

    def absorb(t_natural: float) -> float:
        # the circuit waits lined up, the others fly a longer cruise leg; a circuit stretched
        # by a fleet's leg_scale and wind may simply last longer than its nominal 15 minutes
        if target_s <= 0.0:
            return 0.0
        extra_ = target_s - t_natural
        if extra_ < 0.0:
            if name == "circuit":
                return 0.0
            raise ValidationError(f"the {name} route is longer than its {target_s} s")
        return extra_

    route = route_for(atm, 0.0)
    extra = absorb(route(cfg, atm, 0.0).t)
    if name == "circuit" and extra > 0.0:  # the stand-still shifts the pattern in time
        route = route_for(atm, extra)
        extra = absorb(route(cfg, atm, 0.0).t)
    b = route(cfg, atm, extra)
    atm = replace(atm, t_end_s=b.t)
    b = route(cfg, atm, extra)
    return b.plan(b.t), atm


def _run(name: str, cfg: ScenarioConfig, seed: int) -> SimResult:
    sc = SCENARIOS[name]
    cfg = _drawn_end_points(cfg, seed)
    plan, atm = build_plan(name, cfg)
    # a record that starts airborne: departure = the ground point below its first sample; an
    # airfield departure carries the true direction of its runway and its threshold, where the
    # take-off roll starts (as a runway database would)
    thr_lat, thr_lon = threshold_point(cfg)
    field = replace(cfg.airfield, runway_true_deg=float(cfg.runway_deg % 360.0),
                    threshold_lat_deg=thr_lat, threshold_lon_deg=thr_lon)
    departure = (Position(float(plan.lat0_deg), float(plan.lon0_deg), cfg.arrival_elev_m)
                 if sc.airborne else field)
    pre_meta = FlightMeta(departure=departure, geoid_undulation_m=cfg.geoid_undulation_m)
    truth = simulate_truth(plan, cfg.truth_rate_hz, output_plane(pre_meta))
    events = _events(plan, truth, cfg)
    arrival = field if name == "circuit" else _arrival(plan, truth, cfg)
    station = None
    if cfg.radar_scan_s > 0:
        base = cfg.airfield if name == "seed-ads-arms" else arrival
        lat, lon = offset_point(base, *cfg.station_offset_m)
        station = Position(lat, lon, base.elev_m)
    suite = scenario_sensor_models(cfg, station)
    airdata_truth, extra_truth = _airdata_error(cfg, truth, seed)
    rec = record_log(truth, suite, seed, cfg.truth_rate_hz, cfg.faults, airdata_truth)
    extra_truth.update(rec.truth_extra)
    if extra_truth:
        truth = truth.assign(**extra_truth)

    meta = FlightMeta(
        aircraft_id=cfg.aircraft.aircraft_id, flight_id=cfg.flight_id, epoch_utc=cfg.epoch_utc,
        departure=departure, arrival=arrival, station=station,
        gnss_lever_arm_m=_three(cfg.aircraft.gnss_lever_arm_m),
        gnss_alt_datum="ellipsoid", baro_datum="pressure",
        qnh_departure_hpa=round(qnh_hpa(atm, departure.elev_m, 0.0), 2),
        qnh_arrival_hpa=round(qnh_hpa(atm, arrival.elev_m, plan.t_end_s), 2),
        geoid_undulation_m=cfg.geoid_undulation_m,
    )
    sensor_truth = scenario_sensor_truth(name, seed, cfg, suite, events, rec.faults)
    return SimResult(log=rec.log, truth=truth, meta=meta, sensor_truth=json_ready(sensor_truth))


def _three(v: Any) -> tuple[float, float, float]:
    """Three floats (a lever arm)."""
    return (float(v[0]), float(v[1]), float(v[2]))


def _drawn_end_points(cfg: ScenarioConfig, seed: int) -> ScenarioConfig:
    """The touchdown and line-up distances drawn from their spreads (seeded), where given."""
    if cfg.touchdown_sd_m > 0.0:
        d = stream(seed, "touchdown").normal(cfg.touchdown_m, cfg.touchdown_sd_m)
        cfg = replace(cfg, touchdown_m=float(np.clip(d, 100.0, 1000.0)), touchdown_sd_m=0.0)
    if cfg.lineup_sd_m > 0.0:
        d = stream(seed, "lineup").normal(cfg.lineup_m, cfg.lineup_sd_m)
        cfg = replace(cfg, lineup_m=float(d), lineup_sd_m=0.0)
    return cfg


def _events(plan: Any, truth: pd.DataFrame, cfg: ScenarioConfig) -> dict[str, Any]:
    """Lift-off and touchdown of the truth (time, position) and the end points' distances."""
    t = truth["t_s"].to_numpy()
    events: dict[str, Any] = {"liftoff_t_s": None, "touchdown_t_s": None,
                              "touchdown_past_threshold_m": cfg.touchdown_m,
                              "lineup_past_threshold_m": cfg.lineup_m}
    for key, t_ev in (("liftoff", plan.liftoff_s), ("touchdown", plan.touchdown_s)):
        if np.isfinite(t_ev):
            i = int(np.searchsorted(t, t_ev))
            events[f"{key}_t_s"] = float(t_ev)
            events[f"{key}_lat_deg"] = float(truth["lat_deg"].iloc[i])
            events[f"{key}_lon_deg"] = float(truth["lon_deg"].iloc[i])
    return events


def _arrival(plan: Any, truth: pd.DataFrame, cfg: ScenarioConfig) -> Position:
    """The arrival airfield: reference point ``ARP_OFFSET_M`` down the landing runway (its
    direction the track at touchdown, its threshold ``touchdown_m`` behind the touchdown), or
    the last position (and height) of a record that ends airborne."""
    if np.isfinite(plan.touchdown_s):
        t = truth["t_s"].to_numpy()
        i = int(np.searchsorted(t, plan.touchdown_s))
        trk = np.radians(truth["track_deg"].iloc[i])
        td = Position(float(truth["lat_deg"].iloc[i]), float(truth["lon_deg"].iloc[i]))
        lat, lon = offset_point(td, ARP_OFFSET_M * np.cos(trk), ARP_OFFSET_M * np.sin(trk))
        thr_lat, thr_lon = offset_point(td, -cfg.touchdown_m * np.cos(trk),
                                   -cfg.touchdown_m * np.sin(trk))
        # the landing runway's direction: the track at touchdown (on the centre line)
        return Position(lat, lon, cfg.arrival_elev_m,
                        runway_true_deg=float(np.degrees(trk) % 360.0),
                        threshold_lat_deg=thr_lat, threshold_lon_deg=thr_lon)
    # a record that ends in the air ends at the aircraft's own position, its height included
    # (a last known position, as a radar hand-off gives it: docs/signals.md, "An arrival for a
    # record that ends airborne")
    last = truth.iloc[-1]
    return Position(float(last["lat_deg"]), float(last["lon_deg"]), float(last["alt_msl_m"]))


def _airdata_error(cfg: ScenarioConfig, truth: pd.DataFrame, seed: int
                   ) -> tuple[pd.DataFrame | None, dict[str, np.ndarray]]:
    """The air data seen through a Gauss-Markov error per axis (the seed ADS/ARMS scenario),
    and the error series for the truth table; ``(None, {})`` without one."""
    if not cfg.airdata_gm_sigma_mps > 0.0:
        return None, {}
    t = truth["t_s"].to_numpy()
    rng = stream(seed, "airdata")
    dt = 1.0 / cfg.truth_rate_hz
    dv_e = gauss_markov(t.size, dt, cfg.airdata_gm_sigma_mps, cfg.airdata_gm_tau_s, rng)
    dv_n = gauss_markov(t.size, dt, cfg.airdata_gm_sigma_mps, cfg.airdata_gm_tau_s, rng)
    ve = truth["ve_mps"].to_numpy() + dv_e
    vn = truth["vn_mps"].to_numpy() + dv_n
    airdata_truth = truth.assign(tas_mps=np.hypot(ve, vn),
                                 heading_deg=wrap360(np.degrees(np.arctan2(ve, vn))))
    return airdata_truth, {"airdata_err_e_mps": dv_e, "airdata_err_n_mps": dv_n}


def simulate(scenario: str, seed: int = 0, **overrides: Any) -> SimResult:
    """Simulate a named scenario.

    Parameters
    ----------
    scenario : ``circuit``, ``regional``, ``seed-ads-arms``, ``landing`` or ``longhaul`` (the
        point-mass truth), or a JSBSim scenario (``jsbsim-circuit``, ``jsbsim-xc``,
        ``jsbsim-jet``, ``jsbsim-spiral``, ``jsbsim-spin``, ``jsbsim-airwork``,
        ``jsbsim-holding``, ``jsbsim-goaround``; ``airframe=`` picks the aircraft:
        :func:`flightrecon.sim.jsbsim_truth.simulate_jsbsim`, needs the ``jsbsim`` extra)
    seed : noise seed (same seed, same numbers, byte-identical files)
    **overrides : :class:`ScenarioConfig` (or
        :class:`~flightrecon.sim.jsbsim_scenarios.JsbsimConfig`) fields to replace (unknown
        names are an error)

    Raises
    ------
    ValidationError
        Unknown scenario or setting, a negative seed, or settings that cannot be flown.
    """
    if scenario in JSBSIM_SCENARIOS:
        from flightrecon.sim.jsbsim_truth import simulate_jsbsim

        return simulate_jsbsim(scenario, seed, **overrides)
    _check_seed(seed)
    return _run(scenario, scenario_config(scenario, **overrides), seed)


def _check_seed(seed: int) -> None:
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValidationError(f"the seed must be a non-negative integer, got {seed!r}")


def simulate_fleet(aircraft_id: str, n_flights: int, seed: int = 0,
                   scenario: str = "circuit", **overrides: Any) -> tuple[SimResult, ...]:
    """``n_flights`` flights of one airframe (same persistent errors and performance), differing
    in route (``leg_scale``), weather (wind, temperature, sea-level pressure) and noise.

    The airframe is :func:`~flightrecon.sim.aircraft.draw_aircraft` of ``aircraft_id`` and
    ``seed`` on the scenario's aircraft type; flight ``i`` draws its weather from
    ``SeedSequence([seed, crc32(id), i])``.
    """
    _check_seed(seed)
    if scenario in JSBSIM_SCENARIOS:
        raise ValidationError("fleets (simulate_fleet, --fleet-flights) use the point-mass "
                              "scenarios; fly JSBSim scenarios with one seed each")
    if n_flights < 1:
        raise ValidationError("a fleet needs at least one flight")
    base = scenario_config(scenario, **overrides)
    aircraft = draw_aircraft(aircraft_id, seed, base.aircraft)
    out = []
    root = aircraft_seed(aircraft_id, seed)
    for i in range(n_flights):
        ss = np.random.SeedSequence(root.entropy, spawn_key=(1000 + i,))
        rng = np.random.Generator(np.random.PCG64(ss))
        w = base.wind
        wind = replace(w, speed0_mps=float(rng.uniform(0.0, 1.5) * max(w.speed0_mps, 4.0)),
                       from0_deg=float(rng.uniform(0.0, 360.0)))
        cfg = replace(base, aircraft=aircraft, flight_id=f"F{i + 1:02d}", wind=wind,
                      temp_offset_k=float(rng.normal(0.0, 8.0)),
                      p_sl_departure_hpa=float(rng.normal(1013.0, 8.0)),
                      leg_scale=float(rng.uniform(0.8, 1.2)))
        cfg = replace(cfg, p_sl_arrival_hpa=cfg.p_sl_departure_hpa + float(rng.normal(0, 2.0)))
        noise_seed = int(ss.generate_state(1)[0])
        out.append(_run(scenario, cfg, noise_seed))
    return tuple(out)
