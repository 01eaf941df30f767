"""The settings of a simulated scenario run (:class:`ScenarioConfig`), apart from the scenarios
that use them (:mod:`flightrecon.sim.scenarios`), so that the route builders and the sensor
suites can name its type without importing the scenarios."""

from __future__ import annotations

from dataclasses import dataclass

from flightrecon.sim.aircraft import LIGHT, Aircraft
from flightrecon.sim.sensors import Faults
from flightrecon.sim.weather import WindField
from flightrecon.types import Position

__all__ = ["CALM", "DEFAULT_AIRFIELD", "NO_FAULTS", "ScenarioConfig"]

DEFAULT_AIRFIELD = Position(40.46, 50.05, 3.0)
"""Departure airfield of the circuit, regional and long-haul scenarios (MSL elevation)."""
CALM = WindField()
NO_FAULTS = Faults()


@dataclass(frozen=True)
class ScenarioConfig:
    """Settings of a scenario run (override any field by name in :func:`simulate`).

    Rates are in Hz and must divide ``truth_rate_hz``; 0 disables a channel.  Positions: MSL
    elevations.  ``leg_scale`` stretches the route's straight legs (fleet variation).
    ``duration_s`` sets the record's length of the ``longhaul`` (its cruise absorbs it) and of
    the ``circuit`` (it waits lined up the longer; a circuit longer than that keeps its own).
    ``touchdown_m`` is the touchdown's distance past the landing threshold (the circuit flies
    to it; a landing places the threshold that far before its touchdown); with
    ``touchdown_sd_m`` > 0 each seed draws it from N(touchdown_m, touchdown_sd_m^2),
    clipped to [100, 1000] m (a pilot's touchdown dispersion).  The take-off roll starts
    :data:`ARP_OFFSET_M` before the airfield reference point, ``lineup_m`` past the departure
    threshold (with ``lineup_sd_m`` > 0 drawn per seed from N(lineup_m, lineup_sd_m^2): where the
    crew lines up).
    """

    aircraft: Aircraft = LIGHT
    flight_id: str = "F1"
    epoch_utc: str = "2026-01-01T10:00:00Z"
    airfield: Position = DEFAULT_AIRFIELD
    runway_deg: float = 160.0
    arrival_elev_m: float = 3.0
    geoid_undulation_m: float = -22.0
    wind: WindField = CALM
    temp_offset_k: float = 0.0
    p_sl_departure_hpa: float = 1013.25
    p_sl_arrival_hpa: float = 1013.25
    truth_rate_hz: float = 16.0
    loads_hz: float = 16.0
    attitude_hz: float = 8.0
    airspeed_hz: float = 4.0
    baro_hz: float = 4.0
    gnss_hz: float = 1.0
    doppler_hz: float = 0.0
    wind_hz: float = 0.0
    gnss_dropouts: tuple[tuple[float, float], ...] = ()
    radar_scan_s: float = 0.0
    radar_range_sd_m: float = 50.0
    radar_azimuth_sd_deg: float = 0.25
    radar_elevation_sd_deg: float = 0.1
    radar_outages: tuple[tuple[float, float], ...] = ()
    station_offset_m: tuple[float, float] = (0.0, 0.0)
    airdata_gm_sigma_mps: float = 0.0
    airdata_gm_tau_s: float = 360.0
    duration_s: float = 0.0
    cruise_alt_msl_m: float = 0.0
    leg_scale: float = 1.0
    faults: Faults = NO_FAULTS
    ideal_sensors: bool = False
    touchdown_m: float = 300.0
    touchdown_sd_m: float = 0.0
    lineup_m: float = 0.0
    lineup_sd_m: float = 0.0
