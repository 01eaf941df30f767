"""1 Hz glass-cockpit exports of simulated JSBSim flights: accuracy and honesty of the joint
smoother (issue #36, item 5, on the fleet; ``scripts/onehz_study.py`` is the real export).

Each flight (``simulate(scenario, seed, airframe=...)``; ``FLIGHTS`` x seeds 1-2) is written as
a Garmin glass-cockpit CSV (:mod:`flightrecon.sim.glass_cockpit`: 1 Hz, whole-second stamps,
magnetic heading with the avionics' variation, the altimeter's indication at the departure
QNH, no longitudinal acceleration) with its sidecar (airfields with their runways, QNH,
geoid), read back as recorded by ``load_flight`` and reconstructed by the joint smoother
(``run_joint``).  The reference is the truth (the centre of mass), at every whole second of
the export:

* **recorder only** (``withhold_gnss``: every GNSS channel withheld; departure and arrival
  from the sidecar): horizontal and vertical RMS over the airborne seconds (truth
  ``on_ground`` false) against dead reckoning (TAS along the heading, no wind) with a linear
  end-point correction (:func:`flightrecon.methods.baselines.dead_reckoning`,
  ``corrected=True``); mean NEES per axis (north, east, up).
* **GNSS gaps**: the GPS used except in one window of 300 s, and in another run of 120 s,
  centred in the airborne part (the GNSS columns masked in a copy of the flight; a flight
  whose airborne part is shorter than the gap plus 60 s of GPS on each side has no such gap).
  Inside the gap the joint's error against dead reckoning from the last fix before the gap
  with the wind of the minute before it (the mean of GPS velocity minus the TAS vector over
  those 60 s, from the recorded heading and TAS); mean NEES per axis inside the gap.

NEES per axis is ``e_i^2 / sd_i^2`` averaged over the seconds, ``sd_i`` the joint's reported
standard deviation (the truth has none).  A consistent smoother gives 1 per axis; the bar
(issue #36) is 5.  The pipeline's health verdict on each joint track
(:func:`flightrecon.pipeline.health.method_health`) is reported beside it: the estimators are
measured as they are, nothing tuned.

Writes ``docs/tables/onehz_fleet.json`` and ``docs/tables/onehz_fleet.md`` (``--tag`` appends a
suffix).  About 2 minutes on a 2-core machine once the kernels are compiled
(4 minutes with ``--steps``).

``--steps`` adds, recorder only, the simulated log thinned to its whole seconds with and
without ``n_long_g``: what each step from the native log to the export costs; and each gap
flown again on the simulated log and on the two thinned logs (the export's window), with what
1 Hz samples of the true acceleration lose in it (:func:`sampled_acceleration_error`).

Usage: ``python scripts/onehz_fleet_study.py [--seeds 1 2] [--steps] [--tag before]``; the
tables in docs/ are ``--steps`` (seeds 1-2) and ``--seeds 3 4 --tag seeds34``.  Same seeds, same
numbers (checked: two runs gave the same figures).
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.cleaning import clean_flight
from flightrecon.geo.frames import output_plane
from flightrecon.ingest import load_flight
from flightrecon.ingest.gnss_use import GnssUse
from flightrecon.methods.joint.method import run_joint
from flightrecon.pipeline.health import method_health
from flightrecon.sim import simulate, write_simulation
from flightrecon.sim.glass_cockpit import write_glass_cockpit
from flightrecon.types import CleanFlight, Flight

sys.path.insert(0, str(Path(__file__).resolve().parent))

from onehz_study import (  # noqa: E402  (the real export's study)
    corrections,
    dr_in_gap,
    dr_linear_errors,
    joint_errors,
    with_gaps,
)
from table_header import command_line, header  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "tables"
#: (scenario, airframe) flown
FLIGHTS = (("jsbsim-circuit", "c172p"), ("jsbsim-airwork", "c172p"),
           ("jsbsim-circuit", "pc7"), ("jsbsim-holding", "c310"))
GAPS_S = (300.0, 120.0)
#: GPS kept on each side of a gap [s] (the minute before gives the baseline's wind)
MARGIN_S = 60.0
#: the bars of issue #36 item 5
BAR_RECORDER, BAR_GAP, BAR_NEES = 1.0, 0.5, 5.0


def load(path: Path, withhold: bool) -> Flight:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_flight(path, gnss_use=GnssUse(withhold=withhold))


def truth_reference(truth: pd.DataFrame, clean: CleanFlight) -> pd.DataFrame:
    """The truth at the export's whole seconds, airborne only, in the output plane."""
    t = clean.grid["t_s"].to_numpy(float)
    t = t[np.isclose(t, np.round(t))]
    tt = truth["t_s"].to_numpy(float)
    cols = {c: np.interp(t, tt, truth[c].to_numpy(float)) for c in
            ("lat_deg", "lon_deg", "alt_m")}
    air = np.interp(t, tt, (~truth["on_ground"].astype(bool)).to_numpy(float)) > 0.999
    e, n, u = output_plane(clean.meta).forward(cols["lat_deg"], cols["lon_deg"], cols["alt_m"])
    ref = pd.DataFrame({"t_s": t, "n": n, "e": e, "u": u})
    return ref[air].reset_index(drop=True)


