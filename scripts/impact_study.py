"""Impact detection, recorder saturation and attitude beyond 90 deg on JSBSim flights
(docs/jsbsim.md, "Upsets and impact").

For each run: simulate a JSBSim scenario (recorder only, no GNSS), clean it, and compare the
cleaning's impact (:mod:`flightrecon.cleaning.impact`) with the truth's first contact (the
earlier of ``impact_t_s``, the first truth sample with a gear on the ground, and the first
truth sample with a load-factor magnitude of ``CONTACT_G`` or more: the structure striking);
record the peak loads, the saturated channels, the truth's largest bank and pitch, and run
the joint smoother and Sabziev: do their tracks reach the impact, are they finite, and the
joint's RMS horizontal error on the airborne truth samples with the saturated load factors
treated as missing (the default) and kept as read.  The landings (``jsbsim-circuit``) and the
shipped sample logs are the false-positive check: no impact may be detected there.

Usage::

    python scripts/impact_study.py --runs 5            # seeds 7000 + 100 k + i (case k)
    python scripts/impact_study.py --runs 5 --write    # and docs/tables/impact_study.json
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from mc_joint import errors, noise_from_sensors  # noqa: E402
from table_header import command_line  # noqa: E402

import flightrecon.methods.joint.problem as jm  # noqa: E402
from flightrecon.cleaning import clean_flight  # noqa: E402
from flightrecon.ingest.api import load_flight  # noqa: E402
from flightrecon.methods.joint import JointSettings  # noqa: E402
from flightrecon.methods.joint.method import run_joint  # noqa: E402
from flightrecon.pipeline import ReconstructSettings, run_method  # noqa: E402
from flightrecon.sim import simulate  # noqa: E402
from flightrecon.types import Flight  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
#: a truth load-factor magnitude this large is a structural contact with the ground (the
#: Cessna's flight loads stay below 6 g in every upset flown); the truth's ``impact_t_s`` is the
#: first sample with a *gear* contact, which a wing tip or the nose can precede by seconds
CONTACT_G = 8.0
#: label -> (scenario, overrides); "rollover": the spiral rolling on to 130 deg of bank at
#: 10 deg/s (past the knife edge into a steep, partly inverted dive), its climb shortened
CASES: dict[str, tuple[str, dict]] = {
    "jsbsim-spiral": ("jsbsim-spiral", {}),
    "jsbsim-spin": ("jsbsim-spin", {}),
    "rollover": ("jsbsim-spiral", {"spiral_bank_deg": 130.0, "spiral_roll_rate_dps": 10.0,
                                   "scale": 0.1}),
    "jsbsim-circuit": ("jsbsim-circuit", {}),
}


def _track_end(track, prefix: str) -> tuple[float, bool]:
    """Last time with a finite position of ``prefix`` and whether every row is finite."""
    n, e = track[f"{prefix}north_m"].to_numpy(float), track[f"{prefix}east_m"].to_numpy(float)
    ok = np.isfinite(n) & np.isfinite(e)
    t = track["t_s"].to_numpy(float)
    return (float(t[ok][-1]) if ok.any() else float("nan")), bool(ok.all())


def _impact_facts(clean) -> dict:
    ph = clean.phases
    rep = next((r for r in clean.report if r["action"] == "impact"), None)
    sat = sorted({r["channel"] for r in clean.report if r["action"] == "saturation"})
    return {"impact_t_s": None if ph is None else float(ph.impact_t_s),
            "peak_load_g": None if ph is None else float(ph.impact_peak_load_g),
            "peaks_g": None if rep is None else [rep["peak_n_long_g"], rep["peak_n_lat_g"],
                                                 rep["peak_n_norm_g"]],
            "sink_mps": None if rep is None else rep["sink_rate_mps"],
            "saturated": sat,
            "roll_despiked": sum(r["count"] for r in clean.report
                                 if r["action"] == "despike" and r["channel"] == "roll_deg")}


def one_run(label: str, seed: int) -> dict:
    scenario, overrides = CASES[label]
    r = simulate(scenario, seed, gnss_hz=0.0, **overrides)
    ev = r.sensor_truth["events"]
    tr = r.truth
    mag = np.sqrt(tr["n_long_g"] ** 2 + tr["n_lat_g"] ** 2 + tr["n_norm_g"] ** 2).to_numpy()
    hard = np.flatnonzero(mag >= CONTACT_G)
    first = None
    if ev.get("impact_t_s") is not None:
        first = float(ev["impact_t_s"])
        if len(hard):
            first = min(first, float(tr["t_s"].iloc[hard[0]]))
    res: dict = {"case": label, "scenario": scenario, "overrides": overrides, "seed": seed,
                 "truth_impact_t_s": ev.get("impact_t_s"), "truth_first_contact_t_s": first,
                 "truth_max_bank_deg": float(np.max(np.abs(tr["roll_deg"]))),
                 "truth_max_abs_pitch_deg": float(np.max(np.abs(tr["pitch_deg"]))),
                 "truth_peak_load_g": float(np.max(np.sqrt(tr["n_long_g"] ** 2
                                                           + tr["n_lat_g"] ** 2
                                                           + tr["n_norm_g"] ** 2)))}
    clean = clean_flight(Flight(data=r.log, meta=r.meta))
    res.update(_impact_facts(clean))
    airborne = ~tr["on_ground"].to_numpy(bool)
    if ev.get("impact_t_s") is not None:
        airborne[-1] = True
    settings = JointSettings(noise=noise_from_sensors(r.sensor_truth))
    for tag, deweight in (("joint", True), ("joint_kept", False)):
        if not deweight:
            if not res["saturated"]:
                continue
            orig = jm.saturated_loads
            jm.saturated_loads = lambda g: np.zeros(len(g), bool)  # type: ignore[assignment]
        t0 = time.perf_counter()
        try:
            j = run_joint(clean, settings=settings)
        finally:
            if not deweight:
                jm.saturated_loads = orig  # type: ignore[assignment]
        e = errors(j.track, "joint_", tr, airborne)
        e.pop("profile", None)
        end, finite = _track_end(j.track, "joint_")
        res[tag] = {"rms_h_m": e["rms_h_m"], "nees_n": e.get("nees_n"),
                    "nees_e": e.get("nees_e"), "converged": bool(j.summary["converged"]),
                    "end_t_s": end, "all_finite": finite, "time_s": time.perf_counter() - t0}
    try:
        sab = run_method("sabziev", clean, ReconstructSettings())
        end, finite = _track_end(sab.track, "sabziev_")
        e = errors(sab.track, "sabziev_", tr, airborne)
        res["sabziev"] = {"rms_h_m": e["rms_h_m"], "end_t_s": end, "all_finite": finite,
                          "healthy": sab.summary.get("healthy")}
    except Exception as exc:  # noqa: BLE001 - a method failing is a result
        res["sabziev"] = {"error": f"{type(exc).__name__}: {exc}"[:200]}
    res["record_end_t_s"] = float(clean.grid["t_s"].iloc[-1])
    return res


def sample_logs() -> list[dict]:
    out = []
    for p in sorted((ROOT / "sample_logs").glob("*.csv")):
        mp = p.with_suffix(".mapping.toml")
        try:
            clean = clean_flight(load_flight(p, mapping=mp if mp.exists() else None))
        except Exception as exc:  # noqa: BLE001
            out.append({"log": p.name, "error": f"{type(exc).__name__}: {exc}"[:200]})
            continue
        out.append({"log": p.name, **_impact_facts(clean)})
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--runs", type=int, default=5)
    ap.add_argument("--cases", default=",".join(CASES))
    ap.add_argument("--write", action="store_true")
    a = ap.parse_args()
    rows = []
    for k, sc in enumerate(a.cases.split(",")):
        for i in range(a.runs):
            seed = 7000 + 100 * k + i
            row = one_run(sc, seed)
            rows.append(row)
            print(json.dumps(row), flush=True)
    logs = sample_logs()
    for row in logs:
        print(json.dumps(row), flush=True)
    if a.write:
        path = ROOT / "docs" / "tables" / "impact_study.json"
        path.write_text(json.dumps({"command": command_line(), "runs": rows, "sample_logs": logs},
                                   indent=1) + "\n")
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
