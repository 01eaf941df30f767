"""Noise estimation of the joint smoother: variance-component scales of each noise group from
the normalised smoothed residuals."""

from __future__ import annotations

from typing import Any

import numpy as np

from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.layout import Measurements
from flightrecon.methods.joint.settings import SOURCES, JointSettings

NOISE_GROUPS = {("air", jl.TAS): "air_tas", ("air", jl.HEADING): "air_heading",
                ("baro", jl.BARO): "baro", ("gnss_pos", jl.NED_POS): "gnss_pos",
                ("gnss_vel", jl.STATE): "gnss_vel", ("radar", jl.RANGE): "radar_range",
                ("radar", jl.AZIMUTH): "radar_azimuth", ("radar", jl.ELEVATION): "radar_elevation",
                ("doppler", jl.DOPPLER): "doppler_speed", ("doppler", jl.TRACK): "doppler_track"}
"""Sensor error variances that ``estimate_noise`` scales, one factor per group (the end points,
ground and runway constraints and the sparse recorded wind are priors, not estimated)."""


def noise_groups(meas: Measurements) -> np.ndarray:
    """Index into NOISE_GROUPS of each measurement, -1 where its variance is not estimated."""
    g = np.full(len(meas.z), -1, dtype=np.int64)
    for i, (src, mt) in enumerate(NOISE_GROUPS):
        g[(meas.source == SOURCES.index(src)) & (meas.mtype == mt)] = i
    return g


def innovation_loglik(innov: np.ndarray, innov_var: np.ndarray, sel: np.ndarray) -> float:
    """Log-likelihood of the data by the prediction-error decomposition,
    ``-1/2 sum_j (nu_j^2 / S_j + ln(2 pi S_j))`` over the selected scalar innovations ``nu``
    with their variances ``S`` (the exact likelihood of the linearised model for the given
    noise; Harvey 1989, section 3.4)."""
    ok = sel & np.isfinite(innov) & np.isfinite(innov_var) & (innov_var > 0)
    if not ok.any():
        return float("nan")
    s = innov_var[ok]
    return float(-0.5 * np.sum(innov[ok] ** 2 / s + np.log(2.0 * np.pi * s)))


def _em_noise_scales(groups, res, hph, r0, use, min_count: int = 30) -> dict[int, float]:
    """M-step of expectation-maximisation for one variance factor c per group.

    With z_j = h_j(x) + v_j, v_j ~ N(0, c R0_j), the expected complete-data log-likelihood under
    the smoothed posterior is maximised by c = mean_j[(e_j^2 + H_j P_s H_j^T) / R0_j] over the
    group's measurements (e: smoothed residual; Shumway & Stoffer 1982, eq. 12 for a scalar
    factor; linearised at the smoothed trajectory).  Groups with fewer than ``min_count``
    measurements keep their factor.
    """
    out = {}
    for gi in np.unique(groups[groups >= 0]):
        sel = (groups == gi) & use & np.isfinite(res) & np.isfinite(hph)
        if sel.sum() >= min_count:
            out[int(gi)] = float(np.mean((res[sel] ** 2 + hph[sel]) / r0[sel]))
    return out


def noise_update(groups: np.ndarray, hph: np.ndarray, r0: np.ndarray, res: np.ndarray,
                  use: np.ndarray, scale: np.ndarray, settings: JointSettings,
                  info: dict[str, Any]) -> tuple[np.ndarray, bool]:
    """EM step of the noise factors (:func:`_em_noise_scales`) on the measurements taken at
    face value (``use``), bounded by ``noise_factor_bounds``; the new factors into ``info``.
    Returns them and whether any moved by more than ``noise_tol``."""
    new_scale = scale.copy()
    lo_b, hi_b = settings.noise_factor_bounds
    for gi, c in _em_noise_scales(groups, res, hph, r0, use).items():
        new_scale[gi] = min(max(c, lo_b), hi_b)   # bounded: no runaway factor
    moved = bool(np.any(np.abs(new_scale / scale - 1.0) > settings.noise_tol))
    info["noise_scale"] = {name: float(new_scale[i]) for i, name in enumerate(NOISE_GROUPS.values())
                           if np.any(groups == i)}
    return new_scale, moved
