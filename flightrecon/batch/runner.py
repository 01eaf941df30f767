"""Fleet processing: many flights as Dask tasks, one coefficient-store writer (docs/batch.md).

The client (this process) discovers the logs, skips those already done (manifests,
:mod:`flightrecon.batch.manifest`), submits one :func:`flightrecon.batch.task.run_flight` task
per remaining flight and, as each finishes, records its Sabziev fit in the coefficient store in
one transaction, then writes its manifest.  Workers never open the store: SQLite has one writer,
and the client is it.  At the end it refreshes the per-aircraft averages and writes the batch
summary table.
"""

from __future__ import annotations

import csv
import math
import time
import uuid
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from flightrecon.batch.discover import LogEntry, confined, discover_logs, output_paths
from flightrecon.batch.manifest import (
    input_hashes,
    is_up_to_date,
    read_manifest,
    settings_key,
    write_manifest,
)
from flightrecon.errors import FlightReconError, OutputError
from flightrecon.ingest.gnss_use import GnssUse
from flightrecon.pipeline import ReconstructSettings

FORMATS: tuple[str, ...] = ("parquet", "csv", "geojson", "kml")

#: columns of ``batch_summary.csv``
SUMMARY_COLUMNS: tuple[str, ...] = (
    "input", "name", "status", "error", "exit_code", "aircraft_id", "flight_id", "duration_s",
    "k1", "k2", "k3", "sabziev_converged", "stored", "sources", "joint_mean_nis",
    "sns_nis_per_dof", "north_sd_m_median", "east_sd_m_median", "up_sd_m_median", "warnings",
    "elapsed_s", "result")

#: the Parquet type of each summary column (``batch_summary.parquet``): the CSV's columns with
#: their types kept; a missing value is null
SUMMARY_TYPES: dict[str, str] = {
    **{c: "string" for c in ("input", "name", "status", "error", "aircraft_id", "flight_id",
                             "stored", "sources", "result")},
    **{c: "float64" for c in ("duration_s", "k1", "k2", "k3", "joint_mean_nis",
                              "sns_nis_per_dof", "north_sd_m_median", "east_sd_m_median",
                              "up_sd_m_median", "elapsed_s")},
    "exit_code": "int64", "warnings": "int64", "sabziev_converged": "bool"}

#: columns of ``aircraft_averages.csv`` (per axis: fits used, mean, sd, branch)
AVERAGE_COLUMNS: tuple[str, ...] = ("aircraft_id", "n_flights") + tuple(
    f"{a}_{q}" for a in ("k1", "k2", "k3") for q in ("n", "mean", "sd", "branch"))


@dataclass(frozen=True)
class FlightTask:
    """What every flight's task is given besides its files: the reconstruction ``settings``, the
    result format ``fmt``, the batch's ``mapping`` (absolute path or ``None``), its GNSS options
    ``gnss_use`` and its ``--frame-rate`` ``frame_rate_hz``
    (:func:`flightrecon.batch.task.run_flight`)."""

    settings: ReconstructSettings
    fmt: str
    mapping: str | None = None
    gnss_use: GnssUse | None = None
    frame_rate_hz: float | None = None


@dataclass(frozen=True)
class FlightOutcome:
    """One flight of a batch: ``status`` is ``ok``, ``failed`` or ``skipped``; ``row`` its line of
    the batch summary table (:data:`SUMMARY_COLUMNS`)."""

    log: Path
    name: str
    status: str
    row: dict[str, Any]


@dataclass(frozen=True)
class BatchResult:
    """Result of :func:`batch`.

    Attributes
    ----------
    outcomes : one per flight, in input order
    averages : rows of ``aircraft_averages.csv`` (:data:`AVERAGE_COLUMNS`)
    summary_csv, averages_csv : the tables written
    elapsed_s : wall time of the batch
    summary_parquet : the summary table as Parquet (:data:`SUMMARY_TYPES`)
    """

    outcomes: tuple[FlightOutcome, ...]
    averages: tuple[dict[str, Any], ...]
    summary_csv: Path
    averages_csv: Path
    elapsed_s: float
    summary_parquet: Path | None = None

    def count(self, status: str) -> int:
        """Number of flights with ``status``."""
        return sum(1 for o in self.outcomes if o.status == status)

    @property
    def exit_code(self) -> int:
        """0 when no flight failed, else the exit code of the first failed flight."""
        for o in self.outcomes:
            if o.status == "failed":
                return int(o.row.get("exit_code") or 1)
        return 0


