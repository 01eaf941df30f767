"""Running a reconstruction: the estimators on a cleaned flight (:func:`reconstruct_clean`),
the whole chain from a log (:func:`reconstruct`) and the coefficient store's part in it."""

from __future__ import annotations

import os
import warnings
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import replace
from pathlib import Path
from typing import Any

import pandas as pd

from flightrecon.errors import (
    ConvergenceError,
    FlightReconError,
    FlightReconWarning,
    MetadataError,
    NoResultError,
)
from flightrecon.pipeline.combine import combine
from flightrecon.pipeline.health import has_finite_track, method_health
from flightrecon.pipeline.registry import (
    ALL_METHODS,
    METHOD_FUNCTIONS,
    Reconstruction,
    ReconstructSettings,
    available_methods,
    run_method,
)
from flightrecon.pipeline.summary import build_summary, result_choice
from flightrecon.types import CleanFlight, Flight, MethodResult


def default_workers() -> int:
    """Threads for the estimators: two where the machine has two cores or more.

    The estimators are independent and their compiled kernels release the GIL, so the joint
    smoother runs beside the others; the results do not depend on the number of threads.
    """
    return max(1, min(2, os.cpu_count() or 1))


def reconstruct_clean(clean: CleanFlight, settings: ReconstructSettings = ReconstructSettings(),
                      progress: Callable[[str], None] | None = None, workers: int | None = None
                      ) -> tuple[pd.DataFrame, dict[str, MethodResult], dict[str, Any]]:
    """Run the estimators on a cleaned flight and combine them.

    ``workers`` threads run the estimators (default :func:`default_workers`; 1: one after the
    other, in the order of ``ALL_METHODS``).  Returns the track, the method results and the
    per-method status for the summary.
    """
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
    status: dict[str, Any] = {m: {"status": "skipped", "reason": avail[m]}
                              for m in ALL_METHODS if m not in chosen}
    results: dict[str, MethodResult] = {}
    workers = default_workers() if workers is None else max(1, int(workers))

    def run(name: str) -> MethodResult:
        if progress:
            progress(name)
        return run_method(name, clean, settings)

    # with two threads the joint smoother, the longest, starts first and runs beside the others
    order = sorted(chosen, key=lambda name: name != "joint") if workers > 1 else chosen
    with ThreadPoolExecutor(max_workers=workers) as pool:
        futures = {m: pool.submit(run, m) for m in order}
    for m in chosen:
        try:
            res = futures[m].result()
        except FlightReconError as exc:
            if settings.strict:
                raise
            status[m] = {"status": "failed", "reason": str(exc)}
            continue
        results[m] = res
        health = method_health(res, clean)
        status[m] = {**res.summary, "status": "ok" if health["healthy"] else "unhealthy",
                     "health": health}
        if not health["healthy"]:
            status[m]["reason"] = "; ".join(pr["what"] for pr in health["problems"])
            if settings.strict:
                raise ConvergenceError(f"method '{m}' is unhealthy: {status[m]['reason']} "
                                       "(--strict)")
    if not results:
        raise MetadataError("no estimator could run on this flight: " + "; ".join(
            f"{m}: {s.get('reason')}" for m, s in status.items()))
    healthy = {m: status[m]["status"] == "ok" for m in results}
    if not any(has_finite_track(r) for r in results.values()):
        raise NoResultError("no method produced a finite track, nothing was written: "
                            + _reasons(status))
    track = combine(clean, results, healthy=healthy)
    return track, results, status


def _reasons(status: dict[str, Any]) -> str:
    return "; ".join(f"{m} {s.get('status')}" + (f" ({s['reason']})" if s.get("reason") else "")
                     for m, s in status.items())


def fleet_settings(settings: ReconstructSettings, store_path: str | Path | None,
                   aircraft_id: str | None) -> tuple[ReconstructSettings, dict[str, Any]]:
    """Settings with the aircraft's fleet-mean coefficients for the initial-value mode.

    The mean is taken by :meth:`flightrecon.store.CoefficientStore.fleet_mean` (converged fits on
    the majority branch per axis); its flight-to-flight spread is propagated into the Sabziev
    track's standard deviations.  At least two fits per axis are required.
    """
    from flightrecon.store import CoefficientStore

    if not aircraft_id:
        raise MetadataError("fleet coefficients need the aircraft id (--aircraft or the "
                            "sidecar's flight.aircraft_id)")
    with CoefficientStore(store_path, create=False) as store:
        fm = store.fleet_mean(aircraft_id, min_flights=2)
    info = {"aircraft_id": aircraft_id, "k": list(fm.k), "sd": list(fm.sd), "flights": list(fm.n),
            "branch": list(fm.branch), "store": str(store_path)}
    return replace(settings, k=tuple(fm.k), k_sd=tuple(fm.sd)), info


