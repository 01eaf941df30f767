"""The reconstruction pipeline: the library API behind ``flightrecon reconstruct``.

Data flows one way::

    load_flight (ingest) -> clean_flight (cleaning) -> estimators -> combine -> export

Each estimator returns a :class:`flightrecon.types.MethodResult` whose columns carry its prefix
(``sabziev_``, ``arms_``, ``azimuth_``, ``sns_``).  The unprefixed default result is taken, per
sample, from the best available method (see :data:`DEFAULT_PRIORITY`) and the ``source`` column
records which one informed each sample.

Examples
--------
>>> from flightrecon.pipeline import reconstruct          # doctest: +SKIP
>>> rec = reconstruct("sample_logs/circuit.parquet")      # doctest: +SKIP
>>> rec.track[["t_s", "north_m", "east_m", "up_m"]]       # doctest: +SKIP
"""

from __future__ import annotations

import hashlib
import importlib
import platform
import os
import warnings
from collections.abc import Callable, Sequence
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from flightrecon import __version__
from flightrecon.errors import FlightReconError, FlightReconWarning, MetadataError
from flightrecon.types import CleanFlight, Flight, MethodResult

SUMMARY_SCHEMA_VERSION = 1

#: method name -> (module, function)
METHOD_FUNCTIONS: dict[str, tuple[str, str]] = {
    "joint": ("flightrecon.filters.joint_method", "run_joint"),
    "sabziev": ("flightrecon.fusion.method", "run_sabziev"),
    "arms": ("flightrecon.filters.arms_method", "run_arms"),
    "azimuth": ("flightrecon.filters.azimuth_method", "run_azimuth"),
    "sns": ("flightrecon.filters.sns_method", "run_sns"),
}
ALL_METHODS: tuple[str, ...] = tuple(METHOD_FUNCTIONS)

#: order in which methods supply the unprefixed horizontal track, sample by sample
DEFAULT_PRIORITY: tuple[str, ...] = ("joint", "sns", "arms", "sabziev", "azimuth")


@dataclass(frozen=True)
class ReconstructSettings:
    """Settings of one reconstruction (written into the summary so the run can be repeated).

    Attributes
    ----------
    methods : methods to run; ``None`` runs every method the flight's data allows
    rate_hz : grid rate for the input channels (``None``: the fastest input channel's rate)
    k : Sabziev coefficients (k1, k2, k3) for the initial-value mode (no arrival point needed)
    k_sd : their standard deviations (fleet spread), propagated into the Sabziev track
    arms_form, arms_linearisation : ADS/ARMS estimator form (``joint``/``cascade``) and
        linearisation (``ekf``/``converted``)
    azimuth_model : ``aided`` or ``singer``
    sns_model, sns_form : SNS dead-reckoning model (``auto``/``airspeed``/``doppler``) and
        filter form (``consistent``/``seed``)
    joint_noise : overrides of the joint smoother's error budget
        (:class:`flightrecon.filters.joint.JointNoise` field -> value)
    joint_estimate_noise : scale each source's noise from the flight's own residuals
    strict : raise on the first method that fails or does not converge
    sns_noise : overrides of the SNS noise (:func:`flightrecon.filters.sns_method.sns_noise_with`)
    start, end : trim the record to ``start <= t_s <= end`` before cleaning (seconds from the
        epoch or UTC timestamps; :func:`flightrecon.cleaning.trim.trim_flight`)
    """

    methods: tuple[str, ...] | None = None
    rate_hz: float | None = None
    k: tuple[float, float, float] | None = None
    k_sd: tuple[float, float, float] | None = None
    arms_form: str = "joint"
    arms_linearisation: str = "ekf"
    azimuth_model: str = "aided"
    sns_model: str = "auto"
    sns_form: str = "consistent"
    joint_noise: dict[str, float] | None = None
    joint_estimate_noise: bool = False
    strict: bool = False
    start: float | str | None = None
    end: float | str | None = None
    sns_noise: dict[str, float] | None = None


@dataclass(frozen=True)
class Reconstruction:
    """Result of :func:`reconstruct`: the combined track, the summary and the pieces."""

    track: pd.DataFrame
    summary: dict[str, Any]
    clean: CleanFlight
    results: dict[str, MethodResult] = field(default_factory=dict)


