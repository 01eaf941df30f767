"""Fleet study: the recorder-only joint smoother on JSBSim aircraft x scenario x recorder format
(docs/jsbsim.md, "Fleet study"; issue #38).

Every run flies one JSBSim schedule with one aircraft and one seed, **recorder only** (no GNSS,
no radar), writes it as ``flightrecon simulate`` does, and reads it back through the ordinary
path in two formats:

* ``canonical``: the project's recorder at its own rates (loads 16 Hz, attitude 8, airspeed and
  baro 4; the jets 8/4/2/2), ``load_flight`` on the written log and its sidecar;
* ``ed112``: the same log as an ED-112 minimum-rate export (``flightrecon simulate --export
  ed112``: loads 8/4/4 Hz, pitch 4, roll 2, magnetic heading, CAS and SAT, pressure altitude in
  feet 1 Hz, frame slots, 12-bit words) read by ``load_flight`` through its mapping file.

Then ``clean_flight`` and the joint smoother as ``flightrecon reconstruct`` runs it (default
settings: no data-sheet noise, no tuning), its health verdict (``method_health``, the rule that
decides ``ok`` / ``unhealthy``), and dead reckoning from airspeed and heading with the linear
end-point correction on the same cleaned flight.  Per run, on the airborne truth samples:

* the joint's RMS horizontal error and its ratio to DR + linear (the bars: at most 0.7 at the
  canonical rates, 1.0 at the minimum rates);
* the joint's RMS vertical error (bar 40 m) and its run-averaged NEES per horizontal axis;
* the end points: the joint's track at the line-up against the departure threshold and at the
  detected touchdown against the touchdown point the smoother was given (the air distance
  flown from the screen height, ``float_touchdown``, or ``touchdown_m`` past the arrival
  threshold without a recorded flare), in runway axes, each divided by the smoother's own sd
  for it (``roll_start_sd_m`` / the touchdown's along, ``runway_halfwidth_m`` across); "met" when
  every such ratio is at most 2; and the track's last position's distance from the arrival
  threshold.

Usage::

    python scripts/fleet_study.py --seeds 2                 # every case; docs/tables/fleet_*
    python scripts/fleet_study.py --seeds 1 --cases pc7:jsbsim-circuit --no-write
    python scripts/fleet_study.py --summarise docs/tables/fleet_runs.json

Seeds: 6000 + 10 i for run i (the same for every case: one weather per seed and scenario).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from flightrecon.cleaning import clean_flight
from flightrecon.ingest import load_flight
from flightrecon.methods.baselines import dead_reckoning
from flightrecon.methods.joint.settings import JointNoise
from flightrecon.pipeline import ReconstructSettings, run_method
from flightrecon.pipeline.health import method_health
from flightrecon.sim import simulate, write_simulation
from flightrecon.sim.io import write_export
from flightrecon.sim.jsbsim_flight import Runway

sys.path.insert(0, str(Path(__file__).resolve().parent))

from table_header import header  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TABLES = ROOT / "docs" / "tables"
FORMATS = ("canonical", "ed112")
CASES = (
    ("c172p", "jsbsim-circuit", {}), ("c310", "jsbsim-circuit", {}),
    ("737", "jsbsim-circuit", {}),
    ("t6texan2", "jsbsim-circuit", {}), ("pc7", "jsbsim-circuit", {}),
    ("global5000", "jsbsim-circuit", {}), ("B747", "jsbsim-circuit", {}),
    ("c172p", "jsbsim-airwork", {}), ("t6texan2", "jsbsim-airwork", {}),
    ("pc7", "jsbsim-airwork", {}),
    ("c172p", "jsbsim-holding", {}), ("c310", "jsbsim-holding", {}),
    ("pc7", "jsbsim-holding", {}),
    ("c172p", "jsbsim-goaround", {}), ("c310", "jsbsim-goaround", {}),
    ("global5000", "jsbsim-goaround", {}),
    ("B747", "jsbsim-goaround", {}),
    ("c310", "jsbsim-xc", {"scale": 0.2}), ("t6texan2", "jsbsim-xc", {"scale": 0.2}),
    ("pc7", "jsbsim-xc", {"scale": 0.2}),
    ("global5000", "jsbsim-jet", {"scale": 0.05}), ("B747", "jsbsim-jet", {"scale": 0.05}),
)
"""(aircraft, scenario, overrides): each aircraft on the schedules that fit its class (the
cross-country and the jet flight shortened; docs/jsbsim.md)."""

RATIO_BAR = {"canonical": 0.7, "ed112": 1.0}
VERTICAL_BAR_M = 40.0


def interp_errors(track: pd.DataFrame, truth: pd.DataFrame, airborne: np.ndarray
                   ) -> dict[str, float]:
    """RMS horizontal and vertical errors and NEES of ``track`` (``joint_`` columns or bare)
    interpolated to the airborne truth samples inside its coverage."""
    p = "joint_" if "joint_north_m" in track.columns else ""
    t = truth["t_s"].to_numpy()[airborne]
    tt = track["t_s"].to_numpy(float)
    out: dict[str, float] = {}
    inside = (t >= tt[0]) & (t <= tt[-1])

    def at(col: str) -> np.ndarray:
        return np.interp(t, tt, track[col].to_numpy(float))
    en = at(f"{p}north_m") - truth["north_m"].to_numpy()[airborne]
    ee = at(f"{p}east_m") - truth["east_m"].to_numpy()[airborne]
    ok = inside & np.isfinite(en) & np.isfinite(ee)
    out["rms_h_m"] = float(np.sqrt(np.mean(en[ok] ** 2 + ee[ok] ** 2))) if ok.any() else math.nan
    out["coverage"] = float(ok.mean())
    if f"{p}up_m" in track.columns:
        eu = at(f"{p}up_m") - truth["up_m"].to_numpy()[airborne]
        okv = ok & np.isfinite(eu)
        out["rms_v_m"] = float(np.sqrt(np.mean(eu[okv] ** 2))) if okv.any() else math.nan
    if f"{p}north_sd_m" in track.columns:
        sn, se = at(f"{p}north_sd_m"), at(f"{p}east_sd_m")
        good = ok & (sn > 0) & (se > 0)
        out["nees_n"] = float(np.mean((en[good] / sn[good]) ** 2))
        out["nees_e"] = float(np.mean((ee[good] / se[good]) ** 2))
    return out


def _arrival_given(summary: dict) -> tuple[float, float]:
    """Distance past the arrival threshold and its sd of the touchdown the smoother was given:
    from the recorded flare where it measured one (``float_touchdown``), else ``touchdown_m``."""
    nz = JointNoise()
    for e in summary.get("end_points", []):
        if e["which"] == "arrival" and "flare" in e:
            return float(e["flare"]["touchdown_m"]), float(e["flare"]["sd_m"])
    return nz.touchdown_m, nz.touchdown_sd_m


def _end_points(track: pd.DataFrame, clean, meta, summary: dict) -> dict[str, float]:
    """The joint's track against the end points it was given (module docstring)."""
    nz = JointNoise()
    tt = track["t_s"].to_numpy(float)
    lat = track["joint_lat_deg"].to_numpy(float)
    lon = track["joint_lon_deg"].to_numpy(float)
    out: dict[str, float] = {}
    ratios = []
    ph = clean.phases
    td_m, td_sd_m = _arrival_given(summary)
    for which, pos, t_ev, dist, sd_along in (
            ("departure", meta.departure, ph.lineup_t_s, 0.0, nz.roll_start_sd_m),
            ("arrival", meta.arrival, ph.touchdown_t_s, td_m, td_sd_m)):
        if pos is None or pos.threshold is None or pos.runway_true_deg is None or \
                t_ev is None or not np.isfinite(t_ev):
            continue
        rw = Runway(pos.threshold_lat_deg, pos.threshold_lon_deg, pos.runway_true_deg,
                    pos.elev_m)
        i = int(np.clip(np.searchsorted(tt, t_ev), 0, len(tt) - 1))
        along, cross = rw.coords(lat[i], lon[i])
        out[f"{which}_along_m"] = float(along - dist)
        out[f"{which}_cross_m"] = float(cross)
        ratios += [abs(along - dist) / sd_along, abs(cross) / nz.runway_halfwidth_m]
        if which == "arrival":
            fin = np.isfinite(lat) & np.isfinite(lon)
            a_end, c_end = rw.coords(lat[fin][-1], lon[fin][-1])
            out["end_from_threshold_m"] = float(math.hypot(a_end, c_end))
    out["end_point_ratio"] = float(max(ratios)) if ratios else math.nan
    return out


