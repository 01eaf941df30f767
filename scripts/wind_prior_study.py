"""Winds-aloft prior on JSBSim flights, departure only (issue 21, docs/wind.md).

Every run flies one JSBSim scenario (``flightrecon.sim.simulate("jsbsim-...", seed)``: its own
weather, turbulence, persistent sensor errors and recorder noise per seed), recorded without
GNSS or radar; the sidecar's arrival is removed: **the departure airfield is the only end
point**.  The winds-aloft forecast is made from the truth's wind model
(``flightrecon.sim.jsbsim_scenarios.draw_weather``: the mean wind without the turbulence) at
the middle of the airborne part, at levels every ``LEVEL_STEP_M`` from below the field to above
the highest altitude flown, each level's speed raised by 1.5 m/s and its direction turned by
8 deg (``FORECAST_SPEED_ERR_MPS``, ``FORECAST_DIR_ERR_DEG``), sd 2 m/s per component.  The
truth's wind also changes in time and by random walks in time and height, which the forecast
does not know.

Per run, on the airborne truth samples, horizontal RMS position error [m] and the error at the
last airborne sample, of

* the joint smoother without the prior (``joint``) and with it (``joint_wind``),
* dead reckoning from airspeed and heading without wind (``dr``) and with the forecast's wind
  (``dr_wind``).

The joint smoother's noise budget is the simulated sensors' data sheet (``noise_from_sensors``
of ``scripts/mc_joint.py``), as in ``scripts/mc_jsbsim.py``.  Nothing is tuned here.

Usage::

    python scripts/wind_prior_study.py --runs 10                     # writes docs/tables/
    python scripts/wind_prior_study.py --runs 2 --no-write
    python scripts/wind_prior_study.py --scenario jsbsim-xc --runs 3

Seeds: run i of a scenario uses seed 7000 + 100 k + i, k its index in ``SCENARIOS``.
Writes docs/tables/wind_prior_<scenario>.md and docs/tables/wind_prior_<scenario>_runs.json.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from mc_joint import errors, noise_from_sensors  # noqa: E402
from table_header import header  # noqa: E402

from flightrecon.cleaning import clean_flight  # noqa: E402
from flightrecon.errors import ValidationError  # noqa: E402
from flightrecon.methods.baselines import dead_reckoning  # noqa: E402
from flightrecon.methods.joint import JointSettings  # noqa: E402
from flightrecon.methods.joint.method import run_joint  # noqa: E402
from flightrecon.sim import simulate  # noqa: E402
from flightrecon.sim.jsbsim_scenarios import draw_weather  # noqa: E402
from flightrecon.types import Flight, WindLevel  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
TABLES = ROOT / "docs" / "tables"
SCENARIOS = ("jsbsim-circuit", "jsbsim-xc", "jsbsim-jet")
FORECAST_SPEED_ERR_MPS = 1.5
FORECAST_DIR_ERR_DEG = 8.0
FORECAST_SD_MPS = 2.0
LEVEL_STEP_M = 300.0


def forecast(scenario: str, seed: int, truth, speed_err_mps: float = FORECAST_SPEED_ERR_MPS,
             dir_err_deg: float = FORECAST_DIR_ERR_DEG,
             sd_mps: float = FORECAST_SD_MPS) -> tuple[WindLevel, ...]:
    """The winds-aloft table of a JSBSim run (module docstring): :func:`forecast_from_field`
    of the scenario's wind for ``seed``."""
    return forecast_from_field(draw_weather(scenario, seed).wind, truth, speed_err_mps,
                               dir_err_deg, sd_mps)


