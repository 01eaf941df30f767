"""The joint smoother's checks after the solve (flightrecon/methods/joint/health.py,
``run_health``) and the track's sources column (output.py, ``provenance``): the warnings in
the order the user reads them (docs/output.md, "Method health"), the verdicts they lead to."""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from flightrecon.errors import FlightReconWarning
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.health import run_health
from flightrecon.methods.joint.output import provenance
from flightrecon.methods.joint.settings import SOURCES, JointSettings, prior_table


def _run(n: int = 200, **over) -> SimpleNamespace:
    """A stand-in for a JointRun of ``n`` one-second states, air data and pressure altitude
    measured each second, everything in order unless ``over`` says otherwise."""
    t = np.arange(float(n))
    meas = SimpleNamespace(t=np.r_[t, t], source=np.r_[np.zeros(n, int), np.ones(n, int)])
    run = dict(t=t, x=np.zeros((n, jl.N_STATE)), var=np.ones((n, jl.N_STATE)),
               P_pv=np.tile(np.eye(6), (n, 1, 1)), h_m=np.full(n, 500.0), meas=meas,
               resid_norm=np.zeros(2 * n), weights=np.ones(2 * n), innov=np.ones(2 * n),
               innov_var=np.ones(2 * n), clock_offsets_s={}, noise_check=None,
               iterations=[{"converged": True}], converged=True, stop_reason="converged",
               cholesky_fallbacks=0, gust=None, last_shift_m=None)
    return SimpleNamespace(**(run | over))


def _problem(**settings) -> SimpleNamespace:
    return SimpleNamespace(settings=JointSettings(**settings), attitude_note="the attitude note",
                           inputs=SimpleNamespace(notes=("an input note",)))


def test_a_clean_run_is_healthy_and_says_only_its_notes():
    h = run_health(_problem(), _run(), [], None, prior_table(JointSettings()))
    assert h.healthy and h.converged and not h.consistency.gross
    assert h.warnings == ["an input note", "the attitude note"]
    assert h.settling is None and h.remaining_k_m is None
    assert set(h.sources) == {"air", "baro"} and not h.sources["baro"]["flagged_inconsistent"]


def test_every_warning_in_its_order_and_the_verdicts():
    """Guards the order of the run's warnings (the summary's and the console's): the notes,
    an inconsistent source, the noise check, the noise estimation's and the passes'
    convergence, a clock offset, the gust at its bound, Cholesky fallbacks, uncalibrated GNSS
    gaps (also on the console), a gross mean NIS, an implausible sensor error, a wind faster
    than its walk; each of the last three makes the run unhealthy."""
    n = 200
    resid = np.zeros(2 * n)
    resid[n::10] = 9.0                                   # 10 % of the baro rows beyond 5 sigma
    x = np.zeros((n, jl.N_STATE))
    x[n // 2, jl.IS] = 0.9                               # airspeed scale +90 %
    x[:, jl.IW] = np.linspace(0.0, 50.0, n)              # 50 m/s of wind change in 200 s
    s = JointSettings()
    run = _run(n, resid_norm=resid, x=x, innov=np.full(2 * n, 3.0), converged=False,
               stop_reason="at the cap", iterations=[{"converged": False}],
               clock_offsets_s={"gnss": (0.8, 0.01)}, cholesky_fallbacks=2,
               noise_check={"accepted": False, "loglik_estimated": -9.0, "loglik_default": -5.0},
               gust={"rounds": [1], "sd_mps": s.gust_bounds_mps[1]})
    gaps = {"factor": None, "gaps_s": [[10.0, 40.0]], "note": "no room for a held-out stretch"}
    with pytest.warns(FlightReconWarning, match="GNSS gaps"):
        h = run_health(_problem(estimate_noise=True), run, [], gaps, prior_table(s))
    starts = ["an input note", "the attitude note", "joint: source 'baro' inconsistent",
              "joint: the estimated noise did not raise", "joint: noise estimation did not",
              "joint: not converged after 1 passes: at the cap", "joint: gnss clock offset +0.80",
              "joint: the turbulence's gust sd", "joint: on 2 steps", "joint: GNSS gaps [[10.0",
              "joint: mean NIS per measurement 9.0", "joint: tas_scale estimated at +0.9",
              "joint: the wind changed by 50"]
    assert len(h.warnings) == len(starts)
    for w, start in zip(h.warnings, starts):
        assert w.startswith(start), (w, start)
    assert not h.healthy and not h.converged and h.consistency.gross
    assert h.corrections["tas_scale"]["value"] == pytest.approx(0.9)


def test_the_sources_column_names_the_sources_within_their_window():
    """Guards the track's ``joint_sources`` against its definition: the sources with a
    measurement within 5 s of the sample (60 s for the end points), '+'-joined in the order of
    SOURCES."""
    rng = np.random.default_rng(3)
    picks = ["air", "gnss_pos", "endpoint"]
    src = np.array([SOURCES.index(p) for p in rng.choice(picks, 400)])
    tm = rng.uniform(0.0, 3000.0, 400)
    t_out = np.linspace(-100.0, 3100.0, 1601)
    got = provenance(SimpleNamespace(meas=SimpleNamespace(t=tm, source=src)), t_out)
    for i in range(0, len(t_out), 7):
        near = [name for s_i, name in enumerate(SOURCES)
                if np.any(np.abs(tm[src == s_i] - t_out[i])
                          <= (60.0 if name == "endpoint" else 5.0))]
        assert got[i] == "+".join(near)
