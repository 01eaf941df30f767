"""``flightrecon simulate``: write a simulated log with its truth, metadata and sensor truth."""

from __future__ import annotations

from pathlib import Path

import click

SCENARIO_NAMES = ("circuit", "regional", "seed-ads-arms", "landing", "longhaul",
                  "jsbsim-circuit", "jsbsim-xc", "jsbsim-jet", "jsbsim-spiral", "jsbsim-spin",
                  "jsbsim-airwork", "jsbsim-holding", "jsbsim-goaround")
"""Point-mass scenarios, then the JSBSim ones (docs/jsbsim.md; need the ``jsbsim`` extra)."""

AIRFRAME_NAMES = ("c172p", "c310", "737", "t6texan2", "pc7", "global5000", "B747")
"""The JSBSim aircraft (``flightrecon.sim.jsbsim_scenarios.AIRFRAMES``; a test keeps the two
equal: the names are here so that the help needs no simulator import)."""

EXPORT_NAMES = ("ed112", "garmin")
"""Recorder exports written beside the log (``flightrecon.sim.io.EXPORT_FORMATS``)."""


@click.command("simulate")
@click.argument("scenario", type=click.Choice(SCENARIO_NAMES))
@click.option("--seed", type=int, default=0, show_default=True, help="Noise seed.")
@click.option("--fleet-flights", type=click.IntRange(min=1), default=None,
              help="Simulate K flights of one airframe (files <stem>_F01... beside LOG).")
@click.option("--aircraft-id", default="A1", show_default=True,
              help="Airframe id for --fleet-flights (persistent errors drawn from it).")
@click.option("--scale", type=click.FloatRange(min=0.01, max=1.0), default=None,
              help="JSBSim scenarios: shorten the en-route legs by this factor (1 = full "
                   "length).")
@click.option("--airframe", type=click.Choice(AIRFRAME_NAMES), default=None,
              help="JSBSim scenarios: fly this aircraft instead of the scenario's own "
                   "(docs/jsbsim.md, \"Fleet\").")
@click.option("--export", "export", type=click.Choice(EXPORT_NAMES), default=None,
              help="Also write the log as this recorder export: ed112 = the ED-112 minimum "
                   "rates (<stem>.ed112.csv, its mapping <stem>.ed112.mapping.toml and "
                   "sidecar <stem>.ed112.meta.toml; recorder channels only); garmin = a "
                   "Garmin glass-cockpit CSV at 1 Hz (<stem>.garmin.csv, read as recorded "
                   "without a mapping, and its sidecar <stem>.garmin.meta.toml).")
@click.option("--no-gnss", is_flag=True, help="Record no GNSS (recorder channels only).")
@click.option("-o", "--output", "output", required=True,
              type=click.Path(dir_okay=False, path_type=Path),
              help="Log file (.parquet or .csv); truth, sidecar and sensor truth beside it.")
@click.pass_context
def command(ctx: click.Context, scenario: str, seed: int, fleet_flights: int | None,
            aircraft_id: str, scale: float | None, airframe: str | None, export: str | None,
            no_gnss: bool, output: Path) -> None:
    """Simulate SCENARIO and write its log (-o), <stem>.truth.parquet, <stem>.meta.toml and
    <stem>.sensors.json.

    The jsbsim-* scenarios fly the JSBSim flight dynamics model (a second, independent truth:
    docs/jsbsim.md) with the project's recorder model on top."""
    from flightrecon.errors import OutputError
    from flightrecon.sim import simulate, simulate_fleet, write_simulation
    from flightrecon.sim.io import write_export

    if output.suffix.lower() not in (".parquet", ".csv"):
        raise OutputError("the log must end in .parquet or .csv", file=str(output))
    quiet = bool(ctx.obj and ctx.obj.get("quiet"))
    overrides: dict = {"gnss_hz": 0.0} if no_gnss else {}
    if scale is not None:
        if not scenario.startswith("jsbsim-"):
            raise click.UsageError("--scale applies to the jsbsim-* scenarios only")
        overrides["scale"] = scale
    if airframe is not None:
        if not scenario.startswith("jsbsim-"):
            raise click.UsageError("--airframe applies to the jsbsim-* scenarios only")
        overrides["airframe"] = airframe
    if fleet_flights is None:
        results = [(output, simulate(scenario, seed, **overrides))]
    else:
        flights = simulate_fleet(aircraft_id, fleet_flights, seed, scenario=scenario,
                                 **overrides)
        results = [(output.with_name(f"{output.stem}_{r.meta.flight_id}{output.suffix}"), r)
                   for r in flights]
    for path, result in results:
        written = write_simulation(result, path)
        if export is not None:
            written.update(write_export(result, path, export))
        if not quiet:
            for p in written.values():
                click.echo(f"wrote {p}")
