"""The gust state's standard deviation estimated from the flight (docs/joint.md, "Wind and
turbulence").

The gust ``u`` (layout: ``S_GUST``) is a stationary first-order Gauss-Markov process of variance
sigma_u^2 per axis. Under the model, the smoothed mean and variance of every sample satisfy
E[u_hat^2 + var(u | data)] = sigma_u^2 (law of total variance), so

    sigma_u^2 <- mean over the airborne steps and both axes of (u_hat_k^2 + P_uu,k)

is a fixed point at the flight's own gust variance: with sigma_u too large the data shrink u_hat
and its variance below it, too small they push them above. It is the moment form of the
expectation-maximisation update of a stationary variance; with ``JointSettings.estimate_gust``
the smoother applies it after each pass that computed the smoothed covariances and is not the
last (:func:`gust_update`), over-relaxed (twice the step in log space), while the pass moved the
track by more than 10 ``converge_m`` or the noise factors are estimated too, until it moves by
less than ``gust_tol`` (at most ``gust_rounds`` changes): it follows the Gauss-Newton passes and
adds none of its own where the track is already pinned down (GNSS). A change is a new cost
function, and the pass after it says so (``parameters_changed``). What the gust absorbs besides
the turbulence (the sideslip, the angle of attack in turns, the airspeed lag) counts into the
estimate: it is the air data's effective disagreement with a steady wind.
"""

from __future__ import annotations

from dataclasses import replace
from typing import TYPE_CHECKING

import numpy as np

from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.nominal import _q_vector
from flightrecon.methods.joint.settings import JointNoise

if TYPE_CHECKING:
    from flightrecon.methods.joint.linearisation import _Flight
    from flightrecon.methods.joint.smoother import _Pass, _State


def gust_decay(dt: np.ndarray, tas_mps: np.ndarray, nz: JointNoise,
               min_airspeed_mps: float) -> np.ndarray:
    """Decay of the gust state over each step, a_k = exp(-V_k dt_k / L) (docs/joint.md, "Wind
    and turbulence").

    The gust is a first-order Gauss-Markov process in the distance flown (the frozen-turbulence
    view of the Dryden model: correlation length L = ``nz.gust_length_m``), so its correlation
    time is L / V with V the recorded airspeed at the step, held at ``min_airspeed_mps`` where
    it is lower or missing (on the ground the gust then decorrelates within seconds and no air
    data are used there).
    """
    v = np.where(np.isfinite(tas_mps), tas_mps, 0.0)
    v = np.maximum(v, min_airspeed_mps)
    return np.exp(-np.asarray(dt, float) * v / nz.gust_length_m)


def gust_sd_estimate(xs: np.ndarray, var: np.ndarray, airborne: np.ndarray) -> float | None:
    """sqrt(mean(u_hat^2 + P_uu)) over the steps ``airborne`` and both gust axes (module
    docstring); None without such a step or with a non-finite value.

    Parameters
    ----------
    xs, var : (N, n) smoothed states and their variances.
    airborne : (N,) bool, the steps whose air data the smoother uses.
    """
    if not airborne.any():
        return None
    m = float(np.mean(xs[airborne, jl.S_GUST] ** 2 + var[airborne, jl.S_GUST]))
    return float(np.sqrt(m)) if np.isfinite(m) and m > 0 else None


def set_gust_sd(fl: _Flight, sd_mps: float) -> None:
    """Give the flight's models the gust sd ``sd_mps`` in place: the settings, the process
    noise and the prior of x_0 (the rest of the prior, its mean included, unchanged)."""
    noise = replace(fl.settings.noise, gust_mps=float(sd_mps))
    fl.settings, fl.q = replace(fl.settings, noise=noise), _q_vector(noise)
    if fl.P0 is not None:
        fl.P0 = fl.P0.copy()
        fl.P0[jl.S_GUST, jl.S_GUST] = np.eye(2) * float(sd_mps) ** 2
        fl.P0inv = np.linalg.inv(fl.P0)


def gust_update(fl: _Flight, st: _State, out: _Pass, X: np.ndarray, it: int) -> bool:
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
