"""Damped iterations of the joint smoother on its MAP cost (docs/joint.md, "Filter, smoother,
iterations"; flightrecon/methods/joint/cost.py).

* the compiled cost against a plain Python evaluation of the same formula;
* the robust loss against the IRLS weights the smoother uses (majorise-minimise);
* the cost per pass never rises (point-mass and JSBSim flights);
* a JSBSim flight whose undamped iterations did not converge now converges (and the undamped
  ones still do not: the test would not pass on the old iterations);
* non-convergence comes with its reason.
"""

from dataclasses import replace

import numpy as np
import pytest
from _scripts import load_script

from flightrecon.cleaning import clean_flight
from flightrecon.methods.joint import JointSettings
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint import linearisation as lin
from flightrecon.methods.joint import solve as sm
from flightrecon.methods.joint import solve as upd
from flightrecon.methods.joint.method import run_joint
from flightrecon.methods.joint.model import (
    add_process_noise,
    map_cost,
    measure_into,
    robust_loss,
    transition_into,
)
from flightrecon.methods.joint.problem import joint_inputs, problem_of
from flightrecon.types import Flight

mc = load_script("mc_joint")


@pytest.fixture(scope="module")
def recorder_flight():
    r = mc.make_flight("recorder", 1001)
    return r, clean_flight(Flight(data=r.log, meta=r.meta))


def _reference_cost(X, x0, P0inv, dyn, sc, geo, step, c, c_rej):
    """J(X) of flightrecon/methods/joint/cost.py written out with numpy: the transition and
    process noise from their own functions, a dense solve per step, h(x) per measurement."""
    d = X[0] - x0
    prior = 0.5 * d @ P0inv @ d
    process = 0.0
    eps64 = 64 * np.finfo(float).eps
    for k in range(1, len(X)):
        F = np.empty((jl.N_STATE, jl.N_STATE))
        transition_into(F, k, dyn.dt, dyn.Cen, dyn.Cnb, dyn.Csf, dyn.Jatt, dyn.acc, dyn.q[4],
                        dyn.dz, dyn.ga)
        xp = F @ X[k - 1]
        xp[:3] += dyn.Cen[k - 1] @ dyn.dP[k]
        xp[3:6] += dyn.dV[k]
        Q = np.zeros((jl.N_STATE, jl.N_STATE))
        add_process_noise(Q, k, dyn.dt, dyn.Cen, dyn.dz, dyn.qv_extra, dyn.q, dyn.ga)
        e = X[k] - xp
        act = (np.diag(Q) > (eps64 * (np.abs(X[k]) + np.abs(xp))) ** 2) & (np.diag(Q) > 0)
        if act.any():
            process += 0.5 * e[act] @ np.linalg.solve(Q[np.ix_(act, act)], e[act])
    data = 0.0
    for j in range(len(sc.z)):
        k = int(step[j])
        hx = measure_into(np.empty(jl.N_STATE), j, k, X[k], sc.mtype, sc.z, sc.tau, sc.H, sc.row,
                          sc.d, dyn.Cen, geo.pnom, geo.hnom, geo.pst, geo.Cst)
        r = sc.z[j] - hx
        if sc.mtype[j] in jl.ANGLE_TYPES:
            r = (r + np.pi) % (2 * np.pi) - np.pi
        a = abs(r / np.sqrt(sc.r[j]))
        data += (0.5 * a * a if a <= c else c * a - 0.5 * c * c if a <= c_rej
                 else c * c_rej - 0.5 * c * c)
    return prior, process, data


