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


def _unit(quantity: str) -> str:
    """Short unit of a sensor error from its name's suffix."""
    for suffix, unit in (("_deg", "deg"), ("_g", "g"), ("_m", "m"), ("_per_km", "(m/s)/km")):
        if quantity.endswith(suffix):
            return unit
    return "1"


def _calibration_table(cal) -> str:
    header = ["error", "unit", "n", "mean", "sd", "prior_sd", "drift_per_sqrt_day", "drift",
              "applied", "excluded"]
    applied = cal.priors()
    rows = [[q.quantity, _unit(q.quantity), str(q.n), _num(q.mean, ".4g"),
             _num(q.sd, ".3g"), _num(q.prior_sd, ".3g"), _num(q.drift_sd_per_sqrt_day, ".3g"),
             q.drift_source.split(":")[0], "yes" if q.quantity in applied else "no",
             str(len(q.excluded))] for q in cal.quantities]
    return _table(header, rows)


def _echo_calibration(cal) -> None:
    used = cal.flights_used()
    click.echo(f"sensor calibration of {cal.aircraft_id} at {cal.at_utc}"
               + (f", configuration '{cal.configuration}'" if cal.configuration else "")
               + f": {cal.n_flights} flight(s) recorded, {len(used)} used"
               + (f" ({', '.join(used)})" if used else ""))
    click.echo(_calibration_table(cal))
    for q in cal.quantities:
        for e in q.excluded:
            if not e.reason.startswith("not observed"):
                click.echo(f"  excluded {q.quantity} of flight {e.flight_id}: {e.reason}")
    n_unobs = sum(1 for q in cal.quantities for e in q.excluded
                  if e.reason.startswith("not observed"))
    if n_unobs:
        click.echo(f"  {n_unobs} estimate(s) left out as not observed on their flight "
                   f"(sd >= 0.95 x prior sd); --json lists them")
    for c in cal.changes:
        click.echo(f"  sensor change {c.quantity} at {c.change_utc}" + (f": {c.note}" if c.note
                                                                         else ""))
    click.echo("  applied = used as the joint smoother's prior by reconstruct "
               "--use-fleet-coefficients")


def _calibration_dict(cal) -> dict[str, Any]:
    d = asdict(cal)
    d["flights_used"] = list(cal.flights_used())
    d["applied"] = sorted(cal.priors())
    return d


def _calibrations_table(cals: list) -> str:
    header = ["flight", "date_utc", "configuration", "sources", "tas_mps", "converged",
              "log_sha256", "errors"]
    rows = [[c.flight_id, c.flight_date_utc, c.configuration or "-", c.sources or "-",
             f"{_num(c.tas_range_mps[0], '.0f')}-{_num(c.tas_range_mps[1], '.0f')}",
             "yes" if c.converged else "NO", (c.log_sha256 or "-")[:12], str(len(c.estimates))]
            for c in cals]
    return _table(header, rows)


@click.group("coeffs")
def command() -> None:
    """Per-aircraft store: Sabziev coefficients k1..k3 and the joint smoother's sensor
    calibration (list, show, average, export, remove, sensor-change, drift)."""


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
        cals = store.list_calibrations(aircraft_id)
    if as_json:  # the Sabziev fits (sensor estimates: coeffs show AIRCRAFT --json)
        _echo_json([f.as_dict() for f in fits])
        return
    click.echo(f"store: {path}")
    fitted = {(f.aircraft_id, f.flight_id) for f in fits}
    only = [c for c in cals if (c.aircraft_id, c.flight_id) not in fitted]
    if not fits and not only:
        suffix = f" for aircraft '{aircraft_id}'" if aircraft_id else ""
        click.echo("no flights recorded" + suffix)
        return
    if fits:
        click.echo(_flights_table(fits))
    if only:
        click.echo("flights with sensor estimates and no Sabziev fit:")
        click.echo(_table(["aircraft", "flight", "date_utc", "sources"],
                          [[c.aircraft_id, c.flight_id, c.flight_date_utc, c.sources or "-"]
                           for c in only]))
    n_cal = len({(c.aircraft_id, c.flight_id) for c in cals})
    n_air = len({f.aircraft_id for f in fits} | {c.aircraft_id for c in cals})
    click.echo(f"{len(fitted) + len(only)} flight(s), {n_air} aircraft; {len(fits)} Sabziev "
               f"fit(s), {n_cal} with sensor estimates")


