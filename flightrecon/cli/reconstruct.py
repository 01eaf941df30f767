"""``flightrecon reconstruct``: the main job."""

from __future__ import annotations

from pathlib import Path

import click

from flightrecon.cli.common import (
    default_output,
    errors_name_file,
    gnss_use_from_options,
    gnss_use_options,
    input_options,
    NonEmptyPath,
    parse_k,
    position_option_values,
    read_noise_file,
    read_sns_noise_file,
)
from flightrecon.cli.console import echo_warning
from flightrecon.cli.trim import trim_options


@click.command("reconstruct")
@click.argument("log", type=click.Path(path_type=Path))
@input_options
@click.option("--departure", metavar="LAT,LON,ELEV_M", help="Departure airfield (MSL elevation).")
@click.option("--arrival", metavar="LAT,LON,ELEV_M", help="Arrival airfield / touchdown point.")
@click.option("--station", metavar="LAT,LON,ELEV_M", help="Ground radar position.")
@click.option("--fix", "fixes", metavar="T_S,LAT,LON[,ALT_M[,SD_M]]", multiple=True,
              help="A known position at a time of the record (radar return, waypoint report, "
                   "witness; ALT_M MSL, SD_M per axis, default 100 m); repeatable. A "
                   "measurement of the joint smoother at its time; Sabziev's end point when "
                   "it is at the end of a record without --arrival (docs/wind.md).")
@click.option("--wind", "wind_file", type=click.Path(dir_okay=False, path_type=Path),
              help="Winds-aloft prior: CSV alt_msl_m,from_deg,speed_mps[,sd_mps]: the joint "
                   "smoother's wind prior by altitude, the wind of Sabziev and dead reckoning "
                   "where the log records none (docs/wind.md).")
@gnss_use_options
@click.option("--aircraft", "aircraft_id", metavar="ID", help="Aircraft id.")
@click.option("--methods", metavar="LIST",
              help="Comma-separated methods to run (joint,sabziev,arms,azimuth,sns); "
                   "default: every method the data allow.")
@click.option("--k", "k_text", metavar="K1,K2,K3",
              help="Sabziev coefficients: initial-value mode, no arrival point needed.")
@click.option("--rate", "rate_hz", type=float, help="Grid rate for input channels [Hz].")
@click.option("--arms-form", type=click.Choice(["joint", "cascade"]), default="joint",
              show_default=True,
              help="ADS/ARMS: one filter of track and air-data error together (joint), or the "
                   "paper's two stages, track first (cascade); docs/arms.md.")
@click.option("--arms-linearisation", type=click.Choice(["ekf", "converted"]), default="ekf",
              show_default=True,
              help="ADS/ARMS radar measurement: range/azimuth linearised at each step (ekf), or "
                   "converted to Cartesian positions first (converted); docs/arms.md.")
@click.option("--azimuth-model", type=click.Choice(["aided", "singer"]), default="aided",
              show_default=True,
              help="Azimuth channel: driven by the measured load factors (aided) or a Singer "
                   "manoeuvre model without them (singer); docs/azimuth.md.")
@click.option("--sns-model", type=click.Choice(["auto", "airspeed", "doppler"]), default="auto",
              show_default=True,
              help="SNS smoother: heading-airspeed or heading-Doppler dead reckoning; auto: "
                   "Doppler when the log has it; docs/sns.md.")
@click.option("--sns-form", type=click.Choice(["consistent", "seed"]), default="consistent",
              show_default=True,
              help="SNS smoother: the consistent discretisation (consistent) or the paper's "
                   "equations as printed (seed); docs/sns.md.")
@click.option("--noise", "noise_file", type=click.Path(dir_okay=False, path_type=Path),
              help="TOML file overriding the joint smoother's sensor error budget "
                   "([joint] table, see docs/joint.md).")
@click.option("--estimate-noise", is_flag=True,
              help="Joint smoother: estimate each source's noise variance from the flight "
                   "itself (expectation-maximisation; docs/joint.md).")
@click.option("--gap-stretches", "gap_stretches", type=click.IntRange(min=0), default=None,
              metavar="N",
              help="Joint smoother, GNSS gaps: calibrate the in-gap position sd on up to N "
                   "held-out stretches of the flight's own GNSS (default 6; 0: the model's "
                   "sd; docs/joint.md, \"GNSS gaps\").")
@click.option("--store", "store_path", type=NonEmptyPath(dir_okay=False, path_type=Path),
              help="Coefficient store (SQLite): the flight's fitted k1..k3 and the joint "
                   "smoother's sensor-error estimates are recorded there under its aircraft id.")
