"""Acceptance study of the per-aircraft sensor calibration (issue 22, docs/store.md).

For each seed: one aircraft with fixed persistent sensor errors (drawn once per seed from the
joint smoother's default priors, as ``scripts/mc_joint.py``'s ``prior_aircraft``) flies
``--flights`` routine 15-minute circuits with 1 Hz GNSS, one day apart, each in its own wind.
The joint smoother's estimates of every flight are recorded in a fresh coefficient store and
fused (``CoefficientStore.calibration``: prior divided out, inverse-variance combination with an
estimated random-walk drift, outliers flagged).

1. **Recovery**: for each persistent error the simulator sets, is the truth within 2 fused sd?
2. **The accident flight**: a further flight of the same aircraft the next day, recorder only
   (no GNSS, no radar), departure airfield and runway known, **no arrival point**, a 20-minute
   circuit in a new random wind.  Reconstructed by the joint smoother
   * without the calibration (the default priors), and
   * with it (the fused means and sd as the smoother's priors, ``--use-fleet-coefficients``),
   each without wind information and with a winds-aloft forecast 1.5 m/s and 8 deg off (the
   flight's true mean wind field at the middle of the flight, every 300 m of altitude, speed
   + 1.5 m/s, direction + 8 deg, sd 2 m/s per component: ``reconstruct --wind``'s table,
   ``FlightMeta.wind_aloft``; ``scripts/wind_prior_study.py``'s ``forecast_from_field``), and
   compared with dead reckoning from airspeed and heading without wind (and with the
   forecast's wind).  Error: horizontal RMS against truth over the airborne part, and the
   position error at touchdown.

The truth is the point-mass simulator (flightrecon.sim), which shares the smoother's model and
flatters it, or (``--truth jsbsim``) the JSBSim Cessna circuit (docs/store.md).

Usage::

    python scripts/fleet_calibration.py --seeds 5 --flights 4     # writes the tables
    python scripts/fleet_calibration.py --seeds 1 --flights 3 --no-write

Seeds: seed s (0-based) draws the aircraft from SeedSequence([1000 + s, 4242]); routine flight i
uses simulation seed 100 * (s + 1) + i, the accident flight 100 * (s + 1) + 50.
Writes docs/tables/fleet_calibration.md and docs/tables/fleet_calibration_runs.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from flightrecon.cleaning import clean_flight
from flightrecon.errors import ValidationError
from flightrecon.methods.baselines import dead_reckoning
from flightrecon.methods.joint import JointNoise, JointSettings
from flightrecon.methods.joint.method import run_joint
from flightrecon.sim import simulate
from flightrecon.sim.scenarios import scenario_config
from flightrecon.sim.weather import WindField
from flightrecon.store import CoefficientStore, from_joint_summary
from flightrecon.store.adapt import flight_conditions
from flightrecon.types import Flight

sys.path.insert(0, str(Path(__file__).resolve().parent))

from table_header import header  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TABLE = ROOT / "docs" / "tables" / "fleet_calibration.md"
RUNS = ROOT / "docs" / "tables" / "fleet_calibration_runs.json"
AIRCRAFT_ID = "SIM-CAL"
FORECAST_SPEED_ERR_MPS = 1.5
FORECAST_DIR_ERR_DEG = 8.0
FORECAST_SD_MPS = 2.0
# the accident flight: a 20-minute circuit, recorder only (as mc_joint.py's recorder case)
ACCIDENT = {"leg_scale": 2.4, "duration_s": 1320.0, "gnss_hz": 0.0,
            "touchdown_m": JointNoise().touchdown_m, "touchdown_sd_m": JointNoise().touchdown_sd_m,
            "lineup_sd_m": JointNoise().roll_start_sd_m}

#: simulator aircraft field -> (joint correction name, sign): the simulator's conventions are
#: reading minus true, as the smoother's; the normal load factor is -f_z, hence the z sign
TRUTH_MAP = {
    "tas_scale": ("airspeed_scale", None, 1.0),
    "heading_bias_deg": ("heading_bias_deg", None, 1.0),
    "roll_bias_deg": ("roll_bias_deg", None, 1.0),
    "pitch_bias_deg": ("pitch_bias_deg", None, 1.0),
    "accel_bias_x_g": ("accel_bias_g", 0, 1.0),
    "accel_bias_y_g": ("accel_bias_g", 1, 1.0),
    "accel_bias_z_g": ("accel_bias_g", 2, -1.0),
    "accel_scale_x": ("accel_scale", 0, 1.0),
    "accel_scale_y": ("accel_scale", 1, 1.0),
    "accel_scale_z": ("accel_scale", 2, 1.0),
}


def random_wind(seed: int) -> WindField:
    """The circuit's wind with random walks in time and height instead of its sinusoid
    (mc_joint.py's ``random_wind``), mean speed and direction drawn anew per seed."""
    nz = JointNoise()
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([int(seed), 77])))
    base = scenario_config("circuit").wind
    return replace(base, speed_amp_mps=0.0, dir_amp_deg=0.0,
                   speed0_mps=float(rng.uniform(4.0, 12.0)),
                   from0_deg=float(rng.uniform(0.0, 360.0)),
                   rw_time_mps_sqrt_s=nz.wind_rw_mps_sqrt_s,
                   rw_alt_mps_sqrt_m=nz.wind_shear_mps_per_sqrt_m, rw_seed=seed)