@command.command("show")
@_store_option
@click.argument("aircraft_id", metavar="AIRCRAFT")
@click.argument("flight_id", metavar="[FLIGHT]", required=False)
@_json_option
def show_cmd(store_path: Path | None, aircraft_id: str, flight_id: str | None,
             as_json: bool) -> None:
    """Show one AIRCRAFT's flights and fused sensor calibration, or one FLIGHT in full
    (settings, input hashes, sensor-error estimates)."""
    from flightrecon.errors import StoreError

    with _open(store_path) as store:
        if flight_id is not None:
            try:
                cal = store.get_calibration(aircraft_id, flight_id)
            except StoreError:
                cal = None
            try:
                fit = store.get(aircraft_id, flight_id)
            except StoreError:
                if cal is None:
                    raise
                fit = None
            if as_json:
                d = fit.as_dict() if fit is not None else {"aircraft_id": aircraft_id,
                                                           "flight_id": flight_id}
                _echo_json({**d, "calibration": None if cal is None else cal.as_dict()})
                return
            if cal is not None:
                click.echo(f"sensor errors estimated on flight {flight_id} ({cal.sources}; "
                           f"TAS {_num(cal.tas_range_mps[0], '.0f')}-"
                           f"{_num(cal.tas_range_mps[1], '.0f')} m/s, configuration "
                           f"'{cal.configuration}', log {cal.log_sha256 or '-'})")
                click.echo(_table(["error", "value", "sd", "prior_mean", "prior_sd", "unit"],
                                  [[e.quantity, _num(e.value, ".4g"), _num(e.sd, ".3g"),
                                    _num(e.prior_mean, ".3g"), _num(e.prior_sd, ".3g"), e.unit]
                                   for e in cal.estimates]))
            if fit is None:
                return
            click.echo("Sabziev fit:")
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
        cals = store.list_calibrations(aircraft_id)
        fused = store.calibration(aircraft_id) if cals else None
    if not fits and not cals:
        raise StoreError(f"no flights of aircraft '{aircraft_id}' in the store",
                         file=str(store.path))
    if as_json:  # one object per flight: its Sabziev fit's fields and its "calibration"
        by_id = {c.flight_id: c.as_dict() for c in cals}
        rows = [{**f.as_dict(), "calibration": by_id.pop(f.flight_id, None)} for f in fits]
        rows += [{"aircraft_id": aircraft_id, "flight_id": fid, "calibration": c}
                 for fid, c in by_id.items()]
        _echo_json(rows)
        return
    if fits:
        click.echo(_flights_table(fits))
        click.echo(f"{len(fits)} Sabziev fit(s) of {aircraft_id}; averages: flightrecon coeffs "
                   f"average {aircraft_id}")
    if cals:
        click.echo(_calibrations_table(cals))
        _echo_calibration(fused)


@command.command("average")
@_store_option
@click.argument("aircraft_id", metavar="AIRCRAFT")
@_json_option
@click.option("--at", "at_utc", metavar="DATE",
              help="Calibration for this UTC date or time (default: the latest flight's).")
@click.option("--configuration", metavar="TEXT",
              help="Fuse only the flights flown in this configuration.")
def average_cmd(store_path: Path | None, aircraft_id: str, as_json: bool, at_utc: str | None,
                configuration: str | None) -> None:
    """AIRCRAFT's fused sensor calibration and the per-axis mean, median, spread and drift of
    its Sabziev coefficients.

    Sensor errors: each flight's estimate with its prior divided out, combined by inverse
    variance with a random-walk drift (set with `coeffs drift`, else estimated), outliers
    (4 sd from the other flights) excluded, flights before a sensor change left out
    (docs/store.md).  Coefficients: only converged fits on each axis's majority root branch are
    averaged (ties go to the negative, physical branch); the others are listed as excluded.
    The fleet mean that --use-fleet-coefficients uses follows: the time constant -1/k (k1, k3)
    or loop frequency sqrt(-k2) (k2) over the fits on the stable branch, weighted by each
    root's conditioning, with its flight-to-flight spread and chi2/dof (about 1 when the fits
    scatter as their conditioning says; much more: not one aircraft value).
    """
    from flightrecon.errors import StoreError

    with _open(store_path) as store:
        cals = store.list_calibrations(aircraft_id)
        fused = (store.calibration(aircraft_id, at_utc, configuration=configuration)
                 if cals else None)
        try:
            st = store.aircraft_stats(aircraft_id)
        except StoreError:
            if fused is None:
                raise
            st = None
    if as_json:
        d = None
        if st is not None:
            d = asdict(st)
            for ax, a in zip(d["axes"], st.axes):
                ax["excluded_counts"] = a.excluded_counts()
        _echo_json({**(d or {"aircraft_id": aircraft_id}), "sabziev": d,
                    "calibration": None if fused is None else _calibration_dict(fused)})
        return
    if fused is not None:
        _echo_calibration(fused)
    if st is None:
        return
    click.echo(f"aircraft {aircraft_id}: {st.n_flights} Sabziev fit(s) recorded")
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
    click.echo("fleet mean (stable branch, weighted by each root's conditioning):")
    header = ["axis", "quantity", "n", "weighted", "mean", "se", "spread", "chi2_dof", "k"]
    rows = [[p.axis, p.quantity, str(p.n), "yes" if p.weighted else "no", _num(p.mean),
             _num(p.se), _num(p.spread), _num(p.chi2_dof, ".3g"), _num(p.k)]
            for p in (a.prop for a in st.axes) if p is not None]
    click.echo(_table(header, rows))