@click.option("--use-fleet-coefficients", is_flag=True,
              help="Use what the aircraft's routine flights in --store taught: its sensor "
                   "calibration as the joint smoother's priors and its mean k1..k3 (no arrival "
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
@click.option("-o", "--output", type=NonEmptyPath(dir_okay=False, path_type=Path),
              help="Result file (.parquet, .csv, .geojson, .kml, .czml). Default: "
                   "<log stem>.recon.parquet beside the log.")
@click.option("--format", "fmt", type=click.Choice(["csv", "parquet", "geojson", "kml", "czml"]),
              help="Output format (default: from the suffix of -o; a suffix naming another "
                   "format is refused).")
@click.option("--summary", "summary_path",
              type=NonEmptyPath(dir_okay=False, path_type=Path),
              help="Summary JSON (default: <output stem>.summary.json).")
@click.option("--report", "report_dir", type=NonEmptyPath(path_type=Path),
              help="Also write figures and a self-contained report.html into this folder.")
@trim_options
@click.pass_context
def command(ctx: click.Context, *, log: Path, gnss, radar, mapping, sidecar, departure,
            arrival, station, fixes, wind_file, no_gnss, withhold_gnss, gnss_interval,
            gnss_sd, aircraft_id, methods, k_text, rate_hz,
            arms_form, arms_linearisation, azimuth_model, sns_model, sns_form, noise_file, estimate_noise,
            gap_stretches, store_path, use_fleet_coefficients, strict, keep_unhealthy, workers, output, fmt,
            summary_path, report_dir, start=None, end=None, frame_rate_hz=None) -> None:
    """Reconstruct the trajectory of LOG and write it with its uncertainty and a summary.

    Writes the result (-o, default <log stem>.recon.parquet beside the log), the summary
    JSON (--summary, default <output stem>.summary.json beside the result) and, with
    --report, a folder with report.html and its figures, as one unit (all new or all old).
    Every output path is checked before any work.
    """
    from flightrecon.cli.common import check_run_outputs, publish_reconstruction
    from flightrecon.cli.progress import check_format, compile_notice, stage_progress
    from flightrecon.errors import NoResultError
    from flightrecon.pipeline import ALL_METHODS, ReconstructSettings, reconstruct

    quiet = bool(ctx.obj and ctx.obj.get("quiet"))
    method_list = _method_list(methods)
    overrides = position_option_values(departure=departure, arrival=arrival, station=station)
    if fixes:
        overrides["fixes"] = list(fixes)  # parsed and validated in ingest (priors.py)
    if wind_file is not None:
        overrides["wind_aloft"] = str(wind_file)
    if aircraft_id:
        overrides["aircraft_id"] = aircraft_id
    gnss_use = gnss_use_from_options(no_gnss, withhold_gnss, gnss_interval, gnss_sd)
    settings = ReconstructSettings(
        methods=method_list, rate_hz=rate_hz, k=parse_k(k_text) if k_text else None,
        arms_form=arms_form, arms_linearisation=arms_linearisation, azimuth_model=azimuth_model,
        sns_model=sns_model, sns_form=sns_form, strict=strict, keep_unhealthy=keep_unhealthy,
        joint_noise=(read_noise_file(noise_file) or None) if noise_file else None,
        sns_noise=read_sns_noise_file(noise_file) if noise_file else None,
        joint_estimate_noise=estimate_noise, joint_gap_stretches=gap_stretches,
        start=start, end=end)
    if use_fleet_coefficients and not store_path:
        from flightrecon.store import default_store_path

        store_path = default_store_path()
    out = output or default_output(log, ".recon.parquet")
    out_fmt = check_format(out, fmt)
    summ = summary_path or out.with_name(out.stem + ".summary.json")
    # every output against every input and the other outputs, before any work (exit 9)
    check_run_outputs(log, gnss=gnss, radar=radar, mapping=mapping, sidecar=sidecar,
                      noise_file=noise_file, result=out, summary=summ, report=report_dir,
                      store=store_path, store_is_input=use_fleet_coefficients, fmt=out_fmt)
    stages = ["ingest", "cleaning", "plausibility", *(method_list or ALL_METHODS), "export"]
    if report_dir:
        stages.append("report")
    with (errors_name_file(log, sidecar), compile_notice(quiet),
          stage_progress(quiet, stages, "reconstruct") as stage):
        # the store is written with the outputs (publish_reconstruction), not before them
        try:
            rec = reconstruct(log, gnss=gnss, radar=radar, mapping=mapping, sidecar=sidecar,
                              meta_overrides=overrides, settings=settings, progress=stage,
                              store=store_path, use_fleet_coefficients=use_fleet_coefficients,
                              workers=workers, record=False, gnss_use=gnss_use,
                              frame_rate_hz=frame_rate_hz)
        except NoResultError as exc:     # the warnings first: they may say why
            if not quiet:
                for w in exc.warnings:
                    echo_warning(w)
            raise
        stage("export")
        page = publish_reconstruction(rec, out, summ, out_fmt, report_dir, store_path,
                                      title=f"flightrecon: {log.name}",
                                      record=not use_fleet_coefficients, stage=stage)
    if not quiet:
        _print_outcome(rec.summary)
    click.echo(f"wrote {out}")
    click.echo(f"wrote {summ}")
    if report_dir:
        click.echo(f"wrote {page}")
    if not (rec.summary.get("result") or {}).get("method"):
        raise NoResultError("no method produced a physically possible track; the unhealthy "
                            f"tracks were written for inspection to {out}")


def _method_list(methods: str | None) -> tuple[str, ...] | None:
    """``--methods a,b`` as a tuple of known method names (``None``: every method)."""
    from flightrecon.pipeline import ALL_METHODS

    if not methods:
        return None
    method_list = tuple(m.strip() for m in methods.split(",") if m.strip())
    unknown = [m for m in method_list if m not in ALL_METHODS]
    if unknown or not method_list:
        raise click.BadParameter(
            f"unknown method(s) {', '.join(unknown) or '(none given)'}; choose from "
            f"{', '.join(ALL_METHODS)}", param_hint="--methods")
    return method_list


def _print_outcome(summary: dict) -> None:
    """The run in a few lines on stderr: fleet coefficients used or recorded, each method's
    status, the warnings, where the result comes from, the events."""
    fc = summary.get("fleet_coefficients")
    if fc:
        cal = fc.get("calibration")
        if cal:
            click.echo(f"  fleet calibration of {fc['aircraft_id']} at {cal['at_utc']}: "
                       f"{len(cal['applied'])} sensor errors as priors, from "
                       f"{cal['n_flights']} flight(s)", err=True)
        else:
            click.echo(f"  no fleet calibration: {fc.get('calibration_missing')}", err=True)
        if fc.get("k") is not None:
            click.echo(f"  fleet coefficients of {fc['aircraft_id']}: k = {fc['k']} "
                       f"(flights per axis {fc['flights']})", err=True)
    sc = summary.get("stored_coefficients")
    if sc and sc.get("recorded", True):
        what = ([f"k = {sc['k']}"] if sc.get("k") else []) + (
            ["sensor calibration"] if sc.get("calibration") else [])
        click.echo(f"  recorded {' and '.join(what)} for {sc['aircraft_id']}/"
                   f"{sc['flight_id']} in {sc['store']}", err=True)
    elif sc:
        click.echo(f"  nothing recorded in {sc['store']}: "
                   f"{sc.get('reason') or sc.get('note')}", err=True)
    for name, st in summary["methods"].items():
        line = f"  {name:8s} {st.get('status')}"
        # the reason of an unhealthy method already names its health problems
        why = [str(st["reason"])] if st.get("reason") else [
            str(p.get("what")) for p in (st.get("health") or {}).get("problems", [])]
        if why:
            line += ": " + "; ".join(why)
        click.echo(line, err=True)
    gc = (summary["methods"].get("joint") or {}).get("gap_calibration")
    if gc and gc.get("factor") is not None:
        click.echo(f"  gap sd calibrated on {len(gc['stretches_s'])} held-out stretches of this "
                   f"flight's GNSS: factor {gc['factor']:.3g} (held-out mean NEES "
                   f"{_mean(gc['nees_before']):.2f} before)", err=True)
    # the verdicts in the summary's warnings are on the method lines above already
    verdicts = {f"{name} unhealthy: {st.get('reason')}" for name, st in summary["methods"].items()}
    for w in summary["warnings"]:
        if w not in verdicts:
            echo_warning(w)
    res = summary.get("result") or {}
    if res.get("method"):
        click.echo(f"  result from {res['method']}: {res['why']}", err=True)
    click.echo(_events_line(summary), err=True)


def _mean(rows: list[list[float]]) -> float:
    """Mean of a list of rows of numbers."""
    vals = [v for r in rows for v in r]
    return sum(vals) / len(vals) if vals else float("nan")


def _events_line(summary: dict) -> str:
    """One line: lift-off / touchdown in UTC and the count of the events' alerts and cautions
    (their levels: :data:`flightrecon.events.SEVERITIES`; "warning" is the tool's own lines)."""
    ev = summary.get("events") or []
    key = [e for e in ev if e.get("kind") in ("liftoff", "touchdown", "impact", "end_airborne")]
    text = ", ".join(f"{e['label']} {(e.get('utc') or '')[11:19] or ('t = %.1f s' % e['t_s'])}"
                     + (" UTC" if e.get("utc") else "") for e in key)
    n_alert = sum(1 for e in ev if e.get("severity") == "alert")
    n_caut = sum(1 for e in ev if e.get("severity") == "caution")
    return (f"  events: {text or 'no lift-off or touchdown in the record'}; {n_alert} alert(s), "
            f"{n_caut} caution(s) in the summary's events table")
