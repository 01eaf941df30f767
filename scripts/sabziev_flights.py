"""Flights with truth for the Sabziev studies: the independent corpus and JSBSim flights.

:func:`corpus_flight` loads ``<shared>/corpus/c<i>-fdr.parquet`` (recorder only) with the
departure and arrival of its ``c<i>-meta.json``; :func:`jsbsim_flight` simulates a JSBSim
scenario.  Both return a :class:`TruthFlight`: the cleaned flight and the truth on the grid
(north, east in the output tangent plane; up = height above the departure airfield, geometric).
:func:`evaluate` compares a Sabziev result and the project's dead-reckoning baselines
(:func:`flightrecon.fusion.baselines.dead_reckoning`) with that truth.
"""

from __future__ import annotations

import json
import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.cleaning import clean_flight
from flightrecon.fusion.baselines import dead_reckoning
from flightrecon.geo.frames import msl_to_ellipsoid, output_plane
from flightrecon.types import CleanFlight, Flight, MethodResult, Position

SHARED = Path(os.environ.get("FLIGHTRECON_SHARED", "/work/shared"))


@dataclass
class TruthFlight:
    """A cleaned flight with its truth on the grid (module docstring)."""

    name: str
    clean: CleanFlight
    truth_neu: np.ndarray  # (N, 3) north, east, up [m] on the grid, NaN outside the truth


def _truth_neu(clean: CleanFlight, t_truth, lat, lon, alt_ell) -> np.ndarray:
    meta = clean.meta
    plane = output_plane(meta)
    e, n, _u = plane.forward(np.asarray(lat), np.asarray(lon), np.asarray(alt_ell))
    up = np.asarray(alt_ell) - msl_to_ellipsoid(meta.departure.elev_m, meta.geoid_undulation_m)
    t = clean.grid["t_s"].to_numpy(float)
    return np.column_stack([np.interp(t, t_truth, x, left=np.nan, right=np.nan)
                            for x in (np.asarray(n), np.asarray(e), up)])


def corpus_flight(i: int) -> TruthFlight:
    """Corpus flight ``c<i>`` (recorder only) with its departure and arrival (README there)."""
    from flightrecon.ingest import load_flight

    d = SHARED / "corpus"
    m = json.loads((d / f"c{i}-meta.json").read_text())
    dep, arr = (Position(*m[k]) for k in ("departure", "arrival"))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        flight = load_flight(d / f"c{i}-fdr.parquet",
                             meta_overrides={"departure": dep, "arrival": arr})
        clean = clean_flight(flight)
    tr = pd.read_parquet(d / f"c{i}-truth.parquet")
    t_epoch = 0.0  # the recorder log and the truth share their time origin
    truth = _truth_neu(clean, tr["time_s"].to_numpy(float) + t_epoch, tr["lat_deg"],
                       tr["lon_deg"], tr["alt_geod_m"])
    return TruthFlight(f"c{i} (corpus)", clean, truth)


def jsbsim_flight(scenario: str, seed: int, **overrides: Any) -> TruthFlight:
    """A JSBSim flight (``flightrecon.sim.simulate``), cleaned, with its truth."""
    from flightrecon.sim import simulate

    sim = simulate(scenario, seed, **overrides)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        clean = clean_flight(Flight(data=sim.log, meta=sim.meta))
    tr = sim.truth
    truth = _truth_neu(clean, tr["t_s"].to_numpy(float), tr["lat_deg"], tr["lon_deg"],
                       tr["alt_m"])
    scale = overrides.get("scale")
    label = scenario.removeprefix("jsbsim-") + (f" x{scale:g}" if scale else "")
    return TruthFlight(f"{label} s{seed}", clean, truth)


def _rms(x: np.ndarray) -> float:
    x = x[np.isfinite(x)]
    return float(np.sqrt(np.mean(x**2))) if len(x) else float("nan")


def evaluate(f: TruthFlight, res: MethodResult) -> dict[str, Any]:
    """Errors of a Sabziev result and of the baselines against the truth, on the fusion
    interval: horizontal RMS (``hor_rms_m``, of the horizontal distance), vertical RMS, the
    ratio to dead reckoning with a linear end correction, the end-point miss per axis."""
    s = res.summary
    t = f.clean.grid["t_s"].to_numpy(float)
    i0, i1 = (int(np.argmin(np.abs(t - x))) for x in s["interval_s"])
    sl = slice(i0, i1 + 1)
    tr = res.track
    n, e, u = (tr[f"sabziev_{a}_m"].to_numpy(float)[sl] for a in ("north", "east", "up"))
    tn, te, tu = (f.truth_neu[sl, j] for j in range(3))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        drl = dead_reckoning(f.clean, corrected=True)
        dr = dead_reckoning(f.clean)
    dn, de = drl["north_m"].to_numpy(float)[sl], drl["east_m"].to_numpy(float)[sl]
    rn, re_ = dr["north_m"].to_numpy(float)[sl], dr["east_m"].to_numpy(float)[sl]
    hor = _rms(np.hypot(n - tn, e - te))
    hor_drl = _rms(np.hypot(dn - tn, de - te))
    finite = bool(np.all(np.isfinite(n)) and np.all(np.isfinite(e)) and np.all(np.isfinite(u)))
    end = s.get("end_residual_m", {})
    miss = max((abs(v) for v in end.values() if v is not None), default=float("nan"))
    if not finite:
        miss = float("nan")
    return {
        "flight": f.name, "duration_s": float(t[i1] - t[i0]), "finite": finite,
        "hor_rms_m": hor, "hor_rms_drl_m": hor_drl, "hor_rms_dr_m": _rms(np.hypot(rn - tn,
                                                                                  re_ - te)),
        "ratio_drl": hor / hor_drl if hor_drl > 0 else float("nan"),
        "up_rms_m": _rms(u - tu), "end_miss_m": miss, "converged": bool(s.get("converged")),
        "k": [s.get("k1"), s.get("k2"), s.get("k3")],
        "roots": {a: s["axes"][a].get("branch") for a in s.get("axes", {})},
    }
