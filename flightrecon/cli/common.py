"""Helpers shared by the CLI commands (option parsing, default paths, progress)."""

from __future__ import annotations

import contextlib
import math
from collections.abc import Callable, Iterator
from pathlib import Path

import click

from flightrecon.errors import MetadataError


def input_options(f):
    """The options naming a flight's companion files: --gnss, --radar, --mapping, --sidecar;
    and --frame-rate for a recorder whose time is its frame count."""
    path = click.Path(dir_okay=False, path_type=Path)
    for opt in reversed((
        click.option("--gnss", type=path, help="Separate GNSS file."),
        click.option("--radar", type=path, help="Separate radar (range/azimuth) file."),
        click.option("--mapping", type=path, help="Column-mapping TOML for a foreign log."),
        click.option("--sidecar", type=path,
                     help="Metadata TOML (default: <log stem>.meta.toml beside the log)."),
        click.option("--frame-rate", "frame_rate_hz", type=float, metavar="HZ",
                     help="Frames a second of a recorder whose time is its frame count (a "
                          "folder of one-column files or a table with no time column): row k "
                          "at (k-1)/HZ s; wins over the mapping's [time] rate_hz."),
    )):
        f = opt(f)
    return f


def gnss_use_options(f):
    """The options choosing how the GNSS fixes are used: --no-gnss, --withhold-gnss,
    --gnss-interval, --gnss-sd (:func:`gnss_use_from_options` turns them into a
    :class:`flightrecon.ingest.gnss_use.GnssUse`; docs/ingest.md, "Using the GNSS")."""
    for opt in reversed((
        click.option("--no-gnss", "no_gnss", is_flag=True,
                     help="Withhold GNSS: use none of the log's GNSS channels nor a GNSS file "
                          "(a recorder-only reconstruction, e.g. to compare with the GNSS "
                          "track)."),
        click.option("--withhold-gnss", "withhold_gnss", metavar="START:END", multiple=True,
                     help="Withhold the GNSS fixes from START to END (seconds of the log's "
                          "time, as --start/--end); repeatable; reported in the summary "
                          "(docs/ingest.md, 'Using the GNSS')."),
        click.option("--gnss-interval", "gnss_interval", type=float, metavar="S",
                     help="Use at most one GNSS fix every S seconds (the first of each "
                          "S-second slot of the log's time; e.g. 1 for 1 Hz from a 10 Hz "
                          "frame)."),
        click.option("--gnss-sd", "gnss_sd", metavar="H[:V]",
                     help="The GNSS receiver's sd in metres, horizontal per axis [and "
                          "vertical], in place of the log's figure; the rounding of positions "
                          "recorded in steps is still added on top."),
    )):
        f = opt(f)
    return f


def gnss_use_from_options(no_gnss: bool = False, withhold_gnss: tuple[str, ...] = (),
                          gnss_interval: float | None = None, gnss_sd: str | None = None):
    """The options of :func:`gnss_use_options` as a
    :class:`flightrecon.ingest.gnss_use.GnssUse` (a bad value: a usage error naming the
    option, exit 2)."""
    from flightrecon.ingest.gnss_use import GnssUse, parse_gnss_sd, parse_window

    hint = "--withhold-gnss"
    try:
        wins = tuple(parse_window(w) for w in withhold_gnss)
        hint = "--gnss-sd"
        h, v = parse_gnss_sd(gnss_sd) if gnss_sd is not None else (None, None)
        hint = "--gnss-interval"
        return GnssUse(withhold=no_gnss, withhold_s=wins, interval_s=gnss_interval, h_sd_m=h,
                       v_sd_m=v)
    except MetadataError as exc:
        raise click.BadParameter(exc.message, param_hint=hint) from None


class NonEmptyPath(click.Path):
    """A click path that refuses an empty string (``-o ''``) as a usage error (exit code 2)
    instead of taking it for the current folder."""

    def convert(self, value, param, ctx):
        if isinstance(value, str) and value.strip() == "":
            self.fail("the path is empty", param, ctx)
        if isinstance(value, str) and self.file_okay and not self.dir_okay \
                and Path(value).name in ("", ".", ".."):
            self.fail(f"'{value}' is a folder, not a file name", param, ctx)
        return super().convert(value, param, ctx)