def sha256_file(path: str | Path, chunk: int = 1 << 20) -> str:
    """SHA-256 of a file's bytes (hex)."""
    h = hashlib.sha256()
    with open(path, "rb") as fh:
        while True:
            b = fh.read(chunk)
            if not b:
                break
            h.update(b)
    return h.hexdigest()


def available_methods(clean: CleanFlight, settings: ReconstructSettings) -> dict[str, str | None]:
    """Which methods the data allow: name -> ``None`` if runnable, else the reason it is not."""
    meta = clean.meta
    out: dict[str, str | None] = {}
    g = clean.grid
    needed = [c for c in ("n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg",
                          "heading_deg", "tas_mps") if c not in g.columns]
    out["joint"] = None if not needed else f"missing input channels {', '.join(needed)}"
    has_end = meta.arrival is not None or settings.k is not None
    out["sabziev"] = None if has_end else (
        "no arrival point and no coefficients (give --arrival, or --k / fleet coefficients)")
    has_radar = len(clean.radar) > 0 and "arms_azimuth_deg" in clean.radar.columns
    if not has_radar:
        reason = "no radar plots in the data"
    elif meta.station is None:
        reason = "radar plots but no station position (give --station)"
    else:
        reason = None
    out["arms"] = reason
    out["azimuth"] = reason
    has_gnss = len(clean.gnss) > 0 and "gnss_lat_deg" in clean.gnss.columns
    out["sns"] = None if has_gnss else "no GNSS fixes in the data"
    if meta.departure is None:
        out["sabziev"] = out["sabziev"] or ("no departure airfield (the fusion integrates from "
                                            "the lift-off point; give --departure)")
        if meta.origin is None:
            for m in out:
                out[m] = out[m] or ("no departure position and no GNSS or radar fix to place "
                                    "the frame (give --departure)")
    return out


def _method_kwargs(name: str, s: ReconstructSettings) -> dict[str, Any]:
    if name == "joint":
        from flightrecon.filters.joint import JointNoise, JointSettings

        try:
            noise = replace(JointNoise(), **(s.joint_noise or {}))
        except TypeError as exc:
            raise MetadataError(f"unknown joint noise setting: {exc}") from exc
        return {"settings": JointSettings(noise=noise, estimate_noise=s.joint_estimate_noise)}
    if name == "sabziev":
        return {"k": s.k, "k_sd": s.k_sd, "strict": s.strict}
    if name == "arms":
        return {"form": s.arms_form, "linearisation": s.arms_linearisation}
    if name == "azimuth":
        return {"model": s.azimuth_model}
    if name == "sns":
        return {"model": s.sns_model, "form": s.sns_form, "noise_overrides": s.sns_noise}
    raise KeyError(name)


def run_method(name: str, clean: CleanFlight, settings: ReconstructSettings) -> MethodResult:
    """Run one estimator by name on a cleaned flight."""
    mod_name, fn_name = METHOD_FUNCTIONS[name]
    fn: Callable[..., MethodResult] = getattr(importlib.import_module(mod_name), fn_name)
    return fn(clean, **_method_kwargs(name, settings))


def _spans(t: np.ndarray, bad: np.ndarray, gap_s: float = 5.0) -> list[list[float]]:
    """Time spans [start, end] of the samples where ``bad`` holds (joined across gaps < gap_s)."""
    tb = t[bad]
    if len(tb) == 0:
        return []
    brk = np.flatnonzero(np.diff(tb) > gap_s)
    starts = np.r_[tb[0], tb[brk + 1]]
    ends = np.r_[tb[brk], tb[-1]]
    return [[float(a), float(b)] for a, b in zip(starts, ends)]


def method_health(res: MethodResult) -> dict[str, Any]:
    """Generic health of a method's track: where its position turns non-finite inside its own
    coverage, or its standard deviation is missing or not positive where it gives a position
    (a covariance that lost positive definiteness), with the time spans.  The method's own
    verdicts (``converged``, ``healthy``) are kept; any of these makes the method unhealthy,
    so the default result falls back to the healthy sources."""
    tr = res.track
    p = res.name + "_"
    t = tr["t_s"].to_numpy(float)
    out: dict[str, Any] = {"problems": []}
    if f"{p}north_m" in tr.columns and len(tr):
        pos = tr[[f"{p}north_m", f"{p}east_m"]].to_numpy(float)
        fin = np.isfinite(pos).all(axis=1)
        if fin.any():
            i0, i1 = np.flatnonzero(fin)[[0, -1]]
            inside = np.zeros(len(t), bool)
            inside[i0:i1 + 1] = True
            holes = inside & ~fin & ~np.isnan(pos).all(axis=1)  # inf or half-missing
            if holes.any():
                out["problems"].append({"what": "non-finite position inside the coverage",
                                        "spans_s": _spans(t, holes)})
            for c in (f"{p}north_sd_m", f"{p}east_sd_m"):
                if c in tr.columns:
                    sd = tr[c].to_numpy(float)
                    bad = fin & ~(sd > 0)
                    if bad.any():
                        out["problems"].append({"what": f"{c} missing or not positive",
                                                "spans_s": _spans(t, bad)})
    s = res.summary
    if s.get("converged") is False:
        out["problems"].append({"what": "did not converge", "spans_s": []})
    if s.get("healthy") is False:
        out["problems"].append({"what": "reports itself unhealthy", "spans_s": []})
    out["healthy"] = not out["problems"]
    return out


