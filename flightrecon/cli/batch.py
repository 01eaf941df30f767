"""``flightrecon batch``: reconstruct many flights on a Dask cluster (docs/batch.md)."""

from __future__ import annotations

import sys
from pathlib import Path

import click

from flightrecon.cli.common import gnss_use_from_options, gnss_use_options, parse_k
from flightrecon.cli.trim import trim_options


@click.command("batch")
@click.argument("inputs", nargs=-1, required=True)
@click.option("--out", "out_dir", required=True, type=click.Path(file_okay=False, path_type=Path),
              help="Output folder: results, summaries, manifests, batch_summary.csv, "
                   "aircraft_averages.csv.")
@click.option("--scheduler", metavar="ADDRESS",
              help="Dask scheduler address (tcp://host:port) or scheduler file (*.json); "
                   "default: a local cluster on this machine.")
@click.option("--workers", type=click.IntRange(min=1),
              help="Worker processes of the local cluster (default: the CPU count).")
@click.option("--store", "store_path", type=click.Path(dir_okay=False, path_type=Path),
              help="Coefficient store (SQLite): each flight's fitted k1..k3 and joint "
                   "sensor-error estimates are recorded there by this process (single writer), "
                   "one record per distinct log.")
@click.option("--force", is_flag=True, help="Redo flights already done with the same inputs "
                                            "and settings.")
@click.option("--methods", metavar="LIST",
              help="Comma-separated methods to run (joint,sabziev,arms,azimuth,sns); "
                   "default: every method each flight's data allow.")
@click.option("--rate", "rate_hz", type=float, help="Grid rate for input channels [Hz].")
@click.option("--k", "k_text", metavar="K1,K2,K3",
              help="Sabziev coefficients: initial-value mode, no arrival point needed.")
@click.option("--estimate-noise", is_flag=True,
              help="Joint smoother: estimate each source's noise variance from the flight "
                   "itself (expectation-maximisation; docs/joint.md).")
@click.option("--gap-stretches", "gap_stretches", type=click.IntRange(min=0), default=None,
              metavar="N",
              help="Joint smoother, GNSS gaps: calibrate the in-gap position sd on up to N "
                   "held-out stretches of each flight's own GNSS (default 6; 0: the model's "
                   "sd; docs/joint.md, \"GNSS gaps\"), as for reconstruct.")
@click.option("--mapping", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              help="Column-mapping TOML for the logs whose sidecar names no mapping (a "
                   "sidecar's [files] mapping wins, as for reconstruct).")
@click.option("--frame-rate", "frame_rate_hz", type=float, metavar="HZ",
              help="Frames a second of recorders whose time is their frame count (a table "
                   "with no time column): row k at (k-1)/HZ s, for every log of the batch; "
                   "wins over a mapping's [time] rate_hz, as for reconstruct.")
@click.option("--format", "fmt", type=click.Choice(["parquet", "csv", "geojson", "kml"]),
              default="parquet", show_default=True, help="Result format.")
@gnss_use_options
@trim_options
@click.pass_context
def command(ctx: click.Context, *, inputs: tuple[str, ...], out_dir: Path,
            scheduler: str | None, workers: int | None, store_path: Path | None, force: bool,
            methods: str | None, rate_hz: float | None, k_text: str | None, estimate_noise: bool,
            gap_stretches: int | None, mapping: Path | None, fmt: str,
            frame_rate_hz: float | None = None, no_gnss: bool = False,
            withhold_gnss: tuple[str, ...] = (), gnss_interval: float | None = None,
            gnss_sd: str | None = None, start: str | None = None,
            end: str | None = None) -> None:
    """Reconstruct every log among INPUTS (files, folders, globs) into --out, one Dask task per
    flight; a failed flight is reported and the batch goes on; a re-run skips finished flights."""
    from flightrecon.batch import batch, open_client
    from flightrecon.pipeline import ReconstructSettings

    quiet = bool(ctx.obj and ctx.obj.get("quiet"))
    gnss_use = gnss_use_from_options(no_gnss, withhold_gnss, gnss_interval, gnss_sd)
    if store_path is not None:   # a store that cannot be used: exit 10 before any cluster starts
        from flightrecon.store.db import check_store_path

        check_store_path(store_path)
    settings = ReconstructSettings(
        methods=tuple(m.strip() for m in methods.split(",") if m.strip()) if methods else None,
        rate_hz=rate_hz, k=parse_k(k_text) if k_text else None,
        joint_estimate_noise=estimate_noise, joint_gap_stretches=gap_stretches, start=start,
        end=end)
    bar = None
    if not quiet:
        from tqdm import tqdm

        bar = tqdm(total=None, desc="batch", unit=" flight", file=sys.stderr, leave=True)
    counts = {"ok": 0, "failed": 0, "skipped": 0}

    def started(total: int) -> None:
        if bar is not None:
            bar.total = total
            bar.refresh()

    def progress(oc, total: int) -> None:
        counts[oc.status] += 1
        if bar is not None:
            bar.total = total
            bar.update(1)
            rate = bar.format_dict.get("rate")
            bar.set_postfix(done=counts["ok"], failed=counts["failed"], skipped=counts["skipped"],
                            per_h=f"{3600 * rate:.0f}" if rate else "-")
        if not quiet and oc.status == "failed":
            click.echo(f"  failed {oc.log}: {oc.row['error']}", err=True)

    try:
        with open_client(scheduler, workers) as client:
            res = batch(list(inputs), out_dir, client=client, settings=settings,
                        store=store_path, force=force, progress=progress, fmt=fmt,
                        mapping=mapping, gnss_use=gnss_use, started=started,
                        frame_rate_hz=frame_rate_hz)
    finally:
        if bar is not None:
            bar.close()
    if not quiet:
        for r in res.averages:
            ks = ", ".join(f"{a} = {r[a + '_mean']:.6g} (n {r[a + '_n']})" for a in ("k1", "k2",
                                                                                   "k3"))
            click.echo(f"  {r['aircraft_id']}: {ks}", err=True)
    click.echo(f"{res.count('ok')} ok, {res.count('failed')} failed, {res.count('skipped')} "
               f"skipped in {res.elapsed_s:.1f} s")
    click.echo(f"wrote {res.summary_csv}")
    if getattr(res, "summary_parquet", None) is not None:
        click.echo(f"wrote {res.summary_parquet}")
    click.echo(f"wrote {res.averages_csv}")
    if res.exit_code:
        # SystemExit, not ctx.exit: the CLI runs click with standalone_mode=False, which turns
        # ctx.exit(code) into a return value that flightrecon.cli.main.main() drops
        sys.exit(res.exit_code)
