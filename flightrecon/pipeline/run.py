"""Running a reconstruction: the estimators on a cleaned flight (:func:`reconstruct_clean`),
the whole chain from a log (:func:`reconstruct`) and the coefficient store's part in it."""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import pandas as pd

from flightrecon.errors import (
    ConvergenceError,
    FlightReconError,
    FlightReconWarning,
    MetadataError,
    NoResultError,
)
from flightrecon.memory import release_unused
from flightrecon.pipeline.coldstart import (
    ChildMethods,
    EarlyChild,
    child_methods,
    load_first_kernel_early,
)
from flightrecon.pipeline.combine import combine
from flightrecon.pipeline.fleet import fleet_settings, record_flight
from flightrecon.pipeline.health import has_finite_track, method_health
from flightrecon.pipeline.registry import (
    ALL_METHODS,
    METHOD_FUNCTIONS,
    Reconstruction,
    ReconstructSettings,
    available_methods,
    run_method,
)
from flightrecon.pipeline.status import FEEDS_DEFAULT, method_status
from flightrecon.pipeline.summary import build_summary, result_choice
from flightrecon.pipeline.unit_doubts import DOUBTFUL, doubt
from flightrecon.types import CleanFlight, Flight, MethodResult

if TYPE_CHECKING:
    from flightrecon.ingest.gnss_use import GnssUse

NUMERICAL_FAILURES: tuple[type[BaseException], ...] = (
    FlightReconError, ValueError, ArithmeticError, np.linalg.LinAlgError)
"""What a method may raise and still leave the others' results standing: the project's own
errors, and numerical breakdowns (``LinAlgError`` is a ``ValueError``; ``FloatingPointError``,
``ZeroDivisionError`` and ``OverflowError`` are ``ArithmeticError``).  Anything else is a bug
and stops the run."""


def default_workers() -> int:
    """Threads for the estimators: two where the machine has two cores or more.

    The estimators are independent and their compiled kernels release the GIL, so the joint
    smoother runs beside the others; the results do not depend on the number of threads.
    """
    return max(1, min(2, os.cpu_count() or 1))


def _chosen_methods(clean: CleanFlight, settings: ReconstructSettings
                    ) -> tuple[list[str], dict[str, Any]]:
    """The methods to run (those asked for, or every one the flight allows) and the summary
    status of the others (skipped, with the reason); MetadataError for a method asked for that
    does not exist or cannot run on this flight."""
    avail = available_methods(clean, settings)
    if settings.methods is None:
        chosen = [m for m in ALL_METHODS if avail[m] is None]
    else:
        unknown = [m for m in settings.methods if m not in METHOD_FUNCTIONS]
        if unknown:
            raise MetadataError(f"unknown method(s) {', '.join(unknown)}; "
                                f"choose from {', '.join(ALL_METHODS)}")
        for m in settings.methods:
            if avail[m] is not None:
                raise MetadataError(f"method '{m}' cannot run on this flight: {avail[m]}")
        chosen = list(settings.methods)
    status: dict[str, Any] = {m: {"status": "skipped",
                                  "reason": avail[m] or "not among the methods asked for "
                                                        "(--methods)"}
                              for m in ALL_METHODS if m not in chosen}
    return chosen, status