def fleet_aircraft(s: int, base=None):
    """The aircraft of seed ``s``: persistent errors drawn from the joint smoother's priors
    (on ``base``, default the point-mass circuit's aircraft type)."""
    nz = JointNoise()
    rng = np.random.Generator(np.random.PCG64(np.random.SeedSequence([1000 + s, 4242])))
    base = scenario_config("circuit").aircraft if base is None else base
    return replace(base, aircraft_id=AIRCRAFT_ID,
                   accel_bias_g=tuple(float(v) for v in rng.normal(0.0, nz.accel_bias_g, 3)),
                   accel_scale=tuple(float(v) for v in rng.normal(0.0, nz.accel_scale, 3)),
                   heading_bias_deg=float(rng.normal(0.0, nz.heading_bias_deg)),
                   roll_bias_deg=float(rng.normal(0.0, nz.attitude_bias_deg)),
                   pitch_bias_deg=float(rng.normal(0.0, nz.attitude_bias_deg)),
                   airspeed_scale=float(rng.normal(0.0, nz.tas_scale)))


def truth_value(aircraft, name: str) -> float:
    field, idx, sign = TRUTH_MAP[name]
    v = getattr(aircraft, field)
    return sign * float(v if idx is None else v[idx])


def airborne_errors(track: pd.DataFrame, prefix: str, truth: pd.DataFrame) -> tuple[float, float]:
    """Horizontal RMS over the airborne samples and the error at the last airborne sample [m]."""
    air = ~truth["on_ground"].to_numpy(bool)
    m = pd.DataFrame({"t_s": truth["t_s"][air]}).merge(track, on="t_s", how="left")
    tr = truth[air]
    e = np.hypot(m[f"{prefix}north_m"].to_numpy() - tr["north_m"].to_numpy(),
                 m[f"{prefix}east_m"].to_numpy() - tr["east_m"].to_numpy())
    ok = np.isfinite(e)
    return float(np.sqrt(np.mean(e[ok] ** 2))), float(e[ok][-1])


def forecast_table(truth_source: str, sim_seed: int, truth: pd.DataFrame):
    """The accident flight's winds-aloft forecast (module docstring) from its wind field."""
    sys.path.insert(0, str(ROOT / "scripts"))
    from wind_prior_study import forecast_from_field

    if truth_source == "pointmass":
        field = random_wind(sim_seed)
    else:
        from flightrecon.sim.jsbsim_scenarios import draw_weather

        field = draw_weather("jsbsim-circuit", sim_seed).wind
    return forecast_from_field(field, truth, FORECAST_SPEED_ERR_MPS, FORECAST_DIR_ERR_DEG,
                               FORECAST_SD_MPS)


