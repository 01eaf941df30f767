"""Flights with truth for the Sabziev studies: the independent corpus and JSBSim flights.

:func:`corpus_flight` loads ``<shared>/corpus/c<i>-fdr.parquet`` (recorder only) with the
departure and arrival of its ``c<i>-meta.json``; :func:`jsbsim_flight` simulates a JSBSim
scenario.  Both return a :class:`TruthFlight`: the cleaned flight and the truth on the grid
(north, east in the output tangent plane; up = height above the departure airfield, geometric).
:func:`evaluate` compares a Sabziev result and the project's dead-reckoning baselines
(:func:`flightrecon.methods.baselines.dead_reckoning`) with that truth.
"""

from __future__ import annotations

import json
import os
import sys
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.cleaning import clean_flight
from flightrecon.geo.frames import msl_to_ellipsoid, output_plane
from flightrecon.methods.baselines import dead_reckoning
from flightrecon.types import CleanFlight, Flight, MethodResult, Position

sys.path.insert(0, str(Path(__file__).resolve().parent))

from table_header import header  # noqa: E402

SHARED = Path(os.environ.get("FLIGHTRECON_SHARED",
                              Path(__file__).resolve().parents[2] / "shared"))


@dataclass
class TruthFlight:
    """A cleaned flight with its truth on the grid (module docstring)."""

    name: str
    clean: CleanFlight
    truth_neu: np.ndarray  # (N, 3) north, east, up [m] on the grid, NaN outside the truth
    truth: pd.DataFrame | None = None  # the simulator's truth (JSBSim flights), else None


def _truth_neu(clean: CleanFlight, t_truth, lat, lon, alt_ell) -> np.ndarray:
    meta = clean.meta
    plane = output_plane(meta)
    e, n, _u = plane.forward(np.asarray(lat), np.asarray(lon), np.asarray(alt_ell))
    up = np.asarray(alt_ell) - msl_to_ellipsoid(meta.departure.elev_m, meta.geoid_undulation_m)
    t = clean.grid["t_s"].to_numpy(float)
    return np.column_stack([np.interp(t, t_truth, x, left=np.nan, right=np.nan)
                            for x in (np.asarray(n), np.asarray(e), up)])