def _method_healthy(res: MethodResult) -> bool:
    return method_health(res)["healthy"]


def _text_column(codes: np.ndarray, names: Sequence[str], na_value: Any = pd.NA) -> Any:
    """A pyarrow-backed pandas string array whose row ``i`` is ``names[codes[i]]``.

    Built in Arrow from small integer codes (one ``take``) instead of from a Python object
    array: 576 000 rows take about 10 ms instead of about 100 ms.
    """
    import pyarrow as pa

    arr = pa.array(list(names), type=pa.large_string()).take(pa.array(codes))
    return pd.array(arr, dtype=pd.StringDtype("pyarrow", na_value=na_value))


def _on_grid(tr: pd.DataFrame, t: np.ndarray) -> pd.DataFrame:
    """A method's track on the grid rows: itself when it is already on them, else a left merge
    on ``t_s`` (grid rows the method does not cover get NaN)."""
    if len(tr) != len(t) or not np.array_equal(tr["t_s"].to_numpy(), t):
        tr = pd.DataFrame({"t_s": t}).merge(tr, on="t_s", how="left")
    return tr


def combine(clean: CleanFlight, results: dict[str, MethodResult],
            priority: Sequence[str] = DEFAULT_PRIORITY) -> pd.DataFrame:
    """Assemble the output table: the unprefixed default result plus every method's columns.

    Horizontal position, velocity and their standard deviations come, sample by sample, from
    the first healthy method in ``priority`` that covers the sample (``source`` says which).
    The vertical comes from the Sabziev solution where present, else from pressure altitude
    relative to the departure airfield (``up_source``); lat/lon/alt (WGS-84 ellipsoidal height)
    are the tangent-plane position converted back through pyproj.  Where the joint smoother is
    healthy its up, vertical velocity, wind and provenance replace those (docs/output.md).

    The columns are assembled as numpy arrays and the table is built once; the text columns
    are built in Arrow from integer codes; each method's health is evaluated once; the
    height-to-plane conversion (3 PROJ passes) runs only on the samples whose up does not come
    from the joint smoother (and their neighbours, which the vertical-velocity difference
    uses).  Every value is the same as computing each column on every sample.
    """
    from flightrecon.geo.frames import output_plane

    t = clean.grid["t_s"].to_numpy()
    n = len(t)
    healthy = {name: _method_healthy(res) for name, res in results.items()}
    aligned: dict[str, pd.DataFrame] = {}

    def grid_track(name: str) -> pd.DataFrame:
        if name not in aligned:
            aligned[name] = _on_grid(results[name].track, t)
        return aligned[name]

    cols: dict[str, np.ndarray] = {}
    for q, unit in (("north", "m"), ("east", "m"), ("vn", "mps"), ("ve", "mps")):
        cols[f"{q}_{unit}"] = np.full(n, np.nan)
        cols[f"{q}_sd_{unit}"] = np.full(n, np.nan)
    source = np.zeros(n, dtype=np.int8)  # index into source_names; 0: no method
    source_names = [""]
    for name in priority:
        res = results.get(name)
        if res is None or not healthy[name]:
            continue
        if f"{name}_north_m" not in res.track.columns:
            continue
        tr = grid_track(name)
        fin = (np.isfinite(tr[f"{name}_north_m"].to_numpy())
               & np.isfinite(tr[f"{name}_east_m"].to_numpy()))
        take = (source == 0) & fin
        if not take.any():
            continue
        source_names.append(name)
        source[take] = len(source_names) - 1
        for key, arr in cols.items():
            src = f"{name}_{key}"
            if src in tr.columns:
                arr[take] = tr[src].to_numpy()[take]
    # vertical
    up = np.full(n, np.nan)
    up_sd = np.full(n, np.nan)
    up_names = ("", "sabziev", "baro", "joint")
    up_source = np.zeros(n, dtype=np.int8)  # index into up_names
    sab = results.get("sabziev")
    if sab is not None and healthy["sabziev"] and "sabziev_up_m" in sab.track.columns:
        su = grid_track("sabziev")
        v = su["sabziev_up_m"].to_numpy()
        ok = np.isfinite(v)
        up[ok] = v[ok]
        up_source[ok] = 1
        if "sabziev_up_sd_m" in su.columns:
            up_sd[ok] = su["sabziev_up_sd_m"].to_numpy()[ok]
    if "baro_alt_m" in clean.grid.columns and clean.meta.departure is not None:
        from flightrecon.geo.atmosphere import isa_pressure_pa, pressure_altitude_m

        qnh = clean.meta.qnh_departure_hpa or 1013.25
        # pressure altitude of the departure airfield: ISA altitude of its station pressure
        p_field = isa_pressure_pa(clean.meta.departure.elev_m) * qnh / 1013.25
        h_field = float(pressure_altitude_m(p_field))
        baro = clean.grid["baro_alt_m"].to_numpy() - h_field
        fill = ~np.isfinite(up) & np.isfinite(baro)
        up[fill] = baro[fill]
        up_source[fill] = 2
    plane = output_plane(clean.meta)
    east, north = cols["east_m"], cols["north_m"]
    jt = results.get("joint")
    tj = grid_track("joint") if jt is not None and healthy["joint"] else None
    # Sabziev and pressure heights are heights above the departure airfield: turn them into
    # tangent-plane up (the plane falls below the ellipsoid with distance, 31 m at 20 km)
    if tj is None:
        up, lat, lon, alt = _height_to_plane_up(plane, east, north, up)
    else:
        j_ok = np.isfinite(tj["joint_up_m"].to_numpy())
        need = ~j_ok
        need[1:] |= ~j_ok[:-1]
        need[:-1] |= ~j_ok[1:]
        up = _height_to_plane_up(plane, east, north, up, where=need)[0]
    dt = np.gradient(t) if n > 1 else np.ones(n)
    vu = np.gradient(up) / dt if n > 1 else np.full(n, np.nan)
    extra: dict[str, Any] = {}
    if tj is not None:
        up = np.where(j_ok, tj["joint_up_m"].to_numpy(), up)
        up_sd = np.where(j_ok, tj["joint_up_sd_m"].to_numpy(), up_sd)
        vu = np.where(j_ok, tj["joint_vu_mps"].to_numpy(), vu)
        up_source[j_ok] = 3
        extra["vu_sd_mps"] = tj["joint_vu_sd_mps"].to_numpy()
        for c in ("wind_n_mps", "wind_e_mps", "wind_n_sd_mps", "wind_e_sd_mps"):
            extra[c] = tj["joint_" + c].to_numpy()
        extra["provenance"] = tj["joint_sources"].astype(
            pd.StringDtype("pyarrow", na_value=np.nan)).array
        lat, lon, alt = plane.inverse(east, north, up)
    out: dict[str, Any] = {"t_s": t, **cols, "up_m": up, "up_sd_m": up_sd, "vu_mps": vu,
                           "lat_deg": lat, "lon_deg": lon, "alt_m": alt,
                           "source": _text_column(source, source_names),
                           "up_source": _text_column(up_source, up_names), **extra}
    # the table owns writeable arrays (read-only views of the grid or the joint track are
    # copied); each method's own columns are appended as its (lazily copied) table
    out = {k: v.copy() if isinstance(v, np.ndarray) and not v.flags.writeable else v
           for k, v in out.items()}
    parts: list[pd.DataFrame] = [pd.DataFrame(out, copy=False)]
    names = set(out)
    for name in ALL_METHODS:
        res = results.get(name)
        if res is None or name == "joint":
            continue
        own = [c for c in res.track.columns if c != "t_s"]
        if names.intersection(own) or len(set(own)) < len(own):  # not expected: prefixed names
            return _combine_table(out, results, t)
        names.update(own)
        parts.append(grid_track(name)[own].reset_index(drop=True))
    return pd.concat(parts, axis=1)