def forecast_from_field(wind, truth, speed_err_mps: float = FORECAST_SPEED_ERR_MPS,
                        dir_err_deg: float = FORECAST_DIR_ERR_DEG,
                        sd_mps: float = FORECAST_SD_MPS) -> tuple[WindLevel, ...]:
    """A winds-aloft table from a simulator wind field (``flightrecon.sim.weather.WindField``,
    both truth sources'): its mean wind at the middle of the airborne part, every
    ``LEVEL_STEP_M`` from 300 m below the lowest to 300 m above the highest truth altitude
    (MSL), speed + ``speed_err_mps``, direction + ``dir_err_deg``, ``sd_mps`` per component."""
    air = ~truth["on_ground"].to_numpy(bool)
    t_mid = float(np.median(truth["t_s"].to_numpy(float)[air]))
    h = truth["alt_msl_m"].to_numpy(float)
    z = np.arange(np.floor(h.min() / LEVEL_STEP_M) * LEVEL_STEP_M - LEVEL_STEP_M,
                  h.max() + 2 * LEVEL_STEP_M, LEVEL_STEP_M)
    wn, we = wind.velocity(z, np.full(len(z), t_mid))
    speed = np.hypot(wn, we) + speed_err_mps
    frm = np.mod(np.degrees(np.arctan2(-we, -wn)) + dir_err_deg, 360.0)
    return tuple(WindLevel(alt_msl_m=float(a), from_deg=float(f), speed_mps=float(s),
                           sd_mps=sd_mps) for a, f, s in zip(z, frm, speed))


def _err(track, prefix, truth, airborne) -> dict:
    """RMS (``errors`` of mc_joint.py) and the horizontal error at the last airborne sample."""
    e = errors(track, prefix, truth, airborne)
    e.pop("profile", None)
    tr = truth[airborne]
    m = tr[["t_s"]].merge(track, on="t_s", how="left")
    d = np.hypot(m[f"{prefix}north_m"].to_numpy(float) - tr["north_m"].to_numpy(float),
                 m[f"{prefix}east_m"].to_numpy(float) - tr["east_m"].to_numpy(float))
    d = d[np.isfinite(d)]
    e["end_h_m"] = float(d[-1]) if len(d) else float("nan")
    return e


def one_run(scenario: str, seed: int) -> dict:
    t0 = time.perf_counter()
    try:
        r = simulate(scenario, seed, gnss_hz=0.0)
    except ValidationError as exc:  # the simulator refused the truth: listed, never dropped
        return {"scenario": scenario, "seed": seed, "sim_error": str(exc)}
    res: dict = {"scenario": scenario, "seed": seed, "sim_time_s": time.perf_counter() - t0,
                 "duration_s": float(r.truth["t_s"].iloc[-1])}
    truth = r.truth
    airborne = ~truth["on_ground"].to_numpy(bool)
    levels = forecast(scenario, seed, truth)
    meta0 = replace(r.meta, arrival=None)
    settings = JointSettings(noise=noise_from_sensors(r.sensor_truth))
    for case, meta in (("", meta0), ("_wind", replace(meta0, wind_aloft=levels))):
        clean = clean_flight(Flight(data=r.log, meta=meta))
        t1 = time.perf_counter()
        j = run_joint(clean, settings=settings)
        res[f"joint{case}_time_s"] = time.perf_counter() - t1
        res[f"joint{case}"] = _err(j.track, "joint_", truth, airborne)
        res[f"joint{case}_converged"] = bool(j.summary["converged"])
        wp = j.summary.get("wind_prior")
        if wp is not None:
            res["wind_prior_pseudo_measurements"] = wp["pseudo_measurements"]
        d = dead_reckoning(clean)
        res[f"dr{case}"] = _err(d, "", truth, airborne)
        res[f"dr{case}_wind_source"] = d.attrs.get("wind")
    print(f"{scenario} seed {seed}: joint {res['joint']['rms_h_m']:.0f} m, with prior "
          f"{res['joint_wind']['rms_h_m']:.0f} m; DR {res['dr']['rms_h_m']:.0f} m, with wind "
          f"{res['dr_wind']['rms_h_m']:.0f} m ({time.perf_counter() - t0:.0f} s)",
          file=sys.stderr)
    return res


def gmean(x) -> float:
    x = np.asarray(x, float)
    return float(np.exp(np.mean(np.log(x))))


