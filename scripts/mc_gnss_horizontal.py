"""Monte Carlo: GNSS fixes without height (latitude and longitude only), joint smoother and SNS.

Receiver exports often carry latitude and longitude but no height.  Such fixes are used
horizontally (the vertical comes from the pressure altitude).  Each run flies the ``gnss`` case
of ``scripts/mc_joint.py`` (a 15-minute circuit with 1 Hz GNSS and a 2-minute GNSS dropout from
400 s; same seeds, 3000 + i), reconstructs it twice, with the fixes' heights and with
``gnss_alt_m`` removed, and measures the horizontal error against the truth over the airborne
part *outside the dropout* (from 30 s after it ends: the smoother closes the gap from both
sides, the error inside it is the gap's, not the fixes').  The claim checked: without heights
the track stays within the fixes' accuracy, the 2-D RMS of a fix's horizontal error
(``sqrt(2) * pos_sd_h_m``, 3.5 m for the simulator's 2.5 m per axis), and close to the track with
heights.  Both run with the sensors' data-sheet noise for the GNSS: the joint smoother with
``mc_joint.noise_from_sensors``, SNS with its GNSS position and velocity sd overridden
(``ReconstructSettings.sns_noise``; with its default 3 m it weights the fixes less than they
deserve and its RMS error was 3.2 m on the first runs).

Usage::

    # writes docs/tables/gnss_horizontal_mc.md:
    python scripts/mc_gnss_horizontal.py --runs 40
    python scripts/mc_gnss_horizontal.py --runs 3 --no-write
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from table_header import header  # noqa: E402

HERE = Path(__file__).resolve().parent
ROOT = HERE.parent
sys.path.insert(0, str(HERE))

DROPOUT = (400.0, 120.0)
SETTLE_S = 30.0
SEED0 = 3000


def _errors(track, prefix: str, truth, keep: np.ndarray) -> float:
    import pandas as pd

    m = pd.DataFrame({"t_s": truth["t_s"][keep]}).merge(track, on="t_s", how="left")
    tr = truth[keep]
    en = m[f"{prefix}north_m"].to_numpy() - tr["north_m"].to_numpy()
    ee = m[f"{prefix}east_m"].to_numpy() - tr["east_m"].to_numpy()
    ok = np.isfinite(en) & np.isfinite(ee)
    return float(np.sqrt(np.mean(en[ok] ** 2 + ee[ok] ** 2))) if ok.any() else float("nan")


def one_run(seed: int) -> dict:
    from mc_joint import noise_from_sensors

    from flightrecon.cleaning import clean_flight
    from flightrecon.methods.joint import JointSettings
    from flightrecon.methods.joint.method import run_joint
    from flightrecon.pipeline import ReconstructSettings, run_method
    from flightrecon.sim import simulate
    from flightrecon.types import Flight

    r = simulate("circuit", seed=seed, gnss_dropouts=(DROPOUT,))
    truth = r.truth
    t = truth["t_s"].to_numpy()
    keep = ~truth["on_ground"].to_numpy(bool) & ~(
        (t >= DROPOUT[0]) & (t < DROPOUT[0] + DROPOUT[1] + SETTLE_S))
    js = JointSettings(noise=noise_from_sensors(r.sensor_truth))
    out = {"seed": seed, "fix_h_sd_m": float(r.sensor_truth["sensors"]["gnss"]["pos_sd_h_m"])}
    for name, log in (("with_height", r.log), ("horizontal", r.log.drop(columns=["gnss_alt_m"]))):
        clean = clean_flight(Flight(data=log, meta=r.meta))
        j = run_joint(clean, settings=js)
        g = r.sensor_truth["sensors"]["gnss"]
        s = run_method("sns", clean, ReconstructSettings(sns_noise={
            "pos_sd_m": float(g["pos_sd_h_m"]), "vel_sd_mps": float(g["vel_sd_mps"])}))
        out[name] = {"joint_rms_h_m": _errors(j.track, "joint_", truth, keep),
                     "sns_rms_h_m": _errors(s.track, "sns_", truth, keep),
                     "joint_gnss_pos_used": int(j.summary["sources"].get("gnss_pos", {})
                                                .get("count", 0))}
    return out


def summarise(rows: list[dict]) -> str:
    fix = float(np.sqrt(2.0) * rows[0]["fix_h_sd_m"])
    lines = [f"Runs: {len(rows)} (seeds {rows[0]['seed']}..{rows[-1]['seed']}); "
             "15-minute circuits, "
             f"1 Hz GNSS, dropout {DROPOUT[0]:g}-{DROPOUT[0] + DROPOUT[1]:g} s; errors over the "
             f"airborne part outside the dropout (+{SETTLE_S:g} s). Fixes' horizontal accuracy "
             f"(2-D RMS): {fix:.2f} m.", "",
             "| fixes | method | mean RMS_h [m] | max RMS_h [m] | "
             "runs within the fixes' accuracy | "
             "GNSS position scalars used (mean) |", "|---|---|---|---|---|---|"]
    for name in ("with_height", "horizontal"):
        for m in ("joint", "sns"):
            v = np.array([r[name][f"{m}_rms_h_m"] for r in rows])
            used = np.mean([r[name]["joint_gnss_pos_used"] for r in rows]) if m == "joint" else None
            lines.append(f"| {name.replace('_', ' ')} | {m} | {np.mean(v):.2f} | {np.max(v):.2f} | "
                         f"{int(np.sum(v <= fix))}/{len(v)} | "
                         f"{'-' if used is None else f'{used:.0f}'} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=40)
    ap.add_argument("--no-write", action="store_true")
    a = ap.parse_args()
    rows = []
    for i in range(a.runs):
        rows.append(one_run(SEED0 + i))
        print(i, json.dumps(rows[-1]), file=sys.stderr)
    text = summarise(rows)
    print(text)
    if not a.no_write:
        (ROOT / "docs" / "tables" / "gnss_horizontal_mc.md").write_text(
            header() + text + "\n")
        (ROOT / "docs" / "tables" / "gnss_horizontal_mc_runs.json").write_text(
            json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
