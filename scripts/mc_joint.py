"""Monte Carlo study of the joint post-flight smoother against the single methods.

Cases (simulated flights, every run a new seed of the scenario: new noise, new weather draw):

* ``recorder``: 20-minute circuits (legs stretched), recorder only (no GNSS, no radar); end
  points = departure and arrival airfield reference points with the runway's true direction
  and threshold; line-up N(0, 100 m) and touchdown N(400 m, 150 m) past the threshold; the
  scenario's wind with its sinusoid in time replaced by random walks in time and height
  (``random_wind``); the persistent sensor errors drawn from the smoother's priors
  (``prior_aircraft``). Joint smoother vs the Sabziev fusion vs dead reckoning from airspeed
  and heading with and without a linear end-point correction.
* ``recorder_no_runway``: the same flights (same seeds) without the runway in the metadata
  (neither direction nor threshold: the heading bias then has no absolute reference, and the
  end points are the reference point with the generic 1500 m prior).
* ``recorder_smooth_wind``: the same circuits in the scenario's smooth wind only.
* ``gnss``: 15-minute circuits with 1 Hz GNSS and a 2-minute GNSS dropout; joint vs SNS
  smoother.
  Consistency: run-averaged NEES of the joint smoother's north and east positions.
* ``radar``: the ``landing`` scenario, radar only (no GNSS); joint vs ADS/ARMS and azimuth channel.
* ``corrupt_gnss``: circuits with GNSS offset by 500 m north for 60 s; ``corrupt_radar``:
  landings with GNSS and the radar clock 2 s late: detection and the error.

Usage::

    python scripts/mc_joint.py --runs 40            # full size; writes docs/tables/joint_mc.md
    python scripts/mc_joint.py --runs 3 --no-write  # quick look
    python scripts/mc_joint.py --summarise docs/tables/joint_mc_runs.json  # tables only

Seeds: run i of case c uses seed 1000 * (case index + 1) + i (``recorder_no_runway`` and
``recorder_smooth_wind`` use the ``recorder`` seeds).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
from scipy import stats

from flightrecon.cleaning import clean_flight
from flightrecon.methods.baselines import dead_reckoning
from flightrecon.methods.joint import JointNoise, JointSettings
from flightrecon.methods.joint.method import run_joint
from flightrecon.pipeline import ReconstructSettings, run_method
from flightrecon.sim import simulate
from flightrecon.sim.scenarios import scenario_config
from flightrecon.sim.weather import WindField
from flightrecon.types import Flight

sys.path.insert(0, str(Path(__file__).resolve().parent))

from table_header import header  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
FIGURE = ROOT / "docs" / "figures" / "joint_recorder_consistency.png"
CASES = ("recorder", "gnss", "radar", "corrupt_gnss", "corrupt_radar", "recorder_no_runway",
         "recorder_smooth_wind")
SAME_FLIGHTS = {"recorder_no_runway": "recorder", "recorder_smooth_wind": "recorder"}
"""Cases that fly another case's flights (same seeds: a paired comparison)."""


# the recorder circuits line up and touch down dispersed about the thresholds as the smoother's
# end-point model assumes (docs/joint.md, "End points"): the premise of its consistency check
TOUCHDOWN = {"touchdown_m": JointNoise().touchdown_m, "touchdown_sd_m": JointNoise().touchdown_sd_m,
             "lineup_sd_m": JointNoise().roll_start_sd_m}
RECORDER = {"leg_scale": 2.4, "duration_s": 1320.0, "gnss_hz": 0.0, **TOUCHDOWN}
"""The recorder cases' circuits: legs stretched to 20 minutes from lift-off to touchdown, in a
22-minute record (lined up for about 35 s before the take-off roll, 60 s on the runway after
touchdown)."""


