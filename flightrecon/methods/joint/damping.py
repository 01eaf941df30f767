"""Step-size control of the joint smoother's Gauss-Newton passes (docs/joint.md, "Filter,
smoother, iterations"): the backtracking line search on the MAP cost along the Gauss-Newton
step and, where it finds no lower cost, the Levenberg-Marquardt step (Sarkka & Svensson 2020,
"Levenberg-Marquardt and line-search extended Kalman smoothers", ICASSP, algorithms 2 and 3).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint import passes as jp
from flightrecon.methods.joint.linearisation import (
    models_about,
    pass_cost,
    pass_scalars,
    with_pseudo,
)
from flightrecon.methods.joint.state import (
    PassModels,
    PassResult,
    PassStep,
    SmootherFlight,
    SmootherState,
)

__all__ = ["full_step", "line_search", "lm_step"]


def line_search(fl: SmootherFlight, mdl: PassModels, X: np.ndarray | None,
                 start: tuple[dict[str, float], np.ndarray, np.ndarray] | None, out: PassResult,
                 r: np.ndarray, weights: np.ndarray) -> PassStep:
    """Backtracking line search along the Gauss-Newton step (Sarkka & Svensson 2020, alg. 3):
    X + alpha (X_GN - X), alpha = 1, 1/2, ... (``line_search_halvings`` times), the first
    whose MAP cost does not exceed the cost of X (``start``: its cost, residuals and rates;
    every cost under this pass's
    clock offsets, roll, noise factors).  The first pass (no iterate yet) takes the full step;
    so does every pass with ``line_search`` off (the cost is still evaluated and reported)."""
    s = fl.settings
    X_gn = out.xs
    gn_shift = float(np.max(np.abs(X_gn[:, jl.S_POS] - mdl.pnom)))
    alpha, evals, gn_cost = 1.0, 0, np.nan
    while True:
        Xc = X_gn if alpha == 1.0 or X is None else X + alpha * (X_gn - X)
        mc, Xc = models_about(fl, Xc, mdl.Cen, mdl.clock, mdl.roll)
        cost, res, rate = pass_cost(fl, mc, Xc, r, weights)
        evals += 1
        if alpha == 1.0:   # the backward pass's residuals: the undamped iterations unchanged
            res, rate = out.res, out.rate
            gn_cost = cost["cost"]
        step = PassStep(Xc, alpha, cost, mc, res, rate, evals, True, gn_shift, gn_cost)
        if (X is None or start is None or not s.line_search
                or (np.isfinite(cost["cost"]) and cost["cost"] <= start[0]["cost"])):
            return step
        if evals > s.line_search_halvings:
            # no step size lowered the cost: the iterate stays (the lowest-cost one)
            return PassStep(X, 0.0, start[0], mdl, start[1], start[2], evals, False, gn_shift,
                         gn_cost)
        del step, mc   # the rejected candidate's models go before the next one's are built
        alpha *= 0.5


def lm_step(fl: SmootherFlight, st: SmootherState, mdl: PassModels,
             start: tuple[dict[str, Any], np.ndarray, np.ndarray], r: np.ndarray
             ) -> PassStep | None:
    """Levenberg-Marquardt step when the line search failed (Sarkka & Svensson 2020, alg. 2):
    the smoothing pass with the pseudo-measurements of :func:`with_pseudo` about the iterate,
    lambda from ``lm_lambda0`` (or ten times the last one) multiplied by 10 until the cost
    does not exceed the iterate's, at most up to ``lm_lambda_max``; None if none did."""
    s = fl.settings
    assert st.X is not None and st.bufs is not None and st.weights is not None
    if st.lm_bufs is None:  # its own buffers: the plain pass's filter outputs are kept
        st.lm_bufs = tuple(np.empty_like(b) for b in st.bufs)
    xf, Pf, xp, Pp = st.lm_bufs
    assert fl.x0 is not None and fl.P0 is not None
    sd = np.sqrt(np.diag(fl.P0))
    lam, evals = max(10.0 * st.lm_lambda, s.lm_lambda0), 0
    while lam <= s.lm_lambda_max:
        sc = with_pseudo(pass_scalars(mdl, fl.T, r, st.weights), st.X, sd, lam)
        jp.forward(xf, Pf, xp, Pp, fl.x0, fl.P0, mdl.dyn, sc, mdl.geo, 0.0, st.X)
        xs = jp.backward_mean(xf, Pf, xp, Pp, mdl.dyn, sc, mdl.geo)[0]
        mc, Xc = models_about(fl, xs, mdl.Cen, mdl.clock, mdl.roll)
        cost, res, rate = pass_cost(fl, mc, Xc, r, st.weights)
        evals += 1
        if np.isfinite(cost["cost"]) and cost["cost"] <= start[0]["cost"]:
            st.lm_lambda = lam / 10.0
            return PassStep(Xc, 1.0, cost, mc, res, rate, evals, True, np.nan, np.nan, lam)
        lam *= 10.0
    return None


def full_step(step: PassStep) -> bool:  # the accepted iterate is the pass's own smoothed states
    return step.ok and step.alpha == 1.0 and step.lm_lambda == 0.0