def _touchdown_truth(track: pd.DataFrame, truth: pd.DataFrame, events: dict, meta,
                     summary: dict) -> dict[str, float]:
    """At the true touchdown: how far the given touchdown point (:func:`_arrival_given` past
    the arrival threshold) is from where the aircraft touched down, along the runway, and the
    joint's horizontal error there."""
    if "touchdown_t_s" not in events or meta.arrival is None or meta.arrival.threshold is None:
        return {}
    pos = meta.arrival
    rw = Runway(pos.threshold_lat_deg, pos.threshold_lon_deg, pos.runway_true_deg, pos.elev_m)
    along, _ = rw.coords(events["touchdown_lat_deg"], events["touchdown_lon_deg"])
    t = events["touchdown_t_s"]
    i = int(np.searchsorted(truth["t_s"].to_numpy(), t - 1e-9))
    tt = track["t_s"].to_numpy(float)
    dn = float(np.interp(t, tt, track["joint_north_m"].to_numpy(float))) \
        - float(truth["north_m"].iloc[i])
    de = float(np.interp(t, tt, track["joint_east_m"].to_numpy(float))) \
        - float(truth["east_m"].iloc[i])
    return {"given_touchdown_off_m": float(along - _arrival_given(summary)[0]),
            "track_error_at_touchdown_m": float(math.hypot(dn, de))}


