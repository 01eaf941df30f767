"""The joint smoother's position sd inside a withheld GNSS gap on JSBSim flights: error and
NEES with and without the held-out gap calibration (docs/joint.md, "GNSS gaps: the sd
calibrated on held-out stretches"; issues #35 item 5, #36 item 5).

Every flight is simulated with the shipped JSBSim scenarios (``flightrecon.sim.simulate``,
seeded: same seed, same logs) and written as the simulator's native log (16/8/4 Hz, GNSS at
1 Hz).  Per flight two runs, each with one gap withheld (``GnssUse(withhold_s=...)``): 300 s
centred on the airborne span and 120 s centred a quarter into it.  Each run is reconstructed
by the joint smoother with the default settings, once with ``gap_stretches = 0`` (before: the
model's sd) and once with the default (after: calibrated on held-out stretches of the same
flight's GNSS).  Per run and horizontal axis: the gap's RMS error against the truth and the
mean NEES ``mean(e^2 / sd^2)`` over the gap's 1 s samples.

Degrees of freedom: the errors inside one gap are one drifting random walk, correlated over
the whole gap (the sd grows smoothly with it), so one gap gives about one degree of freedom per
axis, not one per sample.  The aggregate mean NEES of ``m`` gap-axes is then compared with the
95 % band of chi-square(m) / m.

Usage::

    python scripts/gap_study.py                 # writes docs/tables/gap_nees.md and .json
    python scripts/gap_study.py --flights 0 1   # a subset (indices into FLIGHTS)
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
from scipy.stats import chi2

from flightrecon.cleaning import clean_flight
from flightrecon.geo.frames import output_plane
from flightrecon.ingest import load_flight
from flightrecon.ingest.gnss_use import GnssUse
from flightrecon.methods.joint import JointSettings
from flightrecon.methods.joint.method import run_joint
from flightrecon.sim import simulate, write_simulation

sys.path.insert(0, str(Path(__file__).resolve().parent))

from table_header import command_line, header  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "docs" / "tables"
#: (scenario, airframe): the aircraft and manoeuvres of the JSBSim fleet
FLIGHTS = (("jsbsim-airwork", "c172p"), ("jsbsim-holding", "c172p"),
           ("jsbsim-goaround", "c172p"), ("jsbsim-jet", "global5000"),
           ("jsbsim-airwork", "t6texan2"), ("jsbsim-airwork", "pc7"),
           ("jsbsim-xc", "c310"), ("jsbsim-spin", "c172p"), ("jsbsim-circuit", "B747"))
#: gap length [s] -> where its centre lies in the airborne span (share of it)
GAPS = ((300.0, 0.5), (120.0, 0.25))
#: GNSS kept after lift-off and before touchdown around a gap [s]
MARGIN_S = 60.0
#: the bar of issue #35 / #36 per gap and axis
BAR_NEES = 5.0


def _truth_ne(truth: pd.DataFrame, meta: Any, t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The truth's north and east in the output plane at times ``t``."""
    tt = truth["t_s"].to_numpy(float)
    lat, lon, alt = (np.interp(t, tt, truth[c].to_numpy(float))
                     for c in ("lat_deg", "lon_deg", "alt_m"))
    e, n, _ = output_plane(meta).forward(lat, lon, alt)
    return n, e