def _combine_table(out: dict[str, Any], results: dict[str, MethodResult], t: np.ndarray
                   ) -> pd.DataFrame:
    """:func:`combine`'s table when method columns collide: a later column replaces an earlier
    one of the same name in its place."""
    for name in ALL_METHODS:
        res = results.get(name)
        if res is None or name == "joint":
            continue
        tr = _on_grid(res.track, t)
        for c in res.track.columns:
            if c != "t_s":
                out[c] = tr[c].to_numpy()
    return pd.DataFrame(out)


def _height_to_plane_up(plane, east, north, height_above_origin, where=None):
    """Tangent-plane ``up`` of points given by plane (east, north) and height above the plane's
    origin along the local vertical; returns (up, lat, lon, ellipsoidal height).

    Two fixed-point steps (the local vertical is within a few mrad of the plane's normal for
    flights of a few hundred km) give millimetres.  With the boolean mask ``where`` only those
    points are converted (each point's conversion is independent of the others): ``up`` is the
    input height elsewhere and ``lat, lon, h`` are ``None``.
    """
    h_in = np.asarray(height_above_origin, float)
    if where is not None:
        up = h_in.copy()
        idx = np.flatnonzero(where)
        if len(idx):
            up[idx] = _height_to_plane_up(plane, np.asarray(east)[idx],
                                          np.asarray(north)[idx], h_in[idx])[0]
        return up, None, None, None
    target = plane.h0_m + h_in
    up = h_in.copy()
    ok = np.isfinite(east) & np.isfinite(north) & np.isfinite(up)
    for _ in range(3):
        lat, lon, h = plane.inverse(east, north, up)
        up = np.where(ok, up + (target - h), up)
    lat, lon, h = plane.inverse(east, north, up)
    return up, lat, lon, h


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
        health = method_health(res)
        status[m] = {"status": "ok" if health["healthy"] else "unhealthy", **res.summary,
                     "health": health}
    if not results:
        raise MetadataError("no estimator could run on this flight: " + "; ".join(
            f"{m}: {s.get('reason')}" for m, s in status.items()))
    track = combine(clean, results)
    return track, results, status


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
    return {"store": str(store_path), "aircraft_id": fit.aircraft_id, "flight_id": fit.flight_id,
            "k": [fit.k1, fit.k2, fit.k3], "converged": fit.converged}


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
    if fleet is not None:
        summary["fleet_coefficients"] = fleet
    rec = Reconstruction(track=track, summary=summary, clean=clean, results=results)
    if store is not None and record and not use_fleet_coefficients and "sabziev" in results:
        stage("store")
        summary["stored_coefficients"] = record_coefficients(store, rec)
    return rec


