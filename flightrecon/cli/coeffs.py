"""``flightrecon coeffs``: inspect, average, export and prune the per-aircraft coefficient store.

The work is done by :mod:`flightrecon.store`; this module only parses options and prints.
Every subcommand takes ``--store PATH`` (default ``$FLIGHTRECON_STORE``, else the per-user data
folder, see docs/store.md).  Store problems exit with code 10.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict
from pathlib import Path
from typing import Any

import click

_store_option = click.option(
    "--store", "store_path", type=click.Path(dir_okay=False, path_type=Path),
    help="Coefficient store file (default: $FLIGHTRECON_STORE, else "
         "~/.local/share/flightrecon/coefficients.sqlite or the platform's equivalent).")
_json_option = click.option("--json", "as_json", is_flag=True, help="Machine-readable JSON output.")


def _open(store_path: Path | None):
    """Open an existing store (reading commands never create one)."""
    from flightrecon.store import CoefficientStore

    return CoefficientStore(store_path, create=False)


def _resolved(store_path: Path | None) -> Path:
    from flightrecon.store import default_store_path

    return store_path if store_path is not None else default_store_path()


def _plain(obj: Any) -> Any:
    """JSON-ready copy: NaN and infinities become null, tuples lists."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {k: _plain(v) for k, v in obj.items()}
    if isinstance(obj, (list, tuple)):
        return [_plain(v) for v in obj]
    return obj


def _echo_json(obj: Any) -> None:
    click.echo(json.dumps(_plain(obj), indent=2, allow_nan=False))


def _num(x: float | None, fmt: str = ".6g") -> str:
    if x is None or (isinstance(x, float) and not math.isfinite(x)):
        return "-"
    return format(x, fmt)


def _table(header: list[str], rows: list[list[str]]) -> str:
    """A plain fixed-width table, columns left-aligned."""
    widths = [max(len(h), *(len(r[i]) for r in rows)) if rows else len(h)
              for i, h in enumerate(header)]
    lines = ["  ".join(h.ljust(w) for h, w in zip(header, widths)).rstrip()]
    lines.append("  ".join("-" * w for w in widths))
    lines += ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in rows]
    return "\n".join(lines)


def _converged_text(f) -> str:
    """``yes``, or ``NO`` with the axes that did not converge."""
    if f.converged:
        return "yes"
    bad = [ax for ax, ok in zip(("k1", "k2", "k3"), f.axis_converged) if not ok]
    return "NO (" + ",".join(bad) + ")"


def _flights_table(fits: list) -> str:
    header = ["aircraft", "flight", "date_utc", "duration_s", "k1_per_s", "k2_per_s2", "k3_per_s",
              "branch", "converged", "residual_m", "iterations"]
    short = {"negative": "neg", "positive": "pos", "none": "-"}
    rows = [[f.aircraft_id, f.flight_id, f.flight_date_utc, _num(f.duration_s, ".0f"),
             _num(f.k1), _num(f.k2), _num(f.k3), "/".join(short[b] for b in f.branch),
             _converged_text(f), _num(f.residual_m, ".3g"),
             "-" if f.iterations is None else str(f.iterations)] for f in fits]
    return _table(header, rows)


@click.group("coeffs")
def command() -> None:
    """Per-aircraft store of Sabziev coefficients k1..k3: list, show, average, export, remove."""


@command.command("list")
@_store_option
@click.option("--aircraft", "aircraft_id", metavar="ID", help="Only this aircraft.")
@_json_option
def list_cmd(store_path: Path | None, aircraft_id: str | None, as_json: bool) -> None:
    """List the recorded flights (all aircraft, or one)."""
    path = _resolved(store_path)
    if not path.exists():
        if as_json:
            _echo_json([])
        else:
            click.echo(f"store: {path} (does not exist yet: no flights recorded)")
        return
    with _open(store_path) as store:
        fits = store.list_flights(aircraft_id)
    if as_json:
        _echo_json([f.as_dict() for f in fits])
        return
    click.echo(f"store: {path}")
    if not fits:
        suffix = f" for aircraft '{aircraft_id}'" if aircraft_id else ""
        click.echo("no flights recorded" + suffix)
        return
    click.echo(_flights_table(fits))
    n_air = len({f.aircraft_id for f in fits})
    click.echo(f"{len(fits)} flight(s), {n_air} aircraft")


