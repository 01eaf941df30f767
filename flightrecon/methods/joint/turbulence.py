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

import numpy as np

from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.settings import JointNoise


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
