"""The sensor suite of a point-mass scenario (:mod:`flightrecon.sim.scenarios`) and the
``<stem>.sensors.json`` document of what was drawn (docs/simulator.md)."""

from __future__ import annotations

import dataclasses
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from flightrecon.sim.sensors import (
    AirspeedSensor,
    ArmsRadar,
    AttitudeSensor,
    BaroSensor,
    DopplerSensor,
    GnssReceiver,
    LoadFactorSensor,
    SensorSuite,
    WindSensor,
)
from flightrecon.types import Position

if TYPE_CHECKING:
    from flightrecon.sim.scenarios import ScenarioConfig


def scenario_sensor_suite(cfg: ScenarioConfig, station: Position | None) -> SensorSuite:
    """The scenario's sensors: its aircraft's errors, ideal where asked, the air data of
    the ADS/ARMS seed scenario without their own errors, GNSS, radar, Doppler, wind."""
    a = cfg.aircraft
    ideal = cfg.ideal_sensors
    air_gm = cfg.airdata_gm_sigma_mps > 0.0

    def rate(x):
        return x if x > 0 else None

    loads = LoadFactorSensor(cfg.loads_hz, a.accel_bias_g, a.accel_scale)
    att = AttitudeSensor(cfg.attitude_hz, heading_bias_deg=a.heading_bias_deg,
                         roll_bias_deg=a.roll_bias_deg, pitch_bias_deg=a.pitch_bias_deg)
    aspd = AirspeedSensor(cfg.airspeed_hz, scale=a.airspeed_scale)
    baro = BaroSensor(cfg.baro_hz, bias_m=a.baro_bias_m)
    if air_gm:  # air data = ground velocity + Gauss-Markov error, nothing else (docs/arms.md)
        att = replace(att, heading_noise_sd_deg=0.0, heading_bias_deg=0.0)
        aspd = replace(aspd, scale=0.0, noise_sd_mps=0.0, lag_s=0.0)
    if ideal:
        loads = LoadFactorSensor(cfg.loads_hz, (0.0,) * 3, (0.0,) * 3, (0.0,) * 3)
        att = AttitudeSensor(cfg.attitude_hz, 0.0, 0.0, 0.0, 0.0)
        aspd = AirspeedSensor(cfg.airspeed_hz, 0.0, 0.0, 0.0)
        baro = BaroSensor(cfg.baro_hz, 0.0, 0.0, 0.0, 0.0, 0.0)
    gnss = None
    if rate(cfg.gnss_hz):
        gnss = GnssReceiver(cfg.gnss_hz, dropouts=cfg.gnss_dropouts,
                            lever_arm_m=a.gnss_lever_arm_m)
        if ideal:
            gnss = replace(gnss, pos_sd_h_m=0.0, pos_sd_v_m=0.0, vel_sd_mps=0.0)
    radar = None
    if cfg.radar_scan_s > 0 and station is not None:
        radar = ArmsRadar(station, cfg.geoid_undulation_m, cfg.radar_scan_s,
                          cfg.radar_range_sd_m, cfg.radar_azimuth_sd_deg,
                          cfg.radar_elevation_sd_deg, cfg.radar_outages)
    doppler = (DopplerSensor(cfg.doppler_hz, a.doppler_scale, a.drift_bias_deg)
               if rate(cfg.doppler_hz) else None)
    wind = (WindSensor(cfg.wind_hz, speed_bias_mps=1.0, from_bias_deg=-4.0,
                       speed_gm_sd_mps=2.0, speed_gm_tau_s=900.0, from_gm_sd_deg=5.0,
                       from_gm_tau_s=900.0) if rate(cfg.wind_hz) else None)
    return SensorSuite(loads, att, aspd, baro, gnss, radar, doppler, wind)


def json_ready(x: Any) -> Any:
    """``x`` with dataclasses, tuples and numpy scalars turned into JSON-ready values."""
    if dataclasses.is_dataclass(x):
        return {f.name: json_ready(getattr(x, f.name)) for f in dataclasses.fields(x)}
    if isinstance(x, (tuple, list)):
        return [json_ready(v) for v in x]
    if isinstance(x, dict):
        return {str(k): json_ready(v) for k, v in x.items()}
    if isinstance(x, (np.floating, np.integer)):
        return x.item()
    return x


def sensor_truth_document(name: str, seed: int, cfg: ScenarioConfig, suite: Any,
                  events: dict[str, Any], faults: Any) -> dict[str, Any]:
    """The ``<stem>.sensors.json`` document: the errors drawn, the sensors, the weather."""
    a = cfg.aircraft
    return {
        "scenario": name, "seed": int(seed),
        "aircraft": json_ready(a),
        "persistent_errors": {
            "accel_bias_g": list(suite.loads.bias_g), "accel_scale": list(suite.loads.scale),
            "heading_bias_deg": suite.attitude.heading_bias_deg,
            "roll_bias_deg": suite.attitude.roll_bias_deg,
            "pitch_bias_deg": suite.attitude.pitch_bias_deg,
            "airspeed_scale": suite.airspeed.scale, "baro_bias_m": suite.baro.bias_m,
            "doppler_scale": suite.doppler.scale if suite.doppler else None,
            "drift_bias_deg": suite.doppler.drift_bias_deg if suite.doppler else None,
            "wind_speed_bias_mps": suite.wind.speed_bias_mps if suite.wind else None,
            "wind_from_bias_deg": suite.wind.from_bias_deg if suite.wind else None,
            "gnss_lever_arm_m": list(a.gnss_lever_arm_m),
        },
        "airdata_error_gm": ({"sigma_mps": cfg.airdata_gm_sigma_mps,
                              "tau_s": cfg.airdata_gm_tau_s,
                              "series": ["airdata_err_e_mps", "airdata_err_n_mps"]}
                             if cfg.airdata_gm_sigma_mps > 0 else None),
        "sensors": {s.group: json_ready(s) for s in suite.fitted()},
        "weather": {"wind": json_ready(cfg.wind), "temp_offset_k": cfg.temp_offset_k,
                    "p_sl_departure_hpa": cfg.p_sl_departure_hpa,
                    "p_sl_arrival_hpa": cfg.p_sl_arrival_hpa},
        "events": events,
        "faults": [json_ready(f) for f in faults],
        "truth_rate_hz": cfg.truth_rate_hz,
    }
