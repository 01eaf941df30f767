"""Worked example: does the mean of an aircraft's Sabziev coefficients reconstruct a flight
whose arrival point is unknown?  (Sabziev's hypothesis, docs/methods.md section 1.)

For each simulated aircraft (persistent sensor errors of its own), ``--flights`` circuits with
different weather are flown.  Leave-one-out: each flight in turn is held out; the others are
fitted (boundary-value mode) and recorded in a fresh coefficient store; the held-out flight is
reconstructed

* with the fleet-mean coefficients (initial-value mode, no arrival point),
* with its own fitted coefficients (boundary-value mode: the best the method can do),
* by dead reckoning from airspeed and heading (no end point either),

and each is compared with the truth (horizontal RMS over the airborne part).

Usage::

    python scripts/fleet_hypothesis.py --aircraft 2 --flights 6

writes docs/tables/fleet_hypothesis.md and docs/figures/fleet_hypothesis.png.
Seeds: aircraft a uses simulate_fleet(f"AC{a}", n, seed=100 + a).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from dataclasses import replace
from pathlib import Path

import matplotlib

sys.path.insert(0, str(Path(__file__).resolve().parent))

from table_header import header  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402

from flightrecon.cleaning import clean_flight
from flightrecon.methods.baselines import dead_reckoning  # noqa: E402
from flightrecon.methods.sabziev.method import run_sabziev  # noqa: E402
from flightrecon.sim import simulate_fleet  # noqa: E402
from flightrecon.store import CoefficientStore, from_sabziev_summary  # noqa: E402
from flightrecon.types import Flight  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


def horizontal_rms(track: pd.DataFrame, prefix: str, truth: pd.DataFrame) -> float:
    air = ~truth["on_ground"].to_numpy(bool)
    m = pd.DataFrame({"t_s": truth["t_s"][air]}).merge(track, on="t_s", how="left")
    tr = truth[air]
    e = np.hypot(m[f"{prefix}north_m"].to_numpy() - tr["north_m"].to_numpy(),
                 m[f"{prefix}east_m"].to_numpy() - tr["east_m"].to_numpy())
    return float(np.sqrt(np.nanmean(e ** 2)))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--aircraft", type=int, default=2)
    ap.add_argument("--flights", type=int, default=6)
    ap.add_argument("--no-write", action="store_true")
    a = ap.parse_args()
    rows = []
    for ac in range(a.aircraft):
        ac_id = f"AC{ac + 1}"
        sims = simulate_fleet(ac_id, a.flights, seed=100 + ac)
        cleans = [clean_flight(Flight(data=s.log, meta=s.meta)) for s in sims]
        fits = [run_sabziev(c) for c in cleans]
        for hold in range(a.flights):
            with tempfile.TemporaryDirectory() as d:
                with CoefficientStore(Path(d) / "s.sqlite") as store:
                    for i, (s, f) in enumerate(zip(sims, fits)):
                        if i == hold:
                            continue
                        store.record(from_sabziev_summary(
                            f.summary, aircraft_id=ac_id, flight_id=s.meta.flight_id or str(i),
                            flight_date_utc=s.meta.epoch_utc))
                    fm = store.fleet_mean(ac_id, min_flights=2)
            sim, clean = sims[hold], cleans[hold]
            # the held-out flight has no arrival point: initial-value mode with the fleet mean
            clean_noarr = replace(clean, meta=replace(clean.meta, arrival=None))
            iv = run_sabziev(clean_noarr, k=fm.k, k_sd=tuple(0.0 if not np.isfinite(x) else x
                                                             for x in fm.sd))
            own = fits[hold]
            rows.append({
                "aircraft": ac_id, "flight": sim.meta.flight_id,
                "k_own": [own.summary.get("k1"), own.summary.get("k2"), own.summary.get("k3")],
                "converged_own": own.summary.get("converged"),
                "k_fleet": list(fm.k), "k_fleet_sd": list(fm.sd), "n_fleet": list(fm.n),
                "rms_fleet_mean_m": horizontal_rms(iv.track, "sabziev_", sim.truth),
                "rms_own_k_m": horizontal_rms(own.track, "sabziev_", sim.truth),
                "rms_dead_reckoning_m": horizontal_rms(dead_reckoning(clean), "", sim.truth),
                "fleet_sd_mean_m": float(np.nanmean(np.hypot(
                    iv.track.get("sabziev_north_sd_m", np.nan),
                    iv.track.get("sabziev_east_sd_m", np.nan)))),
            })
            print(rows[-1])
    df = pd.DataFrame(rows)
    lines = ["| aircraft | flight | own k1, k2, k3 (converged) | fleet-mean k1, k2, k3 (flights) | "
             "RMS fleet mean [m] | RMS own k [m] | RMS dead reckoning [m] | "
             "reported sd (fleet) [m] |",
             "|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ko = ", ".join("-" if x is None else f"{x:.3g}" for x in r["k_own"])
        kf = ", ".join(f"{x:.3g}" for x in r["k_fleet"])
        lines.append(f"| {r['aircraft']} | {r['flight']} | {ko} ({r['converged_own']}) | {kf} "
                     f"({', '.join(map(str, r['n_fleet']))}) | {r['rms_fleet_mean_m']:.0f} | "
                     f"{r['rms_own_k_m']:.0f} | {r['rms_dead_reckoning_m']:.0f} | "
                     f"{r['fleet_sd_mean_m']:.0f} |")
    better_dr = int(np.sum(df["rms_fleet_mean_m"] < df["rms_dead_reckoning_m"]))
    lines += ["", f"Fleet mean better than dead reckoning in {better_dr}/{len(df)} held-out "
              f"flights; median RMS: fleet mean {df['rms_fleet_mean_m'].median():.0f} m, own k "
              f"{df['rms_own_k_m'].median():.0f} m, dead reckoning "
              f"{df['rms_dead_reckoning_m'].median():.0f} m."]
    text = "\n".join(lines)
    print(text)
    if a.no_write:
        return
    (ROOT / "docs" / "tables").mkdir(parents=True, exist_ok=True)
    (ROOT / "docs" / "tables" / "fleet_hypothesis.md").write_text(
        header() + f"{text}\n")
    fig, ax = plt.subplots(figsize=(7, 4))
    x = np.arange(len(df))
    ax.bar(x - 0.27, df["rms_own_k_m"], 0.27, label="own fitted k (arrival known)")
    ax.bar(x, df["rms_fleet_mean_m"], 0.27, label="fleet-mean k (arrival unknown)")
    ax.bar(x + 0.27, df["rms_dead_reckoning_m"], 0.27, label="dead reckoning")
    ax.set_xticks(x, [f"{r['aircraft']}/{r['flight']}" for r in rows], rotation=45)
    ax.set_yscale("log")
    ax.set_ylabel("horizontal RMS error [m]")
    ax.legend(fontsize=8)
    ax.set_title("Held-out flights: Sabziev with fleet-mean coefficients")
    fig.tight_layout()
    (ROOT / "docs" / "figures").mkdir(parents=True, exist_ok=True)
    fig.savefig(ROOT / "docs" / "figures" / "fleet_hypothesis.png", dpi=110)


if __name__ == "__main__":
    main()