def corpus_flight(i: int) -> TruthFlight:
    """Corpus flight ``c<i>`` (recorder only) with its departure and arrival (README there)."""
    from flightrecon.ingest import load_flight

    d = SHARED / "corpus"
    m = json.loads((d / f"c{i}-meta.json").read_text())
    dep, arr = (Position(*m[k]) for k in ("departure", "arrival"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        flight = load_flight(d / f"c{i}-fdr.parquet",
                             # the corpus gives ellipsoidal heights (README there): no geoid
                             meta_overrides={"departure": dep, "arrival": arr,
                                             "geoid_undulation_m": 0.0})
        clean = clean_flight(flight)
    tr = pd.read_parquet(d / f"c{i}-truth.parquet")
    t_epoch = 0.0  # the recorder log and the truth share their time origin
    truth = _truth_neu(clean, tr["time_s"].to_numpy(float) + t_epoch, tr["lat_deg"],
                       tr["lon_deg"], tr["alt_geod_m"])
    return TruthFlight(f"c{i} (corpus)", clean, truth)


def jsbsim_flight(scenario: str, seed: int, *, wind_channel: bool = False,
                  **overrides: Any) -> TruthFlight:
    """A JSBSim flight (``flightrecon.sim.simulate``), cleaned, with its truth; with
    ``wind_channel`` the truth's wind (north, east) is given to the log as recorded wind
    channels (``wind_speed_mps``, ``wind_from_deg``), as on a recorder that logs wind."""
    from flightrecon.sim import simulate

    sim = simulate(scenario, seed, **overrides)
    tr = sim.truth
    log = sim.log
    if wind_channel:
        log = log.copy()
        tl = log["t_s"].to_numpy(float)
        wn = np.interp(tl, tr["t_s"], tr["wind_n_mps"])
        we = np.interp(tl, tr["t_s"], tr["wind_e_mps"])
        log["wind_speed_mps"] = np.hypot(wn, we)
        log["wind_from_deg"] = (np.degrees(np.arctan2(we, wn)) + 180.0) % 360.0
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        clean = clean_flight(Flight(data=log, meta=sim.meta))
    truth = _truth_neu(clean, tr["t_s"].to_numpy(float), tr["lat_deg"], tr["lon_deg"],
                       tr["alt_m"])
    scale = overrides.get("scale")
    label = scenario.removeprefix("jsbsim-") + (f" x{scale:g}" if scale else "")
    if overrides.get("airframe"):
        label = f"{overrides['airframe']} {label}"

    return TruthFlight(f"{label} s{seed}" + (" +wind" if wind_channel else ""), clean, truth,
                       tr)


def _rms(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if len(x) else float("nan")


def evaluate(f: TruthFlight, res: MethodResult) -> dict[str, Any]:
    """Errors of a Sabziev result and of the baselines against the truth, on the fusion
    interval: horizontal RMS (``hor_rms_m``, of the horizontal distance), vertical RMS, the
    ratio to dead reckoning with a linear end correction, the end-point miss per axis."""
    s = res.summary
    t = f.clean.grid["t_s"].to_numpy(float)
    i0, i1 = (int(np.argmin(np.abs(t - x))) for x in s["interval_s"])
    sl = slice(i0, i1 + 1)
    tr = res.track
    n, e, u = (tr[f"sabziev_{a}_m"].to_numpy(float)[sl] for a in ("north", "east", "up"))
    tn, te, tu = (f.truth_neu[sl, j] for j in range(3))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        drl = dead_reckoning(f.clean, corrected=True)
        dr = dead_reckoning(f.clean)
    dn, de = drl["north_m"].to_numpy(float)[sl], drl["east_m"].to_numpy(float)[sl]
    rn, re_ = dr["north_m"].to_numpy(float)[sl], dr["east_m"].to_numpy(float)[sl]
    hor = _rms(np.hypot(n - tn, e - te))
    hor_drl = _rms(np.hypot(dn - tn, de - te))
    finite = bool(np.all(np.isfinite(n)) and np.all(np.isfinite(e)) and np.all(np.isfinite(u)))
    end = s.get("end_residual_m", {})
    miss = max((abs(v) for v in end.values() if v is not None), default=float("nan"))
    if not finite:
        miss = float("nan")
    return {
        "flight": f.name, "duration_s": float(t[i1] - t[i0]), "finite": finite,
        "hor_rms_m": hor, "hor_rms_drl_m": hor_drl, "hor_rms_dr_m": _rms(np.hypot(rn - tn,
                                                                                  re_ - te)),
        "ratio_drl": hor / hor_drl if hor_drl > 0 else float("nan"),
        "up_rms_m": _rms(u - tu), "end_miss_m": miss, "converged": bool(s.get("converged")),
        "k": [s.get("k1"), s.get("k2"), s.get("k3")],
        "roots": {a: s["axes"][a].get("branch") for a in s.get("axes", {})},
    }


# --------------------------------------------------------------------------------------------
# The study: every flight, both policies, one table
# --------------------------------------------------------------------------------------------
FLIGHTS: tuple[tuple[str, int, dict[str, Any]], ...] = (
    *(("corpus", i, {}) for i in (1, 2)),
    *(("jsbsim-circuit", s, {}) for s in (1, 2, 3, 4, 5)),
    *(("jsbsim-xc", s, {"scale": 0.3}) for s in (1, 2, 3)),
    *(("jsbsim-jet", s, {"scale": 0.2}) for s in (1, 2, 3)),
    *(("jsbsim-spiral", s, {}) for s in (1, 2, 3)),
    *(("jsbsim-spin", s, {}) for s in (1, 2, 3)),
    *(("jsbsim-jet", s, {"scale": 0.2, "wind_channel": True}) for s in (1, 2, 3)),
    ("jsbsim-xc", 1, {"scale": 1.0, "wind_channel": True}),
    ("jsbsim-jet", 1, {"scale": 1.0, "wind_channel": True}),
)
"""The independent flights of the study (issue #37): the corpus, JSBSim circuits, cross-country
flights (scale 0.3), jets (scale 0.2), spiral dives and spins to the ground; then the jets, a
full cross-country flight (81 min) and a full jet flight (3.2 h) with the true wind given as a
recorded wind channel."""

FLEET_FLIGHTS: tuple[tuple[str, int, dict[str, Any]], ...] = (
    *(("jsbsim-circuit", 1, {"airframe": a}) for a in ("c310", "t6texan2", "pc7",
                                                       "global5000", "B747")),
    *(("jsbsim-airwork", 1, {"airframe": a}) for a in ("c172p", "t6texan2", "pc7")),
    *(("jsbsim-holding", 1, {"airframe": a}) for a in ("c172p", "c310", "pc7")),
    *(("jsbsim-goaround", 1, {"airframe": a}) for a in ("c172p", "c310", "global5000",
                                                        "B747")),
)
"""The JSBSim fleet of issue #38 (docs/jsbsim.md, "Fleet"): other aircraft and the airwork,
holding and go-around schedules, one seed each (``--fleet``)."""


def one(kind: str, i: int, overrides: dict[str, Any]) -> list[dict[str, Any]]:
    """Both policies on one flight: :func:`evaluate` plus the health verdict of the pipeline
    (:func:`flightrecon.pipeline.health.method_health`, the envelope included)."""
    from flightrecon.methods.sabziev.method import run_sabziev
    from flightrecon.pipeline.health import method_health

    f = corpus_flight(i) if kind == "corpus" else jsbsim_flight(kind, i, **overrides)
    rows = []
    for policy in ("stable", "paper"):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            res = run_sabziev(f.clean, policy=policy)
        ev = evaluate(f, res)
        h = method_health(res, f.clean)
        ev["policy"] = policy
        ev["health"] = "ok" if h["healthy"] else "unhealthy: " + "; ".join(
            p["what"] for p in h["problems"])
        ev["own_health"] = res.summary.get("health_problems", [])
        ev["fallback_axes"] = res.summary.get("fallback_axes", [])
        ev["vertical_reference"] = res.summary.get("vertical_reference", {})
        ev["reasons"] = {a: res.summary["axes"][a].get("reason") for a in res.summary["axes"]}
        rows.append(ev)
    return rows


def _f(x: Any, fmt: str = ".0f") -> str:
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "-"
    return format(x, fmt)


def _root(ev: dict[str, Any]) -> str:
    out = []
    for a in ("x", "y", "z"):
        br = ev["roots"].get(a)
        out.append("lin" if a in ev["fallback_axes"] else {"negative": "neg",
                                                           "positive": "POS"}.get(br, "none"))
    return "/".join(out)


def write_tables(rows: list[dict[str, Any]], out: Path, elapsed: float,
                 name: str = "sabziev_independent") -> None:
    """``docs/tables/<name>.md`` and ``.json`` (module docstring)."""
    out.mkdir(parents=True, exist_ok=True)
    (out / f"{name}.json").write_text(json.dumps(rows, indent=1, default=str))
    head = ("| flight | min | policy | finite | end miss [m] | hor RMS [m] | DR+lin [m] | ratio "
            "| up RMS [m] | k1 | k2 | k3 | roots x/y/z | health |")
    lines = ["# Sabziev fusion on independent flights (issue #37)", "",
             f"Generated by `python scripts/sabziev_accuracy.py --independent` ({elapsed:.0f} s). "
             "Corpus flights c1, c2 (recorder only, departure and arrival from their meta "
             "files, both end in the air) and JSBSim flights (circuits; cross-country at scale "
             "0.3; jets at scale 0.2; spiral dives and spins to the ground). Errors against the "
             "truth between lift-off and the end of the fusion interval: `hor RMS` of the "
             "horizontal distance; `DR+lin` the same for air-data dead reckoning with a linear "
             "end-point correction (`flightrecon.methods.baselines.dead_reckoning(corrected="
             "True)`); `ratio` = hor RMS / DR+lin; `up RMS` against the geometric height above "
             "the departure airfield; `end miss` the largest per-axis miss of the end point "
             "(`-` when the track is not finite). Roots: `neg` a root on the stable branch, "
             "`POS` on the positive (non-physical) branch, `lin` no root taken (the stable "
             "track with its end miss removed linearly), `none` no root and no track. "
             "`health`: the pipeline's verdict (its own checks, the method's and the "
             "envelope's).", "", head, "|" + "---|" * 14]
    for ev in rows:
        k = ev["k"]
        lines.append(
            f"| {ev['flight']} | {ev['duration_s'] / 60:.0f} | {ev['policy']} | "
            f"{'yes' if ev['finite'] else 'NO'} | {_f(ev['end_miss_m'], '.1e')} | "
            f"{_f(ev['hor_rms_m'])} | {_f(ev['hor_rms_drl_m'])} | {_f(ev['ratio_drl'], '.2f')} | "
            f"{_f(ev['up_rms_m'], '.1f')} | {_f(k[0], '.3g')} | {_f(k[1], '.3g')} | "
            f"{_f(k[2], '.3g')} | {_root(ev)} | {ev['health'][:90]} |")
    st = [r for r in rows if r["policy"] == "stable"]
    pa = [r for r in rows if r["policy"] == "paper"]

    def summ(rs: list[dict[str, Any]]) -> str:
        fin = [r for r in rs if r["finite"]]
        ratios = [r["ratio_drl"] for r in fin]
        ups = [r["up_rms_m"] for r in fin]
        ok = sum(r["health"] == "ok" for r in rs)
        return (f"{len(fin)} of {len(rs)} finite, {ok} healthy; ratio to DR+lin median "
                f"{np.median(ratios):.2f}, max {np.max(ratios):.2f}; up RMS median "
                f"{np.median(ups):.1f} m, max {np.max(ups):.1f} m; largest end miss "
                f"{max(r['end_miss_m'] for r in fin):.1e} m")

    lines += ["", f"**stable** (default): {summ(st)}.", "",
              f"**paper** (both branches, NaN without a root): {summ(pa)}.", ""]
    (out / f"{name}.md").write_text(header() + "\n".join(lines))


def study(out: Path, flights: tuple[tuple[str, int, dict[str, Any]], ...] = FLIGHTS,
          name: str = "sabziev_independent") -> list[dict[str, Any]]:
    """Run ``flights`` (default :data:`FLIGHTS`) with both policies and write the tables
    ``<name>.md`` and ``.json`` into ``out``."""
    import time

    t0 = time.perf_counter()
    rows: list[dict[str, Any]] = []
    for kind, i, ov in flights:
        for ev in one(kind, i, ov):
            rows.append(ev)
            print(f"{ev['flight']:16s} {ev['policy']:6s} finite={ev['finite']} ratio="
                  f"{ev['ratio_drl']:.2f} up={ev['up_rms_m']:.1f} miss={ev['end_miss_m']:.1e} "
                  f"{_root(ev)} {ev['health'][:60]}", flush=True)
    write_tables(rows, out, time.perf_counter() - t0, name)
    return rows
