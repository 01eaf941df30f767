"""``flightrecon reconstruct``: the main job."""

from __future__ import annotations

from pathlib import Path

import click

from flightrecon.cli.common import (
    default_output,
    input_options,
    parse_k,
    position_option_values,
    progress_bar,
    read_noise_file,
    read_sns_noise_file,
)
from flightrecon.cli.trim import trim_options


@click.command("reconstruct")
@click.argument("log", type=click.Path(dir_okay=False, path_type=Path))
@input_options
@click.option("--departure", metavar="LAT,LON,ELEV_M", help="Departure airfield (MSL elevation).")
@click.option("--arrival", metavar="LAT,LON,ELEV_M", help="Arrival airfield / touchdown point.")
@click.option("--station", metavar="LAT,LON,ELEV_M", help="Ground radar position.")
@click.option("--aircraft", "aircraft_id", metavar="ID", help="Aircraft id.")
@click.option("--methods", metavar="LIST",
              help="Comma-separated methods to run (joint,sabziev,arms,azimuth,sns); "
                   "default: every method the data allow.")
@click.option("--k", "k_text", metavar="K1,K2,K3",
              help="Sabziev coefficients: initial-value mode, no arrival point needed.")
@click.option("--rate", "rate_hz", type=float, help="Grid rate for input channels [Hz].")
@click.option("--arms-form", type=click.Choice(["joint", "cascade"]), default="joint",
              show_default=True)
@click.option("--arms-linearisation", type=click.Choice(["ekf", "converted"]), default="ekf",
              show_default=True)
@click.option("--azimuth-model", type=click.Choice(["aided", "singer"]), default="aided",
              show_default=True)
@click.option("--sns-model", type=click.Choice(["auto", "airspeed", "doppler"]), default="auto",
              show_default=True)
@click.option("--sns-form", type=click.Choice(["consistent", "seed"]), default="consistent",
              show_default=True)
@click.option("--noise", "noise_file", type=click.Path(dir_okay=False, path_type=Path),
              help="TOML file overriding the joint smoother's sensor error budget "
                   "([joint] table, see docs/joint.md).")
@click.option("--estimate-noise", is_flag=True,
              help="Joint smoother: estimate each source's noise variance from the flight "
                   "itself (expectation-maximisation; docs/joint.md).")
@click.option("--store", "store_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Coefficient store (SQLite): a fitted flight's k1..k3 are recorded there "
                   "under its aircraft id.")
@click.option("--use-fleet-coefficients", is_flag=True,
              help="Reconstruct with the aircraft's mean k1..k3 from --store (no arrival "
                   "point needed).")
@click.option("--strict", is_flag=True,
              help="Fail (exit 8) on the first method that fails, does not converge or is "
                   "unhealthy (its track not physically possible).")
@click.option("--keep-unhealthy", is_flag=True,
              help="When no method is healthy, still write the methods' tracks under their "
                   "prefixes for inspection (the default columns stay empty; exit 8).")
@click.option("--workers", type=click.IntRange(min=1),
              help="Threads for the estimators (default: 2 on a machine with 2 cores or more; "
                   "the result does not depend on it).")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              help="Result file (.parquet, .csv, .geojson, .kml). Default: <log stem>.recon.parquet "
                   "beside the log.")
@click.option("--format", "fmt", type=click.Choice(["csv", "parquet", "geojson", "kml"]),
              help="Output format (default: from the suffix of -o).")
@click.option("--summary", "summary_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Summary JSON (default: <output stem>.summary.json).")
@click.option("--report", "report_dir", type=click.Path(file_okay=False, path_type=Path),
              help="Also write figures and a self-contained report.html into this folder.")
