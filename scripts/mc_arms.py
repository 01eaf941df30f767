"""Monte Carlo study of the ADS/ARMS estimators (METHODS.md section 2; Vasyliev 2025).

Reproduces the paper's simulation (speed 100 m/s, nearly straight flight, sigma_theta 0.25 deg,
sigma_rho 50 m, dt 1 s, air-data error per axis Gauss-Markov with sigma 20 m/s and 1/alpha
360 s) and writes, under ``docs/``:

* ``figures/arms_fig2_dv_estimate.png``: estimated vs simulated air-data error, one run (the
  paper's Fig. 2), cascade filter (the paper's) and joint smoother (the product);
* ``figures/arms_fig3_rms_vs_sd.png``: Monte Carlo RMS of the air-data error estimate vs the
  filter's predicted sd over time (the paper's Fig. 3), cascade and joint, filter and smoother;
* ``figures/arms_nees.png``: run-averaged NEES of the joint form with its 95 % chi-square band;
* ``tables/arms_consistency.md``: filter vs smoother, cascade vs joint;
* ``tables/arms_linearisation.md``: EKF vs converted measurements at short and long range.

Deviations from the paper, all documented in docs/arms.md: the truth's ground velocity is a CV
random walk with q = 0.01 m^2/s^3 (the filter's own model, so that consistency is testable; the
paper's flight is exactly straight), and V* carries 0.2 m/s white noise (with none, V* pins
Vx + dVx exactly and the joint covariance is singular after each update, NEES undefined).

Usage::

    python scripts/mc_arms.py            # 200 runs per configuration, about 2 minutes
    python scripts/mc_arms.py --runs 20  # quick look (does not overwrite unless --write)
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import matplotlib

sys.path.insert(0, str(Path(__file__).resolve().parent))

from table_header import header  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from scipy import stats

from flightrecon.methods import arms as A

ROOT = Path(__file__).resolve().parents[1]
MODEL = A.ArmsModel(q_m2ps3=0.01, sigma_air_mps=0.2)
DURATION_S = 1800.0
SEED = 20251125
GEOMETRIES = {
    # name: (start x east, start y north) [m], flying east at 100 m/s
    "paper (closest 30 km)": (-60e3, 30e3),
    "short range (closest 2 km)": (-90e3, 2e3),
    "long range (100-140 km)": (-90e3, 100e3),
}
FIRST_MINUTE_S = 60.0


def _inputs(sc, i):
    plots = A.RadarPlots.from_arrays(sc.t_s, sc.range_m[i], sc.azimuth_rad[i], MODEL)
    air = A.AirData(sc.t_s, sc.air[i, :, 0], sc.air[i, :, 1])
    return plots, air


def _collect(sc, runs, make):
    """Errors and predicted variances of dV, W and the full joint state for every run.

    ``make(plots, air) -> ArmsEstimate``; returns dict of (M, N, 2) errors and variances."""
    M, N = runs, len(sc.t_s)
    out = {k: np.empty((M, N, 2)) for k in ("e_dv", "v_dv", "e_w", "v_w", "e_p", "v_p")}
    for i in range(M):
        est = make(*_inputs(sc, i))
        out["e_dv"][i] = est.dv - sc.dv[i]
        out["v_dv"][i] = est.dv_cov[:, [0, 1], [0, 1]]
        out["e_w"][i] = est.vel - sc.vel[i]
        out["v_w"][i] = est.vel_cov[:, [0, 1], [0, 1]]
        out["e_p"][i] = est.pos - sc.pos[i]
        out["v_p"][i] = est.pos_cov[:, [0, 1], [0, 1]]
    return out


def _joint_nees(sc, runs, smoothed, linearisation="ekf"):
    M, N = runs, len(sc.t_s)
    nees = np.zeros(N)
    for i in range(M):
        run = A.run_joint_model(*_inputs(sc, i), MODEL, linearisation=linearisation,
                                smooth=smoothed)
        src = run.smooth if smoothed else run.filt
        truth = np.column_stack([sc.pos[i, :, 0], sc.vel[i, :, 0], sc.pos[i, :, 1],
                                 sc.vel[i, :, 1], sc.dv[i]])
        e = src.x - truth
        nees += np.einsum("ki,ki->k", e, np.linalg.solve(src.P, e[..., None])[..., 0])
    return nees / M


def _pooled(c, key, late):
    rms = np.sqrt(np.mean(c["e_" + key][:, late] ** 2))
    sd = np.sqrt(np.mean(c["v_" + key][:, late]))
    return rms, sd


def _per_epoch_ratio(c, key):
    rms = np.sqrt(np.mean(c["e_" + key] ** 2, axis=(0, 2)))
    sd = np.sqrt(np.mean(c["v_" + key], axis=(0, 2)))
    return rms, sd, rms / sd


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=200)
    ap.add_argument("--write", action="store_true",
                    help="write docs even with fewer than 200 runs")
    args = ap.parse_args(argv)
    M = args.runs
    write = M >= 200 or args.write
    figdir, tabdir = ROOT / "docs" / "figures", ROOT / "docs" / "tables"
    figdir.mkdir(parents=True, exist_ok=True)
    tabdir.mkdir(parents=True, exist_ok=True)
    t_start = time.time()

    # ---------------- paper geometry: cascade vs joint, filter vs smoother
    sc = A.simulate_paper_scenario(MODEL, runs=M, duration_s=DURATION_S,
                                   start_xy_m=GEOMETRIES["paper (closest 30 km)"], seed=SEED)
    t = sc.t_s
    late = t >= FIRST_MINUTE_S
    configs = {
        "cascade, filter (paper)": lambda p, a: A.estimate_of(
            A.run_cascade(p, a, MODEL, smooth=False), smoothed=False),
        "cascade, smoother": lambda p, a: A.estimate_of(A.run_cascade(p, a, MODEL)),
        "joint, filter": lambda p, a: A.estimate_of(
            A.run_joint_model(p, a, MODEL, smooth=False), smoothed=False),
        "joint, smoother": lambda p, a: A.estimate_of(A.run_joint_model(p, a, MODEL)),
    }
    res = {name: _collect(sc, M, fn) for name, fn in configs.items()}
    nees_f = _joint_nees(sc, M, smoothed=False)
    nees_s = _joint_nees(sc, M, smoothed=True)
    lo, hi = stats.chi2.ppf([0.025, 0.975], 6 * M) / M

    lines = [
        "# ADS/ARMS: consistency, cascade vs joint, filter vs smoother",
        "",
        (f"`python scripts/mc_arms.py` (seed {SEED}), {M} runs of {DURATION_S:.0f} s, paper "
        "setting (sigma_rho 50 m, sigma_theta 0.25 deg, dt 1 s, dV Gauss-Markov sigma 20 m/s, "
        "1/alpha 360 s), q = 0.01 m^2/s^3, sigma_air 0.2 m/s, closest approach 30 km, EKF. "
        "Statistics pooled over both axes, all runs and t >= 60 s. Ratio = RMS / predicted sd "
        "(1 = consistent). Within +-15 %: share of epochs (t >= 60 s) whose per-epoch ratio "
        "(over runs and axes) is within 0.85-1.15."),
        "",
        ("| form | dV RMS [m/s] | dV pred sd [m/s] | dV ratio | dV within +-15 % | "
        "W RMS [m/s] | W pred sd [m/s] | W ratio | pos RMS [m] | pos ratio |"),
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, c in res.items():
        r_dv, s_dv = _pooled(c, "dv", late)
        r_w, s_w = _pooled(c, "w", late)
        r_p, s_p = _pooled(c, "p", late)
        _, _, ratio_t = _per_epoch_ratio(c, "dv")
        within = np.mean(np.abs(ratio_t[late] - 1.0) <= 0.15)
        lines.append(f"| {name} | {r_dv:.3f} | {s_dv:.3f} | {r_dv / s_dv:.3f} | {within:.1%} | "
                     f"{r_w:.3f} | {s_w:.3f} | {r_w / s_w:.3f} | {r_p:.1f} | {r_p / s_p:.3f} |")
    lines += [
        "",
        (f"Joint form, run-averaged NEES of the 6-state [x, Vx, y, Vy, dVx, dVy] (expected 6; 95 % "
        f"band for {M} runs: {lo:.2f}-{hi:.2f}):"),
        "",
        "| joint | mean NEES (t >= 60 s) | epochs inside band |",
        "|---|---|---|",
        f"| filter | {nees_f[late].mean():.3f} | "
        f"{np.mean((nees_f[late] > lo) & (nees_f[late] < hi)):.1%} |",
        f"| smoother | {nees_s[late].mean():.3f} | "
        f"{np.mean((nees_s[late] > lo) & (nees_s[late] < hi)):.1%} |",
        "",
    ]
    table1 = "\n".join(lines)

    # ---------------- EKF vs converted at short and long range (joint form)
    lin_cfg = {"EKF": ("ekf", "predicted"), "converted (at predicted)": ("converted", "predicted"),
               "converted (at measured)": ("converted", "measured")}
    lines = [
        "# ADS/ARMS: EKF vs converted measurements at short and long range",
        "",
        (f"`python scripts/mc_arms.py` (seed {SEED} + geometry index), {M} runs of "
        f"{DURATION_S:.0f} s per geometry, joint form, same setting as arms_consistency.md. "
        "RMS pooled over both axes, all runs, t >= 60 s; 'near' = the epochs with horizontal "
        "range below 15 km (short-range geometry only). Ratio = RMS / predicted sd."),
        "",
        ("| geometry | linearisation | pass | dV RMS [m/s] | dV ratio | W RMS [m/s] | W ratio | "
        "pos RMS [m] | near: W RMS [m/s] | near: W ratio |"),
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for gi, (gname, start) in enumerate(GEOMETRIES.items()):
        if gi == 0:
            continue
        scg = A.simulate_paper_scenario(MODEL, runs=M, duration_s=DURATION_S, start_xy_m=start,
                                        seed=SEED + gi)
        rng_true = np.hypot(scg.pos[..., 0], scg.pos[..., 1])
        near = rng_true < 15e3
        for lname, (lin, at) in lin_cfg.items():
            for smoothed in (False, True):
                c = _collect(scg, M, lambda p, a, lin=lin, at=at, sm=smoothed: A.estimate_of(
                    A.run_joint_model(p, a, MODEL, linearisation=lin, converted_at=at, smooth=sm),
                    smoothed=sm))
                r_dv, s_dv = _pooled(c, "dv", late)
                r_w, s_w = _pooled(c, "w", late)
                r_p, _ = _pooled(c, "p", late)
                if near.any() and gi == 1:
                    m = near & late[None, :]
                    rn = np.sqrt(np.mean(c["e_w"][m] ** 2))
                    sn = np.sqrt(np.mean(c["v_w"][m]))
                    near_txt = f"{rn:.3f} | {rn / sn:.3f}"
                else:
                    near_txt = "- | -"
                lines.append(f"| {gname} | {lname} | {'smoother' if smoothed else 'filter'} | "
                             f"{r_dv:.3f} | {r_dv / s_dv:.3f} | {r_w:.3f} | {r_w / s_w:.3f} | "
                             f"{r_p:.1f} | {near_txt} |")
    lines.append("")
    table2 = "\n".join(lines)
    print(table1)
    print(table2)
    print(f"elapsed {time.time() - t_start:.0f} s")
    if not write:
        print("fewer than 200 runs: docs not written (use --write)")
        return
    (tabdir / "arms_consistency.md").write_text(header() + table1)
    (tabdir / "arms_linearisation.md").write_text(header() + table2)

    # ---------------- figures
    plots, air = _inputs(sc, 0)
    cf = A.estimate_of(A.run_cascade(plots, air, MODEL, smooth=False), smoothed=False)
    js = A.estimate_of(A.run_joint_model(plots, air, MODEL))
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for a, ax in enumerate(axes):
        ax.plot(t, sc.dv[0, :, a], "k-", lw=1.2, label="simulated dV (2)")
        ax.plot(t, cf.dv[:, a], "C0-", lw=0.8, label="cascade filter estimate (1, paper)")
        ax.plot(t, js.dv[:, a], "C3--", lw=0.8, label="joint smoother estimate")
        ax.set_ylabel(f"dV{'xy'[a]} [m/s]")
        ax.grid(alpha=0.3)
    axes[0].legend(loc="best", fontsize=8)
    axes[0].set_title("Air-data error: estimate vs simulation, one run (cf. paper Fig. 2)")
    axes[1].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(figdir / "arms_fig2_dv_estimate.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(9, 5))
    for (name, c), col in zip(res.items(), ("C0", "C1", "C2", "C3")):
        rms, sd, _ = _per_epoch_ratio(c, "dv")
        ax.plot(t, rms, color=col, lw=1.0, label=f"{name}: MC RMS (1)")
        ax.plot(t, sd, color=col, lw=1.0, ls="--", label=f"{name}: predicted sd (2)")
    ax.set_ylim(0, 2.0)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("air-data error estimate [m/s]")
    ax.set_title(f"RMS of the air-data error estimate vs predicted sd, {M} runs (cf. paper Fig. 3)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, ncol=2)
    fig.tight_layout()
    fig.savefig(figdir / "arms_fig3_rms_vs_sd.png", dpi=120)
    plt.close(fig)

    fig, ax = plt.subplots(figsize=(9, 4))
    ax.plot(t, nees_f, lw=0.8, label="joint filter")
    ax.plot(t, nees_s, lw=0.8, label="joint smoother")
    ax.axhline(lo, color="k", ls=":", lw=0.8, label="95 % band")
    ax.axhline(hi, color="k", ls=":", lw=0.8)
    ax.axhline(6.0, color="k", lw=0.5)
    ax.set_xlabel("t [s]")
    ax.set_ylabel("run-averaged NEES (6 states)")
    ax.set_title(f"Joint form consistency, {M} runs")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(figdir / "arms_nees.png", dpi=120)
    plt.close(fig)
    print("written:", tabdir / "arms_consistency.md", tabdir / "arms_linearisation.md",
          figdir / "arms_fig2_dv_estimate.png", figdir / "arms_fig3_rms_vs_sd.png",
          figdir / "arms_nees.png")


if __name__ == "__main__":
    main()