def _attempt(fn, *args, **kw):
    try:
        return fn(*args, **kw), None
    except Exception as exc:  # noqa: BLE001 - a failure is a result of the study
        return None, f"{type(exc).__name__}: {exc}"[:300]


def one_run(airframe: str, scenario: str, overrides: dict, seed: int, tmp: Path) -> list[dict]:
    """Both formats of one flight (one row each; a flight the simulator refused: one row)."""
    base = {"airframe": airframe, "scenario": scenario, "seed": seed}
    t0 = time.perf_counter()
    r, err = _attempt(simulate, scenario, seed, airframe=airframe, gnss_hz=0.0, **overrides)
    if r is None:
        return [{**base, "format": "-", "sim_error": err}]
    sim_s = time.perf_counter() - t0
    truth = r.truth
    airborne = ~truth["on_ground"].to_numpy(bool)
    log = tmp / f"{airframe}-{scenario}-{seed}.parquet"
    write_simulation(r, log)
    write_export(r, log, "ed112")
    rows = []
    for fmt in FORMATS:
        row = {**base, "format": fmt, "sim_time_s": sim_s,
               "duration_s": float(truth["t_s"].iloc[-1]),
               "events": {k: v for k, v in r.sensor_truth["events"].items() if k.endswith("t_s")}}
        if fmt == "canonical":
            flight, err = _attempt(load_flight, log)
        else:
            flight, err = _attempt(load_flight, log.with_name(log.stem + ".ed112.csv"),
                                   mapping=log.with_name(log.stem + ".ed112.mapping.toml"))
        if flight is None:
            rows.append({**row, "load_error": err})
            continue
        clean, err = _attempt(clean_flight, flight)
        if clean is None:
            rows.append({**row, "clean_error": err})
            continue
        t1 = time.perf_counter()
        j, err = _attempt(run_method, "joint", clean, ReconstructSettings())
        row["joint_time_s"] = time.perf_counter() - t1
        if j is None:
            row["joint"] = {"error": err}
        else:
            row["joint"] = interp_errors(j.track, truth, airborne)
            h = method_health(j, clean)
            row["healthy"] = bool(h["healthy"])
            row["health_problems"] = [p["what"] for p in h["problems"]][:4]
            row["converged"] = bool(j.summary.get("converged"))
            corr = j.summary.get("corrections", {})
            row["heading_bias_deg"] = corr.get("heading_bias_deg")
            row["tas_scale"] = corr.get("tas_scale")
            pe = r.sensor_truth["persistent_errors"]
            row["heading_bias_truth_deg"] = pe["heading_bias_deg"]
            row["tas_scale_truth"] = pe["airspeed_scale"]
            row["joint_warnings"] = list(j.summary.get("warnings", []))[:5]
            row["ends"] = _end_points(j.track, clean, flight.meta, j.summary)
            row["ends"].update(_touchdown_truth(j.track, truth, r.sensor_truth["events"],
                                                flight.meta, j.summary))
        d, err = _attempt(dead_reckoning, clean, corrected=True)
        row["dr_linear"] = {"error": err} if d is None else interp_errors(d, truth, airborne)
        rows.append(row)
    return rows