def summary(err: dict[str, np.ndarray], mask: np.ndarray) -> dict[str, float]:
    h = np.hypot(err["n"][mask], err["e"][mask])
    res = {"rms_h_m": float(np.sqrt(np.mean(h ** 2))), "max_h_m": float(np.max(h)),
           "rms_v_m": float(np.sqrt(np.mean(err["u"][mask] ** 2))),
           "mean_v_m": float(np.mean(err["u"][mask]))}
    for ax in "neu":
        res["nees_" + ax] = float(np.mean(err[ax][mask] ** 2 / err["sd_" + ax][mask] ** 2))
        res["rms_sd_" + ax + "_m"] = float(np.sqrt(np.mean(err["sd_" + ax][mask] ** 2)))
    return res


def health(j: Any, clean: CleanFlight) -> dict[str, Any]:
    h = method_health(j, clean)
    return {"healthy": bool(h["healthy"]), "problems": [p["what"] for p in h["problems"]]}


def recorder_only(path: Path, truth: pd.DataFrame) -> dict[str, Any]:
    clean = clean_flight(load(path, True))
    ref = truth_reference(truth, clean)
    t0 = time.perf_counter()
    j = run_joint(clean)
    err = joint_errors(j.track, ref)
    res: dict[str, Any] = {"joint": summary(err, np.ones(len(ref), bool)),
                           "time_s": time.perf_counter() - t0, "health": health(j, clean),
                           "corrections": corrections(j.summary)}
    res["dr_linear"] = dr_linear_errors(clean, ref)
    res["ratio_to_dr"] = res["joint"]["rms_h_m"] / res["dr_linear"]["rms_h_m"]
    return res


def gnss_ne(flight: Flight, clean: CleanFlight) -> pd.DataFrame:
    """The log's GNSS fixes in the output plane (t_s, n, e, vn, ve)."""
    g = flight.data.dropna(subset=["gnss_lat_deg", "gnss_lon_deg", "gnss_alt_m"])
    e, n, _ = output_plane(clean.meta).forward(g.gnss_lat_deg.to_numpy(float),
                                               g.gnss_lon_deg.to_numpy(float),
                                               g.gnss_alt_m.to_numpy(float))
    return pd.DataFrame({"t_s": g.t_s.to_numpy(float), "n": n, "e": e,
                         "vn": g.gnss_vn_mps.to_numpy(float),
                         "ve": g.gnss_ve_mps.to_numpy(float)})


