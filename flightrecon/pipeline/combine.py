"""Combination of the methods' tracks into the unprefixed default result, and the datum
conversion of heights to the output plane."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.pipeline.health import method_health
from flightrecon.pipeline.registry import ALL_METHODS, DEFAULT_PRIORITY
from flightrecon.tracks import plane_up_of_height
from flightrecon.types import CleanFlight, MethodResult


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
            priority: Sequence[str] = DEFAULT_PRIORITY,
            healthy: dict[str, bool] | None = None) -> pd.DataFrame:
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
    if healthy is None:  # the pipeline passes its verdicts (with the envelope checks)
        healthy = {name: method_health(res)["healthy"] for name, res in results.items()}
    aligned: dict[str, pd.DataFrame] = {}

    def grid_track(name: str) -> pd.DataFrame:
        if name not in aligned:
            aligned[name] = _on_grid(results[name].track, t)
        return aligned[name]

    cols, source, source_names = _horizontal(results, priority, healthy, grid_track, n)
    up, up_sd, up_source = _heights(clean, results, healthy, grid_track, n)
    plane = output_plane(clean.meta)
    east, north = cols["east_m"], cols["north_m"]
    jt = results.get("joint")
    tj = grid_track("joint") if jt is not None and healthy["joint"] else None
    # Sabziev and pressure heights are heights above the departure airfield: turn them into
    # tangent-plane up (the plane falls below the ellipsoid with distance, 31 m at 20 km)
    if tj is None:
        up, lat, lon, alt = plane_up_of_height(plane, east, north, up)
    else:
        j_ok = np.isfinite(tj["joint_up_m"].to_numpy())
        need = ~j_ok
        need[1:] |= ~j_ok[:-1]
        need[:-1] |= ~j_ok[1:]
        up = plane_up_of_height(plane, east, north, up, where=need)[0]
    dt = np.gradient(t) if n > 1 else np.ones(n)
    vu = np.gradient(up) / dt if n > 1 else np.full(n, np.nan)
    extra: dict[str, Any] = {}
    if tj is not None:
        up = np.where(j_ok, tj["joint_up_m"].to_numpy(), up)
        up_sd = np.where(j_ok, tj["joint_up_sd_m"].to_numpy(), up_sd)
        vu = np.where(j_ok, tj["joint_vu_mps"].to_numpy(), vu)
        up_source[j_ok] = 3
        extra = _joint_extra(tj)
        lat, lon, alt = plane.inverse(east, north, up)
    miss = ~np.isfinite(up) & np.isfinite(east) & np.isfinite(north)
    if miss.any():
        # a position without a height (no departure airfield for the pressure altitude, no
        # healthy height): its latitude and longitude at the plane's own height (a height error
        # h moves them by about d h / R: 16 m at 100 km and 1 km); alt_m stays unknown
        la, lo, _ = plane.inverse(east[miss], north[miss], np.zeros(int(miss.sum())))
        lat, lon = np.array(lat, dtype=float), np.array(lon, dtype=float)
        lat[miss], lon[miss] = la, lo
    out: dict[str, Any] = {"t_s": t, **cols, "up_m": up, "up_sd_m": up_sd, "vu_mps": vu,
                           "lat_deg": lat, "lon_deg": lon, "alt_m": alt,
                           "source": _text_column(source, source_names),
                           "up_source": _text_column(up_source, _UP_NAMES), **extra}
    return _with_method_columns(out, results, t, grid_track)


#: ``up_source`` codes: none, Sabziev, pressure altitude, joint smoother
_UP_NAMES = ("", "sabziev", "baro", "joint")


def _horizontal(results: dict[str, MethodResult], priority: Sequence[str],
                healthy: dict[str, bool], grid_track: Callable[[str], pd.DataFrame], n: int
                ) -> tuple[dict[str, np.ndarray], np.ndarray, list[str]]:
    """Horizontal position and velocity with their sds, sample by sample from the first
    healthy method in ``priority`` that covers it; the source code of each sample and the
    names the codes stand for (0: no method)."""
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
    return cols, source, source_names


def _heights(clean: CleanFlight, results: dict[str, MethodResult], healthy: dict[str, bool],
             grid_track: Callable[[str], pd.DataFrame], n: int
             ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Height above the departure airfield: the healthy Sabziev solution where present, else
    the height from the pressure altitude (:func:`flightrecon.geo.pressure_height.
    pressure_height_m`: through the recorded temperature where there is one); its sd (the
    Sabziev solution's own where it gives one, else the pressure height's) and source codes
    (:data:`_UP_NAMES`)."""
    up = np.full(n, np.nan)
    up_sd = np.full(n, np.nan)
    up_source = np.zeros(n, dtype=np.int8)  # index into _UP_NAMES
    p_height, p_sd = _pressure_height(clean)
    sab = results.get("sabziev")
    if sab is not None and healthy["sabziev"] and "sabziev_height_m" in sab.track.columns:
        # the fusion's own vertical: its height above the departure airfield (its up_m is that
        # height in the plane at its own position; the default's horizontal may be another's)
        su = grid_track("sabziev")
        v = su["sabziev_height_m"].to_numpy()
        ok = np.isfinite(v)
        up[ok] = v[ok]
        up_source[ok] = 1
        if "sabziev_up_sd_m" in su.columns:
            up_sd[ok] = su["sabziev_up_sd_m"].to_numpy()[ok]
        elif p_sd is not None:  # the pressure height made to meet the end: its budget
            up_sd[ok] = p_sd[ok]
    if p_height is not None and p_sd is not None:
        fill = ~np.isfinite(up) & np.isfinite(p_height)
        up[fill] = p_height[fill]
        up_sd[fill] = p_sd[fill]
        up_source[fill] = 2
    return up, up_sd, up_source