def _v(r: dict, m: str, k: str) -> float:
    v = r.get(m, {}).get(k, math.nan)
    return float(v) if v is not None else math.nan


def _ends(rs: list[dict], key: str) -> np.ndarray:
    return np.array([r.get("ends", {}).get(key, math.nan) for r in rs], float)


def summarise(rows: list[dict]) -> str:
    """The per-case table (geometric means over seeds) and the per-run table."""
    flown = [r for r in rows if "sim_error" not in r]
    lines = ["| aircraft | scenario | format | runs | joint / DR+lin (geo. mean) | bar | "
             "meets bar | joint RMS h [m] (median) | DR+lin [m] (median) | RMS v [m] "
             "(median) | v <= 40 m | NEES n / e (mean) | healthy | end points met | "
             "given touchdown point off [m] (median abs) | track error at touchdown [m] "
             "(median) |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    keys = []
    for r in flown:
        k = (r["airframe"], r["scenario"], r["format"])
        if k not in keys:
            keys.append(k)
    for k in keys:
        rs = [r for r in flown if (r["airframe"], r["scenario"], r["format"]) == k]
        jr = np.array([_v(r, "joint", "rms_h_m") for r in rs])
        dl = np.array([_v(r, "dr_linear", "rms_h_m") for r in rs])
        vv = np.array([_v(r, "joint", "rms_v_m") for r in rs])
        nn = np.array([_v(r, "joint", "nees_n") for r in rs])
        ne = np.array([_v(r, "joint", "nees_e") for r in rs])
        ok = np.isfinite(jr) & np.isfinite(dl) & (dl > 0)
        g = float(np.exp(np.mean(np.log(jr[ok] / dl[ok])))) if ok.any() else math.nan
        bar = RATIO_BAR[k[2]]
        meets = int(np.sum(jr[ok] / dl[ok] <= bar))
        ends = [r.get("ends", {}).get("end_point_ratio", math.nan) for r in rs]
        fin = np.isfinite(nn) & np.isfinite(ne)

        def med(v):
            f = v[np.isfinite(v)]
            return f"{np.median(f):.0f}" if f.size else "-"
        lines.append(
            f"| {k[0]} | {k[1]} | {k[2]} | {len(rs)} | {g:.2f} | {bar:.1f} | "
            f"{meets}/{int(ok.sum())} | {med(jr)} | {med(dl)} | {med(vv)} | "
            f"{int(np.sum(vv[np.isfinite(vv)] <= VERTICAL_BAR_M))}/{int(np.isfinite(vv).sum())}"
            f" | " + (f"{np.mean(nn[fin]):.2f} / {np.mean(ne[fin]):.2f}" if fin.any() else "-")
            + f" | {sum(bool(r.get('healthy')) for r in rs)}/{len(rs)} | "
            f"{sum(e <= 2.0 for e in ends if np.isfinite(e))}/{sum(np.isfinite(e) for e in ends)}"
            f" | {med(np.abs(_ends(rs, 'given_touchdown_off_m')))}"
            f" | {med(_ends(rs, 'track_error_at_touchdown_m'))} |")
    lines += ["", "Per run (RMS over the airborne truth samples; end points: the largest of "
              "|along| / sd and |cross| / sd at the line-up and the touchdown, and the track's "
              "last position from the arrival threshold):", "",
              "| aircraft | scenario | format | seed | min | joint h [m] | DR+lin [m] | ratio | "
              "joint v [m] | NEES n / e | verdict | end-point ratio | end from threshold [m] |",
              "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in flown:
        j = r.get("joint", {})
        e = r.get("ends", {})
        jr, dl = _v(r, "joint", "rms_h_m"), _v(r, "dr_linear", "rms_h_m")
        verdict = ("error: " + (r.get("load_error") or r.get("clean_error")
                                or j.get("error", ""))[:60]
                   if ("load_error" in r or "clean_error" in r or "error" in j)
                   else ("ok" if r.get("healthy") else "unhealthy: "
                         + "; ".join(r.get("health_problems", []))[:60]))

        def f0(v):
            return f"{v:.0f}" if v is not None and np.isfinite(v) else "-"
        lines.append(
            f"| {r['airframe']} | {r['scenario']} | {r['format']} | {r['seed']} | "
            f"{r.get('duration_s', 0) / 60:.0f} | {f0(jr)} | {f0(dl)} | "
            f"{jr / dl if dl > 0 else math.nan:.2f} | {f0(_v(r, 'joint', 'rms_v_m'))} | "
            + (f"{j['nees_n']:.1f} / {j['nees_e']:.1f}" if "nees_n" in j else "-")
            + f" | {verdict} | {e.get('end_point_ratio', math.nan):.1f} | "
            f"{f0(e.get('end_from_threshold_m'))} |")
    refused = [r for r in rows if "sim_error" in r]
    if refused:
        lines += ["", "Flights the simulator refused (not counted above):", ""]
        lines += [f"* {r['airframe']} {r['scenario']} {r['seed']}: {r['sim_error']}"
                  for r in refused]
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=2, help="seeds per case")
    ap.add_argument("--cases", default="",
                    help="comma-separated aircraft:scenario to run (default: every case)")
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--runs-file", default="fleet_runs.json")
    ap.add_argument("--summarise", metavar="RUNS_JSON", nargs="+")
    a = ap.parse_args()
    if a.summarise:
        rows = [r for f in a.summarise for r in json.loads(Path(f).read_text())]
    else:
        chosen = [c for c in CASES if not a.cases or f"{c[0]}:{c[1]}" in a.cases.split(",")]
        rows = []
        with tempfile.TemporaryDirectory() as d:
            for i in range(a.seeds):  # round-robin: every case has runs early
                for airframe, scenario, over in chosen:
                    seed = 6000 + 10 * i
                    new = one_run(airframe, scenario, over, seed, Path(d))
                    rows += new
                    for r in new:
                        print(airframe, scenario, seed, r["format"],
                              json.dumps({"joint": _v(r, "joint", "rms_h_m"),
                                          "dr_lin": _v(r, "dr_linear", "rms_h_m"),
                                          "v": _v(r, "joint", "rms_v_m"),
                                          "healthy": r.get("healthy"),
                                          "err": r.get("sim_error") or r.get("load_error")}),
                              file=sys.stderr, flush=True)
                    if not a.no_write:
                        TABLES.mkdir(parents=True, exist_ok=True)
                        (TABLES / a.runs_file).write_text(json.dumps(rows, indent=1,
                                                                     default=str))
    text = summarise(rows)
    print(text)
    if not a.no_write:
        (TABLES / "fleet_study.md").write_text(header() + text)


if __name__ == "__main__":
    main()