def gnss_gap(path: Path, truth: pd.DataFrame, length_s: float,
             window: tuple[float, float] | None = None) -> dict[str, Any] | None:
    """The GPS withheld in one window of ``length_s`` centred in the airborne part (or the
    given ``window``, the export's, for the ``--steps`` logs)."""
    full = load(path, False)
    clean_full = clean_flight(full)
    ref = truth_reference(truth, clean_full)
    t_air = ref.t_s.to_numpy()
    if window is not None:
        a, b = window
    elif t_air.size == 0 or t_air[-1] - t_air[0] < length_s + 2 * MARGIN_S:
        return None
    else:
        a = 0.5 * (t_air[0] + t_air[-1]) - 0.5 * length_s
        b = a + length_s
    clean = clean_flight(with_gaps(full, [(a, b)]))
    t0 = time.perf_counter()
    j = run_joint(clean)
    err = joint_errors(j.track, ref)
    m = ((ref.t_s >= a) & (ref.t_s <= b)).to_numpy()
    s = summary(err, m)
    h_dr = dr_in_gap(clean_full, ref, a, b, fixes=gnss_ne(full, clean_full))
    s["dr_wind_rms_h_m"] = float(np.sqrt(np.mean(h_dr ** 2)))
    s["ratio_to_dr"] = s["rms_h_m"] / s["dr_wind_rms_h_m"]
    return {"length_s": length_s, "t0_s": a, "t1_s": b, **s,
            "with_gps": summary(err, ~m), "time_s": time.perf_counter() - t0,
            "health": health(j, clean)}


def native(path: Path, truth: pd.DataFrame) -> dict[str, Any]:
    """Recorder only on the simulated log itself (16/8/4 Hz, n_long recorded): what the
    export costs."""
    clean = clean_flight(load(path, True))
    ref = truth_reference(truth, clean)
    j = run_joint(clean)
    return {"joint": summary(joint_errors(j.track, ref), np.ones(len(ref), bool)),
            "health": health(j, clean)}


def attribution(sim: Any, folder: Path, stem: str) -> tuple[dict[str, Any], dict[str, Path]]:
    """Recorder only on the simulated log thinned to its whole seconds (every channel is
    sampled there), with ``n_long_g`` kept and then dropped (derived by the reader): the step
    from the native log to the export taken one ingredient at a time.  Also returns the
    thinned logs' paths (for the gaps' steps, :func:`gap_steps`)."""
    log = sim.log[np.isclose(sim.log.t_s % 1.0, 0.0)].reset_index(drop=True)
    out: dict[str, Any] = {}
    paths: dict[str, Path] = {}
    for name, frame in (("onehz_n_long", log), ("onehz_no_n_long", log.drop(columns="n_long_g"))):
        p = folder / f"{stem}_{name}.parquet"
        write_simulation(replace(sim, log=frame), p)
        out[name] = native(p, sim.truth)
        paths[name] = p
    return out, paths


def sampled_acceleration_error(truth: pd.DataFrame, a: float, b: float) -> dict[str, float]:
    """What 1 Hz samples of the true acceleration lose in the window [a, b]: the truth's own
    north-east acceleration (``an_mps2``, ``ae_mps2``) integrated by the trapezoid at its whole
    seconds against the truth's velocity change; the largest horizontal velocity error and the
    horizontal acceleration's variance above 0.5 Hz (the 1 Hz samples' Nyquist frequency:
    what no quadrature of them recovers), with the same over the whole airborne record.  The
    truth's own rate integrates to within a few cm/s (0.05 m/s on the airwork's wing-over)."""
    t = truth["t_s"].to_numpy(float)

    def hf_var(m: np.ndarray) -> float:
        # the periodogram's power above 0.5 Hz, mean of the two axes (Parseval)
        dt = float(np.median(np.diff(t)))
        out = 0.0
        for c in ("an_mps2", "ae_mps2"):
            x = truth[c].to_numpy(float)[m]
            X = np.fft.rfft(x - x.mean())
            f = np.fft.rfftfreq(len(x), dt)
            p = 2.0 * np.abs(X) ** 2 / len(x) ** 2
            out += float(np.sum(p[f > 0.5]))
        return out / 2.0

    m = (t >= a) & (t <= b)
    s = m & np.isclose(t % 1.0, 0.0)
    ts = t[s]
    dv = np.zeros((len(ts), 2))
    for j, (c, v) in enumerate((("an_mps2", "vn_mps"), ("ae_mps2", "ve_mps"))):
        acc = truth[c].to_numpy(float)[s]
        integ = np.r_[0.0, np.cumsum(0.5 * (acc[1:] + acc[:-1]) * np.diff(ts))]
        vel = truth[v].to_numpy(float)[s]
        dv[:, j] = integ - (vel - vel[0])
    air = ~truth["on_ground"].astype(bool).to_numpy()
    return {"max_dv_1hz_mps": float(np.max(np.hypot(dv[:, 0], dv[:, 1]))),
            "hf_var_gap_m2ps4": hf_var(m), "hf_var_air_m2ps4": hf_var(air)}


