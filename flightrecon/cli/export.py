"""``flightrecon export``: convert an existing result to another format."""

from __future__ import annotations

from pathlib import Path

import click


@click.command("export")
@click.argument("result", type=click.Path(dir_okay=False, path_type=Path))
@click.option("--format", "fmt", type=click.Choice(["csv", "parquet", "geojson", "kml"]),
              help="Output format (default: from the suffix of -o).")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path),
              help="Output file (default: RESULT with the format's suffix).")
def command(result: Path, fmt: str | None, output: Path | None) -> None:
    """Convert a reconstruction RESULT (.parquet or .csv) to CSV, Parquet, GeoJSON or KML."""
    from flightrecon.errors import OutputError
    from flightrecon.export.atomic import check_not_input
    from flightrecon.export.writers import read_track, write_track

    if output is None:
        if fmt is None:
            raise OutputError("give -o OUTPUT or --format")
        output = result.with_suffix("." + fmt)
    check_not_input(output, [result])
    track, meta = read_track(result)
    write_track(output, track, meta, fmt)
    click.echo(f"wrote {output}")
