"""``flightrecon plot``: figures and an offline HTML report of a result."""

from __future__ import annotations

from pathlib import Path

import click


@click.command("plot")
@click.argument("result", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--out", "folder", type=click.Path(file_okay=False, path_type=Path),
              help="Report folder (default: <result stem>.report beside the result).")
@click.option("--truth", type=click.Path(dir_okay=False, path_type=Path),
              help="Truth file of a simulated flight, drawn for comparison.")
def command(result: Path, folder: Path | None, truth: Path | None) -> None:
    """Draw the figures of RESULT (.parquet with its metadata) and a self-contained report.html."""
    import pandas as pd

    from flightrecon.export.writers import read_track
    from flightrecon.report import write_report

    from flightrecon.cli.common import report_file_name
    from flightrecon.export.atomic import check_outputs

    summ_path = result.with_name(result.stem + ".summary.json")
    # the report folder must not replace the result, its summary or the truth (exit 9)
    check_outputs({}, {"result": result, "summary": summ_path if summ_path.is_file() else None,
                       "truth file": truth},
                  folders={"report": folder or result.with_name(result.stem + ".report")},
                  folder_names=report_file_name)
    track, meta = read_track(result)
    if not meta and summ_path.is_file():
        import json

        meta = json.loads(summ_path.read_text(encoding="utf-8"))
    tr = pd.read_parquet(truth) if truth else None
    folder = folder or result.with_name(result.stem + ".report")
    page = write_report(folder, track, meta, tr, title=f"flightrecon: {result.name}")
    click.echo(f"wrote {page}")