def record_coefficients(store_path: str | Path | None, rec: Reconstruction) -> dict[str, Any]:
    """Record the flight's fitted Sabziev coefficients in the store (one transaction; a re-run
    of the same aircraft and flight replaces its row).  Returns what was recorded."""
    from flightrecon.store import CoefficientStore, from_sabziev_summary

    sab = rec.results.get("sabziev")
    meta = rec.clean.meta
    if sab is None:
        raise MetadataError("nothing to record: the Sabziev fusion did not run on this flight")
    st = rec.summary["methods"].get("sabziev", {})
    if st.get("status") != "ok":
        return {"store": str(store_path), "recorded": False,
                "reason": f"sabziev {st.get('status')}: {st.get('reason')}"}
    if not meta.aircraft_id:
        raise MetadataError("recording coefficients needs the aircraft id (--aircraft)")
    flight_id = meta.flight_id or (rec.summary["inputs"][0]["sha256"][:16]
                                   if rec.summary["inputs"] else "unknown")
    fit = from_sabziev_summary(
        sab.summary, aircraft_id=meta.aircraft_id, flight_id=flight_id,
        flight_date_utc=meta.epoch_utc or "1970-01-01T00:00:00Z", settings=rec.summary["settings"],
        input_hashes={i["path"]: i["sha256"] for i in rec.summary["inputs"]})
    with CoefficientStore(store_path) as store:
        store.record(fit)
    return {"store": str(store_path), "recorded": True, "aircraft_id": fit.aircraft_id,
            "flight_id": fit.flight_id, "k": [fit.k1, fit.k2, fit.k3],
            "converged": fit.converged}


def reconstruct(log: str | Path, *, gnss: str | Path | None = None, radar: str | Path | None = None,
                mapping: str | Path | None = None, sidecar: str | Path | None = None,
                meta_overrides: dict[str, Any] | None = None,
                settings: ReconstructSettings = ReconstructSettings(),
                progress: Callable[[str], None] | None = None,
                store: str | Path | None = None, use_fleet_coefficients: bool = False,
                record: bool = True, workers: int | None = None) -> Reconstruction:
    """Load, validate, clean and reconstruct a flight from its recorder log.

    Parameters
    ----------
    log : recorder log (CSV or Parquet), canonical or with a ``mapping`` file
    gnss, radar : separate GNSS / radar files merged on UTC time
    sidecar : metadata TOML (default: ``<log stem>.meta.toml`` beside the log)
    meta_overrides : metadata given on the command line (``departure``, ``arrival``, ...)
    settings : :class:`ReconstructSettings`
    progress : callback called with the name of each stage as it starts
    store : coefficient store (SQLite file); with ``record`` a boundary-value Sabziev fit is
        recorded there under the flight's aircraft id
    use_fleet_coefficients : reconstruct with the aircraft's fleet-mean coefficients from
        ``store`` (initial-value mode: no arrival point needed)
    workers : threads for the estimators (default :func:`default_workers`; the result does
        not depend on it)

    Returns
    -------
    Reconstruction
    """
    from flightrecon.cleaning import CleaningSettings, clean_flight
    from flightrecon.cleaning.plausibility import plausibility_checks
    from flightrecon.ingest import load_flight

    def stage(name: str) -> None:
        if progress:
            progress(name)

    stage("ingest")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        flight: Flight = load_flight(log, gnss=gnss, radar=radar, mapping=mapping, sidecar=sidecar,
                                     meta_overrides=meta_overrides)
        fleet = None
        if use_fleet_coefficients:
            settings, fleet = fleet_settings(settings, store, flight.meta.aircraft_id)
        stage("cleaning")
        clean = clean_flight(flight, rate_hz=settings.rate_hz,
                             settings=CleaningSettings(start=settings.start, end=settings.end))
        stage("plausibility")
        findings = plausibility_checks(clean)
        for f in findings:
            warnings.warn(f"{f['check']}: {f['message']}"
                          + (f" (t = {f['spans_s'][0][0]:.0f}..{f['spans_s'][0][1]:.0f} s"
                             + (f" and {len(f['spans_s']) - 1} more" if len(f['spans_s']) > 1
                                else "") + ")" if f["spans_s"] else ""),
                          FlightReconWarning, stacklevel=2)
        track, results, status = reconstruct_clean(clean, settings, progress=stage,
                                                   workers=workers)
    warn_list = list(flight.warnings) + [str(w.message) for w in caught
                                         if str(w.message) not in flight.warnings]
    inputs = [p for p in (log, gnss, radar, mapping, sidecar) if p is not None]
    summary = build_summary(clean, settings, status, inputs=inputs, warnings_=warn_list)
    summary["plausibility"] = findings
    summary["result"] = result_choice(track, status)
    if summary["result"]["method"] is None:
        msg = ("no method produced a physically possible track: " + _reasons(status))
        if not settings.keep_unhealthy:
            raise NoResultError(msg + "; nothing was written (--keep-unhealthy writes the "
                                "unhealthy tracks for inspection)")
        summary["warnings"].append(msg)
    if fleet is not None:
        summary["fleet_coefficients"] = fleet
    rec = Reconstruction(track=track, summary=summary, clean=clean, results=results)
    if store is not None and record and not use_fleet_coefficients and "sabziev" in results:
        stage("store")
        summary["stored_coefficients"] = record_coefficients(store, rec)
    return rec