@command.command("show")
@_store_option
@click.argument("aircraft_id", metavar="AIRCRAFT")
@click.argument("flight_id", metavar="[FLIGHT]", required=False)
@_json_option
def show_cmd(store_path: Path | None, aircraft_id: str, flight_id: str | None,
             as_json: bool) -> None:
    """Show one AIRCRAFT's flights, or one FLIGHT in full (settings, input hashes)."""
    from flightrecon.errors import StoreError

    with _open(store_path) as store:
        if flight_id is not None:
            fit = store.get(aircraft_id, flight_id)
            if as_json:
                _echo_json(fit.as_dict())
                return
            d = fit.as_dict()
            for key in ("settings", "input_hashes"):
                d[key] = json.dumps(d[key], sort_keys=True)
            d["branch"] = ", ".join(f"{ax} {b}" for ax, b in zip(("k1", "k2", "k3"), fit.branch))
            width = max(len(k) for k in d)
            for key, val in d.items():
                shown = _num(val) if isinstance(val, float) else ("-" if val is None else val)
                click.echo(f"{key.ljust(width)}  {shown}")
            return
        fits = store.list_flights(aircraft_id)
    if not fits:
        raise StoreError(f"no flights of aircraft '{aircraft_id}' in the store",
                         file=str(store.path))
    if as_json:
        _echo_json([f.as_dict() for f in fits])
        return
    click.echo(_flights_table(fits))
    click.echo(f"{len(fits)} flight(s) of {aircraft_id}; averages: flightrecon coeffs average "
               f"{aircraft_id}")


@command.command("average")
@_store_option
@click.argument("aircraft_id", metavar="AIRCRAFT")
@_json_option
def average_cmd(store_path: Path | None, aircraft_id: str, as_json: bool) -> None:
    """Per-axis mean, median, spread and drift of AIRCRAFT's coefficients.

    Only converged fits on each axis's majority root branch are averaged (ties go to the
    negative, physical branch); the others are listed as excluded.
    """
    with _open(store_path) as store:
        st = store.aircraft_stats(aircraft_id)
    if as_json:
        d = asdict(st)
        for ax, a in zip(d["axes"], st.axes):
            ax["excluded_counts"] = a.excluded_counts()
        _echo_json(d)
        return
    click.echo(f"aircraft {aircraft_id}: {st.n_flights} flight(s) recorded")
    units = {"k1": "1/s", "k2": "1/s^2", "k3": "1/s"}
    header = ["axis", "unit", "branch", "n", "mean", "median", "std", "drift_per_day",
              "drift_se_per_day", "excluded"]
    rows = [[a.axis, units[a.axis], a.branch or "-", str(a.n), _num(a.mean), _num(a.median),
             _num(a.std), _num(a.drift_per_day, ".3g"), _num(a.drift_se_per_day, ".3g"),
             str(len(a.excluded))] for a in st.axes]
    click.echo(_table(header, rows))
    for a in st.axes:
        for e in a.excluded:
            click.echo(f"  excluded {a.axis} of flight {e.flight_id}: {e.reason}")


@command.command("export")
@_store_option
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="CSV file to write.")
@click.option("--aircraft", "aircraft_id", metavar="ID", help="Only this aircraft.")
def export_cmd(store_path: Path | None, output: Path, aircraft_id: str | None) -> None:
    """Write the recorded flights to a CSV file (atomically)."""
    from flightrecon.export.atomic import check_not_input

    path = _resolved(store_path)
    check_not_input(output, [path, Path(str(path) + "-wal"), Path(str(path) + "-shm")])
    with _open(store_path) as store:
        n = store.export_csv(output, aircraft_id)
    click.echo(f"wrote {output} ({n} flight(s))")


@command.command("remove")
@_store_option
@click.argument("aircraft_id", metavar="AIRCRAFT")
@click.argument("flight_id", metavar="[FLIGHT]", required=False)
@click.option("--yes", "-y", is_flag=True, help="Do not ask for confirmation.")
def remove_cmd(store_path: Path | None, aircraft_id: str, flight_id: str | None,
               yes: bool) -> None:
    """Remove one FLIGHT of AIRCRAFT, or all of AIRCRAFT's flights."""
    from flightrecon.errors import StoreError

    with _open(store_path) as store:
        if flight_id is None:
            n = len(store.list_flights(aircraft_id))
            what = f"all {n} flight(s) of aircraft '{aircraft_id}'"
        else:
            store.get(aircraft_id, flight_id)  # StoreError if absent
            n = 1
            what = f"flight '{flight_id}' of aircraft '{aircraft_id}'"
        if n == 0:
            raise StoreError(f"no flights of aircraft '{aircraft_id}' in the store",
                             file=str(store.path))
        if not yes:
            try:
                agreed = click.confirm(f"remove {what} from {store.path}?", default=False)
            except click.Abort:
                import sys

                if sys.stdin is not None and sys.stdin.isatty():
                    raise  # Ctrl-C at the prompt: interrupted (130)
                raise click.UsageError("no answer to the confirmation (standard input is "
                                       "empty or closed): nothing removed; add --yes to "
                                       "remove without asking") from None
            if not agreed:
                click.echo("nothing removed")
                return
        removed = store.remove(aircraft_id, flight_id)
    click.echo(f"removed {removed} flight(s)")
