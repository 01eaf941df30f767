"""The per-flight task a Dask worker runs: reconstruct one log and write its outputs.

:func:`run_flight` is a top-level function (picklable by reference) that never raises for a bad
flight: any exception becomes a ``failed`` outcome with its message and exit code
(:mod:`flightrecon.errors`), so one corrupt log cannot stop the batch.  It does **not** touch the
coefficient store: it returns the Sabziev method's summary and the flight's identity, and the
client records them (single-writer rule, docs/batch.md).
"""

from __future__ import annotations

import time
import traceback
from pathlib import Path
from typing import Any

import numpy as np

from flightrecon.ingest.gnss_use import GnssUse
from flightrecon.pipeline import ReconstructSettings

#: accuracy columns summarised per flight (median over the samples where they are finite)
SD_COLUMNS: tuple[str, ...] = ("north_sd_m", "east_sd_m", "up_sd_m")


def _median_finite(x: np.ndarray) -> float | None:
    x = np.asarray(x, dtype=np.float64)
    x = x[np.isfinite(x)]
    return float(np.median(x)) if len(x) else None


def accuracy_indicators(track: Any, summary: dict[str, Any]) -> dict[str, Any]:
    """Per-flight accuracy indicators for the batch table.

    ``joint_mean_nis``: the joint smoother's mean normalised innovation squared over all its
    sources, weighted by their measurement counts (docs/joint.md; about the measurement
    dimension per measurement when the error budget is right); ``sns_nis_per_dof`` the SNS
    filter's NIS per degree of freedom; ``<column>_median`` the median standard deviation of
    the default track (docs/output.md).
    """
    out: dict[str, Any] = {}
    methods = summary.get("methods", {})
    srcs = methods.get("joint", {}).get("sources") or {}
    num = den = 0.0
    for s in srcs.values():
        c, nis = s.get("count") or 0, s.get("mean_nis")
        if c and nis is not None and np.isfinite(nis):
            num += c * float(nis)
            den += c
    out["joint_mean_nis"] = num / den if den else None
    out["sns_nis_per_dof"] = methods.get("sns", {}).get("nis_per_dof")
    for c in SD_COLUMNS:
        out[c + "_median"] = _median_finite(track[c].to_numpy()) if c in track.columns else None
    return out


def _sabziev_for_store(summary: dict[str, Any]) -> dict[str, Any] | None:
    sab = summary.get("methods", {}).get("sabziev")
    if not sab or sab.get("status") not in ("ok", "fallback", "unhealthy"):
        return None
    return {k: v for k, v in sab.items() if k != "history"}  # history: large, not needed


def _mapping_for(sidecar: str | None, default: str | None) -> str | None:
    """The batch's default mapping unless the sidecar names the log's own mapping (which
    ``load_flight`` then reads from the sidecar's ``[files]``)."""
    if default is None or sidecar is None:
        return default
    from flightrecon.errors import FlightReconError
    from flightrecon.ingest.sidecar import load_sidecar

    try:
        own = load_sidecar(sidecar).files.get("mapping")
    except FlightReconError:
        return default   # the sidecar fails the flight with its own message
    return None if own is not None else default


def _joint_for_store(summary: dict[str, Any]) -> dict[str, Any] | None:
    """What the store needs of the joint smoother's summary (None unless it ran healthy)."""
    j = summary.get("methods", {}).get("joint")
    if not j or j.get("status") != "ok" or "corrections" not in j:
        return None
    return {"corrections": j["corrections"], "converged": j.get("converged"),
            "sources": {n: {"count": (s or {}).get("count")}
                        for n, s in (j.get("sources") or {}).items()}}


