"""``simulate_jsbsim(name, seed)``: a JSBSim flight, its truth, the recorder on top, metadata.

The truth has the columns of the point-mass simulator (:data:`~flightrecon.sim.TRUTH_COLUMNS`,
same meanings; docs/simulator.md) plus ``cas_mps``, ``mach``, ``agl_m``, ``beta_deg``,
``p_rps, q_rps, r_rps``, ``wind_d_mps``, ``wind_mean_n_mps, wind_mean_e_mps`` (the mean wind
without JSBSim's turbulence) and ``phase`` (index of the schedule's phase).  Where JSBSim gives
a quantity it is JSBSim's (docs/jsbsim.md); the recorder (:func:`~flightrecon.sim.recorder.
record_log`) and the file writer are the project's own, so a JSBSim flight is written and read
exactly like a point-mass one.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.errors import ValidationError
from flightrecon.geo.atmosphere import isa_pressure_pa, pressure_altitude_m
from flightrecon.geo.frames import output_plane
from flightrecon.geo.gravity import normal_gravity
from flightrecon.sim.fdm import Fdm
from flightrecon.sim.jsbsim_flight import fly
from flightrecon.sim.jsbsim_scenarios import (
    AIRFRAMES,
    JsbsimConfig,
    draw_weather,
    jsbsim_config,
    persistent_aircraft,
    recorder_faults,
    schedule,
)
from flightrecon.sim.recorder import record_log
from flightrecon.sim.result import SimResult
from flightrecon.sim.scenario_sensors import json_ready
from flightrecon.sim.sensors import (
    AirspeedSensor,
    AttitudeSensor,
    BaroSensor,
    GnssReceiver,
    LoadFactorSensor,
    SensorSuite,
)
from flightrecon.sim.trajectory import TRUTH_COLUMNS
from flightrecon.types import FlightMeta, Position

__all__ = ["simulate_jsbsim"]

SETTLE_S = 4.0
"""JSBSim runs this long before ``t = 0`` (engine running, the aircraft settled on its gear)."""


def _qnh_hpa(p_pa: float, elev_msl_m: float) -> float:
    """Altimeter setting with which an altimeter at ``elev_msl_m`` reads its elevation."""
    pa = float(pressure_altitude_m(p_pa))
    return round(float(isa_pressure_pa(pa - elev_msl_m)) / 100.0, 2)


def _truth(cols: dict[str, np.ndarray], cfg: JsbsimConfig, meta: FlightMeta,
           wind_mean: tuple[np.ndarray, np.ndarray]) -> pd.DataFrame:
    t = np.round(np.arange(cols["t"].size) / cfg.truth_rate_hz, 9)
    h_msl = cols["h"]
    h_ell = h_msl + cfg.geoid_undulation_m
    vn, ve, vu = cols["vn"], cols["ve"], -cols["vd"]
    dt = 1.0 / cfg.truth_rate_hz
    acc = [np.gradient(v, dt) for v in (vn, ve, vu)]
    east, north, up = output_plane(meta).forward(cols["lat"], cols["lon"], h_ell)
    data = {
        "t_s": t, "lat_deg": cols["lat"], "lon_deg": cols["lon"], "alt_m": h_ell,
        "alt_msl_m": h_msl, "north_m": north, "east_m": east, "up_m": up,
        "vn_mps": vn, "ve_mps": ve, "vu_mps": vu,
        "an_mps2": acc[0], "ae_mps2": acc[1], "au_mps2": acc[2],
        "roll_deg": cols["phi"], "pitch_deg": cols["theta"], "heading_deg": cols["psi"],
        "tas_mps": cols["vt"], "wind_n_mps": cols["wn"], "wind_e_mps": cols["we"],
        "pressure_alt_m": pressure_altitude_m(cols["p_pa"]), "on_ground": cols["wow"].astype(bool),
        "n_long_g": cols["n_long"], "n_lat_g": cols["n_lat"], "n_norm_g": cols["n_norm"],
        "track_deg": cols["track"], "gs_mps": cols["gs"], "alpha_deg": cols["alpha"],
        "sat_degc": cols["t_k"] - 273.15, "static_pressure_pa": cols["p_pa"],
        "gravity_mps2": normal_gravity(cols["lat"], h_ell),
    }
    extra = {"cas_mps": cols["vc"], "mach": cols["mach"], "agl_m": cols["agl"],
             "beta_deg": cols["beta"], "p_rps": cols["p"], "q_rps": cols["q"],
             "r_rps": cols["r"], "wind_d_mps": cols["wd"], "wind_mean_n_mps": wind_mean[0],
             "wind_mean_e_mps": wind_mean[1], "phase": cols["phase"].astype(np.int16)}
    frame = pd.DataFrame({k: np.asarray(data[k]) for k in TRUTH_COLUMNS})
    return frame.assign(**extra)


def scenario_sensor_models(cfg: JsbsimConfig, aircraft) -> SensorSuite:
    if cfg.ideal_sensors:
        return SensorSuite(
            LoadFactorSensor(cfg.loads_hz, (0.0,) * 3, (0.0,) * 3, (0.0,) * 3),
            AttitudeSensor(cfg.attitude_hz, 0.0, 0.0, 0.0, 0.0),
            AirspeedSensor(cfg.airspeed_hz, 0.0, 0.0, 0.0),
            BaroSensor(cfg.baro_hz, 0.0, 0.0, 0.0, 0.0, 0.0),
            GnssReceiver(cfg.gnss_hz, 0.0, 0.0, 0.0) if cfg.gnss_hz > 0 else None)
    a = aircraft
    return SensorSuite(
        LoadFactorSensor(cfg.loads_hz, a.accel_bias_g, a.accel_scale,
                         quantum_g=cfg.loads_quantum_g, range_g=cfg.loads_range_g),
        AttitudeSensor(cfg.attitude_hz, heading_bias_deg=a.heading_bias_deg,
                       roll_bias_deg=a.roll_bias_deg, pitch_bias_deg=a.pitch_bias_deg,
                       quantum_deg=cfg.attitude_quantum_deg),
        AirspeedSensor(cfg.airspeed_hz, scale=a.airspeed_scale, range_mps=cfg.tas_range_mps),
        BaroSensor(cfg.baro_hz, bias_m=a.baro_bias_m),
        GnssReceiver(cfg.gnss_hz, lever_arm_m=a.gnss_lever_arm_m) if cfg.gnss_hz > 0 else None)


def _airfield(rw, length_m: float) -> Position:
    """An airfield from its runway: reference point at the runway's middle, with the runway's
    direction and threshold."""
    lat, lon = rw.point(0.5 * length_m)
    return Position(lat, lon, rw.elev_m, runway_true_deg=float(rw.heading_deg % 360.0),
                    threshold_lat_deg=rw.lat_deg, threshold_lon_deg=rw.lon_deg)


def simulate_jsbsim(name: str, seed: int = 0, **overrides: Any):
    """Fly JSBSim scenario ``name`` (:mod:`flightrecon.sim.jsbsim_scenarios`) for ``seed``.

    Returns a :class:`~flightrecon.sim.scenarios.SimResult`; the same seed gives the same
    numbers (JSBSim is deterministic and its turbulence seeded).

    Raises
    ------
    ValidationError
        Unknown scenario or setting, or a flight the autopilot could not fly.
    FlightReconError
        When the ``jsbsim`` package is not installed.
    """
    cfg = jsbsim_config(name, **overrides)
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ValidationError(f"the seed must be a non-negative integer, got {seed!r}")
    per_control, per_sample = _steps(cfg)
    weather = cfg.weather or draw_weather(name, seed)
    airframe = AIRFRAMES[cfg.airframe]
    phases, dest, max_s, terrain = schedule(name, cfg)
    rw = phases[1].runway
    fdm = Fdm(airframe, weather, *rw.point(10.0), rw.elev_m, rw.heading_deg, cfg.dt_s,
              full_tanks=cfg.full_tanks and cfg.scale >= 0.5)
    fdm.f["fcs/left-brake-cmd-norm"] = fdm.f["fcs/right-brake-cmd-norm"] = 1.0
    fdm.run(round(SETTLE_S / cfg.dt_s))
    fdm.t0_s = fdm.f.get_sim_time()
    cols, events = fly(fdm, phases, per_control, per_sample, max_s, terrain)

    departure = _airfield(rw, cfg.runway_length_m)
    if dest is not None:
        arrival = _airfield(dest, cfg.runway_length_m)
    else:  # the wreckage
        arrival = Position(float(cols["lat"][-1]), float(cols["lon"][-1]), float(fdm.terrain_m))
    meta0 = FlightMeta(departure=departure, geoid_undulation_m=cfg.geoid_undulation_m)
    wind_mean = weather.wind.velocity(cols["h"], cols["t"])
    truth = _truth(cols, cfg, meta0, wind_mean)
    aircraft = persistent_aircraft(name, cfg, seed)
    suite = scenario_sensor_models(cfg, aircraft)
    rec = record_log(truth, suite, seed, cfg.truth_rate_hz, recorder_faults(cfg))
    # the antenna where the receiver has it (at the centre of mass with ideal sensors)
    lever = tuple(float(v) for v in (suite.gnss.lever_arm_m if suite.gnss is not None
                                     else aircraft.gnss_lever_arm_m))
    end_elev = arrival.elev_m
    meta = FlightMeta(
        aircraft_id=aircraft.aircraft_id, flight_id=cfg.flight_id, epoch_utc=cfg.epoch_utc,
        departure=departure, arrival=arrival,
        gnss_lever_arm_m=lever,
        gnss_alt_datum="ellipsoid", baro_datum="pressure",
        qnh_departure_hpa=_qnh_hpa(cols["p_pa"][0], rw.elev_m + cols["agl"][0]),
        qnh_arrival_hpa=_qnh_hpa(cols["p_pa"][-1], end_elev + max(cols["agl"][-1], 0.0)),
        geoid_undulation_m=cfg.geoid_undulation_m)
    sensor_truth = {
        "scenario": name, "seed": int(seed), "truth_source": "jsbsim",
        "jsbsim": {"model": airframe.model, "dt_s": cfg.dt_s, "control_hz": cfg.control_hz},
        "aircraft": json_ready(aircraft),
        "persistent_errors": {
            "accel_bias_g": list(suite.loads.bias_g), "accel_scale": list(suite.loads.scale),
            "heading_bias_deg": suite.attitude.heading_bias_deg,
            "roll_bias_deg": suite.attitude.roll_bias_deg,
            "pitch_bias_deg": suite.attitude.pitch_bias_deg,
            "airspeed_scale": suite.airspeed.scale, "baro_bias_m": suite.baro.bias_m,
            "gnss_lever_arm_m": list(lever)},
        "sensors": {s.group: json_ready(s) for s in suite.fitted()},
        "weather": json_ready(replace(weather)),
        "events": _truth_events(events, truth),
        "faults": [json_ready(f) for f in rec.faults],
        "truth_rate_hz": cfg.truth_rate_hz,
    }
    return SimResult(log=rec.log, truth=truth, meta=meta, sensor_truth=json_ready(sensor_truth))


def _steps(cfg: Any) -> tuple[int, int]:
    """JSBSim steps per control update and control updates per truth sample.

    Raises
    ------
    ValidationError
        A recorder channel switched off, or rates that do not divide each other.
    """
    for rate in (cfg.loads_hz, cfg.attitude_hz, cfg.airspeed_hz, cfg.baro_hz):
        if rate <= 0:
            raise ValidationError("JSBSim scenarios record every recorder channel (rate > 0)")
    per_control = round(1.0 / (cfg.dt_s * cfg.control_hz))
    per_sample = round(cfg.control_hz / cfg.truth_rate_hz)
    if abs(per_control * cfg.dt_s * cfg.control_hz - 1.0) > 1e-9 or \
            abs(per_sample * cfg.truth_rate_hz - cfg.control_hz) > 1e-9:
        raise ValidationError("dt_s must divide 1/control_hz and truth_rate_hz divide "
                              "control_hz")
    return per_control, per_sample


def _truth_events(events: dict[str, Any], truth: pd.DataFrame) -> dict[str, Any]:
    """The flight's events with the truth's position at each, and at an impact its speed,
    vertical speed and attitude at the last sample before the contact."""
    t = truth["t_s"].to_numpy()
    ev: dict[str, Any] = {k: float(v) for k, v in events.items()}
    for key in ("liftoff", "touchdown", "impact"):
        if f"{key}_t_s" in ev:
            i = int(np.searchsorted(t, ev[f"{key}_t_s"] - 1e-9))
            ev[f"{key}_lat_deg"] = float(truth["lat_deg"].iloc[i])
            ev[f"{key}_lon_deg"] = float(truth["lon_deg"].iloc[i])
    if "impact_t_s" in ev:  # the last sample before the contact
        i = truth.shape[0] - 2
        ev["impact_speed_mps"] = float(math.sqrt(truth["gs_mps"].iloc[i] ** 2
                                                 + truth["vu_mps"].iloc[i] ** 2))
        ev["impact_vu_mps"] = float(truth["vu_mps"].iloc[i])
        ev["impact_roll_deg"] = float(truth["roll_deg"].iloc[i])
        ev["impact_pitch_deg"] = float(truth["pitch_deg"].iloc[i])
    return ev