@command.command("export")
@_store_option
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              help="CSV file to write.")
@click.option("--aircraft", "aircraft_id", metavar="ID", help="Only this aircraft.")
@click.option("--calibration", is_flag=True,
              help="Export the sensor-error estimates (one row per flight and error) instead "
                   "of the Sabziev fits.")
def export_cmd(store_path: Path | None, output: Path, aircraft_id: str | None,
               calibration: bool) -> None:
    """Write the recorded flights to a CSV file (atomically)."""
    from flightrecon.export.atomic import check_not_input

    path = _resolved(store_path)
    check_not_input(output, [path, Path(str(path) + "-wal"), Path(str(path) + "-shm")])
    with _open(store_path) as store:
        if calibration:
            n = store.export_calibration_csv(output, aircraft_id)
            click.echo(f"wrote {output} ({n} sensor estimate(s))")
            return
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
            n = len({f.flight_id for f in store.list_flights(aircraft_id)}
                    | {c.flight_id for c in store.list_calibrations(aircraft_id)})
            what = f"all {n} flight(s) of aircraft '{aircraft_id}'"
        else:
            try:
                store.get(aircraft_id, flight_id)
            except StoreError as exc:
                try:
                    store.get_calibration(aircraft_id, flight_id)
                except StoreError:
                    raise exc from None
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


@command.command("sensor-change")
@_store_option
@click.argument("aircraft_id", metavar="AIRCRAFT")
@click.argument("date", metavar="DATE")
@click.option("--error", "quantity", default="*", show_default=True, metavar="NAME",
              help="The sensor error concerned (e.g. tas_scale); '*' for every sensor.")
@click.option("--note", default="", help="Why (work order, part replaced).")
@click.option("--remove", is_flag=True, help="Delete this sensor change instead.")
def sensor_change_cmd(store_path: Path | None, aircraft_id: str, date: str, quantity: str,
                      note: str, remove: bool) -> None:
    """Record that AIRCRAFT's sensor was changed at DATE (UTC): flights before it no longer
    count for its calibration after it."""
    from flightrecon.store import PERSISTENT
    from flightrecon.store.calibration import DAY_DEPENDENT

    if quantity != "*" and quantity not in PERSISTENT + DAY_DEPENDENT:
        raise click.BadParameter(f"unknown sensor error '{quantity}' (choose from "
                                 f"{', '.join(PERSISTENT + DAY_DEPENDENT)} or '*')",
                                 param_hint="--error")
    with _open(store_path) as store:
        if remove:
            n = store.remove_sensor_change(aircraft_id, date, quantity)
            click.echo(f"removed {n} sensor change(s)")
            return
        ch = store.add_sensor_change(aircraft_id, date, quantity, note)
    click.echo(f"sensor change of {ch.quantity} on {ch.aircraft_id} at {ch.change_utc} recorded")


@command.command("drift")
@_store_option
@click.argument("aircraft_id", metavar="AIRCRAFT")
@click.argument("quantity", metavar="ERROR")
@click.argument("value", metavar="SD_PER_SQRT_DAY|estimate")
def drift_cmd(store_path: Path | None, aircraft_id: str, quantity: str, value: str) -> None:
    """Set the random-walk drift of one sensor ERROR of AIRCRAFT (its unit per sqrt(day)), or
    'estimate' to estimate it from the flights again."""
    if value == "estimate":
        q = None
    else:
        try:
            q = float(value)
        except ValueError:
            raise click.BadParameter(f"expected a number or 'estimate', got '{value}'",
                                     param_hint="VALUE") from None
    with _open(store_path) as store:
        store.set_drift(aircraft_id, quantity, q)
    click.echo(f"drift of {quantity} on {aircraft_id}: "
               + ("estimated from the flights" if q is None else f"{q:g} per sqrt(day)"))