def _row(entry: LogEntry, out: dict[str, Any], stored: str) -> dict[str, Any]:
    k = out.get("k") or [None, None, None]
    src = out.get("sources") or {}
    row = {"input": str(entry.log), "name": entry.name, "status": out["status"],
           "error": out.get("error", ""), "exit_code": out.get("exit_code", 0),
           "aircraft_id": out.get("aircraft_id"), "flight_id": out.get("flight_id"),
           "duration_s": out.get("duration_s"), "k1": k[0], "k2": k[1], "k3": k[2],
           "sabziev_converged": out.get("sabziev_converged"), "stored": stored,
           "sources": ";".join(f"{n}:{c}" for n, c in sorted(src.items())),
           "elapsed_s": out.get("elapsed_s"), "result": out.get("result")}
    for c in ("joint_mean_nis", "sns_nis_per_dof", "north_sd_m_median", "east_sd_m_median",
              "up_sd_m_median", "warnings"):
        row[c] = out.get(c)
    return row


def _records(out: dict[str, Any]):
    """The store records of a finished flight: ``(log_sha256, fit or None, calibration or
    None)``; MetadataError when there is nothing to record."""
    from flightrecon.errors import MetadataError
    from flightrecon.store import from_joint_summary, from_sabziev_summary

    if not out.get("aircraft_id"):
        raise MetadataError("no aircraft id")
    inputs = out.get("inputs") or []
    h = out.get("log_sha256") or (inputs[0]["sha256"] if inputs else None)
    if h is None:
        raise MetadataError("no log hash")
    common = dict(aircraft_id=str(out["aircraft_id"]),
                  flight_id=str(out.get("flight_id") or h[:16]),
                  flight_date_utc=out.get("epoch_utc") or "1970-01-01T00:00:00Z",
                  settings=out.get("settings"),
                  input_hashes={i["path"]: i["sha256"] for i in inputs})
    fit = cal = None
    sab = out.get("sabziev")
    # an unhealthy (impossible) Sabziev track is not the aircraft's: its fit is not recorded
    if (sab is not None and sab.get("mode") == "boundary-value"
            and sab.get("status") in ("ok", "fallback")):   # healthy (pipeline/status.py)
        fit = from_sabziev_summary(sab, **common)
    if out.get("joint") is not None:
        cal = from_joint_summary(out["joint"], conditions=out.get("conditions"), log_sha256=h,
                                 **common)
    if fit is None and cal is None:
        raise MetadataError("neither a boundary-value Sabziev fit nor a healthy joint smoother")
    return h, fit, cal


def _record(db, out: dict[str, Any], recs, fits: dict, local_ids: dict) -> str:
    """Record a finished flight (in ``db`` if given, and in ``fits`` for the averages); return
    the table's ``stored`` text.  Without a store the identity rule is applied to this batch's
    flights alone (``local_ids``: (aircraft, flight id) -> log hash)."""
    h, fit, cal = recs
    aircraft = str(out["aircraft_id"])
    if db is not None:
        ident = db.record_flight(aircraft, out.get("flight_id"), h, fit=fit, calibration=cal)
        fid, note = ident.flight_id, ident.note
    else:
        fid = (fit or cal).flight_id
        note = ""
        owner = local_ids.get((aircraft, fid))
        if owner is not None and owner != h:
            new = f"{fid}~{h[:8]}"
            note = (f"flight id '{fid}' of aircraft '{aircraft}' is already used by another log; "
                    f"this log is counted as '{new}'")
            fid = new
        local_ids[(aircraft, fid)] = h
    if fit is not None:
        fits[(aircraft, h)] = replace(fit, flight_id=fid)
    what = "+".join(w for w, p in (("k", fit), ("calibration", cal)) if p is not None)
    return ("yes" if db is not None else "not stored") + f" ({what})" + (
        f": as {fid}, {note}" if note else "")


def _fmt(v: Any) -> Any:
    if v is None:
        return ""
    if isinstance(v, float):
        return "" if math.isnan(v) else repr(v)
    return v


