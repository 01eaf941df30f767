"""``flightrecon info LOG``: channels, rates, duration, gaps and metadata of a log."""

from __future__ import annotations

import json
from pathlib import Path

import click

from flightrecon.cli.common import input_options


def _fmt(v, spec: str = ".3g", none: str = "-") -> str:
    return none if v is None else format(v, spec)


@click.command("info")
@click.argument("log", type=click.Path(path_type=Path))
@input_options
@click.option("--json", "as_json", is_flag=True, help="Machine-readable output (JSON).")
def command(log: Path, gnss, radar, mapping, sidecar, as_json: bool) -> None:
    """Show the channels, rates, duration, gaps and metadata of LOG (validating it)."""
    import warnings

    from flightrecon.errors import FlightReconWarning
    from flightrecon.ingest import describe_flight, load_flight

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FlightReconWarning)
        flight = load_flight(log, gnss=gnss, radar=radar, mapping=mapping, sidecar=sidecar)
    info = describe_flight(flight)
    if as_json:
        click.echo(json.dumps(info, indent=2, default=str))
        return
    click.echo(f"sources:  {', '.join(info['sources'])}")
    click.echo(f"rows:     {info['rows']}")
    click.echo(f"duration: {info['duration_s']:.1f} s (t_s {info['start_s']:.3f} .. "
               f"{info['end_s']:.3f})")
    m = info["metadata"]
    click.echo(f"epoch:    {m['epoch_utc'] or 'unknown'}")
    for k in ("aircraft_id", "flight_id", "departure", "arrival", "station"):
        if m.get(k) is not None:
            click.echo(f"{k + ':':9s} {m[k]}")
    click.echo(f"{'channel':20s} {'unit':5s} {'kind':11s} {'samples':>8s} {'rate_hz':>8s} "
               f"{'gaps':>5s} {'longest_gap_s':>13s}")
    for name, c in info["channels"].items():
        click.echo(f"{name:20s} {c['unit']:5s} {c['kind']:11s} {c['samples']:8d} "
                   f"{_fmt(c['rate_hz']):>8s} {c['gaps']:5d} {_fmt(c['longest_gap_s']):>13s}")
    click.echo("conventions:")
    for k, v in info["conventions"].items():
        if k != "conversions":
            click.echo(f"  {k}: {v}")
    for n in info["conventions"]["conversions"]:
        click.echo(f"  converted: {n}")
    for w in info["warnings"]:
        click.echo(f"warning: {w}", err=True)
