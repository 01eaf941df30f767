"""Signals-layer study on the project's simulator (seeded; writes docs/tables/signals_study.md
and docs/figures/signals_phase_errors.png).

For each scenario and seed:

* phase detection: lift-off / touchdown time errors against the truth ``on_ground``
  transitions, and the lift-off ground-speed error against the truth ground velocity;
* despiking: single- and double-sample spikes of 10-50 x max(noise, quantisation step) are
  injected into the recorded input channels at 0.2 % of their samples (independent random
  positions, at least 20 samples apart); together with the simulator's own fault spikes
  (``sensor_truth["faults"]``) they are the spikes; the caught fraction and the fraction of
  clean samples removed are counted.

Usage::

    python scripts/signals_study.py [--seeds 10] [--out docs]
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
import pandas as pd

from flightrecon.cleaning import clean_flight
from flightrecon.cleaning.steps import Despike, UnwrapAngles, run_steps
from flightrecon.types import Flight

SCENARIOS = ("circuit", "regional", "landing")
CHANNELS = ("n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg", "heading_deg",
            "tas_mps", "baro_alt_m")


def _transitions(truth: pd.DataFrame) -> tuple[float, float, int]:
    og = truth["on_ground"].to_numpy().astype(bool)
    t = truth["t_s"].to_numpy()
    ups = t[np.flatnonzero(og[:-1] & ~og[1:]) + 1]
    downs = t[np.flatnonzero(~og[:-1] & og[1:]) + 1]
    lo = float(ups[0]) if len(ups) else float("nan")
    i = int(np.searchsorted(t, lo)) if len(ups) else -1
    return lo, (float(downs[-1]) if len(downs) else float("nan")), i


def _noise_scale(x: np.ndarray) -> float:
    """Robust noise level of a channel: 1.4826 MAD of its second differences / sqrt(6)."""
    d2 = np.diff(x, 2)
    u = np.unique(x)
    q = float(np.min(np.diff(u))) if len(u) > 1 else 0.0
    return max(1.4826 * float(np.median(np.abs(d2 - np.median(d2)))) / np.sqrt(6.0), q)


def _inject(data: pd.DataFrame, rng: np.random.Generator, frac: float = 0.002):
    out = data.copy()
    truth = {}
    for c in CHANNELS:
        if c not in out.columns:
            continue
        v = out[c].to_numpy(dtype=float).copy()
        ok = np.flatnonzero(np.isfinite(v))
        if len(ok) < 200:
            continue
        scale = _noise_scale(v[ok] if c != "heading_deg" else np.unwrap(v[ok], period=360.0))
        k = max(int(frac * len(ok)), 5)
        lattice = np.arange(20, len(ok) - 21, 20) + rng.integers(0, 20)
        pos = rng.choice(lattice, size=min(k, len(lattice)), replace=False)
        double = rng.random(len(pos)) < 0.25
        amp = rng.uniform(10, 50, len(pos)) * scale * rng.choice([-1, 1], len(pos))
        v[ok[pos]] += amp
        v[ok[pos[double] + 1]] += amp[double]
        if c == "heading_deg":
            v = np.where(np.isfinite(v), v % 360.0, v)
        out[c] = v
        truth[c] = set(ok[pos].tolist()) | set(ok[pos[double] + 1].tolist())
    return out, truth


def run(seeds: int, out_dir: Path) -> None:
    from flightrecon.sim import simulate

    rows, spike_rows = [], []
    for sc in SCENARIOS:
        for seed in range(seeds):
            res = simulate(sc, seed)
            lo, td, i_lo = _transitions(res.truth)
            t0 = time.perf_counter()
            clean = clean_flight(Flight(res.log, res.meta))
            el = time.perf_counter() - t0
            ph = clean.phases
            gs_err = float("nan")
            if i_lo >= 0 and np.isfinite(ph.liftoff_t_s):
                tv = res.truth.iloc[i_lo]
                gs_err = float(np.hypot(*ph.liftoff_velocity_ned_mps[:2])
                               - np.hypot(tv["vn_mps"], tv["ve_mps"]))
            rows.append({"scenario": sc, "seed": seed, "liftoff_err_s": ph.liftoff_t_s - lo,
                         "touchdown_err_s": ph.touchdown_t_s - td, "liftoff_gs_err_mps": gs_err,
                         "clean_s": el})
            rng = np.random.default_rng(1000 + seed)
            dirty, truth = _inject(res.log, rng)
            # the simulator's own fault spikes are spikes too (not clean samples)
            t_log = res.log["t_s"].to_numpy()
            for f in res.sensor_truth.get("faults", []):
                if f.get("kind") == "spike" and f.get("column") in truth:
                    rows_f = np.flatnonzero(np.isclose(t_log, f["t_s"], atol=1e-9)
                                            & np.isfinite(res.log[f["column"]].to_numpy()))
                    truth[f["column"]] |= set(rows_f.tolist())
            _, rep = run_steps(dirty, [UnwrapAngles(), Despike()])
            removed = {r["channel"]: set(r["rows"]) for r in rep if r["action"] == "despike"}
            for c, idx in truth.items():
                got = removed.get(c, set())
                n_clean = int(np.isfinite(dirty[c].to_numpy(dtype=float)).sum()) - len(idx)
                spike_rows.append({"scenario": sc, "seed": seed, "channel": c,
                                   "injected": len(idx), "caught": len(got & idx),
                                   "false": len(got - idx), "clean": n_clean})
            print(rows[-1], flush=True)
    ph = pd.DataFrame(rows)
    sp = pd.DataFrame(spike_rows)
    lines = ["# Signals layer on simulated flights", "",
             f"`python scripts/signals_study.py --seeds {seeds}`: scenarios "
             f"{', '.join(SCENARIOS)} of `flightrecon.sim`, seeds 0-{seeds - 1}.", "",
             "## Phase detection (detected minus truth `on_ground` transition)", "",
             "| scenario | flights | lift-off error mean / max abs [s] | touchdown error mean / "
             "max abs [s] | lift-off ground-speed error mean / max abs [m/s] | clean_flight [s] |",
             "|---|---|---|---|---|---|"]
    def stat(g: pd.DataFrame, col: str) -> str:
        v = g[col].dropna()
        return "n/a" if v.empty else f"{v.mean():+.2f} / {v.abs().max():.2f}"

    for sc, g in ph.groupby("scenario", sort=False):
        f = lambda col, g=g: stat(g, col)  # noqa: E731
        lines.append(f"| {sc} | {len(g)} | {f('liftoff_err_s')} | {f('touchdown_err_s')} | "
                     f"{f('liftoff_gs_err_mps')} | {g['clean_s'].mean():.2f} |")
    lines += ["", "Lift-off ground-speed errors include the simulated airspeed scale error "
              "(2 %) and, in `circuit` (no wind channel), the unmodelled headwind component.", "",
              "## Despiking (spikes of 10-50 x noise at 0.2 % of samples, "
              "plus the simulator's fault spikes)", "",
              "| channel | injected | caught | caught [%] | clean samples | removed clean | "
              "removed clean [%] |", "|---|---|---|---|---|---|---|"]
    for c, g in sp.groupby("channel", sort=False):
        inj, cau = g["injected"].sum(), g["caught"].sum()
        fal, cl = g["false"].sum(), g["clean"].sum()
        lines.append(f"| {c} | {inj} | {cau} | {100 * cau / inj:.1f} | {cl} | {fal} | "
                     f"{100 * fal / cl:.3f} |")
    inj, cau = sp["injected"].sum(), sp["caught"].sum()
    fal, cl = sp["false"].sum(), sp["clean"].sum()
    lines.append(f"| **all** | {inj} | {cau} | {100 * cau / inj:.1f} | {cl} | {fal} | "
                 f"{100 * fal / cl:.3f} |")
    (out_dir / "tables").mkdir(parents=True, exist_ok=True)
    (out_dir / "figures").mkdir(parents=True, exist_ok=True)
    (out_dir / "tables" / "signals_study.md").write_text(
        header() + "\n".join(lines) + "\n", encoding="utf-8")
    fig, ax = plt.subplots(1, 2, figsize=(9, 3.5))
    for a, col, title in ((ax[0], "liftoff_err_s", "lift-off"), (ax[1], "touchdown_err_s",
                                                                 "touchdown")):
        for sc, g in ph.groupby("scenario", sort=False):
            v = g[col].dropna()
            if len(v):
                a.hist(v, bins=np.linspace(-1, 1, 41), alpha=0.6, label=sc)
        a.axvline(-1, color="k", lw=0.8)
        a.axvline(1, color="k", lw=0.8)
        a.set_xlabel(f"{title} error [s] (detected - truth)")
        a.set_ylabel("flights")
        a.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out_dir / "figures" / "signals_phase_errors.png", dpi=110)
    print("\n".join(lines))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs")
    a = ap.parse_args()
    run(a.seeds, a.out)


if __name__ == "__main__":
    main()
