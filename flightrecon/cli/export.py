"""``flightrecon export``: convert an existing result to another format."""

from __future__ import annotations

import json
from pathlib import Path

import click


@click.command("export")
@click.argument("result", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--format", "fmt", type=click.Choice(["csv", "parquet", "geojson", "kml", "czml"]),
              help="Output format (default: from the suffix of -o; a suffix naming another "
                   "format is refused).")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              help="Output file (default: RESULT with the format's suffix, beside it).")
@click.option("--summary", "summary_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Summary JSON of the result (default: the Parquet metadata, else "
                   "<result stem>.summary.json beside it): epoch, geoid undulation, events.")
@click.option("--geoid-undulation", "geoid_m", type=float, metavar="METRES",
              help="Ellipsoid minus MSL in the area [m], for the MSL altitudes of KML when "
                   "the result has no summary (a bare CSV); overrides the summary's.")
@click.pass_context
def command(ctx: click.Context, result: Path, fmt: str | None, output: Path | None,
            summary_path: Path | None, geoid_m: float | None) -> None:
    """Convert a reconstruction RESULT (.parquet or .csv) to CSV, Parquet, GeoJSON, KML
    (Google Earth replay) or CZML (Cesium)."""
    from flightrecon.cli.progress import check_folder, check_format, stage_progress
    from flightrecon.errors import InputFileError
    from flightrecon.export.atomic import check_not_input
    from flightrecon.export.writers import SUFFIX_OF, read_track, write_track

    if output is None:
        if fmt is None:
            raise click.UsageError("give -o OUTPUT or --format")
        output = result.with_name(result.name.rsplit(".", 1)[0] + SUFFIX_OF[fmt]) \
            if "." in result.name else result.with_name(result.name + SUFFIX_OF[fmt])
    out_fmt = check_format(output, fmt)
    check_not_input(output, [result] + ([summary_path] if summary_path else []))
    check_folder(output)
    quiet = bool(ctx.obj and ctx.obj.get("quiet"))
    with stage_progress(quiet, ["read", "write"], "export") as stage:
        stage("read")
        track, meta = read_track(result)
        if summary_path is not None or not meta:
            sp = summary_path or result.with_name(result.stem + ".summary.json")
            if sp.is_file():
                try:
                    meta = json.loads(sp.read_text(encoding="utf-8"))
                except ValueError as exc:
                    raise InputFileError(f"cannot read the summary: {exc}", file=str(sp)) \
                        from exc
            elif summary_path is not None:
                raise InputFileError("no such summary file", file=str(sp))
        stage("write")
        write_track(output, track, meta, out_fmt, geoid_undulation_m=geoid_m)
    click.echo(f"wrote {output}")
