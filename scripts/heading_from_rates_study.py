"""Heading from the body rates: the same flights with a heading channel and with body rates
only (no heading), reconstructed by the joint smoother.

Each run simulates a circuit (``circuit`` scenario, 1 Hz GNSS; seed 5000 + i), computes the
body rates from the true attitude by the inverse Euler kinematics
(``p = phi' - psi' sin(theta)``, ``q = theta' cos(phi) + psi' sin(phi) cos(theta)``,
``r = -theta' sin(phi) + psi' cos(phi) cos(theta)``) at the attitude samples, adds rate-gyro
errors (white 0.05 deg/s per sample, constant biases drawn N(0, 0.01 deg/s): a tactical-grade
gyro, 36 deg/h) and removes ``heading_deg``.  Cases:

* ``gnss``: recorder + 1 Hz GNSS, with the heading vs with the rates (anchored by the runway
  direction and the GNSS track);
* ``recorder``: GNSS removed; with the rates, anchored by the departure and arrival runway
  directions.  Reported beside dead reckoning (airspeed and the *recorded* heading, lift-off to
  touchdown, from the departure point; and its linear end-point correction) and the joint
  smoother with the recorded heading.

Horizontal RMS error against the truth over the airborne part; heading error of the propagated
heading against the truth, with its reported sd.

Usage::

    # writes docs/tables/heading_from_rates.md:
    python scripts/heading_from_rates_study.py --runs 10
    python scripts/heading_from_rates_study.py --runs 2 --no-write
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))

from table_header import header  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SEED0 = 5000
GYRO_NOISE_DPS = 0.05
GYRO_BIAS_DPS = 0.01


def rates_log(log: pd.DataFrame, truth: pd.DataFrame, rng: np.random.Generator
              ) -> tuple[pd.DataFrame, tuple[float, float, float]]:
    """``log`` with p/q/r_dps at the attitude rows (from the truth) and no heading."""
    t = truth["t_s"].to_numpy()
    phi = np.radians(truth["roll_deg"].to_numpy())
    th = np.radians(truth["pitch_deg"].to_numpy())
    psi = np.unwrap(np.radians(truth["heading_deg"].to_numpy()))
    dphi, dth, dpsi = (np.gradient(x, t) for x in (phi, th, psi))
    p = dphi - dpsi * np.sin(th)
    q = dth * np.cos(phi) + dpsi * np.sin(phi) * np.cos(th)
    r = -dth * np.sin(phi) + dpsi * np.cos(phi) * np.cos(th)
    bias = tuple(float(b) for b in rng.normal(0.0, GYRO_BIAS_DPS, 3))
    out = log.drop(columns=["heading_deg"]).copy()
    rows = out["roll_deg"].notna().to_numpy()
    ta = out["t_s"].to_numpy()[rows]
    for name, v, b in (("p_dps", p, bias[0]), ("q_dps", q, bias[1]), ("r_dps", r, bias[2])):
        col = np.full(len(out), np.nan)
        col[rows] = (np.degrees(np.interp(ta, t, v)) + b
                     + GYRO_NOISE_DPS * rng.standard_normal(rows.sum()))
        out[name] = col
    return out, bias


def _rms_h(track, prefix, truth, air):
    m = pd.DataFrame({"t_s": truth["t_s"][air]}).merge(track, on="t_s", how="left")
    tr = truth[air]
    en = m[f"{prefix}north_m"].to_numpy() - tr["north_m"].to_numpy()
    ee = m[f"{prefix}east_m"].to_numpy() - tr["east_m"].to_numpy()
    ok = np.isfinite(en) & np.isfinite(ee)
    return float(np.sqrt(np.mean(en[ok] ** 2 + ee[ok] ** 2)))


def one_run(seed: int) -> dict:
    from flightrecon.cleaning import clean_flight
    from flightrecon.methods.baselines import dead_reckoning
    from flightrecon.methods.joint.method import run_joint
    from flightrecon.sim import simulate
    from flightrecon.types import Flight

    rng = np.random.default_rng(seed)
    r = simulate("circuit", seed=seed)
    truth = r.truth
    air = ~truth["on_ground"].to_numpy(bool)
    gcols = [c for c in r.log.columns if c.startswith("gnss_")]
    rl, bias = rates_log(r.log, truth, rng)
    out: dict = {"seed": seed, "gyro_bias_dps": bias}
    for case, with_gnss in (("gnss", True), ("recorder", False)):
        base = r.log if with_gnss else r.log.drop(columns=gcols)
        rates = rl if with_gnss else rl.drop(columns=gcols)
        ch = clean_flight(Flight(data=base, meta=r.meta))
        cr = clean_flight(Flight(data=rates, meta=r.meta))
        res = {"joint_heading_m": _rms_h(run_joint(ch).track, "joint_", truth, air),
               "joint_rates_m": _rms_h(run_joint(cr).track, "joint_", truth, air)}
        # the propagated heading against the truth, with its reported sd
        g = cr.grid
        th = np.interp(g["t_s"], truth["t_s"], np.unwrap(np.radians(truth["heading_deg"])))
        err = np.degrees(np.angle(np.exp(1j * (np.radians(g["heading_deg"]) - th))))
        res["heading_err_rms_deg"] = float(np.sqrt(np.mean(err ** 2)))
        res["heading_sd_rms_deg"] = float(np.sqrt(np.mean(g["heading_sd_deg"] ** 2)))
        (rep,) = [e for e in cr.report if e["action"] == "heading_from_rates"]
        res["bias_r_est_dps"] = rep["gyro_bias_r_dps"]
        if not with_gnss:
            res["dr_m"] = _rms_h(dead_reckoning(ch, corrected=False), "", truth, air)
            res["dr_linear_m"] = _rms_h(dead_reckoning(ch, corrected=True), "", truth, air)
        out[case] = res
    return out


def summarise(rows: list[dict]) -> str:
    def col(case, key):
        return np.array([r[case][key] for r in rows])

    lines = [f"Runs: {len(rows)} (seeds {rows[0]['seed']}..{rows[-1]['seed']}); circuits; rate "
             f"gyros {GYRO_NOISE_DPS:g} deg/s white, biases N(0, {GYRO_BIAS_DPS:g} deg/s). "
             "Horizontal RMS error over the airborne part [m], mean (max) over runs.", "",
             "| case | joint, recorded heading | joint, heading from rates | ratio rates/heading "
             "(max) | heading error RMS [deg] | reported heading sd RMS [deg] | dead reckoning "
             "(recorded heading) | DR + linear end-point correction |",
             "|---|---|---|---|---|---|---|---|"]
    for case in ("gnss", "recorder"):
        a, b = col(case, "joint_heading_m"), col(case, "joint_rates_m")
        dr = (f"{np.mean(col(case, 'dr_m')):.0f} ({np.max(col(case, 'dr_m')):.0f})"
              if case == "recorder" else "-")
        drl = (f"{np.mean(col(case, 'dr_linear_m')):.0f} ({np.max(col(case, 'dr_linear_m')):.0f})"
               if case == "recorder" else "-")
        lines.append(f"| {case} | {np.mean(a):.2f} ({np.max(a):.2f}) | {np.mean(b):.2f} "
                     f"({np.max(b):.2f}) | {np.max(b / a):.2f} | "
                     f"{np.mean(col(case, 'heading_err_rms_deg')):.2f} | "
                     f"{np.mean(col(case, 'heading_sd_rms_deg')):.2f} | {dr} | {drl} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--no-write", action="store_true")
    a = ap.parse_args()
    rows = []
    for i in range(a.runs):
        rows.append(one_run(SEED0 + i))
        print(i, json.dumps(rows[-1]), file=sys.stderr)
    text = summarise(rows)
    print(text)
    if not a.no_write:
        (ROOT / "docs" / "tables" / "heading_from_rates.md").write_text(
            header() + text + "\n")
        (ROOT / "docs" / "tables" / "heading_from_rates_runs.json").write_text(
            json.dumps(rows, indent=1))


if __name__ == "__main__":
    main()