def _pressure_height(clean: CleanFlight) -> tuple[np.ndarray | None, np.ndarray | None]:
    """Height above the departure field from the pressure altitude and its sd on the grid
    (:func:`flightrecon.geo.pressure_height.pressure_height_m`); ``None`` without a pressure
    altitude or a departure airfield."""
    from flightrecon.geo.atmosphere import field_pressure_altitude_m
    from flightrecon.geo.pressure_height import isa_deviation_k, pressure_height_m

    g = clean.grid
    meta = clean.meta
    if "baro_alt_m" not in g.columns or meta.departure is None:
        return None, None
    # pressure altitude of the departure airfield: ISA altitude of its station pressure
    h_field = field_pressure_altitude_m(meta.departure.elev_m, meta.qnh_departure_hpa)
    t = g["t_s"].to_numpy(float)
    h_p = g["baro_alt_m"].to_numpy(float)
    ph = clean.phases
    t0 = ph.liftoff_t_s if ph is not None and np.isfinite(ph.liftoff_t_s) else float(t[0])
    airborne = t >= t0
    if ph is not None and np.isfinite(ph.touchdown_t_s):
        airborne &= t <= ph.touchdown_t_s
    dev = isa_deviation_k(h_p, g["sat_degc"].to_numpy(float) if "sat_degc" in g.columns
                          else None, airborne)
    return pressure_height_m(t, h_p, h_field, qnh_known=meta.qnh_departure_hpa is not None,
                             deviation=dev, t0_s=t0)


def _joint_extra(tj: pd.DataFrame) -> dict[str, Any]:
    """The joint smoother's columns the default result carries: vertical-velocity sd, wind
    with its sds, and which sources informed each sample."""
    extra: dict[str, Any] = {"vu_sd_mps": tj["joint_vu_sd_mps"].to_numpy()}
    for c in ("wind_n_mps", "wind_e_mps", "wind_n_sd_mps", "wind_e_sd_mps"):
        extra[c] = tj["joint_" + c].to_numpy()
    extra["provenance"] = tj["joint_sources"].astype(
        pd.StringDtype("pyarrow", na_value=np.nan)).array
    return extra


def _with_method_columns(out: dict[str, Any], results: dict[str, MethodResult], t: np.ndarray,
                         grid_track: Callable[[str], pd.DataFrame]) -> pd.DataFrame:
    """The default columns ``out`` and, after them, each method's own columns on the grid."""
    # the table owns writeable arrays (read-only views of the grid or the joint track are
    # copied); each method's own columns are appended as its (lazily copied) table
    out = {k: v.copy() if isinstance(v, np.ndarray) and not v.flags.writeable else v
           for k, v in out.items()}
    parts: list[pd.DataFrame] = [pd.DataFrame(out, copy=False)]
    names = set(out)
    for name in ALL_METHODS:
        res = results.get(name)
        if res is None:
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
        if res is None:
            continue
        tr = _on_grid(res.track, t)
        for c in res.track.columns:
            if c != "t_s":
                out[c] = tr[c].to_numpy()
    return pd.DataFrame(out)
