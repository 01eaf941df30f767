"""Monte Carlo study of the recorder-only estimators on JSBSim flights (docs/jsbsim.md).

Every run flies one JSBSim scenario (``flightrecon.sim.simulate("jsbsim-...", seed)``: new
weather, turbulence, persistent sensor errors and recorder noise per seed) and records it with
the project's recorder, **without GNSS or radar**.  The end points are what the sidecar gives:
the departure airfield (runway direction and threshold) and the arrival airfield, or, for the
upsets, the wreckage (the last position, no runway).  Per run, on the airborne truth samples:

* the joint smoother's RMS horizontal position error, its convergence flag and passes (the
  largest position change of each Gauss-Newton pass and the heading-bias estimate of each), the
  run-averaged NEES per axis (north, east) from its reported standard deviations;
* dead reckoning from airspeed and heading (lift-off to touchdown), with and without the linear
  end-point correction;
* the Sabziev fusion's RMS error (or why it has none).

The joint smoother's noise budget is the simulated sensors' data sheet (``noise_from_sensors`` of
``scripts/mc_joint.py``), as in the point-mass study.  No estimator is tuned here.

Usage::

    python scripts/mc_jsbsim.py --runs 8                  # per scenario; writes docs/tables/
    python scripts/mc_jsbsim.py --runs 2 --no-write       # quick look
    python scripts/mc_jsbsim.py --summarise docs/tables/jsbsim_mc_runs*.json

Seeds: run i of scenario k uses seed 5000 + 100 k + i.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np
from scipy import stats

sys.path.insert(0, str(Path(__file__).resolve().parent))

from mc_joint import errors, noise_from_sensors
from table_header import header  # noqa: E402

from flightrecon.cleaning import clean_flight
from flightrecon.methods.baselines import dead_reckoning
from flightrecon.methods.joint import JointSettings
from flightrecon.methods.joint.method import run_joint
from flightrecon.pipeline import ReconstructSettings, run_method
from flightrecon.sim import simulate
from flightrecon.types import Flight

ROOT = Path(__file__).resolve().parents[1]
TABLES = ROOT / "docs" / "tables"
FIGURE = ROOT / "docs" / "figures" / "jsbsim_mc.png"
SCENARIOS = ("jsbsim-circuit", "jsbsim-xc", "jsbsim-jet", "jsbsim-spiral", "jsbsim-spin")
IMPACT = ("jsbsim-spiral", "jsbsim-spin")


def _method(fn, *args, **kw) -> tuple[object | None, str | None]:
    try:
        return fn(*args, **kw), None
    except Exception as exc:  # noqa: BLE001 - a method failing is a result of the study
        return None, f"{type(exc).__name__}: {exc}"[:300]


def one_run(scenario: str, seed: int) -> dict:
    t0 = time.perf_counter()
    r, err = _method(simulate, scenario, seed, gnss_hz=0.0)
    if r is None:  # the autopilot lost the aircraft: reported, never dropped
        return {"scenario": scenario, "seed": seed, "sim_error": err}
    res: dict = {"scenario": scenario, "seed": seed, "sim_time_s": time.perf_counter() - t0,
                 "duration_s": float(r.truth["t_s"].iloc[-1]),
                 "heading_bias_truth_deg": r.sensor_truth["persistent_errors"]["heading_bias_deg"]}
    truth = r.truth
    airborne = ~truth["on_ground"].to_numpy(bool)
    if scenario in IMPACT:  # the impact sample itself is on the ground: keep the flight to it
        airborne[-1] = True
    clean, err = _method(clean_flight, Flight(data=r.log, meta=r.meta))
    if clean is None:
        res["clean_error"] = err
        return res
    ph = clean.phases
    res["phases"] = {"liftoff_t_s": ph.liftoff_t_s, "touchdown_t_s": ph.touchdown_t_s,
                     "ends_airborne": ph.ends_airborne,
                     "truth_liftoff_t_s": r.sensor_truth["events"].get("liftoff_t_s"),
                     "truth_end_t_s": r.sensor_truth["events"].get(
                         "touchdown_t_s", r.sensor_truth["events"].get("impact_t_s"))}
    t1 = time.perf_counter()
    settings = JointSettings(noise=noise_from_sensors(r.sensor_truth))
    j, err = _method(run_joint, clean, settings=settings)
    res["joint_time_s"] = time.perf_counter() - t1
    if j is None:
        res["joint"] = {"error": err}
    else:
        res["joint"] = errors(j.track, "joint_", truth, airborne)
        res["joint"].pop("profile", None)
        s = j.summary
        its = s["iterations"]
        res["joint_converged"] = bool(s["converged"])
        res["joint_healthy"] = bool(s["healthy"])
        res["joint_passes"] = len(its)
        res["joint_pass_change_m"] = [float(it.get("max_position_change_m", np.nan)) for it in its]
        res["joint_pass_cost"] = [float(it["cost"]) for it in its if "cost" in it]
        res["joint_pass_step"] = [float(it.get("step_size", np.nan)) for it in its]
        res["joint_pass_cost_start"] = [it.get("cost_start") for it in its]
        res["joint_pass_params_changed"] = [bool(it.get("parameters_changed")) for it in its]
        res["joint_stop_reason"] = s.get("stop_reason")
        hb = [it.get("heading_bias_deg") for it in its]
        res["joint_pass_heading_bias_deg"] = [None if v is None else float(v) for v in hb]
        res["joint_heading_bias_deg"] = s["corrections"].get("heading_bias_deg")
        res["joint_tas_scale"] = s["corrections"].get("tas_scale")
        res["tas_scale_truth"] = r.sensor_truth["persistent_errors"]["airspeed_scale"]
        res["joint_gust"] = s.get("gust")
        res["joint_warnings"] = s["warnings"][:5]
    sab, err = _method(run_method, "sabziev", clean, ReconstructSettings())
    res["sabziev"] = {"error": err} if sab is None else errors(sab.track, "sabziev_", truth,
                                                               airborne)
    if sab is not None:
        res["sabziev"].pop("profile", None)
        res["sabziev_status"] = {k: sab.summary.get(k) for k in ("healthy", "converged")
                                 if k in sab.summary}
    for name, corrected in (("dr", False), ("dr_linear", True)):
        d, err = _method(dead_reckoning, clean, corrected=corrected)
        res[name] = {"error": err} if d is None else errors(d, "", truth, airborne)
        res[name].pop("profile", None)
    return res


def _rms(r: dict, m: str) -> float:
    v = r.get(m, {}).get("rms_h_m", np.nan)
    return float(v) if v is not None else np.nan


def _monotone(r: dict) -> bool | None:
    """The joint's MAP cost never rose: within each pass (the accepted iterate against the
    pass's start) and from pass to pass where the take-off roll, the clock offsets and the
    noise factors stayed (otherwise the measurements, so the cost function, changed); relative
    1e-9 for rounding.  None without a cost (runs of the undamped iterations)."""
    c = r.get("joint_pass_cost") or []
    c0 = r.get("joint_pass_cost_start") or []
    ch = r.get("joint_pass_params_changed") or []
    if not c or len(c0) != len(c):
        return None
    ok = all(s is None or b <= s * (1 + 1e-9) for s, b in zip(c0, c))
    ok &= all(chg or b <= a * (1 + 1e-9) for a, b, chg in zip(c, c0[1:], ch[1:]))
    return bool(ok)


def _flown(rows: list[dict]) -> list[dict]:
    """The runs whose truth the simulator accepted (a run with ``sim_error`` has none: the
    autopilot lost the aircraft, or JSBSim's ground model overturned it before take-off)."""
    return [r for r in rows if "sim_error" not in r]


def summarise(rows: list[dict]) -> str:
    rejected = [r for r in rows if "sim_error" in r]
    rows = _flown(rows)
    lines = [("| scenario | runs | joint converged | joint RMS [m] (median) | DR + linear [m] | "
             "DR [m] | Sabziev [m] | joint / DR+linear (geo. mean) | joint < DR+linear | "
             "NEES north | NEES east | 95 % band | cost non-increasing |"),
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for sc in SCENARIOS:
        rs = [r for r in rows if r["scenario"] == sc]
        if not rs:
            continue
        M = len(rs)
        jr = np.array([_rms(r, "joint") for r in rs])
        dl = np.array([_rms(r, "dr_linear") for r in rs])
        dr = np.array([_rms(r, "dr") for r in rs])
        sb = np.array([_rms(r, "sabziev") for r in rs])
        conv = sum(bool(r.get("joint_converged")) for r in rs)
        mono = [_monotone(r) for r in rs]
        mono_s = (f"{sum(m is True for m in mono)}/{sum(m is not None for m in mono)}"
                  if any(m is not None for m in mono) else "-")
        ok = np.isfinite(jr) & np.isfinite(dl) & (dl > 0)
        ratio = float(np.exp(np.mean(np.log(jr[ok] / dl[ok])))) if ok.any() else np.nan
        better = int(np.sum(jr[ok] < dl[ok]))
        nn = np.array([r.get("joint", {}).get("nees_n", np.nan) for r in rs], float)
        ne = np.array([r.get("joint", {}).get("nees_e", np.nan) for r in rs], float)
        fin = np.isfinite(nn) & np.isfinite(ne)
        lo, hi = (stats.chi2.ppf([0.025, 0.975], fin.sum()) / max(fin.sum(), 1)
                  if fin.any() else (np.nan, np.nan))

        def med(v):
            f = v[np.isfinite(v)]
            return f"{np.median(f):.0f}" if f.size else "-"
        nosab = int(np.sum(~np.isfinite(sb)))
        lines.append(
            f"| {sc} | {M} | {conv}/{M} | {med(jr)} | {med(dl)} | {med(dr)} | {med(sb)}"
            + (f" ({nosab} without a track)" if nosab else "")
            + f" | {ratio:.2f} | {better}/{int(ok.sum())} | "
            + (f"{np.mean(nn[fin]):.2f} | {np.mean(ne[fin]):.2f} | [{lo:.2f}, {hi:.2f}] |"
               if fin.any() else "- | - | - |") + f" {mono_s} |")
    lines.append("")
    lines.append("Per run (RMS horizontal error over the airborne truth samples [m]; passes: "
                 "the Gauss-Newton passes of the joint smoother with the largest position "
                 "change of the first and the last pass; heading bias: the joint's estimate "
                 "(truth: the recorder's heading bias)):")
    lines.append("")
    lines.append("| scenario | seed | min | joint | conv. | passes (first -> last change, m) | "
                 "DR + lin. | DR | Sabziev | NEES n / e | heading bias est. / truth [deg] | "
                 "stop |")
    lines.append("|---|---|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        pc = r.get("joint_pass_change_m") or []
        passes = f"{r.get('joint_passes', '-')} ({pc[0]:.0f} -> {pc[-1]:.0f})" if pc else "-"
        j = r.get("joint", {})
        nees = (f"{j['nees_n']:.1f} / {j['nees_e']:.1f}" if "nees_n" in j else "-")
        hb = r.get("joint_heading_bias_deg")
        hb_s = (f"{hb['value']:+.2f}" if isinstance(hb, dict) and "value" in hb else "-")
        sab = r.get("sabziev", {})
        sab_s = (f"{sab['rms_h_m']:.0f}" if np.isfinite(sab.get("rms_h_m", np.nan))
                 else "none")

        def f0(v):
            return f"{v:.0f}" if v is not None and np.isfinite(v) else "-"
        lines.append(
            f"| {r['scenario']} | {r['seed']} | {r.get('duration_s', 0) / 60:.0f} | "
            f"{f0(_rms(r, 'joint'))} | {'yes' if r.get('joint_converged') else 'no'} | {passes} | "
            f"{f0(_rms(r, 'dr_linear'))} | {f0(_rms(r, 'dr'))} | {sab_s} | {nees} | "
            f"{hb_s} / {r.get('heading_bias_truth_deg', float('nan')):+.2f} | "
            f"{(r.get('joint_stop_reason') or '-').split(':')[0]} |")
    if rejected:
        lines += ["", "Seeds without a flight (the simulator refused its truth; not counted "
                  "above):", ""]
        lines += [f"* {r['scenario']} {r['seed']}: {r['sim_error']}" for r in rejected]
    return "\n".join(lines) + "\n"


def _paired_stats(rows: list[dict]) -> str:
    """converged | geo-mean joint / DR+linear | joint < DR+linear | NEES n / e of ``rows``."""
    jr = np.array([_rms(r, "joint") for r in rows])
    dl = np.array([_rms(r, "dr_linear") for r in rows])
    ok = np.isfinite(jr) & np.isfinite(dl) & (dl > 0)
    g = float(np.exp(np.mean(np.log(jr[ok] / dl[ok])))) if ok.any() else np.nan
    conv = sum(bool(r.get("joint_converged")) for r in rows)
    nn = np.array([r.get("joint", {}).get("nees_n", np.nan) for r in rows], float)
    ne = np.array([r.get("joint", {}).get("nees_e", np.nan) for r in rows], float)
    fin = np.isfinite(nn) & np.isfinite(ne)
    nees = f"{np.mean(nn[fin]):.2f} / {np.mean(ne[fin]):.2f}" if fin.any() else "-"
    return (f"{conv}/{len(rows)} | {g:.2f} | {int(np.sum(jr[ok] < dl[ok]))}/{int(ok.sum())} | "
            f"{nees}")


def compare(before: list[dict], after: list[dict]) -> str:
    """Before/after table on the seeds both studies ran (``--before``: the runs of the
    undamped iterations)."""
    lines = ["| scenario | runs (seeds) | before: converged | joint / DR+lin (geo. mean) | "
             "joint < DR+lin | NEES n / e | after: converged | joint / DR+lin (geo. mean) | "
             "joint < DR+lin | NEES n / e | cost non-increasing |",
             "|---|---|---|---|---|---|---|---|---|---|---|"]
    for sc in SCENARIOS:
        a = {r["seed"]: r for r in _flown(after) if r["scenario"] == sc}
        b = {r["seed"]: r for r in _flown(before) if r["scenario"] == sc}
        seeds = sorted(set(a) & set(b))
        if not seeds:
            continue
        mono = [_monotone(a[s]) for s in seeds]
        lines.append(f"| {sc} | {len(seeds)} ({seeds[0]}-{seeds[-1]}) | "
                     f"{_paired_stats([b[s] for s in seeds])} | "
                     f"{_paired_stats([a[s] for s in seeds])} | "
                     f"{sum(m is True for m in mono)}/{sum(m is not None for m in mono)} |")
    return "\n".join(lines) + "\n"


def figure(rows: list[dict], path: Path) -> None:
    """Joint and Sabziev RMS error against dead reckoning + linear correction, per run."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(7, 5.5))
    marks = dict(zip(SCENARIOS, "os^vD"))
    for sc in SCENARIOS:
        rs = [r for r in rows if r["scenario"] == sc]
        if not rs:
            continue
        dl = np.array([_rms(r, "dr_linear") for r in rs])
        for m, col in (("joint", "C0"), ("sabziev", "C3")):
            v = np.array([_rms(r, m) for r in rs])
            conv = np.array([bool(r.get("joint_converged")) for r in rs]) if m == "joint" \
                else np.ones(len(rs), bool)
            ok = np.isfinite(v) & np.isfinite(dl)
            ax.scatter(dl[ok & conv], v[ok & conv], marker=marks[sc], color=col, s=30,
                       label=f"{m}, {sc}")
            if m == "joint" and np.any(ok & ~conv):
                ax.scatter(dl[ok & ~conv], v[ok & ~conv], marker=marks[sc], s=30,
                           facecolors="none", edgecolors=col)
    lim = [10.0, 1e6]
    ax.plot(lim, lim, "k-", lw=0.8, label="= DR + linear")
    ax.plot(lim, [0.5 * x for x in lim], "k--", lw=0.8, label="0.5 x DR + linear (the bar)")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("dead reckoning + linear end correction: RMS horizontal error [m]")
    ax.set_ylabel("method RMS horizontal error [m]")
    ax.set_title("JSBSim flights, recorder only (open: joint not converged)", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=6, ncol=2)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=8, help="runs per scenario")
    ap.add_argument("--scenarios", default=",".join(SCENARIOS))
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--summarise", metavar="RUNS_JSON", nargs="+",
                    help="only rebuild the tables and the figure from runs files")
    ap.add_argument("--before", metavar="RUNS_JSON", nargs="+",
                    help="with --summarise: runs of the undamped iterations (same seeds) for a "
                         "before/after table")
    ap.add_argument("--before-label", default="the undamped Gauss-Newton iterations",
                    help="with --before: what the before runs were (written above the table)")
    ap.add_argument("--runs-file", default="jsbsim_mc_runs.json",
                    help="name of the runs file under docs/tables/ (parallel studies of "
                         "different scenarios each write their own; --summarise merges them)")
    a = ap.parse_args()
    if a.summarise:
        rows = [r for f in a.summarise for r in json.loads(Path(f).read_text())]
    else:
        rows = []
        runs_file = TABLES / a.runs_file
        chosen = [sc for sc in SCENARIOS if sc in a.scenarios.split(",")]
        # round-robin over the scenarios (every scenario has runs early), the runs file
        # rewritten after each run (an interrupted study keeps what it measured)
        for i in range(a.runs):
            for sc in chosen:
                seed = 5000 + 100 * SCENARIOS.index(sc) + i
                row = one_run(sc, seed)
                rows.append(row)
                print(sc, seed, json.dumps({m: row.get(m, {}).get("rms_h_m") for m in
                                            ("joint", "dr_linear", "sabziev")}),
                      "converged", row.get("joint_converged"), file=sys.stderr, flush=True)
                if not a.no_write:
                    TABLES.mkdir(parents=True, exist_ok=True)
                    runs_file.write_text(json.dumps(rows, indent=1, default=str))
    text = summarise(rows)
    if a.before:
        before = [r for f in a.before for r in json.loads(Path(f).read_text())]
        text += (f"\nBefore ({a.before_label}: "
                 f"{', '.join(Path(f).name for f in a.before)}) and after, on the same seeds:"
                 "\n\n" + compare(before, rows))
    print(text)
    if not a.no_write:
        n = max(sum(r["scenario"] == s for r in rows) for s in SCENARIOS)
        TABLES.mkdir(parents=True, exist_ok=True)
        (TABLES / "jsbsim_mc.md").write_text(
            header() + f"(at most {n} runs per scenario)\n\n" + text)
        figure(rows, FIGURE)


if __name__ == "__main__":
    main()
