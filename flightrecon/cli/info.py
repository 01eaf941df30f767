"""``flightrecon info LOG``: channels, rates, duration, gaps and metadata of a log."""

from __future__ import annotations

import math
from pathlib import Path

import click

from flightrecon.cli.common import gnss_use_from_options, gnss_use_options, input_options
from flightrecon.cli.console import echo_warning


def _fmt(v, spec: str = ".3g", none: str = "-") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return none
    return format(v, spec)


def _lat(v: float) -> str:
    return f"{abs(v):.5f}°{'N' if v >= 0 else 'S'}"


def _lon(v: float) -> str:
    return f"{abs(v):.5f}°{'E' if v >= 0 else 'W'}"


def position_text(p) -> str:
    """``40.46000°N 50.05000°E, 3 m MSL; runway 160° true from 40.46677°N 50.04677°E``."""
    if isinstance(p, dict):
        get = p.get
    else:
        def get(k):
            return getattr(p, k, None)
    text = f"{_lat(get('lat_deg'))} {_lon(get('lon_deg'))}, {_fmt(get('elev_m'), '.0f')} m MSL"
    if get("runway_true_deg") is not None:
        text += f"; runway {round(get('runway_true_deg')) % 360 or 360:03d}° true"
        if get("threshold_lat_deg") is not None and get("threshold_lon_deg") is not None:
            text += f" from {_lat(get('threshold_lat_deg'))} {_lon(get('threshold_lon_deg'))}"
    return text


@click.command("info")
@click.argument("log", type=click.Path(path_type=Path))
@input_options
@click.option("--json", "as_json", is_flag=True,
              help="Machine-readable output: standard JSON (no NaN) on stdout.")
@gnss_use_options
def command(log: Path, gnss, radar, mapping, sidecar, as_json: bool, no_gnss: bool = False,
            withhold_gnss: tuple[str, ...] = (), gnss_interval: float | None = None,
            gnss_sd: str | None = None, frame_rate_hz: float | None = None) -> None:
    """Show the channels, rates, duration, gaps and metadata of LOG (validating it); reads
    only, writes nothing."""
    import warnings

    from flightrecon.errors import FlightReconWarning
    from flightrecon.export.encode import to_json
    from flightrecon.ingest import describe_flight, load_flight

    from flightrecon.ingest.door import DoorRefusal

    gnss_use = gnss_use_from_options(no_gnss, withhold_gnss, gnss_interval, gnss_sd)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FlightReconWarning)
            flight = load_flight(log, gnss=gnss, radar=radar, mapping=mapping, sidecar=sidecar,
                                 gnss_use=gnss_use, frame_rate_hz=frame_rate_hz)
    except DoorRefusal as exc:          # the checks up to the refusal, then the error
        if as_json:
            click.echo(to_json({"door": [c.as_dict() for c in exc.checks]}))
        else:
            _echo_door([c.as_dict() for c in exc.checks])
        raise
    info = describe_flight(flight)
    if as_json:
        click.echo(to_json(info))
        return
    m = info["metadata"]
    click.echo(f"sources:   {', '.join(str(s) for s in info['sources'])}")
    click.echo(f"rows:      {info['rows']}")
    click.echo(f"duration:  {info['duration_s']:.1f} s (t_s {info['start_s']:.3f} .. "
               f"{info['end_s']:.3f})")
    click.echo(f"epoch:     {m.get('epoch_utc') or 'unknown (times are seconds from the start)'}")
    for k, label in (("aircraft_id", "aircraft"), ("flight_id", "flight")):
        if m.get(k) is not None:
            click.echo(f"{label + ':':10s} {m[k]}")
    for k in ("departure", "arrival", "station"):
        if m.get(k) is not None:
            click.echo(f"{k + ':':10s} {position_text(m[k])}")
    if m.get("geoid_undulation_m") is not None:
        click.echo(f"{'geoid:':10s} undulation {m['geoid_undulation_m']:g} m (ellipsoid - MSL"
                   + (f", {m['geoid_model']}" if m.get("geoid_model") else "") + ")")
    header = (f"{'channel':20s} {'unit':5s} {'kind':11s} {'samples':>8s} {'rate_hz':>8s} "
              f"{'gaps':>5s} {'longest_gap_s':>13s} {'min':>10s} {'max':>10s}")
    click.echo(header)
    for name, c in info["channels"].items():
        click.echo(f"{name:20s} {c['unit']:5s} {c['kind']:11s} {c['samples']:8d} "
                   f"{_fmt(c['rate_hz']):>8s} {c['gaps']:5d} {_fmt(c['longest_gap_s']):>13s} "
                   f"{_fmt(c.get('min'), '.5g'):>10s} {_fmt(c.get('max'), '.5g'):>10s}")
    click.echo("conventions:")
    for k, v in info["conventions"].items():
        if k != "conversions":
            click.echo(f"  {k}: {v}")
    for n in info["conventions"]["conversions"]:
        click.echo(f"  converted: {n}")
    _echo_door(info["door"])
    for w in info["warnings"]:
        echo_warning(w)


def _echo_door(checks: list[dict]) -> None:
    """The door's checks, one line each: check, channel, verdict, figure, evidence
    (docs/ingest.md, "The door")."""
    if not checks:
        return
    click.echo("door:")
    click.echo(f"  {'check':22s} {'channel':18s} {'verdict':8s} {'figure':>8s}  evidence")
    for c in checks:
        click.echo(f"  {c['check']:22s} {c['channel']:18s} {c['verdict']:8s} "
                   f"{_fmt(c.get('figure'), '.3g'):>8s}  {c.get('detail', '')}")