def run_flight(log: str, sidecar: str | None, result_path: str, summary_path: str,
               settings: ReconstructSettings, fmt: str,
               mapping: str | None = None, gnss_use: GnssUse | None = None,
               frame_rate_hz: float | None = None) -> dict[str, Any]:
    """Reconstruct ``log`` and write its result and summary atomically.

    Calls :func:`flightrecon.pipeline.reconstruct` with ``store=None, record=False`` (the client
    records the coefficients).

    Parameters
    ----------
    log, sidecar : the recorder log and its metadata TOML (``None``: none)
    result_path, summary_path : where to write (already confined to the output folder)
    settings : reconstruction settings
    fmt : ``parquet``, ``csv``, ``geojson`` or ``kml``
    mapping : the batch's ``--mapping``, used when the sidecar names no mapping (the log's own
        mapping, found as ``reconstruct`` finds it, wins)
    gnss_use : the batch's GNSS options (:class:`flightrecon.ingest.gnss_use.GnssUse`, ``None``:
        as recorded)
    frame_rate_hz : the batch's ``--frame-rate`` (a log whose time is its frame count), ``None``:
        none

    Returns
    -------
    dict
        ``status`` (``ok``/``failed``), ``error``, ``exit_code``, ``elapsed_s`` (wall time of the
        task), and for a good flight: ``aircraft_id``, ``flight_id``, ``epoch_utc``,
        ``duration_s`` (the flight's grid span), ``k`` (Sabziev k1..k3 or ``None``),
        ``sources`` (samples per default-result source), the :func:`accuracy_indicators`,
        ``sabziev`` (the method summary for the store, ``None`` if it did not run), ``joint``
        (its sensor-error estimates for the store, ``None`` unless healthy), ``conditions``
        (:func:`flightrecon.store.adapt.flight_conditions`), ``log_sha256``, ``inputs`` and
        ``settings`` (as in the summary).
    """
    from flightrecon.errors import FlightReconError
    from flightrecon.export.writers import write_summary, write_track
    from flightrecon.pipeline import reconstruct
    from flightrecon.store.adapt import flight_conditions

    t0 = time.perf_counter()
    try:
        # one thread per flight: the batch's parallelism is across flights (Dask workers)
        rec = reconstruct(log, sidecar=sidecar, mapping=_mapping_for(sidecar, mapping),
                          settings=settings, store=None, record=False, workers=1,
                          gnss_use=gnss_use, frame_rate_hz=frame_rate_hz)
        write_track(result_path, rec.track, rec.summary, fmt)
        write_summary(summary_path, rec.summary)
    except FlightReconError as exc:
        return {"status": "failed", "error": f"{type(exc).__name__}: {exc}",
                "exit_code": exc.exit_code, "elapsed_s": time.perf_counter() - t0}
    except Exception as exc:  # noqa: BLE001 - reported per flight; the batch goes on
        tb = traceback.format_exception_only(type(exc), exc)[-1].strip()
        return {"status": "failed", "error": f"internal error: {tb}", "exit_code": 1,
                "elapsed_s": time.perf_counter() - t0}
    s = rec.summary
    flight = s["flight"]
    grid = s["grid"]
    sab = _sabziev_for_store(s)
    log_sha = next((i["sha256"] for i in s["inputs"] if i["path"] == str(log)), None)
    k = None
    if sab is not None and all(sab.get(n) is not None for n in ("k1", "k2", "k3")):
        k = [float(sab["k1"]), float(sab["k2"]), float(sab["k3"])]
    src = rec.track["source"].astype("string").fillna("").value_counts()
    return {
        "status": "ok", "error": "", "exit_code": 0,
        "elapsed_s": time.perf_counter() - t0,
        "aircraft_id": flight.get("aircraft_id"), "flight_id": flight.get("flight_id"),
        "epoch_utc": flight.get("epoch_utc"),
        "duration_s": (grid["t1_s"] - grid["t0_s"]) if grid["t0_s"] is not None else None,
        "k": k, "sabziev_converged": None if sab is None else bool(sab.get("converged")),
        "sources": {str(n or "none"): int(c) for n, c in src.items()},
        **accuracy_indicators(rec.track, s),
        "sabziev": sab, "joint": _joint_for_store(s), "conditions": flight_conditions(rec.clean),
        "log_sha256": log_sha, "inputs": s["inputs"], "settings": s["settings"],
        "warnings": len(s["warnings"]),
        "result": str(Path(result_path).name), "summary": str(Path(summary_path).name),
    }