@trim_options
@click.pass_context
def command(ctx: click.Context, log: Path, gnss, radar, mapping, sidecar, departure, arrival,
            station, aircraft_id, methods, k_text, rate_hz, arms_form, arms_linearisation,
            azimuth_model, sns_model, sns_form, noise_file, estimate_noise, store_path,
            use_fleet_coefficients, strict, keep_unhealthy, workers, output, fmt, summary_path,
            report_dir, start=None, end=None) -> None:
    """Reconstruct the trajectory of LOG and write it with its uncertainty and a summary."""
    from flightrecon.export.atomic import check_not_input, sweep_leftovers
    from flightrecon.export.writers import write_summary, write_track
    from flightrecon.pipeline import ReconstructSettings, reconstruct

    quiet = bool(ctx.obj and ctx.obj.get("quiet"))
    overrides = position_option_values(departure=departure, arrival=arrival, station=station)
    if aircraft_id:
        overrides["aircraft_id"] = aircraft_id
    settings = ReconstructSettings(
        methods=tuple(m.strip() for m in methods.split(",") if m.strip()) if methods else None,
        rate_hz=rate_hz, k=parse_k(k_text) if k_text else None, arms_form=arms_form,
        arms_linearisation=arms_linearisation, azimuth_model=azimuth_model, sns_model=sns_model,
        sns_form=sns_form, strict=strict, keep_unhealthy=keep_unhealthy,
        joint_noise=(read_noise_file(noise_file) or None) if noise_file else None,
        sns_noise=read_sns_noise_file(noise_file) if noise_file else None,
        joint_estimate_noise=estimate_noise, start=start, end=end)
    if use_fleet_coefficients and not store_path:
        from flightrecon.store import default_store_path

        store_path = default_store_path()
    out = output or default_output(log, ".recon.parquet")
    inputs = [p for p in (log, gnss, radar, mapping, sidecar) if p is not None]
    check_not_input(out, inputs)
    summ = summary_path or out.with_name(out.stem + ".summary.json")
    check_not_input(summ, inputs)
    sweep_leftovers(out.parent)
    with progress_bar(quiet) as stage:
        rec = reconstruct(log, gnss=gnss, radar=radar, mapping=mapping, sidecar=sidecar,
                          meta_overrides=overrides, settings=settings, progress=stage,
                          store=store_path, use_fleet_coefficients=use_fleet_coefficients,
                          workers=workers)
        stage("export")
        write_track(out, rec.track, rec.summary, fmt)
        write_summary(summ, rec.summary)
        if report_dir:
            from flightrecon.report import write_report

            stage("report")
            page = write_report(report_dir, rec.track, rec.summary,
                                title=f"flightrecon: {log.name}")
    if not quiet:
        fc = rec.summary.get("fleet_coefficients")
        if fc:
            click.echo(f"  fleet coefficients of {fc['aircraft_id']}: k = {fc['k']} "
                       f"(flights per axis {fc['flights']})", err=True)
        sc = rec.summary.get("stored_coefficients")
        if sc and sc.get("recorded"):
            click.echo(f"  recorded k = {sc['k']} for {sc['aircraft_id']}/{sc['flight_id']} "
                       f"in {sc['store']}", err=True)
        elif sc:
            click.echo(f"  coefficients not recorded in {sc['store']}: {sc['reason']}", err=True)
        for name, st in rec.summary["methods"].items():
            line = f"  {name:8s} {st.get('status')}"
            if st.get("reason"):
                line += f": {st['reason']}"
            click.echo(line, err=True)
        for w in rec.summary["warnings"]:
            click.echo(f"  warning: {w}", err=True)
        res = rec.summary.get("result") or {}
        if res.get("method"):
            click.echo(f"  result from {res['method']}: {res['why']}", err=True)
    click.echo(f"wrote {out}")
    click.echo(f"wrote {summ}")
    if report_dir:
        click.echo(f"wrote {page}")
    if not (rec.summary.get("result") or {}).get("method"):
        from flightrecon.errors import NoResultError

        raise NoResultError("no method produced a physically possible track; the unhealthy "
                            f"tracks were written for inspection to {out}")
