"""flightrecon.sim: truth simulator and sample logs (docs/simulator.md).

Public API::

    simulate(scenario, seed=0, **overrides) -> SimResult
    simulate_fleet(aircraft_id, n_flights, seed=0, scenario="circuit", **overrides)
    write_simulation(result, path) -> dict[str, Path]
    simulate("jsbsim-circuit", seed)   # JSBSim truth source (docs/jsbsim.md; jsbsim extra)
    loads_from_acceleration / acceleration_from_loads / dcm_body_to_ned
"""

from flightrecon.sim.aircraft import JET, LIGHT, TURBOPROP, Aircraft, draw_aircraft
from flightrecon.sim.io import meta_toml, write_simulation
from flightrecon.sim.kinematics import (
    acceleration_from_loads,
    dcm_body_to_ned,
    loads_from_acceleration,
)
from flightrecon.sim.plan import PlanBuilder
from flightrecon.sim.scenarios import (
    SCENARIOS,
    ScenarioConfig,
    SimResult,
    scenario_config,
    simulate,
    simulate_fleet,
)
from flightrecon.sim.trajectory import TRUTH_COLUMNS, FlightPlan, simulate_truth

__all__ = [
    "JET",
    "LIGHT",
    "SCENARIOS",
    "TRUTH_COLUMNS",
    "TURBOPROP",
    "Aircraft",
    "FlightPlan",
    "PlanBuilder",
    "ScenarioConfig",
    "SimResult",
    "acceleration_from_loads",
    "dcm_body_to_ned",
    "draw_aircraft",
    "loads_from_acceleration",
    "meta_toml",
    "scenario_config",
    "simulate",
    "simulate_fleet",
    "simulate_truth",
    "write_simulation",
]