def _meta_dict(meta) -> dict[str, Any]:
    d = asdict(meta)
    d.pop("extra", None)
    return d


def build_summary(clean: CleanFlight, settings: ReconstructSettings, status: dict[str, Any], *,
                  inputs: Sequence[str | Path] = (), warnings_: Sequence[str] = ()) -> dict[str, Any]:
    """The summary document (JSON-serialisable) with its schema version."""
    ph = clean.phases
    return {
        "schema_version": SUMMARY_SCHEMA_VERSION,
        "software": {"name": "flightrecon", "version": __version__,
                     "python": platform.python_version()},
        "inputs": [{"path": str(p), "sha256": sha256_file(p)} for p in inputs if Path(p).is_file()],
        "flight": _meta_dict(clean.meta),
        "settings": asdict(settings),
        "grid": {"rate_hz": clean.rate_hz, "samples": len(clean.grid),
                 "t0_s": float(clean.grid["t_s"].iloc[0]) if len(clean.grid) else None,
                 "t1_s": float(clean.grid["t_s"].iloc[-1]) if len(clean.grid) else None},
        "measurements": {"gnss_fixes": len(clean.gnss), "radar_plots": len(clean.radar)},
        "phases": None if ph is None else asdict(ph),
        "cleaning": {"actions": len(clean.report), "report": list(clean.report)[:200]},
        "output": {
            "frame": ("east-north-up tangent plane at the departure airfield (metres)"
                      if clean.meta.departure is not None else
                      "east-north-up tangent plane at the first position fix (meta origin; "
                      "no departure airfield given) (metres)"),
            "alt_datum": "WGS-84 ellipsoidal height (alt_m)",
            "default_source_priority": list(DEFAULT_PRIORITY),
        },
        "methods": status,
        "warnings": list(warnings_),
    }