def run_inputs(log: Path, *, gnss: Path | None = None, radar: Path | None = None,
               mapping: Path | None = None, sidecar: Path | None = None,
               **others: Path | None) -> dict[str, Path]:
    """Every file a run reads, by role: the log, its companions given on the command line,
    the sidecar (given, or found beside the log) and the companion files it names, and
    ``others`` (noise file, truth, a store read from).  Used to refuse outputs over inputs
    before any work (:func:`flightrecon.export.atomic.check_outputs`); a sidecar that cannot
    be read here is reported later by the ingest, with its own message."""
    from flightrecon.errors import FlightReconError
    from flightrecon.ingest.sidecar import discover_sidecar, load_sidecar

    found: dict[str, Path] = {"log": log}
    for k, v in (("GNSS file", gnss), ("radar file", radar), ("mapping file", mapping)):
        if v is not None:
            found[k] = Path(v)
    sc = Path(sidecar) if sidecar is not None else discover_sidecar(log)
    if sc is not None:
        found["sidecar"] = sc
        try:
            companions = load_sidecar(sc).files if sc.is_file() else {}
        except (FlightReconError, OSError, ValueError):
            companions = {}
        for k, v in companions.items():
            found.setdefault(f"{k} file named by the sidecar", Path(v))
    for k, v in others.items():
        if v is not None:
            found[k.replace("_", " ")] = Path(v)
    return found


def parse_k(text: str) -> tuple[float, float, float]:
    """Parse ``K1,K2,K3`` into three floats."""
    try:
        parts = [float(p) for p in text.split(",")]
    except ValueError as exc:
        raise MetadataError(f"--k expects three numbers K1,K2,K3, got '{text}'") from exc
    if len(parts) != 3 or not all(map(math.isfinite, parts)):
        raise MetadataError(f"--k expects three numbers K1,K2,K3, got '{text}'")
    return (parts[0], parts[1], parts[2])


def position_option_values(**opts: str | None) -> dict:
    """``{'departure': Position, ...}`` from ``LAT,LON,ELEV_M`` option strings."""
    from flightrecon.ingest import parse_position

    return {k: parse_position(v) for k, v in opts.items() if v}


def default_output(log: Path, suffix: str) -> Path:
    """A path beside ``log`` that never overwrites it: ``<stem><suffix>``."""
    stem = log.name
    for s in (".parquet", ".csv", ".pq"):
        if stem.lower().endswith(s):
            stem = stem[: -len(s)]
            break
    return log.with_name(stem + suffix)


def read_sns_noise_file(path: Path) -> dict[str, float] | None:
    """The ``[sns]`` table of a noise TOML file (checked by the SNS method), or ``None``."""
    import tomllib

    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except (OSError, tomllib.TOMLDecodeError, UnicodeDecodeError):
        return None   # read_noise_file reports it
    t = doc.get("sns")
    if t is not None and not isinstance(t, dict):
        raise MetadataError("[sns] in the noise file must be a table", file=str(path))
    if t:
        from flightrecon.methods.sns.method import sns_noise_with
        from flightrecon.methods.sns import MODEL_AIRSPEED

        try:
            sns_noise_with(MODEL_AIRSPEED, t)   # keys and values checked now
        except MetadataError as exc:
            raise MetadataError(exc.message, file=str(path)) from None
    return dict(t) if t else None


def read_noise_file(path: Path) -> dict[str, float]:
    """The ``[joint]`` table of a noise TOML file: field name -> number (safe parser)."""
    import tomllib
    from dataclasses import fields

    from flightrecon.methods.joint import POSITIVE_NOISE, JointNoise

    try:
        with open(path, "rb") as fh:
            doc = tomllib.load(fh)
    except FileNotFoundError as exc:
        raise MetadataError("noise file not found", file=str(path)) from exc
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise MetadataError(f"not a valid TOML file: {exc}", file=str(path)) from exc
    table = doc.get("joint")
    if table is None and isinstance(doc.get("sns"), dict):
        return {}   # an SNS-only noise file (read_sns_noise_file)
    if not isinstance(table, dict):
        raise MetadataError("the noise file needs a [joint] or an [sns] table", file=str(path))
    known = {f.name for f in fields(JointNoise)}
    out = {}
    for k, v in table.items():
        if k not in known:
            raise MetadataError(f"unknown noise setting '{k}' (known: {', '.join(sorted(known))})",
                                file=str(path))
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
            raise MetadataError(f"noise setting '{k}' must be a non-negative number",
                                file=str(path))
        if k in POSITIVE_NOISE and v == 0:
            raise MetadataError(f"noise setting '{k}' must be positive (a standard deviation of "
                                "zero would make its measurements exact)", file=str(path))
        out[k] = float(v)
    return out


