"""What reading a recorder with the normal acceleration alone costs (docs/ingest.md, "Normal
acceleration alone"; issue 49, item 5).

Each flight is a JSBSim flight of the fleet (``flightrecon simulate SCENARIO --airframe A
--seed S``: 6-DoF, its own turbulence and sensor errors), written as ``flightrecon simulate``
writes it, and read twice through the ordinary path:

* ``recorded``: the log as written (``n_lat_g`` the simulated lateral accelerometer);
* ``coordinated``: the same log without its ``n_lat_g`` column, the same sidecar: ingest takes
  the lateral load of coordinated flight, 0 g (:func:`flightrecon.ingest.derive.derive_n_lat`).

Each reading is reconstructed by the joint smoother as ``flightrecon reconstruct`` runs it
(default settings) three ways: with its GNSS (every fix), with the GNSS fixes of one window of
``--gap`` seconds in the middle of the airborne part withheld (``--withhold-gnss``), and
recorder only (``--no-gnss``, with the departure and arrival of the sidecar).  Per run, against
the truth: the RMS horizontal error over the airborne samples (over the window's samples for the
gap), the mean NEES per horizontal axis there, and for the recorder-only run the ratio to dead
reckoning with the linear end correction on the same cleaned flight (which does not use the
loads: one figure for both readings).

Usage::

    python scripts/normal_only_study.py                        # the default flights, seed 7100
    python scripts/normal_only_study.py --cases c172p:jsbsim-circuit --seed 7110 --gap 120
"""

from __future__ import annotations

import argparse
import math
import shutil
import sys
import tempfile
import time
from pathlib import Path

import pandas as pd

from flightrecon.cleaning import clean_flight
from flightrecon.ingest import load_flight
from flightrecon.ingest.gnss_use import GnssUse
from flightrecon.methods.baselines import dead_reckoning
from flightrecon.pipeline import ReconstructSettings, run_method
from flightrecon.sim import simulate, write_simulation

sys.path.insert(0, str(Path(__file__).resolve().parent))

from fleet_study import interp_errors as errors  # noqa: E402  (RMS and NEES at truth samples)

CASES = (("c172p", "jsbsim-circuit", {}), ("pc7", "jsbsim-airwork", {}),
         ("c310", "jsbsim-xc", {"scale": 0.2}), ("737", "jsbsim-circuit", {}),
         ("t6texan2", "jsbsim-airwork", {}))
"""(aircraft, scenario, overrides): a light single, a turboprop and a twin, a jet, an aerobatic
trainer's air work (the cross-country shortened as in the fleet study, docs/jsbsim.md)."""


def gap_window(truth: pd.DataFrame, gap_s: float) -> tuple[float, float]:
    """``gap_s`` seconds centred on the middle of the airborne part (shorter if it is)."""
    t = truth["t_s"].to_numpy()[~truth["on_ground"].to_numpy(bool)]
    mid, half = 0.5 * (t[0] + t[-1]), min(gap_s, 0.8 * (t[-1] - t[0])) / 2
    return float(mid - half), float(mid + half)


def one_reading(log: Path, truth: pd.DataFrame, window: tuple[float, float]) -> dict:
    """The three reconstructions of one reading (module docstring)."""
    airborne = ~truth["on_ground"].to_numpy(bool)
    tt = truth["t_s"].to_numpy()
    in_gap = (tt >= window[0]) & (tt <= window[1])
    out: dict = {}
    for mode, use in (("gnss", GnssUse()), ("gap", GnssUse(withhold_s=(window,))),
                      ("recorder", GnssUse(withhold=True))):
        t0 = time.perf_counter()
        flight = load_flight(log, gnss_use=use)
        clean = clean_flight(flight)
        j = run_method("joint", clean, ReconstructSettings())
        out[mode] = errors(j.track, truth, in_gap if mode == "gap" else airborne)
        out[mode]["seconds"] = time.perf_counter() - t0
        if mode == "recorder":
            out["dr_linear"] = errors(dead_reckoning(clean, corrected=True), truth, airborne)
    return out


def one_flight(airframe: str, scenario: str, overrides: dict, seed: int, gap_s: float,
               tmp: Path) -> dict:
    """Both readings of one flight."""
    r = simulate(scenario, seed, airframe=airframe, **overrides)
    log = tmp / f"{airframe}-{scenario}-{seed}.parquet"
    write_simulation(r, log)
    lat = log.with_name(log.stem + "-nolat.parquet")
    pd.read_parquet(log).drop(columns=["n_lat_g"]).to_parquet(lat)
    shutil.copy(log.with_suffix(".meta.toml"), lat.with_suffix(".meta.toml"))
    window = gap_window(r.truth, gap_s)
    return {"airframe": airframe, "scenario": scenario, "seed": seed,
            "duration_s": float(r.truth["t_s"].iloc[-1]), "gap": window,
            "recorded": one_reading(log, r.truth, window),
            "coordinated": one_reading(lat, r.truth, window)}


def table(rows: list[dict]) -> str:
    """The markdown table of docs/ingest.md."""
    lines = ["| aircraft | scenario | seed | min | reading | with GNSS: RMS h [m], NEES n/e | "
             "gap of the GNSS: RMS h [m], NEES n/e | recorder only: RMS h [m], NEES n/e | "
             "recorder only / DR+lin |",
             "|---|---|---|---|---|---|---|---|---|"]
    def cell(x: dict) -> str:
        return (f"{x['rms_h_m']:.1f}, {x.get('nees_n', math.nan):.2f} / "
                f"{x.get('nees_e', math.nan):.2f}")
    for r in rows:
        for reading in ("recorded", "coordinated"):
            e = r[reading]
            ratio = e["recorder"]["rms_h_m"] / e["dr_linear"]["rms_h_m"]
            lines.append(f"| {r['airframe']} | {r['scenario']} | {r['seed']} | "
                         f"{r['duration_s'] / 60:.0f} | {reading} | {cell(e['gnss'])} | "
                         f"{cell(e['gap'])} | {cell(e['recorder'])} | {ratio:.2f} |")
    return "\n".join(lines) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seed", type=int, default=7100)
    ap.add_argument("--gap", type=float, default=300.0, help="GNSS window withheld [s]")
    ap.add_argument("--cases", default="", help="comma-separated aircraft:scenario")
    a = ap.parse_args()
    want = {tuple(c.split(":")) for c in a.cases.split(",") if c}
    rows = []
    with tempfile.TemporaryDirectory() as d:
        for airframe, scenario, ov in CASES:
            if want and (airframe, scenario) not in want:
                continue
            rows.append(one_flight(airframe, scenario, ov, a.seed, a.gap, Path(d)))
            print(table(rows[-1:]).splitlines()[-2:], file=sys.stderr, flush=True)
    sys.stdout.write(table(rows))


if __name__ == "__main__":
    main()