def random_wind(seed: int) -> WindField:
    """The circuit's wind with its slow sinusoid in time replaced by random walks in time and
    height of the joint smoother's default intensity (``wind_rw_mps_sqrt_s``,
    ``wind_shear_mps_per_sqrt_m``): the wind the smoother's model describes, drawn anew for
    each seed (the shear and veer stay: the gradient states are for them). With the sinusoid
    kept on top, the wind changes more in time than the model's random walk allows, and the
    cross-track error exceeded the reported sd by 1.3 times in mid-flight."""
    nz = JointNoise()
    return replace(scenario_config("circuit").wind, speed_amp_mps=0.0, dir_amp_deg=0.0,
                   rw_time_mps_sqrt_s=nz.wind_rw_mps_sqrt_s,
                   rw_alt_mps_sqrt_m=nz.wind_shear_mps_per_sqrt_m, rw_seed=seed)


def prior_aircraft(seed: int):
    """The circuit's aircraft with its persistent sensor errors drawn from the joint smoother's
    default priors (accelerometer bias and scale, heading, roll and pitch biases, airspeed
    scale), anew for each seed: with the line-up, the touchdown and the wind, every quantity
    the model treats as random is drawn as it assumes."""
    nz = JointNoise()
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([int(seed), 4242])))
    return replace(scenario_config("circuit").aircraft,
                   accel_bias_g=tuple(float(v) for v in rng.normal(0.0, nz.accel_bias_g, 3)),
                   accel_scale=tuple(float(v) for v in rng.normal(0.0, nz.accel_scale, 3)),
                   heading_bias_deg=float(rng.normal(0.0, nz.heading_bias_deg)),
                   roll_bias_deg=float(rng.normal(0.0, nz.attitude_bias_deg)),
                   pitch_bias_deg=float(rng.normal(0.0, nz.attitude_bias_deg)),
                   airspeed_scale=float(rng.normal(0.0, nz.tas_scale)))


def make_flight(case: str, seed: int):
    if case == "recorder":
        return simulate("circuit", seed=seed, wind=random_wind(seed), aircraft=prior_aircraft(seed),
                        **RECORDER)
    if case == "recorder_smooth_wind":
        return simulate("circuit", seed=seed, aircraft=prior_aircraft(seed), **RECORDER)
    if case == "recorder_no_runway":
        r = simulate("circuit", seed=seed, wind=random_wind(seed), aircraft=prior_aircraft(seed),
                     **RECORDER)
        bare = {"runway_true_deg": None, "threshold_lat_deg": None, "threshold_lon_deg": None}
        meta = replace(r.meta, departure=replace(r.meta.departure, **bare),
                       arrival=replace(r.meta.arrival, **bare))
        return replace(r, meta=meta)
    if case in ("gnss", "corrupt_gnss"):
        return simulate("circuit", seed=seed, gnss_dropouts=((400.0, 120.0),))
    if case == "radar":
        return simulate("landing", seed=seed, gnss_hz=0.0)
    if case == "corrupt_radar":
        from flightrecon.sim.sensors import Faults

        return simulate("landing", seed=seed, faults=Faults(clock_offsets=(("radar", 2.0),)))
    raise ValueError(case)


def corrupt_gnss(log: pd.DataFrame, t0: float = 300.0, length: float = 60.0,
                 north_m: float = 500.0) -> pd.DataFrame:
    """GNSS fixes moved ``north_m`` north for ``length`` seconds from ``t0`` (a new frame)."""
    log = log.copy()
    sel = (log["t_s"] >= t0) & (log["t_s"] < t0 + length) & log["gnss_lat_deg"].notna()
    log.loc[sel, "gnss_lat_deg"] += north_m / 111_000.0
    return log