def reconstruct_clean(clean: CleanFlight, settings: ReconstructSettings = ReconstructSettings(),
                      progress: Callable[[str], None] | None = None, workers: int | None = None,
                      early_child: EarlyChild | None = None
                      ) -> tuple[pd.DataFrame, dict[str, MethodResult], dict[str, Any]]:
    """Run the estimators on a cleaned flight and combine them.

    ``workers`` threads run the estimators (default :func:`default_workers`; 1: one after the
    other, in the order of ``ALL_METHODS``).  ``early_child``: a child process started before
    the log was read (pipeline/coldstart.py), used if methods go to a child.  Returns the
    track, the method results and the per-method status for the summary.
    """
    chosen, status = _chosen_methods(clean, settings)
    results: dict[str, MethodResult] = {}
    workers = default_workers() if workers is None else max(1, int(workers))

    # on a cold kernel cache the methods other than the joint smoother compile and run in a
    # child process while this one compiles the joint smoother (pipeline/coldstart.py)
    early = early_child.take() if early_child is not None else None
    child = ChildMethods(child_methods(chosen, workers, early_started=early is not None),
                         clean, settings, early)

    def run(name: str) -> MethodResult:
        if progress:
            progress(name)
        if child.handles(name):
            return child.result(name, clean, settings)
        try:
            return run_method(name, clean, settings)
        finally:
            # what the method freed stays in its thread's malloc arena (the CLI does not let
            # glibc trim), where the other thread's estimator cannot reuse it: handed back, so
            # that a finished method's peak does not add to the one still running
            # (docs/performance.md, 10-hour flight: peak 1128 -> 993 MiB)
            release_unused()

    # with two threads the joint smoother, the longest, starts first and runs beside the others
    order = sorted(chosen, key=lambda name: name != "joint") if workers > 1 else chosen
    with child, ThreadPoolExecutor(max_workers=workers) as pool:
        futures = {m: pool.submit(run, m) for m in order}
    for m in chosen:
        try:
            res = futures[m].result()
        except NUMERICAL_FAILURES as exc:
            # one method's failure (bad data it cannot use, or a numerical breakdown: a
            # singular matrix, an overflow) is that method's error, not the whole run's
            if settings.strict:
                raise
            reason = str(exc) if isinstance(exc, FlightReconError) else (
                f"numerical failure ({type(exc).__name__}): {exc}")
            status[m] = {"status": "failed", "reason": reason}
            continue
        results[m] = res
        health = method_health(res, clean)
        status[m] = method_status(res, health)
        doubted = doubt(m, clean.meta.ingest.door) if status[m]["status"] in FEEDS_DEFAULT else None
        if doubted:     # a unit the door doubts or that was overridden (unit_doubts.py)
            before = status[m].get("reason")
            status[m].update(status=DOUBTFUL, reason=f"the door's evidence: {doubted}"
                             + (f"; {before}" if before else ""))
        if settings.strict and status[m]["status"] in ("unhealthy", "stopped"):
            # --strict: a method that stopped short of its convergence test fails it too
            raise ConvergenceError(f"method '{m}' is {status[m]['status']}: "
                                   f"{status[m]['reason']} (--strict)")
    if not results:
        raise MetadataError("no estimator could run on this flight: " + "; ".join(
            f"{m}: {s.get('reason')}" for m, s in status.items()))
    healthy = {m: status[m]["status"] in FEEDS_DEFAULT for m in results}
    if not any(has_finite_track(r) for r in results.values()):
        raise NoResultError("no method produced a finite track, nothing was written: "
                            + _reasons(status))
    order, evidence = default_order(clean, results, healthy)
    track = combine(clean, results, priority=order,
                    healthy={m: healthy[m] and m in order for m in results})
    # the choice's evidence travels with the table to the summary (result_choice)
    track.attrs["default_choice"] = {"order": order, "evidence": evidence}
    return track, results, status


def default_order(clean: CleanFlight, results: dict[str, MethodResult],
                  healthy: dict[str, bool]) -> tuple[list[str], dict[str, Any]]:
    """The order in which the healthy tracks feed the default and the evidence behind it
    (:mod:`flightrecon.pipeline.evidence`)."""
    from flightrecon.pipeline.evidence import choose_order, evidence_summary, track_checks
    from flightrecon.pipeline.registry import DEFAULT_PRIORITY

    checks = track_checks(results, healthy, clean)
    order, why = choose_order(checks, DEFAULT_PRIORITY)
    return order, evidence_summary(checks, order, why)


def _reasons(status: dict[str, Any]) -> str:
    return "; ".join(f"{m} {s.get('status')}" + (f" ({s['reason']})" if s.get("reason") else "")
                     for m, s in status.items())


record_coefficients = record_flight  # the earlier name