def _simulate(truth: str, ac, sim_seed: int, accident: bool, **kw):
    """One flight of aircraft ``ac``: a point-mass circuit, or a JSBSim Cessna circuit whose
    persistent sensor errors are fixed to ``ac``'s (the JSBSim scenarios draw them per seed:
    here the aircraft's are substituted, the weather and noise still vary with the seed)."""
    if truth == "pointmass":
        extra = ACCIDENT if accident else {}
        return simulate("circuit", seed=sim_seed, aircraft=ac, wind=random_wind(sim_seed),
                        **kw, **extra)
    import flightrecon.sim.jsbsim_truth as jt

    orig = jt.persistent_aircraft
    jt.persistent_aircraft = lambda name, cfg, seed: ac
    try:
        return simulate("jsbsim-circuit", seed=sim_seed, **kw,
                        **({"gnss_hz": 0.0} if accident else {}))
    finally:
        jt.persistent_aircraft = orig


REFUSED: list[str] = []
"""Simulation seeds the simulator refused (JSBSim's ground model overturned the aircraft
before take-off), each replaced by the seed + 1000: listed in the tables."""


def _simulate_flown(truth: str, ac, sim_seed: int, accident: bool, **kw):
    """:func:`_simulate`, with a refused seed replaced by ``seed + 1000`` (up to twice)."""
    for seed in (sim_seed, sim_seed + 1000):
        try:
            return _simulate(truth, ac, seed, accident, **kw)
        except ValidationError as exc:
            REFUSED.append(f"{seed}: {exc}")
            print(f"seed {seed} refused: {exc}", file=sys.stderr)
    return _simulate(truth, ac, sim_seed + 2000, accident, **kw)


