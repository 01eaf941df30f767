"""``flightrecon plot``: figures and an offline HTML report of a result."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import click

#: columns every reconstruction result has (a recorder log has none of them)
RESULT_COLUMNS = ("north_m", "east_m", "lat_deg", "lon_deg", "alt_m")


def _load_summary(result: Path, meta: dict[str, Any], summary_path: Path | None
                  ) -> dict[str, Any]:
    from flightrecon.errors import InputFileError

    if summary_path is not None:
        try:
            return json.loads(summary_path.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            raise InputFileError(f"cannot read the summary: {exc}", file=str(summary_path)) \
                from exc
    if meta:
        return meta
    beside = result.with_name(result.stem + ".summary.json")
    if beside.is_file():
        try:
            return json.loads(beside.read_text(encoding="utf-8"))
        except ValueError as exc:
            raise InputFileError(f"cannot read the summary: {exc}", file=str(beside)) from exc
    return {}


def check_truth_matches(track, truth, truth_path: Path, max_median_m: float = 2000.0) -> None:
    """Refuse (usage error) a truth file of another flight: its time span must cover the
    result's, and at the common times the median horizontal distance between the result and
    the truth must stay below ``max_median_m`` (a reconstruction is within metres to hundreds
    of metres of its truth; another flight's truth is kilometres away or does not overlap)."""
    import numpy as np

    need = {"t_s", "lat_deg", "lon_deg"}
    if not need <= set(truth.columns):
        raise click.BadParameter(f"{truth_path} is not a truth file (needs columns "
                                 f"{', '.join(sorted(need))})", param_hint="--truth")
    t, tt = track["t_s"].to_numpy(float), truth["t_s"].to_numpy(float)
    lo, hi = max(t.min(), tt.min()), min(t.max(), tt.max())
    if hi - lo < 0.5 * (t.max() - t.min()):
        raise click.BadParameter(f"{truth_path} covers t = {tt.min():.0f}..{tt.max():.0f} s, "
                                 f"the result t = {t.min():.0f}..{t.max():.0f} s: not the truth "
                                 "of this flight", param_hint="--truth")
    sel = (t >= lo) & (t <= hi)
    la = np.interp(t[sel], tt, truth["lat_deg"].to_numpy(float))
    lo_ = np.interp(t[sel], tt, truth["lon_deg"].to_numpy(float))
    lat, lon = track["lat_deg"].to_numpy(float)[sel], track["lon_deg"].to_numpy(float)[sel]
    d = np.hypot((lat - la) * 111_000.0, (lon - lo_) * 111_000.0 * np.cos(np.radians(la)))
    med = float(np.nanmedian(d)) if np.isfinite(d).any() else float("inf")
    if not med < max_median_m:
        raise click.BadParameter(f"{truth_path} is {med / 1000:.1f} km from the result (median "
                                 "over the common times): the truth of another flight?",
                                 param_hint="--truth")


def recorder_data(summary: dict[str, Any], result: Path, log: Path | None
                  ) -> tuple[Any, Any, Any, str | None]:
    """The cleaned recorder grid and GNSS fixes of the reconstructed log, for the report.

    The log is ``log`` if given, else the first input the summary names (as given, or beside
    the result); it is used only if its SHA-256 matches the summary's.  Returns ``(grid, gnss,
    radar, note)``; ``(None, None, None, why)`` when the log is not available.
    """
    import warnings

    from flightrecon.errors import FlightReconError, FlightReconWarning
    from flightrecon.ingest import load_flight
    from flightrecon.pipeline import sha256_file

    inputs = [i for i in summary.get("inputs") or [] if isinstance(i, dict)]
    want = inputs[0] if inputs else None
    if log is None:
        if want is None:
            return None, None, None, "the summary names no input log"
        cands = [Path(str(want.get("path"))), result.parent / Path(str(want.get("path"))).name]
        log = next((c for c in cands if c.is_file()), None)
        if log is None:
            return None, None, None, f"the log {want.get('path')} was not found"
    if want is not None and want.get("sha256") and sha256_file(log) != want.get("sha256"):
        return None, None, None, (f"{log} differs from the log that was reconstructed (SHA-256): "
                            "not used")
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", FlightReconWarning)
            from flightrecon.cleaning import clean_flight

            flight = load_flight(log)
            rate = (summary.get("settings") or {}).get("rate_hz")
            clean = clean_flight(flight, rate_hz=rate)
    except FlightReconError as exc:
        return None, None, None, f"the log could not be read again: {exc}"
    return clean.grid, clean.gnss, clean.radar, None


def _check_report_not_over_inputs(folder: Path, result: Path, summary_path: Path | None,
                                  truth: Path | None, log: Path | None) -> None:
    """The report folder must not replace the result, its summary, the truth or the log
    (exit 9, before any work)."""
    from flightrecon.cli.common import report_file_name
    from flightrecon.export.atomic import check_outputs

    summ = summary_path or result.with_name(result.stem + ".summary.json")
    check_outputs({}, {"result": result, "summary": summ if summ.is_file() else None,
                       "truth file": truth, "log": log},
                  folders={"report": folder}, folder_names=report_file_name)


@click.command("plot")
@click.argument("result", type=click.Path(dir_okay=False, path_type=Path))
@click.option("-o", "--out", "folder", type=click.Path(file_okay=False, path_type=Path),
              help="Report folder, created if needed (default: <result stem>.report beside "
                   "the result): report.html and one PNG per figure.")
@click.option("--truth", type=click.Path(dir_okay=False, path_type=Path),
              help="Truth file of a simulated flight (<stem>.truth.parquet), drawn for "
                   "comparison; its sensor truth <stem>.sensors.json beside it is overlaid on "
                   "the corrections. Refused when it is not this flight's.")
@click.option("--summary", "summary_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Summary JSON of the result (default: the Parquet metadata, else "
                   "<result stem>.summary.json beside it).")
@click.option("--log", "log", type=click.Path(dir_okay=False, path_type=Path),
              help="The recorder log that was reconstructed, for the attitude, load-factor, "
                   "airspeed and pressure-altitude figures (default: the summary's input, "
                   "used when its SHA-256 matches).")
@click.pass_context
def command(ctx: click.Context, result: Path, folder: Path | None, truth: Path | None,
            summary_path: Path | None, log: Path | None) -> None:
    """Draw the figures of RESULT (a reconstruction: .parquet or .csv) and a self-contained
    report.html; refuses a recorder log (reconstruct it first)."""
    import pandas as pd

    from flightrecon.cli.progress import check_report_folder, stage_progress
    from flightrecon.errors import InputFileError
    from flightrecon.export.writers import read_track
    from flightrecon.report import write_report

    quiet = bool(ctx.obj and ctx.obj.get("quiet"))
    folder = folder or result.with_name(result.stem + ".report")
    _check_report_not_over_inputs(folder, result, summary_path, truth, log)
    check_report_folder(folder)
    with stage_progress(quiet, ["read", "recorder", "figures"], "plot") as stage:
        stage("read")
        track, meta = read_track(result)
        missing = [c for c in RESULT_COLUMNS if c not in track.columns]
        if missing:
            raise click.BadParameter(
                f"{result} is not a reconstruction result (no {', '.join(missing)} column): "
                f"a recorder log? Run 'flightrecon reconstruct {result}' first and plot its "
                "result", param_hint="RESULT")
        summary = _load_summary(result, meta, summary_path)
        tr = sens = None
        if truth is not None:
            if not truth.is_file():
                raise InputFileError("no such truth file", file=str(truth))
            try:
                tr = pd.read_parquet(truth) if truth.suffix.lower() in (".parquet", ".pq") \
                    else pd.read_csv(truth)
            except (OSError, ValueError) as exc:
                raise InputFileError(f"cannot read the truth: {exc}", file=str(truth)) from exc
            check_truth_matches(track, tr, truth)
            stem = truth.name.removesuffix(".parquet").removesuffix(".csv").removesuffix(
                ".truth")
            sp = truth.with_name(stem + ".sensors.json")
            if sp.is_file():
                sens = json.loads(sp.read_text(encoding="utf-8"))
        stage("recorder")
        grid, gnss, radar, note = recorder_data(summary, result, log) if summary else (
            None, None, None, "no summary")
        stage("figures")
        page = write_report(folder, track, summary, tr, title=f"flightrecon: {result.name}",
                            grid=grid, gnss=gnss, radar=radar, sensor_truth=sens,
                            notes=[f"Recorder channels not drawn: {note}."] if note else None)
    if note and not quiet:
        click.echo(f"  note: recorder channels not drawn: {note}", err=True)
    click.echo(f"wrote {page}")
