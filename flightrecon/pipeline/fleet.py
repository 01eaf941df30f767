"""What the store gives a reconstruction and takes from it (docs/store.md): the aircraft's
fleet calibration and coefficients as settings (:func:`fleet_settings`), and the record of a
reconstructed flight (:func:`record_flight`).  The pipeline's side of the store: the store
(:mod:`flightrecon.store`) keeps and averages, this module turns its figures into settings
and a reconstruction into its records."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

from flightrecon.errors import MetadataError

if TYPE_CHECKING:
    from flightrecon.pipeline.registry import Reconstruction, ReconstructSettings


def fleet_settings(settings: ReconstructSettings, store_path: str | Path | None,
                   aircraft_id: str | None, at_utc: str | None = None,
                   configuration: str | None = None
                   ) -> tuple[ReconstructSettings, dict[str, Any]]:
    """Settings with what the aircraft's routine flights taught: its fused sensor calibration as
    the joint smoother's priors and its fleet-mean Sabziev coefficients.

    The calibration (:meth:`flightrecon.store.CoefficientStore.calibration`, at ``at_utc``, the
    flight's date; of its ``configuration`` if given) supplies mean and sd of every persistent
    sensor error observed on at least one flight.  The Sabziev mean
    (:meth:`~flightrecon.store.CoefficientStore.fleet_mean`: the weighted mean time
    constant or loop frequency over at least two stable-branch fits per axis; an axis with fewer
    takes the stable policy's fixed coefficient, ``k_default_axes`` in the info) runs the
    Sabziev fusion in its initial-value mode, its spread propagated into the track's sd.
    Either may be missing (said in the returned info); with neither, StoreError.

    Returns
    -------
    settings, info
        ``info``: ``aircraft_id``, ``store``, ``calibration`` (``at_utc``, ``flights`` used,
        ``n_flights``, per error ``mean``, ``sd``, ``n``, ``drift_sd_per_sqrt_day``,
        ``drift_source``, ``excluded``; or ``None`` with ``calibration_missing``), ``k``, ``sd``,
        ``flights`` and ``branch`` of the Sabziev mean (``None`` with ``k_missing``).
    """
    from flightrecon.errors import StoreError
    from flightrecon.store import CoefficientStore

    if not aircraft_id:
        raise MetadataError("fleet coefficients need the aircraft id (--aircraft or the "
                            "sidecar's flight.aircraft_id)")
    info: dict[str, Any] = {"aircraft_id": aircraft_id, "store": str(store_path)}
    fm = cal = None
    with CoefficientStore(store_path, create=False) as store:
        try:
            fm = store.fleet_mean(aircraft_id, min_flights=2, allow_missing=True)
        except StoreError as exc:
            info["k_missing"] = str(exc)
        try:
            cal = store.calibration(aircraft_id, at_utc, configuration=configuration)
        except StoreError as exc:
            info["calibration_missing"] = str(exc)
    if fm is None and cal is None:
        raise StoreError(f"aircraft '{aircraft_id}' has neither a sensor calibration nor "
                         f"Sabziev coefficients in the store ({info['k_missing']}; "
                         f"{info['calibration_missing']})", file=str(store_path))
    if fm is not None:
        # an axis with fewer than two stable-branch fits is NaN: the Sabziev adapter takes
        # the stable policy's fixed coefficient there (docs/store.md)
        info.update({"k": [None if k != k else k for k in fm.k],
                     "sd": [None if x != x else x for x in fm.sd], "flights": list(fm.n),
                     "branch": list(fm.branch), "k_default_axes": list(fm.missing)})
        settings = replace(settings, k=(fm.k[0], fm.k[1], fm.k[2]),
                           k_sd=(fm.sd[0], fm.sd[1], fm.sd[2]))
    else:
        info.update({"k": None, "sd": None, "flights": None, "branch": None})
    info["calibration"] = None
    if cal is not None:
        priors = cal.priors()
        info["calibration"] = {
            "at_utc": cal.at_utc, "configuration": cal.configuration,
            "flights": list(cal.flights_used()), "n_flights": len(cal.flights_used()),
            "applied": sorted(priors),
            "errors": {q.quantity: {"mean": q.mean, "sd": q.sd, "n": q.n, "unit": q.unit,
                                    "applied": q.quantity in priors,
                                    "drift_sd_per_sqrt_day": q.drift_sd_per_sqrt_day,
                                    "drift_source": q.drift_source,
                                    "excluded": [[e.flight_id, e.reason] for e in q.excluded]}
                       for q in cal.quantities}}
        settings = replace(settings, joint_priors=tuple(
            (name, float(m), float(sd)) for name, (m, sd) in sorted(priors.items())))
    return settings, info


def _log_sha256(rec: Reconstruction, log: str | Path | None) -> str | None:
    """SHA-256 of the flight's log from the summary's inputs (the first input is the log)."""
    inputs = rec.summary.get("inputs") or []
    for i in inputs:
        if log is not None and i["path"] == str(log):
            return i["sha256"]
    return inputs[0]["sha256"] if inputs else None


def record_flight(store_path: str | Path | None, rec: Reconstruction,
                  log: str | Path | None = None) -> dict[str, Any]:
    """Record the flight in the store: its fitted Sabziev coefficients (boundary-value mode) and
    the joint smoother's sensor calibration, under the record its log belongs to (one
    transaction; :mod:`flightrecon.store.identity`: the same log updates its record, a flight id
    taken by another log is disambiguated).  Returns what was recorded."""
    from flightrecon.store import (
        CoefficientStore,
        from_joint_summary,
        from_sabziev_summary,
    )
    from flightrecon.store.adapt import flight_conditions

    meta = rec.clean.meta
    if not meta.aircraft_id:
        raise MetadataError("recording coefficients needs the aircraft id (--aircraft)")
    h = _log_sha256(rec, log)
    if h is None:
        raise MetadataError("recording needs the log file's SHA-256 (the log is not a file)")
    date = meta.epoch_utc or "1970-01-01T00:00:00Z"
    common = dict(aircraft_id=meta.aircraft_id, flight_id=meta.flight_id or h[:16],
                  flight_date_utc=date, settings=rec.summary["settings"],
                  input_hashes={i["path"]: i["sha256"] for i in rec.summary["inputs"]})
    sab, joint = rec.results.get("sabziev"), rec.results.get("joint")
    status = rec.summary["methods"]
    fit = cal = None
    reasons = []
    # an unhealthy (physically impossible) track is not the aircraft's: nothing of it recorded
    if sab is not None and sab.summary.get("mode") == "boundary-value":
        # a fallback's axes without a root are recorded as such (records.py): its roots are
        if status.get("sabziev", {}).get("status") in ("ok", "fallback"):
            fit = from_sabziev_summary(sab.summary, **common)
        else:
            st = status.get("sabziev", {})
            reasons.append(f"sabziev {st.get('status')}: {st.get('reason')}")
    if joint is not None and status.get("joint", {}).get("status") != "ok":
        st = status.get("joint", {})
        reasons.append(f"joint {st.get('status')}: {st.get('reason')}")
    elif joint is not None:
        cal = from_joint_summary(joint.summary, conditions=flight_conditions(rec.clean),
                                 log_sha256=h, **common)
    if fit is None and cal is None:
        why = "; ".join(reasons) or ("neither a boundary-value Sabziev fit nor a healthy joint "
                                     "smoother on this flight")
        return {"store": str(store_path), "aircraft_id": meta.aircraft_id, "flight_id": None,
                "recorded": False, "reason": why, "note": "", "k": None, "converged": None,
                "calibration": False}
    with CoefficientStore(store_path) as store:
        ident = store.record_flight(meta.aircraft_id, meta.flight_id, h, fit=fit,
                                    calibration=cal)
    note = "; ".join([ident.note] * bool(ident.note) + [f"not recorded: {r}" for r in reasons])
    return {"store": str(store_path), "aircraft_id": meta.aircraft_id,
            "flight_id": ident.flight_id, "recorded": True, "identity": ident.action,
            "note": note,
            "k": None if fit is None else [fit.k1, fit.k2, fit.k3],
            "converged": None if fit is None else fit.converged,
            "calibration": cal is not None}
