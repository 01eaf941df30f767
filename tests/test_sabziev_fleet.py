"""The fleet-coefficient path on an accident flight (issue #37, docs/sabziev.md "Fleet k").

A store is filled by routine JSBSim circuits of the c172p airframe (boundary-value fits of the
stable policy, as ``reconstruct --store`` records them); a spiral dive of the same airframe to
ground impact is then reconstructed **without an arrival point** through the fleet path
(:func:`flightrecon.pipeline.run.fleet_settings`, the function behind
``--use-fleet-coefficients``, and :func:`flightrecon.pipeline.run.reconstruct_clean`).  The
Sabziev track must be finite and healthy, and its error against the truth is measured.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import replace

import numpy as np
import pytest

pytest.importorskip("jsbsim")

CIRCUIT_SEEDS = (1, 2, 3)
SPIRAL_SEED = 1


def _flight(scenario: str, seed: int):
    from flightrecon.cleaning import clean_flight
    from flightrecon.geo.frames import msl_to_ellipsoid, output_plane
    from flightrecon.sim import simulate
    from flightrecon.types import Flight

    sim = simulate(scenario, seed)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        clean = clean_flight(Flight(data=sim.log, meta=sim.meta))
    tr = sim.truth
    plane = output_plane(clean.meta)
    e, n, _ = plane.forward(tr["lat_deg"].to_numpy(), tr["lon_deg"].to_numpy(),
                            tr["alt_m"].to_numpy())
    up = tr["alt_m"].to_numpy() - msl_to_ellipsoid(clean.meta.departure.elev_m,
                                                   clean.meta.geoid_undulation_m)
    t = clean.grid["t_s"].to_numpy(float)
    truth = np.column_stack([np.interp(t, tr["t_s"], x, left=np.nan, right=np.nan)
                             for x in (n, e, up)])
    return clean, truth


def test_spiral_without_arrival_from_a_store_of_circuits(tmp_path):
    from flightrecon.methods.baselines import dead_reckoning
    from flightrecon.methods.sabziev.method import run_sabziev
    from flightrecon.pipeline import ReconstructSettings
    from flightrecon.pipeline.run import fleet_settings, reconstruct_clean
    from flightrecon.store import CoefficientStore, from_sabziev_summary

    store = tmp_path / "fleet.sqlite"
    with CoefficientStore(store) as st:
        for seed in CIRCUIT_SEEDS:
            clean, _ = _flight("jsbsim-circuit", seed)
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                res = run_sabziev(clean)
            assert res.summary["mode"] == "boundary-value" and res.summary["healthy"]
            st.record(from_sabziev_summary(res.summary, aircraft_id="C172P-1",
                                           flight_id=f"circuit-{seed}",
                                           flight_date_utc=f"2026-11-0{seed}T10:00:00Z"))
    clean, truth = _flight("jsbsim-spiral", SPIRAL_SEED)
    clean = replace(clean, meta=replace(clean.meta, arrival=None, aircraft_id="C172P-1"))
    settings, info = fleet_settings(ReconstructSettings(methods=("sabziev",)), store,
                                    "C172P-1")
    # the vertical root is found on every circuit: its loop frequency is averaged; an axis
    # with fewer than two stable-branch roots takes the fixed stable coefficient
    assert info["flights"][1] == len(CIRCUIT_SEEDS) and info["k"][1] < 0
    assert settings.k is not None and settings.k_sd is not None
    assert all((k is None) == (f"k{i + 1}" in info["k_default_axes"])
               for i, k in enumerate(info["k"]))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        _track, results, status = reconstruct_clean(clean, settings, workers=1)
    res = results["sabziev"]
    assert res.summary["mode"] == "initial-value"
    assert status["sabziev"]["status"] == "ok", status["sabziev"]
    t0, t1 = res.summary["interval_s"]
    t = clean.grid["t_s"].to_numpy(float)
    sl = (t >= t0) & (t <= t1)
    tr = res.track
    pos = np.column_stack([tr[f"sabziev_{a}_m"].to_numpy(float)[sl]
                           for a in ("north", "east", "up")])
    assert np.all(np.isfinite(pos))
    for c in ("sabziev_north_sd_m", "sabziev_east_sd_m"):
        assert np.all(tr[c].to_numpy(float)[sl] > 0)
    ok = np.all(np.isfinite(truth[sl]), axis=1)
    hor = math.sqrt(np.mean(np.sum((pos[ok, :2] - truth[sl][ok, :2]) ** 2, axis=1)))
    up = math.sqrt(np.mean((pos[ok, 2] - truth[sl][ok, 2]) ** 2))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        dr = dead_reckoning(clean)
    drp = dr[["north_m", "east_m"]].to_numpy(float)[sl][ok]
    hor_dr = math.sqrt(np.mean(np.sum((drp - truth[sl][ok, :2]) ** 2, axis=1)))
    print(f"spiral s{SPIRAL_SEED}, fleet k {info['k']}: horizontal RMS {hor:.0f} m (dead "
          f"reckoning {hor_dr:.0f} m), vertical RMS {up:.1f} m")
    # measured (docs/sabziev.md, "Fleet k"): 0.71-1.03 times dead reckoning without an end
    # correction on the three spirals and three spins with a fleet of eight routine flights;
    # 1.25 leaves room for the smaller fleet here without accepting a track worse than the
    # simplest baseline by more than a quarter
    assert hor <= 1.25 * hor_dr
    # vertical: 1.7-8.1 m RMS on the spirals and spins; 30 m would be a loop gone wrong
    assert up < 30.0