def test_cost_kernel_matches_the_python_formula(recorder_flight):
    """The compiled MAP cost equals the formula evaluated in numpy (relative 1e-9: the two
    sum the same terms in another order) on a smoothed track perturbed so that residuals fall
    in all three branches of the robust loss (quadratic, linear, constant)."""
    r, clean = recorder_flight
    s = JointSettings(noise=mc.noise_from_sensors(r.sensor_truth), iterations=2)
    inp = joint_inputs(clean)
    problem = problem_of(inp, s)
    run = sm.smooth_joint(problem)
    assert problem.flight is not None and run.prior is not None
    # (the flight with the run's prior of x_0: models_about gives the candidate's cost too)
    fl = replace(problem.flight, x0=run.prior[0], P0inv=np.linalg.inv(run.prior[1]))
    assert len(run.meas.z) == len(run.weights)
    at = lin.models_at(fl, lin.Nominal(run.lat_deg, run.lon_deg, run.h_m, run.x[:, jl.S_VEL]),
                       {"gnss": 0.0, "radar": 0.0}, run.roll)
    mdl, X, _ = lin.models_about(fl, run.x, at, run.meas.r, run.weights)
    assert len(mdl.meas.z) == len(run.meas.z)
    rng = np.random.default_rng(3)
    Xp = X.copy()
    Xp[:, jl.S_POS] += np.cumsum(rng.normal(0.0, 3.0, (len(X), 3)), axis=0)
    Xp[:, jl.S_VEL] += rng.normal(0.0, 0.3, (len(X), 3))
    Xp[:, jl.IPSI] += 0.01
    x0 = X[0] + rng.normal(0.0, 1.0, jl.N_STATE) * 1e-3
    P0inv = np.diag(1.0 / (np.arange(1, jl.N_STATE + 1) * 1e-3) ** 2)
    sc = mdl.scalars
    prior, process, data, const, res, rate, n_fail = map_cost(
        Xp, x0, P0inv, mdl.dyn, sc, mdl.geo, s.huber_c, s.reject_c, True)
    ref = _reference_cost(Xp, x0, P0inv, mdl.dyn, sc, mdl.geo, mdl.meas.step, s.huber_c,
                          s.reject_c)
    u = np.abs(res / np.sqrt(mdl.meas.r))
    assert (u < s.huber_c).sum() > 100 and ((u > s.huber_c) & (u < s.reject_c)).sum() > 10
    assert (u > s.reject_c).sum() > 10
    np.testing.assert_allclose([prior, process, data], ref, rtol=1e-9)
    assert n_fail == 0
    # the scale errors and attitude biases have no process noise: perturbed they stay constant
    assert const < 1e-9


def test_robust_loss_is_majorised_by_the_irls_weights():
    """IRLS is a majorise-minimise step on the MAP cost: for every u0 the weighted quadratic
    w(u0) u^2 / 2 + (rho(u0) - w(u0) u0^2 / 2), with w from the smoother's weight rule, lies
    on or above rho(u) everywhere (Lange, Hunter & Yang 2000)."""
    s = JointSettings()
    u = np.linspace(-20.0, 20.0, 4001)
    rho = np.array([robust_loss(v, s.huber_c, s.reject_c, True) for v in u])
    for u0 in (0.5, 2.9, 3.1, 5.0, 7.9, 8.5, 15.0):
        w = upd.robust_weights(np.array([u0]), np.ones(1), s)[0]
        rho0 = robust_loss(u0, s.huber_c, s.reject_c, True)
        maj = w * u ** 2 / 2 + (rho0 - w * u0 ** 2 / 2)
        # (beyond reject_c the rule keeps a weight of 1e-8: a majoriser up to 1e-8 u0^2 / 2)
        assert np.all(maj >= rho - 1e-8 * u0 ** 2 / 2 - 1e-12), u0
    assert robust_loss(100.0, s.huber_c, s.reject_c, False) == 0.5 * 100.0 ** 2


def _assert_cost_never_rises(summary):
    """Within each pass the accepted iterate's cost is at most the pass's start; from pass
    to pass the start is the last accepted cost where the take-off roll, clock offsets and
    noise factors stayed (otherwise the measurement set, so the cost, changed)."""
    its = summary["iterations"]
    for a, b in zip(its, its[1:]):
        assert b["cost"] <= b["cost_start"], b
        if not b["parameters_changed"]:
            assert b["cost_start"] <= a["cost"] * (1 + 1e-9), (a, b)