def noise_from_sensors(sensor_truth: dict) -> JointNoise:
    """The joint smoother's noise budget set to the simulated sensors' specification (what an
    analyst would take from the equipment's data sheets), for the consistency (NEES) check."""
    s = sensor_truth["sensors"]
    kw = {}
    g0 = 9.80665
    loads = s.get("loads") or {}
    att = s.get("attitude") or {}
    if loads:
        # white load-factor and attitude noise, each at its own rate -> velocity random walk of
        # the horizontal acceleration (the one the position needs): the longitudinal and lateral
        # load factors' noise (RMS of the two), and gravity tilted by the roll / pitch noise
        sa = g0 * float(np.sqrt(np.mean(np.square(loads["noise_sd_g"][:2]))))
        sth = g0 * np.radians(max(att.get("roll_noise_sd_deg", 0),
                                  att.get("pitch_noise_sd_deg", 0)))
        psd = sa**2 / loads["rate_hz"] + (sth**2 / att["rate_hz"] if att else 0.0)
        kw["accel_noise_mps2_sqrt_hz"] = float(np.sqrt(psd))
    if att:
        kw["heading_deg"] = float(att["heading_noise_sd_deg"])
    if s.get("airspeed"):
        kw["tas_mps"] = float(s["airspeed"]["noise_sd_mps"])
        kw["airspeed_lag_s"] = float(s["airspeed"].get("lag_s", 0.0))
    if s.get("baro"):
        b = s["baro"]
        kw["baro_m"] = float(np.hypot(b["noise_sd_m"], b.get("quantum_m", 0.0) / np.sqrt(12)))
    if s.get("gnss"):
        kw["gnss_h_m"] = float(s["gnss"]["pos_sd_h_m"])
        kw["gnss_v_m"] = float(s["gnss"]["pos_sd_v_m"])
        kw["gnss_vel_mps"] = float(s["gnss"]["vel_sd_mps"])
    if s.get("radar"):
        r = s["radar"]
        for src, dst in (("range_sd_m", "radar_range_m"), ("azimuth_sd_deg", "radar_azimuth_deg"),
                         ("elevation_sd_deg", "radar_elevation_deg")):
            if src in r:
                kw[dst] = float(r[src])
    return replace(JointNoise(), **kw)


def errors(track: pd.DataFrame, prefix: str, truth: pd.DataFrame, airborne: np.ndarray):
    m = pd.DataFrame({"t_s": truth["t_s"][airborne]}).merge(track, on="t_s", how="left")
    tr = truth[airborne]
    en = m[f"{prefix}north_m"].to_numpy() - tr["north_m"].to_numpy()
    ee = m[f"{prefix}east_m"].to_numpy() - tr["east_m"].to_numpy()
    ok = np.isfinite(en) & np.isfinite(ee)
    out = {"rms_h_m": float(np.sqrt(np.mean(en[ok] ** 2 + ee[ok] ** 2))) if ok.any() else np.nan,
           "max_h_m": float(np.max(np.hypot(en[ok], ee[ok]))) if ok.any() else np.nan,
           "coverage": float(ok.mean())}
    sdn, sde = f"{prefix}north_sd_m", f"{prefix}east_sd_m"
    if sdn in m.columns and sde in m.columns:
        s_n, s_e = m[sdn].to_numpy(), m[sde].to_numpy()
        good = ok & (s_n > 0) & (s_e > 0)
        out["nees_n"] = float(np.mean((en[good] / s_n[good]) ** 2))
        out["nees_e"] = float(np.mean((ee[good] / s_e[good]) ** 2))
        # the errors and standard deviations every 60 s (for the consistency figure)
        t = tr["t_s"].to_numpy()
        pick = np.searchsorted(t, np.arange(np.ceil(t[0] / 60.0) * 60.0, t[-1], 60.0))
        pick = pick[good[pick]]
        out["profile"] = {"t_s": t[pick].tolist(), "err_n": en[pick].tolist(),
                          "err_e": ee[pick].tolist(), "sd_n": s_n[pick].tolist(),
                          "sd_e": s_e[pick].tolist()}
    return out