def summarise(rows: list[dict]) -> str:
    refused = [r for r in rows if "sim_error" in r]
    rows = [r for r in rows if "sim_error" not in r]
    sc = rows[0]["scenario"]
    cols = (("joint", "joint, no wind prior"), ("joint_wind", "joint + winds-aloft prior"),
            ("dr", "DR, no wind"), ("dr_wind", "DR + forecast wind"))
    lines = [f"### {sc}, departure only, forecast 1.5 m/s and 8 deg off ({len(rows)} seeds)", "",
             "Horizontal RMS error over the airborne part [m] (error at the last airborne "
             "sample [m]); joint runtime with the prior [s].", "",
             "| seed | duration [s] | " + " | ".join(c[1] for c in cols)
             + " | prior pseudo-meas. | joint+prior / DR no wind | runtime [s] |",
             "|---|---|" + "---|" * len(cols) + "---|---|---|"]
    for r in rows:
        lines.append(f"| {r['seed']} | {r['duration_s']:.0f} | " + " | ".join(
            f"{r[c]['rms_h_m']:.0f} ({r[c]['end_h_m']:.0f})" for c, _ in cols)
            + f" | {r.get('wind_prior_pseudo_measurements', 0)} | "
            f"{r['joint_wind']['rms_h_m'] / r['dr']['rms_h_m']:.2f} | "
            f"{r['joint_wind_time_s']:.1f} |")
    med = {c: float(np.median([r[c]["rms_h_m"] for r in rows])) for c, _ in cols}
    lines.append("| median | | " + " | ".join(f"{med[c]:.0f}" for c, _ in cols) + " | | | |")

    def ratio(a, b):
        return [r[a]["rms_h_m"] / r[b]["rms_h_m"] for r in rows]

    lines += ["", "| comparison (RMS ratio per seed) | geometric mean | max | seeds below 1 | "
              "seeds at most 0.5 |", "|---|---|---|---|---|"]
    for name, rr in (("joint + prior / DR without wind", ratio("joint_wind", "dr")),
                     ("joint + prior / joint without prior", ratio("joint_wind", "joint")),
                     ("joint without prior / DR without wind", ratio("joint", "dr")),
                     ("DR + forecast / DR without wind", ratio("dr_wind", "dr"))):
        lines.append(f"| {name} | {gmean(rr):.2f} | {np.max(rr):.2f} | "
                     f"{sum(x < 1 for x in rr)}/{len(rr)} | {sum(x <= 0.5 for x in rr)}/"
                     f"{len(rr)} |")
    conv = sum(r["joint_wind_converged"] for r in rows)
    lines += ["", f"Joint with the prior converged on {conv}/{len(rows)} runs; mean runtime per "
              f"joint run {np.mean([r['joint_wind_time_s'] for r in rows]):.1f} s, per simulated "
              f"flight {np.mean([r['sim_time_s'] for r in rows]):.1f} s."]
    if refused:
        lines += ["", "Seeds without a flight (the simulator refused its truth; not counted "
                  "above):", ""] + [f"* {r['seed']}: {r['sim_error']}" for r in refused]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--scenario", choices=SCENARIOS, default="jsbsim-circuit")
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--no-write", action="store_true")
    ap.add_argument("--summarise", type=Path, help="table only, from a runs JSON")
    a = ap.parse_args()
    stem = "wind_prior_" + a.scenario.replace("jsbsim-", "jsbsim_")
    runs_path = TABLES / f"{stem}_runs.json"
    if a.summarise:
        rows = json.loads(a.summarise.read_text())
    else:
        base = 7000 + 100 * SCENARIOS.index(a.scenario)
        rows = []
        for i in range(a.runs):
            rows.append(one_run(a.scenario, base + i))
            if not a.no_write:
                TABLES.mkdir(parents=True, exist_ok=True)
                runs_path.write_text(json.dumps(rows, indent=1))
    text = summarise(rows)
    print(text)
    if not a.no_write:
        (TABLES / f"{stem}.md").write_text(header() + text + "\n")


if __name__ == "__main__":
    main()