def run_seed(s: int, n_flights: int, truth: str = "pointmass") -> dict:
    if truth == "pointmass":
        ac = fleet_aircraft(s)
    else:
        from flightrecon.sim.aircraft import LIGHT

        ac = fleet_aircraft(s, LIGHT)
    out: dict = {"seed": s, "aircraft": {k: truth_value(ac, k) for k in TRUTH_MAP},
                 "baro_bias_m": ac.baro_bias_m, "routine": []}
    with tempfile.TemporaryDirectory() as d:
        store = CoefficientStore(Path(d) / "fleet.sqlite")
        for i in range(n_flights):
            sim_seed = 100 * (s + 1) + i
            t0 = time.perf_counter()
            sim = _simulate_flown(truth, ac, sim_seed, False, flight_id=f"R{i + 1}",
                            epoch_utc=f"2026-03-{i + 1:02d}T09:00:00Z")
            clean = clean_flight(Flight(data=sim.log, meta=sim.meta))
            res = run_joint(clean)
            cal = from_joint_summary(res.summary, aircraft_id=AIRCRAFT_ID, flight_id=f"R{i + 1}",
                                     flight_date_utc=sim.meta.epoch_utc,
                                     conditions=flight_conditions(clean))
            store.record_calibration(cal)
            rms, _ = airborne_errors(res.track, "joint_", sim.truth)
            out["routine"].append({"flight": f"R{i + 1}", "rms_m": rms,
                                   "converged": bool(res.summary["converged"]),
                                   "elapsed_s": time.perf_counter() - t0})
            print(f"seed {s} routine {i + 1}: joint RMS {rms:.1f} m "
                  f"({time.perf_counter() - t0:.0f} s)", file=sys.stderr)
        acc_date = f"2026-03-{n_flights + 1:02d}T09:00:00Z"
        fused = store.calibration(AIRCRAFT_ID, acc_date)
        store.close()
    rec = {}
    for q in fused.quantities:
        item = {"mean": q.mean, "sd": q.sd, "n": q.n, "drift": q.drift_sd_per_sqrt_day,
                "drift_source": q.drift_source,
                "excluded": [[e.flight_id, e.reason] for e in q.excluded]}
        if q.quantity in TRUTH_MAP:
            tv = truth_value(ac, q.quantity)
            item.update({"truth": tv, "z": (q.mean - tv) / q.sd if q.sd > 0 else float("inf"),
                         "prior_sd": q.prior_sd})
        rec[q.quantity] = item
    out["fused"] = rec
    priors = tuple((k, float(m), float(sd)) for k, (m, sd) in sorted(fused.priors().items()))
    out["priors_applied"] = [p[0] for p in priors]
    # the accident flight
    acc_seed = 100 * (s + 1) + 50
    sim = _simulate_flown(truth, ac, acc_seed, True, flight_id="ACC", epoch_utc=acc_date)
    meta = replace(sim.meta, arrival=None)
    acc: dict = {}
    table = forecast_table(truth, acc_seed, sim.truth)
    for wind_case in ("no_wind", "forecast"):
        clean = clean_flight(Flight(data=sim.log, meta=meta if wind_case == "no_wind"
                                    else replace(meta, wind_aloft=table)))
        dr = dead_reckoning(clean)
        acc[f"dead_reckoning_{wind_case}"] = airborne_errors(dr, "", sim.truth)
        for label, pr in (("default_priors", ()), ("calibration", priors)):
            t0 = time.perf_counter()
            res = run_joint(clean, settings=JointSettings(priors=pr))
            acc[f"joint_{label}_{wind_case}"] = airborne_errors(res.track, "joint_", sim.truth)
            print(f"seed {s} accident {wind_case} {label}: RMS, end "
                  f"{acc[f'joint_{label}_{wind_case}']} ({time.perf_counter() - t0:.0f} s)",
                  file=sys.stderr)
    out["accident"] = {k: {"rms_m": v[0], "end_m": v[1]} for k, v in acc.items()}
    return out