def consistency_figure(rows: list[dict], path: Path) -> None:
    """RMS over runs of the joint smoother's north and east errors against the RMS of its
    reported standard deviations, every 60 s of flight, for the recorder-only cases."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    cases = [c for c in ("recorder", "recorder_smooth_wind", "recorder_no_runway")
             if any(r["case"] == c and "profile" in r["joint"] for r in rows)]
    if not cases:
        return
    fig, axes = plt.subplots(len(cases), 2, figsize=(10, 2.8 * len(cases)), squeeze=False,
                             sharex=True)
    for ci, case in enumerate(cases):
        prof = [r["joint"]["profile"] for r in rows if r["case"] == case]
        for ai, (comp, name) in enumerate((("n", "north (about along the runway, 160 deg)"),
                                            ("e", "east (about across it)"))):
            frame = pd.concat([pd.DataFrame({"t": p["t_s"], "e2": np.square(p[f"err_{comp}"]),
                                             "s2": np.square(p[f"sd_{comp}"])}) for p in prof])
            g = frame.groupby("t").mean()
            ax = axes[ci, ai]
            ax.plot(g.index, np.sqrt(g["e2"]), "-o", ms=3, label="RMS error over runs")
            ax.plot(g.index, np.sqrt(g["s2"]), "--", label="RMS reported sd")
            ax.set_title(f"{case} ({len(prof)} runs): {name}", fontsize=9)
            ax.set_ylabel("m")
            ax.grid(alpha=0.3)
            if ci == len(cases) - 1:
                ax.set_xlabel("time [s]")
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=100)
    plt.close(fig)


def one_run(case: str, seed: int) -> dict:
    r = make_flight(case, seed)
    log = r.log
    if case == "corrupt_gnss":
        log = corrupt_gnss(log)
    clean = clean_flight(Flight(data=log, meta=r.meta))
    truth = r.truth
    airborne = ~truth["on_ground"].to_numpy(bool)
    res = {"case": case, "seed": seed}
    t0 = time.perf_counter()
    j = run_joint(clean, settings=JointSettings(noise=noise_from_sensors(r.sensor_truth)))
    res["joint_time_s"] = time.perf_counter() - t0
    res["joint"] = errors(j.track, "joint_", truth, airborne)
    keys = ("count", "beyond_5_sigma", "flagged_inconsistent")
    res["joint_sources"] = {k: {a: v[a] for a in keys}
                            for k, v in j.summary["sources"].items()}
    res["joint_clock"] = j.summary["clock_offsets_s"]
    res["joint_noise_scale"] = j.summary["noise_scale"]
    others = {"recorder": ("sabziev",), "recorder_no_runway": ("sabziev",),
              "recorder_smooth_wind": ("sabziev",), "gnss": ("sns",),
              "radar": ("arms", "azimuth"), "corrupt_gnss": ("sns",),
              "corrupt_radar": ("arms",)}[case]
    for m in others:
        try:
            mr = run_method(m, clean, ReconstructSettings())
            res[m] = errors(mr.track, f"{m}_", truth, airborne)
        except Exception as exc:  # noqa: BLE001 - a comparison method failing is a result
            res[m] = {"error": f"{type(exc).__name__}: {exc}"}
    if case.startswith("recorder"):
        res["dr"] = errors(dead_reckoning(clean, corrected=False), "", truth, airborne)
        res["dr_linear"] = errors(dead_reckoning(clean, corrected=True), "", truth, airborne)
    return res


def summarise(rows: list[dict]) -> str:
    lines = []
    for case in CASES:
        rs = [r for r in rows if r["case"] == case]
        if not rs:
            continue
        M = len(rs)
        methods = [k for k in rs[0] if isinstance(rs[0][k], dict) and "rms_h_m" in rs[0][k]]
        lines += [f"### {case} ({M} runs)", "",
                  "| method | mean RMS horizontal [m] | median | mean max [m] | "
                  "runs where joint is better |",
                  "|---|---|---|---|---|"]
        jr = np.array([r["joint"]["rms_h_m"] for r in rs])
        for m in methods:
            v = np.array([r[m].get("rms_h_m", np.nan) for r in rs])
            mx = np.array([r[m].get("max_h_m", np.nan) for r in rs])
            fin = np.isfinite(v)
            better = "" if m == "joint" else f"{int(np.sum(jr[fin] < v[fin]))}/{int(fin.sum())}"
            if m != "joint" and not fin.all():
                better += f" ({M - int(fin.sum())} run(s) without a track: not converged)"
            lines.append(f"| {m} | {np.nanmean(v):.1f} | {np.nanmedian(v):.1f} | "
                         f"{np.nanmean(mx):.1f} | {better} |")
        for m in methods:
            if m == "joint":
                continue
            v = np.array([r[m].get("rms_h_m", np.nan) for r in rs])
            ok = np.isfinite(v)
            if ok.sum() >= 3:
                w = stats.wilcoxon(jr[ok], v[ok]) if np.any(jr[ok] != v[ok]) else None
                ratio = np.exp(np.mean(np.log(jr[ok] / v[ok])))
                lines.append(f"\njoint / {m}: geometric-mean RMS ratio {ratio:.3f}"
                             + (f", paired Wilcoxon p = {w.pvalue:.2g}" if w else ""))
        if "nees_n" in rs[0]["joint"]:
            nn = np.array([r["joint"]["nees_n"] for r in rs])
            ne = np.array([r["joint"]["nees_e"] for r in rs])
            lo, hi = stats.chi2.ppf([0.025, 0.975], M) / M
            lines.append(f"\njoint run-averaged NEES (1 dof each): north {nn.mean():.2f}, "
                         f"east {ne.mean():.2f}; 95 % band for {M} runs [{lo:.2f}, {hi:.2f}] "
                         "(time-averaged within each run)")
        if case.startswith("corrupt"):
            src = "gnss_pos" if case == "corrupt_gnss" else "radar"
            flagged = sum(bool(r["joint_sources"].get(src, {}).get("flagged_inconsistent"))
                          for r in rs)
            lines.append(f"\n{src} flagged inconsistent in {flagged}/{M} runs")
            if case == "corrupt_radar":
                off = np.array([r["joint_clock"]["radar"]["value"] for r in rs])
                lines.append(f"radar clock offset estimated: mean {off.mean():+.2f} s, "
                             f"sd over runs {off.std(ddof=1) if M > 1 else 0:.2f} s "
                             "(truth -2.00 s: the radar is stamped 2 s late, the offset is "
                             "what is added to its times)")
        lines.append("")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=40)
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--merge", action="store_true",
                    help="keep the other cases' runs of docs/tables/joint_mc_runs.json (re-run "
                         "some cases only)")
    ap.add_argument("--summarise", metavar="RUNS_JSON",
                    help="only rebuild the tables from a runs file "
                         "(docs/tables/joint_mc_runs.json)")
    a = ap.parse_args()
    if a.summarise:
        rows = json.loads(Path(a.summarise).read_text())
        text = summarise(rows)
        print(text)
        if not a.no_write:
            consistency_figure(rows, FIGURE)
            n = max(sum(r["case"] == c for r in rows) for c in CASES)
            (ROOT / "docs" / "tables" / "joint_mc.md").write_text(
                header() + f"({n} runs per case, tables rebuilt from "
                "joint_mc_runs.json)\n\n" + text + "\n")
        return
    rows = []
    for case in CASES:
        if case not in a.cases.split(","):
            continue
        # the no-runway variant flies the recorder case's flights (a paired comparison)
        base = 1000 * (CASES.index(SAME_FLIGHTS.get(case, case)) + 1)
        for i in range(a.runs):
            rows.append(one_run(case, base + i))
            print(case, i, json.dumps({k: v for k, v in rows[-1].items()
                                       if k in ("joint", "sabziev", "sns", "arms", "dr_linear")},
                                      default=str)[:300], file=sys.stderr)
    runs_file = ROOT / "docs" / "tables" / "joint_mc_runs.json"
    if a.merge and runs_file.exists():
        done = {r["case"] for r in rows}
        rows = [r for r in json.loads(runs_file.read_text()) if r["case"] not in done] + rows
    text = summarise(rows)
    print(text)
    if not a.no_write:
        consistency_figure(rows, FIGURE)
        (ROOT / "docs" / "tables").mkdir(parents=True, exist_ok=True)
        (ROOT / "docs" / "tables" / "joint_mc.md").write_text(
            header() + text + "\n")
        (ROOT / "docs" / "tables" / "joint_mc_runs.json").write_text(
            json.dumps(rows, indent=1, default=str))


if __name__ == "__main__":
    main()