def gap_steps(paths: dict[str, Path], truth: pd.DataFrame,
              gaps: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """Each gap of the export flown again on the simulated log itself and on it thinned to
    1 Hz with and without ``n_long_g`` (the export's window): what each step from the native
    log to the export costs inside the gap; with :func:`sampled_acceleration_error`."""
    out = []
    for g in gaps:
        row: dict[str, Any] = {"length_s": g["length_s"],
                               **sampled_acceleration_error(truth, g["t0_s"], g["t1_s"])}
        for name, p in paths.items():
            r = gnss_gap(p, truth, g["length_s"], window=(g["t0_s"], g["t1_s"]))
            row[name] = None if r is None else {k: r[k] for k in (
                "rms_h_m", "max_h_m", "nees_n", "nees_e", "nees_u")}
        out.append(row)
    return out


def one_flight(scenario: str, airframe: str, seed: int, folder: Path,
               steps: bool = False) -> dict[str, Any]:
    sim = simulate(scenario, seed, airframe=airframe)
    path = folder / f"{scenario}_{airframe}_{seed}.csv"
    write_glass_cockpit(sim, path)
    native_path = folder / f"{scenario}_{airframe}_{seed}.parquet"
    write_simulation(sim, native_path)
    air = ~sim.truth["on_ground"].astype(bool)
    res: dict[str, Any] = {"scenario": scenario, "airframe": airframe, "seed": seed,
                           "airborne_s": float(np.ptp(sim.truth["t_s"][air])),
                           "truth_errors": sim.sensor_truth["persistent_errors"]}
    res["recorder_only"] = recorder_only(path, sim.truth)
    res["native_recorder_only"] = native(native_path, sim.truth)
    if steps:
        res["attribution"], thinned = attribution(sim, folder, f"{scenario}_{airframe}_{seed}")
    res["gaps"] = [g for g in (gnss_gap(path, sim.truth, L) for L in GAPS_S) if g is not None]
    if steps:
        res["gap_steps"] = gap_steps({"native": native_path, **thinned}, sim.truth, res["gaps"])
    return res


def _fmt_nees(s: dict[str, float]) -> str:
    return f"{s['nees_n']:.2f} / {s['nees_e']:.2f} / {s['nees_u']:.2f}"


def _flag(ok: bool) -> str:
    return "" if ok else " **x**"


def markdown(runs: list[dict[str, Any]], seeds: list[int]) -> str:
    lines = ["# 1 Hz glass-cockpit export of JSBSim flights: recorder only and GNSS gaps", "",
             "JSBSim flights of the fleet, each written as a Garmin glass-cockpit CSV "
             "(`flightrecon/sim/glass_cockpit.py`: 1 Hz, magnetic heading, altimeter at the "
             "QNH, no longitudinal acceleration), read back as recorded and reconstructed by the "
             f"joint smoother, against the truth (`scripts/onehz_fleet_study.py`, seeds "
             f"{', '.join(map(str, seeds))}). Bars of issue #36 item 5: recorder only at most "
             f"{BAR_RECORDER} x dead reckoning + linear end correction, gaps at most {BAR_GAP} x "
             f"dead reckoning with the wind of the minute before, mean NEES at most {BAR_NEES} "
             "per axis; **x** marks a figure beyond its bar.", "",
             "## Recorder only (GPS withheld; departure and arrival from the sidecar)", "",
             "| flight | airborne [s] | joint RMS (max) [m] | DR + linear RMS [m] | ratio | "
             "vertical RMS (mean) [m] | NEES n / e / u | health | simulated log itself: "
             "joint RMS [m], NEES n / e / u |",
             "|---|---|---|---|---|---|---|---|---|"]
    for r in runs:
        ro = r["recorder_only"]
        j = ro["joint"]
        nees_ok = max(j["nees_n"], j["nees_e"], j["nees_u"]) <= BAR_NEES
        hl = ro["health"]
        lines.append(
            f"| {r['scenario']} {r['airframe']} s{r['seed']} | {r['airborne_s']:.0f} | "
            f"{j['rms_h_m']:.0f} ({j['max_h_m']:.0f}) | {ro['dr_linear']['rms_h_m']:.0f} | "
            f"{ro['ratio_to_dr']:.2f}{_flag(ro['ratio_to_dr'] <= BAR_RECORDER)} | "
            f"{j['rms_v_m']:.1f} ({j['mean_v_m']:+.1f}) | {_fmt_nees(j)}{_flag(nees_ok)} | "
            f"{'ok' if hl['healthy'] else 'unhealthy: ' + '; '.join(hl['problems'])[:120]} | "
            f"{r['native_recorder_only']['joint']['rms_h_m']:.0f}, "
            f"{_fmt_nees(r['native_recorder_only']['joint'])} |")
    ratios = [r["recorder_only"]["ratio_to_dr"] for r in runs]
    lines += ["", f"Ratio to dead reckoning: median {np.median(ratios):.2f}, "
              f"{sum(x <= BAR_RECORDER for x in ratios)} of {len(ratios)} flights within the bar."]
    steps = [r for r in runs if "attribution" in r]
    if steps:
        lines += ["", "What the export costs, recorder only, one ingredient at a time (joint "
                  "RMS [m], NEES n / e / u): the simulated log (16/8/4 Hz, n_long recorded); "
                  "thinned to its whole seconds; thinned and without n_long (derived from TAS "
                  "and pitch); the export (also magnetic heading and MagVar to 0.1 deg, TAS in "
                  "whole knots, loads to 0.01 g, altimeter to 0.1 ft at the QNH).", "",
                  "| flight | simulated log | 1 Hz | 1 Hz, n_long derived | export |",
                  "|---|---|---|---|---|"]
        for r in steps:
            cells = [r["native_recorder_only"]["joint"],
                     r["attribution"]["onehz_n_long"]["joint"],
                     r["attribution"]["onehz_no_n_long"]["joint"], r["recorder_only"]["joint"]]
            lines.append(f"| {r['scenario']} {r['airframe']} s{r['seed']} | " + " | ".join(
                f"{c['rms_h_m']:.0f}, {_fmt_nees(c)}" for c in cells) + " |")
    lines += ["", "## GNSS gaps (GPS used outside them)", "",
              "| flight | gap [s] | joint RMS (max) [m] | DR, wind of the minute before [m] | "
              "ratio | vertical RMS [m] | NEES n / e / u | outside the gap: RMS [m], NEES | "
              "health |", "|---|---|---|---|---|---|---|---|---|"]
    gap_ratios = []
    for r in runs:
        for g in r["gaps"]:
            gap_ratios.append(g["ratio_to_dr"])
            nees_ok = max(g["nees_n"], g["nees_e"], g["nees_u"]) <= BAR_NEES
            w = g["with_gps"]
            hl = g["health"]
            lines.append(
                f"| {r['scenario']} {r['airframe']} s{r['seed']} | {g['length_s']:.0f} | "
                f"{g['rms_h_m']:.0f} ({g['max_h_m']:.0f}) | {g['dr_wind_rms_h_m']:.0f} | "
                f"{g['ratio_to_dr']:.2f}{_flag(g['ratio_to_dr'] <= BAR_GAP)} | "
                f"{g['rms_v_m']:.1f} | {_fmt_nees(g)}{_flag(nees_ok)} | "
                f"{w['rms_h_m']:.1f}, {_fmt_nees(w)} | "
                f"{'ok' if hl['healthy'] else 'unhealthy: ' + '; '.join(hl['problems'])[:120]} |")
    if gap_ratios:
        lines += ["", f"Ratio to dead reckoning in the gaps: median {np.median(gap_ratios):.2f}, "
                  f"{sum(x <= BAR_GAP for x in gap_ratios)} of {len(gap_ratios)} gaps within "
                  "the bar."]
    gsteps = [(r, gs) for r in runs for gs in r.get("gap_steps", [])]
    if gsteps:
        lines += ["", "What the export costs in the gaps, one ingredient at a time (joint RMS "
                  "(max) [m] inside the gap, the export's window): the simulated log; thinned "
                  "to its whole seconds; thinned and without n_long; the export.  Last column: "
                  "the truth's own north-east acceleration at its whole seconds, integrated by "
                  "the trapezoid through the gap, against the truth's velocity change (largest "
                  "horizontal error), and the horizontal acceleration's variance above 0.5 Hz "
                  "(periodogram) in the gap / over the airborne "
                  "record: what no quadrature of 1 Hz samples recovers.", "",
                  "| flight | gap [s] | simulated log | 1 Hz | 1 Hz, n_long derived | export | "
                  "1 Hz samples of the true acceleration: max velocity error [m/s], variance "
                  "above 0.5 Hz gap / airborne [m^2/s^4] |", "|---|---|---|---|---|---|---|"]
        for r, gs in gsteps:
            exp = next(g for g in r["gaps"] if g["length_s"] == gs["length_s"])
            cells = [gs.get("native"), gs.get("onehz_n_long"), gs.get("onehz_no_n_long"), exp]
            lines.append(f"| {r['scenario']} {r['airframe']} s{r['seed']} | "
                         f"{gs['length_s']:.0f} | " + " | ".join(
                             "-" if c is None else f"{c['rms_h_m']:.0f} ({c['max_h_m']:.0f})"
                             for c in cells) +
                         f" | {gs['max_dv_1hz_mps']:.1f}, {gs['hf_var_gap_m2ps4']:.3f} / "
                         f"{gs['hf_var_air_m2ps4']:.3f} |")
    lines.append("")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--tag", default="", help="suffix of the output files")
    ap.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--steps", action="store_true",
                    help="also the native log thinned to 1 Hz, with and without n_long_g")
    ap.add_argument("--flights", type=int, nargs="+", default=None,
                    help="indices into FLIGHTS (default all)")
    ap.add_argument("--markdown-only", action="store_true",
                    help="rewrite the .md from the .json already written, flying nothing")
    args = ap.parse_args()
    name = "onehz_fleet" + (f"_{args.tag}" if args.tag else "")
    if args.markdown_only:
        done = json.loads((OUT / f"{name}.json").read_text())
        (OUT / f"{name}.md").write_text(header() + markdown(
            [r for r in done["runs"] if "error" not in r], done["seeds"]))
        return
    flights = [FLIGHTS[i] for i in args.flights] if args.flights else list(FLIGHTS)
    OUT.mkdir(parents=True, exist_ok=True)
    runs: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for scenario, airframe in flights:
            for seed in args.seeds:
                t0 = time.perf_counter()
                try:
                    r = one_flight(scenario, airframe, seed, Path(tmp), args.steps)
                except Exception as exc:  # a flight that cannot be flown or read: say so
                    r = {"scenario": scenario, "airframe": airframe, "seed": seed,
                         "error": f"{type(exc).__name__}: {exc}"}
                r["wall_s"] = time.perf_counter() - t0
                print(json.dumps(r, indent=1, default=float), flush=True)
                runs.append(r)
                (OUT / f"{name}.json").write_text(json.dumps(
                    {"command": command_line(), "seeds": args.seeds, "runs": runs}, indent=1,
                    default=float) + "\n")
    ok = [r for r in runs if "error" not in r]
    (OUT / f"{name}.md").write_text(header() + markdown(ok, args.seeds) + "".join(
        f"\nNot measured: {r['scenario']} {r['airframe']} s{r['seed']}: {r['error']}\n"
        for r in runs if "error" in r))


if __name__ == "__main__":
    main()