def test_cost_never_rises_on_the_point_mass_recorder_case(recorder_flight):
    r, clean = recorder_flight
    j = run_joint(clean, settings=JointSettings(noise=mc.noise_from_sensors(r.sensor_truth)))
    assert j.summary["converged"], j.summary["stop_reason"]
    _assert_cost_never_rises(j.summary)


@pytest.fixture(scope="module")
def spin_flight():
    pytest.importorskip("jsbsim")
    from flightrecon.sim import simulate

    r = simulate("jsbsim-spin", 5402, gnss_hz=0.0)
    return r, clean_flight(Flight(data=r.log, meta=r.meta))


def test_jsbsim_spin_converges_damped_and_not_undamped(spin_flight):
    """jsbsim-spin seed 5402 (docs/tables/jsbsim_mc.md), recorder only with the wreckage as
    the last position, the turbulence left unmodelled (a gust sd of 1 mm/s: the model before
    the gust state, whose air data then disagree with the flight by metres per second): the
    undamped iterations (full Gauss-Newton steps, innovation gate in every pass) end after 12
    passes still moving the track (5.3 km RMS); damped on the MAP cost they converge, the cost
    never rises, and the error is 2.1 km.  Bounds: 3 km and 0.6 x the undamped error, both
    failed by the undamped iterations.  Guards the damping on a badly specified model."""
    r, clean = spin_flight
    noise = replace(mc.noise_from_sensors(r.sensor_truth), gust_mps=1e-3)
    base = JointSettings(noise=noise)
    airborne = ~r.truth["on_ground"].to_numpy(bool)
    airborne[-1] = True
    old = run_joint(clean, settings=replace(base, line_search=False, first_pass="ekf",
                                            gate_damped=True, iterations=12))
    assert not old.summary["converged"]
    assert old.summary["stop_reason"].startswith("max passes reached")
    new = run_joint(clean, settings=base)
    s = new.summary
    assert s["converged"], s["stop_reason"]
    _assert_cost_never_rises(s)
    e_old = mc.errors(old.track, "joint_", r.truth, airborne)["rms_h_m"]
    e_new = mc.errors(new.track, "joint_", r.truth, airborne)["rms_h_m"]
    assert e_new < 0.6 * e_old and e_new < 3000.0, (e_new, e_old)


def test_non_convergence_is_reported_with_its_reason(recorder_flight):
    r, clean = recorder_flight
    j = run_joint(clean, settings=JointSettings(noise=mc.noise_from_sensors(r.sensor_truth),
                                                iterations=2))
    assert not j.summary["converged"]
    assert j.summary["stop_reason"].startswith("max passes reached (2)")
    assert any("not converged after 2 passes" in w for w in j.summary["warnings"])


def test_a_take_off_roll_cycling_among_three_values_settles(recorder_flight, monkeypatch):
    """Guards the outer loop: the take-off roll refined on each pass's iterate can cycle
    (the fleet study's accident flight of JSBSim seed 0 went round three rolls for 50 passes
    and was reported not converged, 1.9 km off). A roll back at one of an earlier pass is not
    taken, so the roll settles and the passes converge; refined_roll is replaced here by one
    that goes round three roll starts 1 s apart."""
    _, clean = recorder_flight
    calls = []

    def cycling(inp, T, vnom, ba=None):
        roll = inp.roll
        calls.append(1)
        return replace(roll, start_t=roll.start_t + float(len(calls) % 3))

    monkeypatch.setattr(sm, "refined_roll", cycling)
    res = run_joint(clean)
    starts = [it["roll_start_t_s"] for it in res.summary["iterations"]]
    assert res.summary["converged"], res.summary["stop_reason"]
    assert len(set(starts[-3:])) == 1           # settled on one roll
    assert len(set(starts)) <= 3