def tables(runs: list[dict], n_flights: int, truth: str = "pointmass") -> str:
    lines = [f"### Recovery of the persistent errors ({len(runs)} seeds, {n_flights} routine "
             "flights with GNSS each)", "",
             "Per error: fused mean - truth in units of the fused sd (z), and the fused sd "
             "against the default prior sd. Within 2 sd: |z| <= 2. An error no routine flight "
             "observed (sd >= 0.95 x prior sd on every flight: flights used 0) keeps the prior: "
             "its z tests the simulator's draw, not the calibration, and is marked *.", "",
             "| error | truth sd (prior) | median fused sd | flights used | "
             + " | ".join(f"z seed {r['seed']}" for r in runs) + " | within 2 sd |",
             "|---|---|---|---|" + "---|" * len(runs) + "---|"]
    total_in = total = 0
    for q in TRUTH_MAP:
        fz = [r["fused"][q] for r in runs if q in r["fused"]]
        sds = [f["sd"] for f in fz]
        psd = fz[0]["prior_sd"] if fz else float("nan")
        obs = [f for f in fz if f["n"] > 0]
        inside = sum(abs(f["z"]) <= 2 for f in obs)
        total_in += inside
        total += len(obs)
        ns = sorted({f["n"] for f in fz})
        lines.append(f"| {q} | {psd:.3g} | {np.median(sds):.3g} | "
                     f"{'-'.join(map(str, (ns[0], ns[-1]))) if len(ns) > 1 else ns[0]} | "
                     + " | ".join(f"{f['z']:+.2f}" + ("" if f["n"] else "*") for f in fz)
                     + f" | {inside}/{len(obs)} |")
    lines += ["", f"Errors observed by the routine flights, all seeds: {total_in}/{total} within "
              "2 fused sd (a Gaussian would put 95 % there).", ""]
    cases = [("dead_reckoning_no_wind", "dead reckoning, no wind"),
             ("dead_reckoning_forecast", "dead reckoning, forecast wind"),
             ("joint_default_priors_no_wind", "joint, default priors, no wind information"),
             ("joint_calibration_no_wind", "joint, fleet calibration, no wind information"),
             ("joint_default_priors_forecast", "joint, default priors, winds-aloft forecast"),
             ("joint_calibration_forecast", "joint, fleet calibration, winds-aloft forecast")]
    what = "20 minutes" if truth == "pointmass" else "a JSBSim Cessna circuit"
    lines += [f"### The accident flight (recorder only, departure known, no arrival, {what})",
              "", "Horizontal RMS error over the airborne part [m] (error at touchdown [m]).", "",
              "| seed | " + " | ".join(c[1] for c in cases) + " |",
              "|---|" + "---|" * len(cases)]
    for r in runs:
        a = r["accident"]
        lines.append(f"| {r['seed']} | " + " | ".join(
            f"{a[c]['rms_m']:.0f} ({a[c]['end_m']:.0f})" for c, _ in cases) + " |")
    med = {c: float(np.median([r["accident"][c]["rms_m"] for r in runs])) for c, _ in cases}
    lines.append("| median | " + " | ".join(f"{med[c]:.0f}" for c, _ in cases) + " |")

    def ratio(a, b):
        return [r["accident"][a]["rms_m"] / r["accident"][b]["rms_m"] for r in runs]

    cal_nw = ratio("joint_calibration_no_wind", "joint_default_priors_no_wind")
    cal_fc = ratio("joint_calibration_forecast", "joint_default_priors_forecast")
    dr_fc = ratio("joint_calibration_forecast", "dead_reckoning_no_wind")
    dr_nw = ratio("joint_calibration_no_wind", "dead_reckoning_no_wind")
    lines += ["", "| comparison (RMS ratio per seed) | median | max | seeds below 1 |",
              "|---|---|---|---|"]
    for name, rr in (("calibration / default priors, no wind", cal_nw),
                     ("calibration / default priors, forecast", cal_fc),
                     ("calibration + forecast / dead reckoning without wind", dr_fc),
                     ("calibration, no wind / dead reckoning without wind", dr_nw)):
        lines.append(f"| {name} | {np.median(rr):.2f} | {np.max(rr):.2f} | "
                     f"{sum(x < 1 for x in rr)}/{len(rr)} |")
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=5)
    ap.add_argument("--flights", type=int, default=4)
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--truth", choices=("pointmass", "jsbsim"), default="pointmass",
                    help="point-mass circuits (default) or JSBSim Cessna circuits (the "
                         "jsbsim-circuit scenario, about 8 minutes)")
    ap.add_argument("--summarise", type=Path, help="tables only, from a runs JSON")
    a = ap.parse_args()
    sfx = "" if a.truth == "pointmass" else "_" + a.truth
    table = TABLE.with_name(f"fleet_calibration{sfx}.md")
    runs_path = RUNS.with_name(f"fleet_calibration{sfx}_runs.json")
    if a.summarise:
        runs = json.loads(a.summarise.read_text())
        n = len(runs[0]["routine"])
    else:
        runs = []
        for s in range(a.seeds):
            runs.append(run_seed(s, a.flights, a.truth))
            if not a.no_write:  # keep what is done if a later seed is interrupted
                runs_path.parent.mkdir(parents=True, exist_ok=True)
                runs_path.write_text(json.dumps(runs, indent=1))
        n = a.flights
    text = tables(runs, n, a.truth)
    if REFUSED:
        text += ("\n\nSimulation seeds refused by the simulator (replaced by the seed + 1000):\n\n"
                 + "\n".join(f"* {r}" for r in REFUSED) + "\n")
    print(text)
    if not a.no_write:
        table.write_text(header() + text + "\n")


if __name__ == "__main__":
    main()