def reconstruct(log: str | Path, *, gnss: str | Path | None = None, radar: str | Path | None = None,
                mapping: str | Path | None = None, sidecar: str | Path | None = None,
                meta_overrides: dict[str, Any] | None = None,
                settings: ReconstructSettings = ReconstructSettings(),
                progress: Callable[[str], None] | None = None,
                store: str | Path | None = None, use_fleet_coefficients: bool = False,
                record: bool = True, workers: int | None = None, gnss_use: GnssUse | None = None,
                frame_rate_hz: float | None = None) -> Reconstruction:
    """Load, validate, clean and reconstruct a flight from its recorder log.

    Parameters
    ----------
    log : recorder log (CSV or Parquet), canonical or with a ``mapping`` file
    gnss, radar : separate GNSS / radar files merged on UTC time
    sidecar : metadata TOML (default: ``<log stem>.meta.toml`` beside the log)
    meta_overrides : metadata given on the command line (``departure``, ``arrival``, ...)
    settings : :class:`ReconstructSettings`
    progress : callback called with the name of each stage as it starts
    store : coefficient store (SQLite file); with ``record`` the flight's boundary-value Sabziev
        fit and joint sensor calibration are recorded there under the flight's aircraft id
    use_fleet_coefficients : reconstruct with what the aircraft's routine flights in ``store``
        taught (:func:`fleet_settings`): its sensor calibration as the joint smoother's priors
        and its fleet-mean Sabziev coefficients (initial-value mode: no arrival point needed)
    workers : threads for the estimators (default :func:`default_workers`; the result does
        not depend on it)
    gnss_use : how the GNSS fixes are used (withheld, windows, interval, receiver's sd;
        :class:`flightrecon.ingest.gnss_use.GnssUse`, the keyword of
        :func:`flightrecon.ingest.load_flight`)
    frame_rate_hz : frames a second of a recorder timed by its frame count (``--frame-rate``)

    Returns
    -------
    Reconstruction
    """
    def stage(name: str) -> None:
        if progress:
            progress(name)

    workers = default_workers() if workers is None else max(1, int(workers))
    # on a cold kernel cache a child process imports the methods while the log is read; on a
    # warm one numba loads its first kernel meanwhile
    load_first_kernel_early(workers)
    with warnings.catch_warnings(record=True) as caught, EarlyChild(workers) as early:
        warnings.simplefilter("always")
        flight_warnings, clean, settings, fleet, findings = _load_and_clean(
            log, gnss=gnss, radar=radar, mapping=mapping, sidecar=sidecar, stage=stage, store=store,
            meta_overrides=meta_overrides, settings=settings, gnss_use=gnss_use,
            use_fleet_coefficients=use_fleet_coefficients, frame_rate_hz=frame_rate_hz)
        track, results, status = reconstruct_clean(clean, settings, progress=stage,
                                                   workers=workers, early_child=early)
    warn_list = flight_warnings + [str(w.message) for w in caught
                                  if str(w.message) not in flight_warnings]
    # a verdict and its reason belong at the top, beside the warnings that led to it
    warn_list += [f"{m} unhealthy: {s['reason']}" for m, s in status.items()
                  if s.get("status") == "unhealthy" and s.get("reason")]
    inputs = [p for p in (log, gnss, radar, mapping, sidecar) if p is not None]
    summary = build_summary(clean, settings, status, inputs=inputs, warnings_=warn_list)
    summary["plausibility"] = findings
    summary["result"] = result_choice(track, status, **track.attrs.pop("default_choice", {}))
    from flightrecon.events import detect_events, events_table

    summary["events"] = events_table(detect_events(clean, track, status), clean.meta.epoch_utc)
    if summary["result"]["method"] is None:
        msg = ("no method produced a physically possible track: " + _reasons(status))
        if not settings.keep_unhealthy:
            exc = NoResultError(msg + "; nothing was written (--keep-unhealthy writes the "
                                "unhealthy tracks for inspection)")
            exc.warnings = tuple(warn_list)     # what may explain it (a declared unit...)
            raise exc
        summary["warnings"].append(msg)
    if fleet is not None:
        summary["fleet_coefficients"] = fleet
    rec = Reconstruction(track=track, summary=summary, clean=clean, results=results)
    if store is not None and record and not use_fleet_coefficients and (
            "sabziev" in results or "joint" in results):
        stage("store")
        summary["stored_coefficients"] = sc = record_flight(store, rec, log)
        if sc.get("note"):
            summary["warnings"].append(f"store: {sc['note']}")
    return rec


def _load_and_clean(log: str | Path, *, gnss: str | Path | None, radar: str | Path | None,
                    mapping: str | Path | None, sidecar: str | Path | None,
                    meta_overrides: dict[str, Any] | None, settings: ReconstructSettings,
                    stage: Callable[[str], None], store: str | Path | None,
                    use_fleet_coefficients: bool, gnss_use: GnssUse | None = None,
                    frame_rate_hz: float | None = None
                    ) -> tuple[list[str], CleanFlight, ReconstructSettings,
                               dict[str, Any] | None, list[dict[str, Any]]]:
    """Ingest, the fleet's settings (if asked), cleaning and the plausibility checks (each
    finding also a warning); returns the log's warnings, the cleaned flight, the settings used,
    the fleet information and the findings.  The raw log is not kept past cleaning: it is
    freed, with what reading and cleaning left free, before the estimators' peak
    (flightrecon/memory.py)."""
    from flightrecon.cleaning import CleaningSettings, clean_flight
    from flightrecon.cleaning.plausibility import plausibility_checks
    from flightrecon.ingest import load_flight
    from flightrecon.ingest.physics import check_reconstructable

    stage("ingest")
    flight: Flight = load_flight(log, gnss=gnss, radar=radar, mapping=mapping, sidecar=sidecar,
                                 meta_overrides=meta_overrides, gnss_use=gnss_use,
                                 frame_rate_hz=frame_rate_hz)
    check_reconstructable(flight)   # a log too short: refused with the minimum
    fleet = None
    if use_fleet_coefficients:
        settings, fleet = fleet_settings(settings, store, flight.meta.aircraft_id,
                                         at_utc=flight.meta.epoch_utc,
                                         configuration=flight.meta.configuration)
    stage("cleaning")
    clean = clean_flight(flight, rate_hz=settings.rate_hz,
                         settings=CleaningSettings(start=settings.start, end=settings.end))
    flight_warnings = list(flight.warnings)
    del flight
    release_unused()
    stage("plausibility")
    findings = plausibility_checks(clean)
    for f in findings:
        warnings.warn(f"{f['check']}: {f['message']}"
                      + (f" (t = {f['spans_s'][0][0]:.0f}..{f['spans_s'][0][1]:.0f} s"
                         + (f" and {len(f['spans_s']) - 1} more" if len(f['spans_s']) > 1
                            else "") + ")" if f["spans_s"] else ""),
                      FlightReconWarning, stacklevel=3)
    return flight_warnings, clean, settings, fleet, findings
