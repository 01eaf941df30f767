"""The fast paths of the Sabziev root search must not change a single result (issue #13).

The scan of :mod:`flightrecon.methods.sabziev.newton` evaluates ``F`` for all grid points of a branch in
one pass over the data (:func:`flightrecon.methods.sabziev.propagate_end_many`) and the root
finder keeps a memo of the values it has computed.  Both are exact, not approximations: every
lane of the batch performs the same floating-point operations in the same order as the single
evaluation, so the comparisons here are for *equality* (no tolerance), which is what makes
the brackets, the root picked and the reports identical to point-by-point evaluation.
"""

from __future__ import annotations

import numpy as np
import pytest
from test_sabziev_flights import synthetic_flight

from flightrecon.errors import ValidationError
from flightrecon.methods import sabziev as sz
from flightrecon.methods.sabziev import discrete as sz_discrete
from flightrecon.methods.sabziev.newton import find_coefficient

DT = 0.125


@pytest.mark.parametrize("vertical", [False, True])
@pytest.mark.parametrize("hold", ["linear", "zero"])
def test_compiled_step_rows_equal_the_step_coefficients(vertical, hold):
    """``_step_rows`` against :func:`horizontal_step` / :func:`vertical_step`, both branches,
    the series region (|k h| < 1) and the closed-form region, and k = 0: exactly equal."""
    ks = np.array([-40.0, -3.0, -0.5, -1e-3, -1e-9, 0.0, 1e-9, 1e-3, 0.5, 3.0, 40.0])
    rows = sz_discrete._step_rows(vertical, ks, DT, hold == "linear")
    step = sz.vertical_step if vertical else sz.horizontal_step
    for j, k in enumerate(ks):
        c = step(k, DT, hold)
        expect = np.concatenate([c.Phi.reshape(4), c.G0, c.G1])
        assert np.array_equal(rows[:, j], expect), (k, rows[:, j], expect)


@pytest.mark.parametrize("kind", ["horizontal", "vertical"])
def test_batched_end_points_equal_single_evaluations(kind):
    """One pass for many k gives, lane by lane, the end state and misfit of
    :func:`propagate_end`, bit for bit; lanes that overflow are non-finite in both."""
    rng = np.random.default_rng(3)
    n = 4001
    a = rng.normal(0.0, 0.3, n)
    w = 100.0 + np.cumsum(rng.normal(0.0, 0.5, n))
    T = DT * (n - 1)
    if kind == "horizontal":
        ks = np.concatenate([-np.geomspace(1e-4 / T, 1.0 / DT, 25),
                             np.geomspace(1e-4 / T, 2e3 / T, 12)])
        step = sz.horizontal_step
    else:
        ks = np.concatenate([-np.geomspace(1e-6 / T**2, (0.5 / DT) ** 2, 25),
                             np.geomspace(1e-6 / T**2, (2e3 / T) ** 2, 12)])
        step = sz.vertical_step
    with np.errstate(over="ignore", invalid="ignore"):
        q, mis = sz.propagate_end_many(kind, ks, DT, (0.0, 80.0), a, w)
        for j, k in enumerate(ks):
            q1, _, m1 = sz.propagate_end(step(k, DT), (0.0, 80.0), a, w, k)
            assert np.array_equal(q[j], q1, equal_nan=True), k
            assert mis[j] == m1 or (np.isnan(mis[j]) and np.isnan(m1)), k
    assert not np.all(np.isfinite(q[:, 0]))  # the overflow lanes were exercised
    assert sz.propagate_end_many(kind, [], DT, (0.0, 0.0), a, w)[0].shape == (0, 2)
    with pytest.raises(ValidationError):
        sz.propagate_end_many("lateral", ks, DT, (0.0, 0.0), a, w)


def _axis_problem(f, kind: str, end_shift: float = 0.0):
    """(fun, fun_many, kwargs) of one axis of a synthetic flight, as in ``_solve_axis``."""
    t = f["t"]
    dt = t[1] - t[0]
    T = t[-1] - t[0]
    if kind == "vertical":
        a, w, v0, s_T = -f["a_ned"][:, 2], f["h"], -f["v0"][2], -f["end"][2]
        kw = {"k_ref": T**-2, "k_max_pos": (sz.KT_MAX / T) ** 2, "k_max_neg": (0.5 / dt) ** 2,
              "rule": "baro"}
        step = sz.vertical_step
    else:
        vn, _ = sz.air_velocity(f["tas"], f["hdg"], f["truth_v"][:, 1], f["wind"])
        a, w, v0, s_T = f["a_ned"][:, 0], vn, f["v0"][0], f["end"][0]
        kw = {"k_ref": 1.0 / T, "k_max_pos": sz.KT_MAX / T, "k_max_neg": 1.0 / dt,
              "rule": "slowest"}
        step = sz.horizontal_step
    s_T = s_T + end_shift

    def fun(k):
        q, s, m = sz.propagate_end(step(k, dt), (0.0, v0), a, w, k)
        return float(q[0]) - s_T, float(s[0]), m

    def fun_many(ks):
        q, m = sz.propagate_end_many(kind, ks, dt, (0.0, v0), a, w)
        return q[:, 0] - s_T, m

    return fun, fun_many, kw


@pytest.mark.parametrize("kind,end_shift,branch", [
    ("vertical", 0.0, "negative"), ("horizontal", 0.0, "negative"),
    ("horizontal", 5e6, "positive"), ("horizontal", -5e5, "none")])
def test_batched_scan_and_memo_give_the_same_report(kind, end_shift, branch):
    """With the batched scan (and the memo) the report is the same as with point-by-point
    evaluation: root, residual, misfit, branch, reason, brackets and the whole Newton history
    equal; only ``evaluations`` may fall (memo hits).  Covers a converged vertical axis
    (baro rule, several brackets refined), a converged horizontal axis, one whose end point
    is reached only on the positive branch (both branches scanned), and one with an
    unreachable end point (no root: both branches scanned, the failure report
    built from the smallest |F| seen)."""
    f = synthetic_flight(T=900.0, rate_hz=8.0)
    fun, fun_many, kw = _axis_problem(f, kind, end_shift)
    slow = find_coefficient(fun, **kw)
    fast = find_coefficient(fun, fun_many=fun_many, **kw)
    for name in ("converged", "branch", "reason", "iterations", "history", "brackets", "start",
                 "overflow", "rule"):
        assert getattr(fast, name) == getattr(slow, name), name
    for name in ("root", "residual_m", "misfit_m"):
        x, y = getattr(fast, name), getattr(slow, name)
        assert x == y or (np.isnan(x) and np.isnan(y)), name
    assert fast.evaluations <= slow.evaluations
    assert slow.branch == branch


def test_memo_never_recomputes_a_derivative_evaluation():
    """Every ``(F, dF)`` evaluation is made once per ``k`` (the memo), and the reported count
    is what was made: the single evaluations plus the scan points consumed."""
    f = synthetic_flight(T=900.0, rate_hz=8.0)
    fun, fun_many, kw = _axis_problem(f, "vertical")
    calls: list[float] = []
    lanes: list[int] = []

    def counted(k):
        calls.append(k)
        return fun(k)

    def counted_many(ks):
        lanes.append(len(ks))
        return fun_many(ks)

    rep = find_coefficient(counted, fun_many=counted_many, **kw)
    assert rep.converged
    assert len(calls) == len(set(calls))
    # no branch overflows here, so every scanned point is consumed
    assert rep.evaluations == len(calls) + sum(lanes)