def gap_run(path: Path, truth: pd.DataFrame, a: float, b: float, calibrate: bool
            ) -> dict[str, Any]:
    """One reconstruction with GNSS withheld over [a, b]: the gap's error and NEES per axis
    and the calibration's report."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        flight = load_flight(path, gnss_use=GnssUse(withhold_s=((a, b),)))
        clean = clean_flight(flight)
        s = JointSettings() if calibrate else replace(JointSettings(), gap_stretches=0)
        t0 = time.perf_counter()
        j = run_joint(clean, settings=s)
    tr = j.track
    t = np.arange(np.ceil(a), np.floor(b) + 1.0)
    n, e = _truth_ne(truth, clean.meta, t)
    res: dict[str, Any] = {"time_s": time.perf_counter() - t0,
                           "healthy": bool(j.summary["healthy"])}
    for ax, col, ref in (("n", "north", n), ("e", "east", e)):
        err = np.interp(t, tr.t_s, tr[f"joint_{col}_m"]) - ref
        sd = np.interp(t, tr.t_s, tr[f"joint_{col}_sd_m"])
        res[f"rms_{ax}_m"] = float(np.sqrt(np.mean(err ** 2)))
        res[f"rms_sd_{ax}_m"] = float(np.sqrt(np.mean(sd ** 2)))
        res[f"nees_{ax}"] = float(np.mean(err ** 2 / sd ** 2))
    gc = j.summary.get("gap_calibration")
    if gc:
        res["calibration"] = {k: gc.get(k) for k in
                              ("factor", "f_hat", "f_pool", "f_floor", "stretches_s", "nees_before",
                               "nees_after", "fix_sd_m", "heldout_rms_m", "note")}
    return res


def one_flight(scenario: str, airframe: str, seed: int, folder: Path) -> dict[str, Any]:
    sim = simulate(scenario, seed, airframe=airframe)
    path = folder / f"{scenario}_{airframe}_{seed}.parquet"
    write_simulation(sim, path)
    air = ~sim.truth["on_ground"].astype(bool).to_numpy()
    ta = sim.truth["t_s"].to_numpy(float)[air]
    lo, hi = ta[0] + MARGIN_S, ta[-1] - MARGIN_S
    out: dict[str, Any] = {"scenario": scenario, "airframe": airframe, "seed": seed,
                           "airborne_s": float(ta[-1] - ta[0]), "gaps": []}
    for length, where in GAPS:
        mid = ta[0] + where * (ta[-1] - ta[0])
        a = max(lo, mid - 0.5 * length)
        b = a + length
        if b > hi:
            continue
        g = {"length_s": length, "t0_s": float(a), "t1_s": float(b),
             "before": gap_run(path, sim.truth, a, b, False),
             "after": gap_run(path, sim.truth, a, b, True)}
        out["gaps"].append(g)
    return out


def aggregate(runs: list[dict[str, Any]], which: str, length: float | None = None
              ) -> dict[str, Any]:
    """Mean of the per-gap-axis NEES with the chi-square band (one dof per gap and axis)."""
    v = [g[which][f"nees_{ax}"] for r in runs for g in r.get("gaps", [])
         if length is None or g["length_s"] == length for ax in "ne"]
    m = len(v)
    if not m:
        return {"gap_axes": 0}
    return {"gap_axes": m, "mean_nees": float(np.mean(v)), "max_nees": float(np.max(v)),
            "band": [float(chi2.ppf(0.025, m) / m), float(chi2.ppf(0.975, m) / m)]}


def markdown(runs: list[dict[str, Any]], seed: int) -> str:
    lines = [header().rstrip("\n"), "",
             "# GNSS gaps on JSBSim: error and NEES, before / after the held-out calibration",
             "",
             "Native simulated logs (GNSS 1 Hz), one gap withheld per run, the joint smoother "
             "with its defaults; before: `gap_stretches = 0` (the model's sd), after: the "
             "default calibration (docs/joint.md, \"GNSS gaps\").  NEES = mean of e^2/sd^2 over "
             "the gap's 1 s samples, per axis (bar: <= 5).  The factor scales the in-gap excess "
             "variance (eq. G1/G2), held-out stretches in brackets.",
             "",
             "| flight | gap [s] | RMS err n/e [m] | sd before n/e [m] | NEES before n/e | "
             "sd after n/e [m] | NEES after n/e | factor (stretches) |",
             "|---|---|---|---|---|---|---|---|"]
    for r in runs:
        for g in r.get("gaps", []):
            b, a = g["before"], g["after"]
            c = a.get("calibration") or {}
            f = c.get("factor")
            fs = "-" if f is None else f"{f:.3g} ({len(c.get('stretches_s') or [])})"
            lines.append(
                f"| {r['scenario']} {r['airframe']} | {g['length_s']:.0f} "
                f"({g['t0_s']:.0f}-{g['t1_s']:.0f}) | {a['rms_n_m']:.1f} / {a['rms_e_m']:.1f} | "
                f"{b['rms_sd_n_m']:.1f} / {b['rms_sd_e_m']:.1f} | "
                f"{b['nees_n']:.2f} / {b['nees_e']:.2f} | "
                f"{a['rms_sd_n_m']:.1f} / {a['rms_sd_e_m']:.1f} | "
                f"{a['nees_n']:.2f} / {a['nees_e']:.2f} | {fs} |")
    lines += ["", "| gaps | gap-axes (dof) | before: mean NEES | after: mean NEES | "
              "95 % band chi2(m)/m | after: max |", "|---|---|---|---|---|---|"]
    for label, length in (("all", None), *((f"{L:.0f} s", L) for L, _ in GAPS)):
        b, a = aggregate(runs, "before", length), aggregate(runs, "after", length)
        if not a["gap_axes"]:
            continue
        inside = a["band"][0] <= a["mean_nees"] <= a["band"][1]
        lines.append(f"| {label} | {a['gap_axes']} | {b['mean_nees']:.2f} | "
                     f"{a['mean_nees']:.2f} ({'in band' if inside else 'out of band'}) | "
                     f"{a['band'][0]:.2f}-{a['band'][1]:.2f} | {a['max_nees']:.2f} |")
    lines += ["", "Degrees of freedom: one per gap and axis (the errors inside a gap are one "
              "drifting random walk, correlated over the gap), so the band is that of "
              "chi-square(m)/m with m the gap-axes; the two gaps of a flight are taken as "
              "independent (different stretches of the flight, different runs).", ""]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=(__doc__ or "").splitlines()[0])
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--flights", type=int, nargs="+", default=None,
                    help="indices into FLIGHTS (default all)")
    ap.add_argument("--no-write", action="store_true", help="print only")
    args = ap.parse_args()
    flights = [FLIGHTS[i] for i in args.flights] if args.flights else list(FLIGHTS)
    runs: list[dict[str, Any]] = []
    with tempfile.TemporaryDirectory() as tmp:
        for scenario, airframe in flights:
            t0 = time.perf_counter()
            try:
                r = one_flight(scenario, airframe, args.seed, Path(tmp))
            except Exception as exc:  # a flight that cannot be flown or read: say so
                r = {"scenario": scenario, "airframe": airframe, "seed": args.seed,
                     "error": f"{type(exc).__name__}: {exc}"}
            r["wall_s"] = time.perf_counter() - t0
            print(json.dumps(r, default=float), flush=True)
            runs.append(r)
    ok = [r for r in runs if "error" not in r]
    md = markdown(ok, args.seed) + "".join(
        f"\nNot measured: {r['scenario']} {r['airframe']}: {r['error']}\n"
        for r in runs if "error" in r)
    print(md)
    if not args.no_write:
        OUT.mkdir(parents=True, exist_ok=True)
        (OUT / "gap_nees.json").write_text(json.dumps(
            {"command": command_line(), "seed": args.seed, "runs": runs, "aggregate": {
                w: aggregate(ok, w) for w in ("before", "after")}},
            indent=1, default=float) + "\n")
        (OUT / "gap_nees.md").write_text(md)


if __name__ == "__main__":
    main()
