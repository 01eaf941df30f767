"""The gust sd re-estimated between the joint smoother's passes (docs/joint.md, "Turbulence"):
from a pass's smoothed gust states (:func:`~flightrecon.methods.joint.turbulence.gust_sd_estimate`)
into the flight's models for the next pass."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.nominal import q_vector
from flightrecon.methods.joint.state import PassResult, SmootherFlight, SmootherState
from flightrecon.methods.joint.turbulence import gust_sd_estimate


def set_gust_sd(fl: SmootherFlight, sd_mps: float) -> None:
    """Give the flight's models the gust sd ``sd_mps`` in place: the settings, the process
    noise and the prior of x_0 (the rest of the prior, its mean included, unchanged)."""
    noise = replace(fl.settings.noise, gust_mps=float(sd_mps))
    fl.settings, fl.q = replace(fl.settings, noise=noise), q_vector(noise)
    if fl.P0 is not None:
        fl.P0 = fl.P0.copy()
        fl.P0[jl.S_GUST, jl.S_GUST] = np.eye(2) * float(sd_mps) ** 2
        fl.P0inv = np.linalg.inv(fl.P0)


def gust_update(fl: SmootherFlight, st: SmootherState, out: PassResult, X: np.ndarray,
                it: int) -> bool:
    """The gust sd re-estimated from the pass's smoothed track ``X`` (``estimate_gust``;
    :func:`gust_sd_estimate`), recorded in
    ``st.gust_rounds``; where it moved by more than ``gust_tol`` the flight's models take it
    (``fl`` updated in place) and the next pass starts with new models and a new cost.  At
    most ``gust_rounds`` changes.  Returns whether it changed."""
    s = fl.settings
    changes = sum(r["changed"] for r in st.gust_rounds)
    if not s.estimate_gust or out.var is None or changes >= s.gust_rounds:
        return False
    tas = fl.inp.tas[fl.idx]
    est = gust_sd_estimate(X, out.var, np.isfinite(tas) & (tas >= s.min_airspeed_mps))
    if est is None:
        return False
    used = s.noise.gust_mps
    moved = abs(est / used - 1.0) > s.gust_tol
    # over-relaxed in log space (twice the EM step: sd^2 / used): the plain update converges
    # linearly at a rate of 0.55-0.75 here (7 rounds from 2 to 0.54 m/s on the 10-hour
    # benchmark flight); twice the step converges for any rate in (0, 1), at |2 rate - 1|
    nxt = float(np.clip(est * est / used, *s.gust_bounds_mps))
    st.gust_rounds.append({"pass": it, "gust_mps": used, "estimate_mps": est,
                           "next_mps": nxt, "changed": bool(moved)})
    if moved:
        set_gust_sd(fl, nxt)
        st.models, st.cost, st.refit = None, None, True
    return moved