def report_file_name(name: str) -> bool:
    """True for the names a report folder receives (``report.html`` and its figures)."""
    return name.lower().endswith((".html", ".htm", ".png"))


def check_run_outputs(log: Path, *, gnss=None, radar=None, mapping=None, sidecar=None,
                      noise_file=None, result: Path, summary: Path, report: Path | None = None,
                      store: Path | None = None, store_is_input: bool = False,
                      fmt: str | None = None) -> None:
    """Refuse, before any work, a reconstruction whose outputs (result, summary, report folder,
    store) would replace one of its inputs or each other, or cannot be written (exit 9), or
    whose coefficient store cannot be used (exit 10).

    The store is an input when it is only read (fleet coefficients) and an output otherwise;
    either way no other output may be written over it.  A store that is not a flightrecon
    store, is read-only, or lies in a folder that is missing or cannot be written is a store
    error naming the store file (:func:`flightrecon.store.db.check_store_path`)."""
    from flightrecon.export.atomic import check_outputs, sweep_leftovers
    from flightrecon.export.writers import format_from_path

    format_from_path(result, fmt)  # a result whose format cannot be told: refused now
    inputs: dict[str, Path | None] = dict(run_inputs(log, gnss=gnss, radar=radar,
                                                     mapping=mapping, sidecar=sidecar,
                                                     noise_file=noise_file))
    outputs: dict[str, Path | None] = {"result": result, "summary": summary}
    if store is not None and store_is_input:
        inputs["coefficient store"] = store
    elif store is not None:
        outputs["coefficient store"] = store
    check_outputs(outputs, inputs, folders={"report": report}, folder_names=report_file_name,
                  own_checks=("coefficient store",))
    if store is not None:
        from flightrecon.store.db import check_store_path

        check_store_path(store, write=not store_is_input)
    for folder in {result.parent, summary.parent} | ({report, report.parent} if report
                                                      else set()):
        sweep_leftovers(folder if str(folder) else Path("."))


def publish_reconstruction(rec, out: Path, summary_path: Path, fmt: str | None,
                           report_dir: Path | None, store: Path | None, *, title: str,
                           record: bool = True, stage: Callable[[str], None] | None = None):
    """Write the result, its summary and its report as one unit, with the store's record.

    Each is written completely into a hidden staging folder beside its target; then, with the
    catchable signals deferred, the flight's coefficients are recorded in the store (one
    transaction) and every output is renamed into place
    (:class:`flightrecon.export.atomic.Publication`).  An error or interrupt before that
    leaves every previous output and the store as they were.  Returns the report page's path
    (or ``None``).
    """
    from flightrecon.export.atomic import Publication
    from flightrecon.export.writers import format_from_path, write_summary, write_track

    page = None
    fmt = format_from_path(out, fmt)
    with Publication() as pub:
        write_track(pub.file(out), rec.track, rec.summary, fmt, attitude=rec.clean.grid)
        if report_dir is not None:
            from flightrecon.report import write_report

            if stage:
                stage("report")
            staged_page = write_report(pub.folder(report_dir), rec.track, rec.summary,
                                       title=title, grid=rec.clean.grid, gnss=rec.clean.gnss,
                                       radar=rec.clean.radar)
            page = Path(report_dir) / staged_page.name
        staged_summary = pub.file(summary_path)

        def record_then_summary() -> None:
            if store is not None and record and "sabziev" in rec.results:
                from flightrecon.pipeline import record_coefficients

                rec.summary["stored_coefficients"] = record_coefficients(store, rec)
            write_summary(staged_summary, rec.summary)

        pub.commit(before=record_then_summary)
    return page


@contextlib.contextmanager
def errors_name_file(log: Path, sidecar: Path | None = None) -> Iterator[None]:
    """Every error of the project that does not name a file is about the run's log: name it.

    A metadata error on a log with no sidecar also says where the sidecar was looked for
    (the usual cause: departure/arrival airfields missing)."""
    from flightrecon.errors import FlightReconError

    try:
        yield
    except FlightReconError as exc:
        if not exc.file:
            exc.file = str(log)
        if isinstance(exc, MetadataError) and sidecar is None:
            from flightrecon.ingest.sidecar import discover_sidecar

            if discover_sidecar(log) is None and "sidecar" not in exc.message:
                expected = default_output(log, ".meta.toml")
                exc.message += (f" (no sidecar: flight metadata is read from {expected} "
                                "beside the log, or give it on the command line)")
        exc.args = (str(exc),)
        raise