def _write_csv(path: Path, columns: Sequence[str], rows: Sequence[dict[str, Any]]) -> Path:
    from flightrecon.export.atomic import atomic_path

    with atomic_path(path) as tmp, open(tmp, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh, lineterminator="\n")
        w.writerow(columns)
        for r in rows:
            w.writerow([_fmt(r.get(c)) for c in columns])
    return path


def _typed(value: Any, kind: str) -> Any:
    """A summary cell as its Parquet column's type (None: null)."""
    if value is None or (isinstance(value, str) and value == "" and kind != "string"):
        return None
    if kind == "string":
        return str(value)
    if kind == "float64":
        return float(value)
    if kind == "int64":
        return int(value)
    return bool(value)


def write_summary_parquet(path: Path, rows: Sequence[dict[str, Any]]) -> Path:
    """The summary table as Parquet, one typed column per :data:`SUMMARY_COLUMNS`."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    from flightrecon.export.atomic import atomic_path

    types = {"string": pa.string(), "float64": pa.float64(), "int64": pa.int64(),
             "bool": pa.bool_()}
    table = pa.table({c: pa.array([_typed(r.get(c), SUMMARY_TYPES[c]) for r in rows],
                                  type=types[SUMMARY_TYPES[c]]) for c in SUMMARY_COLUMNS})
    with atomic_path(path) as tmp:
        pq.write_table(table, tmp)
    return path


def _average_rows(stats_list) -> list[dict[str, Any]]:
    rows = []
    for st in stats_list:
        r: dict[str, Any] = {"aircraft_id": st.aircraft_id, "n_flights": st.n_flights}
        for a in st.axes:
            r.update({f"{a.axis}_n": a.n, f"{a.axis}_mean": a.mean, f"{a.axis}_sd": a.std,
                      f"{a.axis}_branch": a.branch})
        rows.append(r)
    return rows


def batch(inputs: Sequence[str | Path], out_dir: str | Path, *, client: Any = None,
          settings: ReconstructSettings = ReconstructSettings(), store: str | Path | None = None,
          force: bool = False, progress: Callable[[FlightOutcome, int], None] | None = None,
          fmt: str = "parquet", mapping: str | Path | None = None,
          gnss_use: GnssUse | None = None,
          started: Callable[[int], None] | None = None,
          frame_rate_hz: float | None = None) -> BatchResult:
    """Reconstruct many flights on a Dask cluster; record their coefficients; summarise.

    Parameters
    ----------
    inputs : log files, folders (searched recursively) or globs (:func:`discover_logs`)
    out_dir : output folder (created); every output is confined to it
    client : a ``dask.distributed.Client``; ``None`` runs a local cluster sized to the machine
        (:func:`flightrecon.batch.cluster.open_client`) for the duration of the call
    settings : reconstruction settings of every flight
    store : coefficient store (SQLite) in which the client records each boundary-value Sabziev
        fit, one transaction per flight; ``None``: none (the averages are then taken over this
        batch's fits)
    force : redo flights whose manifest says they are up to date
    progress : called with each :class:`FlightOutcome` as it is known (skipped ones first) and
        the number of flights in the batch
    fmt : result format, one of :data:`FORMATS`
    mapping : mapping file for the logs whose sidecar names none (``--mapping``)
    gnss_use : how every flight's GNSS fixes are used (:class:`flightrecon.ingest.gnss_use.
        GnssUse`: withheld, windows, interval, receiver's sd; a sidecar's ``[gnss]`` is merged
        with it as for ``reconstruct``); part of the settings' key, so a re-run with other GNSS
        options redoes the flights
    started : called once with the number of flights, as soon as the logs are found (before
        any flight is checked or run: a progress bar's total)
    frame_rate_hz : frames a second of the logs whose time is their frame count (``--frame-rate``,
        as for :func:`flightrecon.pipeline.reconstruct`); part of the settings' key

    Returns
    -------
    BatchResult
        Failed flights are in it with their error and exit code; this function raises only for
        a batch that cannot start (no logs, bad output folder, unusable store).
    """
    from flightrecon.store import CoefficientStore
    from flightrecon.store import stats as store_stats

    t_start = time.perf_counter()
    out_dir = _output_folder(out_dir, fmt)
    entries = discover_logs(inputs, out_dir)
    if started is not None:
        started(len(entries))
    store_path = None if store is None else Path(store)
    key = settings_key(settings, fmt, store_path, gnss_use, frame_rate_hz)
    db = CoefficientStore(store_path) if store_path is not None else None
    run = _BatchRun(entries, out_dir, fmt, key, db, progress)
    try:
        todo = []
        for i, e in enumerate(entries):
            paths = output_paths(out_dir, e.name, fmt)
            hashes = input_hashes(e.log, e.sidecar, None if mapping is None else Path(mapping))
            if force or not run.skip_if_done(i, e, paths, hashes):
                todo.append((i, e, paths, hashes))
        if todo:
            task = FlightTask(settings, fmt,
                              None if mapping is None else str(Path(mapping).resolve()),
                              gnss_use, frame_rate_hz)
            _run(todo, client, task, run.finish)
        for j in sorted(run.pending):  # not expected: every submitted flight reports back
            run.record_finished(j, *run.pending.pop(j))
        ordered = tuple(run.outcomes[i] for i in range(len(entries)))
        stats_list = run.aircraft_stats(ordered, store_stats)
    finally:
        if db is not None:
            db.close()
    averages = _average_rows(stats_list)
    summary_csv = _write_csv(confined(out_dir, "batch_summary.csv"), SUMMARY_COLUMNS,
                             [o.row for o in ordered])
    summary_parquet = write_summary_parquet(confined(out_dir, "batch_summary.parquet"),
                                            [o.row for o in ordered])
    averages_csv = _write_csv(confined(out_dir, "aircraft_averages.csv"), AVERAGE_COLUMNS,
                              averages)
    return BatchResult(outcomes=ordered, averages=tuple(averages), summary_csv=summary_csv,
                       averages_csv=averages_csv, elapsed_s=time.perf_counter() - t_start,
                       summary_parquet=summary_parquet)


def _output_folder(out_dir: str | Path, fmt: str) -> Path:
    """The batch's output folder, created, with what an interrupted batch left half-written
    swept away; an unknown format or a file in its place is refused."""
    from flightrecon.export.atomic import sweep_leftovers

    if fmt not in FORMATS:
        raise OutputError(f"unknown format '{fmt}' (choose from {', '.join(FORMATS)})")
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise OutputError("the output folder is a file", file=str(out))
    out.mkdir(parents=True, exist_ok=True)
    sweep_leftovers(out)
    return out


class _BatchRun:
    """The client's record of one batch: outcomes by input index, the Sabziev fits for the
    averages, flight identities without a store.

    Flights are recorded in input order, whatever order they finish in, so that which of two
    logs claiming the same flight id keeps the plain id does not depend on the workers'
    timing (docs/store.md, "Flight identity"); a finished flight waits for the earlier ones.
    """

    def __init__(self, entries: Sequence[LogEntry], out_dir: Path, fmt: str, key: str,
                 db: Any, progress: Callable[[FlightOutcome, int], None] | None) -> None:
        self.entries, self.out_dir, self.fmt, self.key, self.db = entries, out_dir, fmt, key, db
        self.progress = progress
        self.outcomes: dict[int, FlightOutcome] = {}
        self.fits: dict = {}  # (aircraft, log SHA-256) -> FlightCoefficients, for the averages
        self.local_ids: dict = {}  # (aircraft, flight id) -> log SHA-256, identity, no store
        self.pending: dict[int, tuple[dict[str, Any], dict[str, str]]] = {}
        self.next_i = 0

    def _report(self, i: int, oc: FlightOutcome) -> None:
        self.outcomes[i] = oc
        if self.progress:
            self.progress(oc, len(self.entries))

    def skip_if_done(self, i: int, e: LogEntry, paths: dict[str, Path],
                     hashes: dict[str, str]) -> bool:
        """Skip flight ``i`` when its manifest says it is up to date (its fit still counts
        for the averages, recorded again in a replaced store); ``False`` when it must run."""
        man = read_manifest(paths["manifest"])
        if man is None or not is_up_to_date(man, hashes, self.key,
                                            [paths["result"], paths["summary"]]):
            return False
        prev = man["outcome"]
        try:
            recs = _records(prev)
        except FlightReconError:
            recs = None  # the flight had nothing to record
        if recs is not None:
            aircraft, h = str(prev["aircraft_id"]), recs[0]
            fid = self.db.flight_id_of(aircraft, h) if self.db is not None else None
            if fid is None:  # no store, or the store was replaced since: record again
                _record(self.db, prev, recs, self.fits, self.local_ids)
            elif recs[1] is not None:
                self.fits[(aircraft, h)] = replace(recs[1], flight_id=fid)
        row = {**man["row"], "status": "skipped"}
        self._report(i, FlightOutcome(log=e.log, name=e.name, status="skipped", row=row))
        return True

    def finish(self, i: int, out: dict[str, Any], hashes: dict[str, str]) -> None:
        """A flight's task is done: record it, and every later one waiting for it, in order."""
        self.pending[i] = (out, hashes)
        while self.next_i < len(self.entries) and (self.next_i in self.pending
                                                   or self.next_i in self.outcomes):
            j = self.next_i
            if j in self.pending:
                self.record_finished(j, *self.pending.pop(j))
            self.next_i += 1

    def record_finished(self, i: int, out: dict[str, Any], hashes: dict[str, str]) -> None:
        """Store flight ``i``'s fit (one transaction; a StoreError stops the resumable batch),
        write its manifest (or remove a stale one) and report its outcome."""
        e = self.entries[i]
        stored = ""
        paths = output_paths(self.out_dir, e.name, self.fmt)
        if out["status"] == "ok":
            try:
                recs = _records(out)
            except FlightReconError as exc:  # nothing to record: said in the table
                stored = f"no: {exc}"
            else:
                stored = _record(self.db, out, recs, self.fits, self.local_ids)
            row = _row(e, out, stored)
            write_manifest(paths["manifest"], {
                "status": "ok", "log": str(e.log), "inputs": hashes, "settings_key": self.key,
                "finished_utc": time.strftime("%Y-%m-%dT%H:%M:%SZ", time.gmtime()),
                "row": row, "outcome": {k: v for k, v in out.items() if k != "warnings"}})
        else:
            row = _row(e, out, stored)
            paths["manifest"].unlink(missing_ok=True)  # a stale manifest must not outlive this
        self._report(i, FlightOutcome(log=e.log, name=e.name, status=out["status"], row=row))

    def aircraft_stats(self, ordered: Sequence[FlightOutcome], store_stats: Any) -> list:
        """Each aircraft's coefficient statistics: from the store, or over this batch's fits."""
        aircraft = sorted({str(o.row["aircraft_id"]) for o in ordered
                           if o.status != "failed" and o.row.get("aircraft_id")})
        stats_list = []
        for a in aircraft:
            if self.db is not None:
                if self.db.list_flights(a):
                    stats_list.append(self.db.aircraft_stats(a))
            else:
                recs = [f for (ac, _), f in sorted(self.fits.items()) if ac == a]
                if recs:
                    stats_list.append(store_stats.aircraft_stats(a, recs))
        return stats_list


def _run(todo, client, task: FlightTask, finish) -> None:
    """Submit one task per flight and hand each result to ``finish`` as it completes."""
    from flightrecon.batch.cluster import open_client

    if client is None:
        with open_client() as c:
            _submit_all(c, todo, task, finish)
    else:
        _submit_all(client, todo, task, finish)


def _submit_all(client, todo, task: FlightTask, finish) -> None:
    from distributed import as_completed

    from flightrecon.batch.task import run_flight

    futures = {}
    for i, e, paths, hashes in todo:
        fut = client.submit(run_flight, str(e.log.resolve()),
                            None if e.sidecar is None else str(e.sidecar.resolve()),
                            str(paths["result"].resolve()), str(paths["summary"].resolve()),
                            task.settings, task.fmt, task.mapping, task.gnss_use,
                            task.frame_rate_hz, key=f"flightrecon-{e.name}-{uuid.uuid4().hex[:12]}",
                            pure=False)
        futures[fut] = (i, hashes)
    try:
        for fut in as_completed(list(futures)):
            i, hashes = futures[fut]
            try:
                out = fut.result()
            except Exception as exc:  # noqa: BLE001 - a worker died or the task was lost
                out = {"status": "failed", "error": f"task lost: {type(exc).__name__}: {exc}",
                       "exit_code": 1, "elapsed_s": None}
            finish(i, out, hashes)
    finally:
        for fut in futures:
            fut.release()
