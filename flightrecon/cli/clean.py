"""``flightrecon clean``: validate, clean and resample a log; write the grid, the measurements
and the cleaning report."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import Any

import click

from flightrecon.cli.common import input_options
from flightrecon.cli.trim import trim_options

_SUFFIXES = {".parquet": "parquet", ".pq": "parquet", ".csv": "csv"}


def output_paths(out: Path) -> dict[str, Path]:
    """The files ``clean`` writes for ``-o OUT``: grid, GNSS, radar and report paths.

    Raises
    ------
    OutputError
        If the suffix of ``out`` is not ``.parquet``/``.pq``/``.csv``.
    """
    from flightrecon.errors import OutputError

    ext = out.suffix.lower()
    if ext not in _SUFFIXES:
        raise OutputError(f"cannot tell the output format from the suffix '{out.suffix}' "
                          "(use .parquet or .csv)", file=str(out))
    stem = out.with_suffix("")
    return {"grid": out, "gnss": Path(f"{stem}.gnss{out.suffix}"),
            "radar": Path(f"{stem}.radar{out.suffix}"), "report": Path(f"{stem}.cleaning.json")}


def write_clean_outputs(clean, out: Path, inputs: list[Path], settings: dict[str, Any]
                        ) -> list[Path]:
    """Write a :class:`~flightrecon.types.CleanFlight` beside ``out``, atomically.

    The grid goes to ``out`` (Parquet or CSV by suffix), the GNSS fixes and radar plots (when
    present) to ``<stem>.gnss.<ext>`` / ``<stem>.radar.<ext>``, and the report with the grid
    rate, phases and settings to ``<stem>.cleaning.json``.  No path may be an input file.
    Returns the paths written.
    """
    from flightrecon.export.atomic import check_not_input, write_text_atomic
    from flightrecon.export.writers import to_json, write_csv, write_parquet

    paths = output_paths(out)
    for p in paths.values():
        check_not_input(p, inputs)
    doc = {
        "rate_hz": clean.rate_hz,
        "grid_samples": len(clean.grid),
        "gnss_fixes": len(clean.gnss),
        "radar_plots": len(clean.radar),
        "phases": None if clean.phases is None else asdict(clean.phases),
        "settings": settings,
        "inputs": [str(p) for p in inputs],
        "report": list(clean.report),
    }
    fmt = _SUFFIXES[out.suffix.lower()]
    written = []
    tables = {"grid": clean.grid, "gnss": clean.gnss, "radar": clean.radar}
    for key, df in tables.items():
        if key != "grid" and len(df) == 0:
            continue
        if fmt == "parquet":
            write_parquet(paths[key], df, {"cleaning": {k: v for k, v in doc.items()
                                                        if k != "report"}, "table": key})
        else:
            write_csv(paths[key], df)
        written.append(paths[key])
    write_text_atomic(paths["report"], to_json(doc) + "\n")
    written.append(paths["report"])
    return written


@click.command("clean")
@click.argument("log", type=click.Path(dir_okay=False, path_type=Path))
@input_options
@click.option("-o", "--output", "out", required=True, type=click.Path(dir_okay=False,
              path_type=Path), help="Cleaned grid (.parquet or .csv); the measurements and the "
              "report go beside it as <stem>.gnss.<ext>, <stem>.radar.<ext>, <stem>.cleaning.json.")
@click.option("--rate", "rate_hz", type=float, help="Grid rate [Hz] (default: the fastest input "
              "channel's rate).")
@click.option("--max-gap", "max_gap_s", type=float, default=2.0, show_default=True,
              help="Longest gap of an input channel that is interpolated [s].")
@click.option("--gnss-clock-offset", type=float, default=0.0, show_default=True,
              help="Seconds added to the GNSS times.")
@click.option("--radar-clock-offset", type=float, default=0.0, show_default=True,
              help="Seconds added to the radar times.")
@trim_options
@click.pass_context
def command(ctx: click.Context, log: Path, out: Path, rate_hz: float | None, gnss: Path | None,
            radar: Path | None, mapping: Path | None, sidecar: Path | None, max_gap_s: float,
            gnss_clock_offset: float, radar_clock_offset: float, start: str | None = None,
            end: str | None = None) -> None:
    """Clean LOG: despike, unwrap, resample the input channels onto one grid, keep the GNSS fixes
    and radar plots at their own times, detect lift-off and touchdown."""
    from flightrecon.cleaning import CleaningSettings, clean_flight
    from flightrecon.export.atomic import check_not_input, sweep_leftovers
    from flightrecon.ingest import load_flight

    inputs = [p for p in (log, gnss, radar, mapping, sidecar) if p is not None]
    for p in output_paths(out).values():
        check_not_input(p, inputs)
    settings = CleaningSettings(max_gap_s=max_gap_s,
                                clock_offsets_s={"gnss": gnss_clock_offset,
                                                 "radar": radar_clock_offset},
                                start=start, end=end)
    flight = load_flight(log, gnss=gnss, radar=radar, mapping=mapping, sidecar=sidecar)
    clean = clean_flight(flight, rate_hz=rate_hz, settings=settings)
    sweep_leftovers(out.parent)
    written = write_clean_outputs(clean, out, inputs, {
        "rate_hz": rate_hz, "max_gap_s": max_gap_s,
        "clock_offsets_s": dict(settings.clock_offsets_s), "despike": asdict(settings.despike),
        "phases": asdict(settings.phases), "start": start, "end": end})
    quiet = bool(ctx.obj and ctx.obj.get("quiet"))
    if not quiet:
        ph = clean.phases
        if ph is not None:
            click.echo(f"  lift-off t = {ph.liftoff_t_s:.2f} s, touchdown t = "
                       f"{ph.touchdown_t_s:.2f} s", err=True)
        click.echo(f"  {len(clean.report)} cleaning actions; grid {clean.rate_hz:g} Hz, "
                   f"{len(clean.grid)} samples", err=True)
    for p in written:
        click.echo(f"wrote {p}")
