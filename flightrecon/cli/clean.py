"""``flightrecon clean``: validate, clean and resample a log; write the grid, the measurements
and the cleaning report."""

from __future__ import annotations

from dataclasses import asdict
from pathlib import Path
from typing import Any

import click

from flightrecon.cli.common import (
    NonEmptyPath,
    gnss_use_from_options,
    gnss_use_options,
    input_options,
)
from flightrecon.cli.trim import trim_options

_SUFFIXES = {".parquet": "parquet", ".pq": "parquet", ".csv": "csv"}
#: version of the ``flightrecon`` metadata block of the cleaned Parquet tables (docs/output.md)
CLEAN_SCHEMA_VERSION = 1


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


def write_clean_outputs(clean, out: Path, inputs: list[Path], settings: dict[str, Any],
                        warned: list[str] | None = None) -> list[Path]:
    """Write a :class:`~flightrecon.types.CleanFlight` beside ``out``, atomically.

    The grid goes to ``out`` (Parquet or CSV by suffix), the GNSS fixes and radar plots (when
    present) to ``<stem>.gnss.<ext>`` / ``<stem>.radar.<ext>``, and the report with the grid
    rate, phases, settings and the tool's warnings (``warned``) to ``<stem>.cleaning.json``.
    No path may be an input file.  Returns the paths written.
    """
    from flightrecon.export.atomic import Publication, check_not_input, write_text_atomic
    from flightrecon.export.encode import to_json
    from flightrecon.export.writers import write_csv, write_parquet

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
        "warnings": list(warned or ()),
    }
    fmt = _SUFFIXES[out.suffix.lower()]
    written = []
    tables = {"grid": clean.grid, "gnss": clean.gnss, "radar": clean.radar}
    with Publication() as pub:   # the grid, its measurements and its report: one unit
        for key, df in tables.items():
            if key != "grid" and len(df) == 0:
                continue
            if fmt == "parquet":
                write_parquet(pub.file(paths[key]), df, {
                    "schema_version": CLEAN_SCHEMA_VERSION, "table": key,
                    "cleaning": {k: v for k, v in doc.items() if k != "report"}})
            else:
                write_csv(pub.file(paths[key]), df)
            written.append(paths[key])
        write_text_atomic(pub.file(paths["report"]), to_json(doc) + "\n")
        written.append(paths["report"])
        pub.commit()
    return written


@click.command("clean")
@click.argument("log", type=click.Path(path_type=Path))
@input_options
@click.option("-o", "--output", "out", required=True, type=NonEmptyPath(dir_okay=False,
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
@click.option("--json", "as_json", is_flag=True,
              help="Print the cleaning report (the <stem>.cleaning.json document) on stdout "
                   "instead of the summary lines.")
@gnss_use_options
@trim_options
@click.pass_context
def command(ctx: click.Context, *, log: Path, out: Path, rate_hz: float | None,
            gnss: Path | None, radar: Path | None, mapping: Path | None, sidecar: Path | None,
            max_gap_s: float,
            gnss_clock_offset: float, radar_clock_offset: float, as_json: bool,
            no_gnss: bool = False, withhold_gnss: tuple[str, ...] = (),
            gnss_interval: float | None = None, gnss_sd: str | None = None,
            start: str | None = None, end: str | None = None,
            frame_rate_hz: float | None = None) -> None:
    """Clean LOG: despike, unwrap, resample the input channels onto one grid, keep the GNSS fixes
    and radar plots at their own times, detect lift-off and touchdown.

    Writes the grid to -o and, beside it, <stem>.gnss.<ext>, <stem>.radar.<ext> (when the log
    has them) and <stem>.cleaning.json; every path is checked before any work.
    """
    from flightrecon.cleaning import CleaningSettings, clean_flight
    from flightrecon.cli.common import errors_name_file, run_inputs
    from flightrecon.cli.console import collected_warnings
    from flightrecon.cli.progress import stage_progress
    from flightrecon.export.atomic import check_outputs, sweep_leftovers
    from flightrecon.ingest import load_flight

    gnss_use = gnss_use_from_options(no_gnss, withhold_gnss, gnss_interval, gnss_sd)
    inputs = [p for p in (log, gnss, radar, mapping, sidecar) if p is not None]
    check_outputs(output_paths(out), run_inputs(log, gnss=gnss, radar=radar, mapping=mapping,
                                                sidecar=sidecar))
    settings = CleaningSettings(max_gap_s=max_gap_s,
                                clock_offsets_s={"gnss": gnss_clock_offset,
                                                 "radar": radar_clock_offset},
                                start=start, end=end)
    quiet = bool(ctx.obj and ctx.obj.get("quiet"))
    with stage_progress(quiet, ["ingest", "cleaning", "write"], "clean") as stage:
        with errors_name_file(log, sidecar), collected_warnings() as warned:
            stage("ingest")
            flight = load_flight(log, gnss=gnss, radar=radar, mapping=mapping, sidecar=sidecar,
                                 gnss_use=gnss_use, frame_rate_hz=frame_rate_hz)
            stage("cleaning")
            clean = clean_flight(flight, rate_hz=rate_hz, settings=settings)
        stage("write")
        sweep_leftovers(out.parent)
        written = write_clean_outputs(clean, out, inputs, {
            "rate_hz": rate_hz, "max_gap_s": max_gap_s,
            "clock_offsets_s": dict(settings.clock_offsets_s),
            "despike": None if settings.despike is None else asdict(settings.despike),
            "phases": None if settings.phases is None else asdict(settings.phases),
            "start": start, "end": end}, warned)
    if as_json:
        click.echo(written[-1].read_text(encoding="utf-8").rstrip("\n"))
        return
    if not quiet:
        for line in summary_lines(clean):
            click.echo(f"  {line}", err=True)
    for p in written:
        click.echo(f"wrote {p}")


def summary_lines(clean) -> list[str]:
    """Human-readable lines about a cleaned flight: phases in UTC (never ``nan``), the grid,
    the measurements, the cleaning actions by kind."""
    import math
    from collections import Counter

    from flightrecon.events import utc_text

    epoch = clean.meta.epoch_utc
    lines = []

    def when(t: float) -> str:
        u = utc_text(epoch, t)
        return f"{u[11:23]} UTC (t = {t:.2f} s)" if u else f"t = {t:.2f} s"

    ph = clean.phases
    if ph is None:
        lines.append("phases: not detected (see the cleaning report)")
    else:
        lo, td = ph.liftoff_t_s, ph.touchdown_t_s
        lines.append("lift-off: " + (when(lo) if math.isfinite(lo) else
                                     "none in the record (it starts airborne)"
                                     if ph.starts_airborne else "not detected"))
        lines.append("touchdown: " + (when(td) if math.isfinite(td) else
                                      "none in the record (it ends airborne)"
                                      if ph.ends_airborne else "not detected"))
    lines.append(f"grid: {clean.rate_hz:g} Hz, {len(clean.grid)} samples; "
                 f"{len(clean.gnss)} GNSS fixes, {len(clean.radar)} radar plots kept at their "
                 "own times")
    kinds = Counter(str(r.get("action")) for r in clean.report)
    lines.append(f"{len(clean.report)} cleaning actions"
                 + (": " + ", ".join(f"{k} {v}" for k, v in sorted(kinds.items())) if kinds
                    else ""))
    return lines
