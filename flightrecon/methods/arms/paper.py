"""The paper's simulation setting (seed 000): Monte Carlo scenarios for the ADS/ARMS filters."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightrecon.methods.arms.inputs import ArmsModel
from flightrecon.methods.arms.measurement import wrap_angle
from flightrecon.methods.arms.transition import cv_process_noise

# --------------------------------------------------------------------------------------------
# the paper's simulation (section "Computer simulation results"), vectorised over runs
# --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class PaperScenario:
    """Simulated truth and measurements of ``M`` runs on a common 1-s time base (SI, station frame).

    Attributes
    ----------
    t_s : (N,) times
    pos, vel : (M, N, 2) true position [x, y] and ground velocity W
    dv : (M, N, 2) true air-data error (Gauss-Markov)
    range_m, azimuth_rad : (M, N) noisy plots (horizontal range, azimuth)
    air : (M, N, 2) air-data velocity V* = W + dV + white noise
    """

    t_s: np.ndarray
    pos: np.ndarray
    vel: np.ndarray
    dv: np.ndarray
    range_m: np.ndarray
    azimuth_rad: np.ndarray
    air: np.ndarray


def simulate_paper_scenario(model: ArmsModel, *, runs: int, duration_s: float = 1800.0,
                            dt_s: float = 1.0, speed_mps: float = 100.0,
                            start_xy_m: tuple[float, float] = (-60e3, 30e3),
                            track_deg: float = 90.0, seed: int = 0) -> PaperScenario:
    """The paper's simulation: nearly straight flight at ``speed_mps``, Gauss-Markov air-data
    error, noisy range/azimuth plots every ``dt_s``.

    The truth follows the filter's own models so that consistency can be tested: ground velocity
    a CV random walk of PSD ``model.q_m2ps3`` (set it small for the paper's straight flight),
    ``dV`` per axis the exact Gauss-Markov recursion started from its stationary distribution,
    plots with ``sigma_range_m``/``sigma_azimuth_rad``, ``V*`` with ``sigma_air_mps`` white noise.
    The paper gives no geometry; ``start_xy_m`` and ``track_deg`` set it (default: 67 km from the
    station, flying east, closest approach 30 km).
    """
    rng = np.random.default_rng(seed)
    N = round(duration_s / dt_s) + 1
    t = np.arange(N) * dt_s
    M = runs
    dt = np.full(N, dt_s)
    Qcv = cv_process_noise(dt[:2], model.q_m2ps3)[1][:2, :2]
    Lcv = np.linalg.cholesky(Qcv)
    Fcv = np.array([[1.0, dt_s], [0.0, 1.0]])
    phi = np.exp(-model.alpha_ps * dt_s)
    sw = model.gm_sigma_mps * np.sqrt(-np.expm1(-2.0 * model.alpha_ps * dt_s))
    trk = np.deg2rad(track_deg)
    pos = np.empty((M, N, 2))
    vel = np.empty((M, N, 2))
    dv = np.empty((M, N, 2))
    # per axis a = 0 (x, east), 1 (y, north)
    s0 = (np.array(start_xy_m), speed_mps * np.array([np.sin(trk), np.cos(trk)]))
    for a in range(2):
        st = np.empty((M, 2))
        st[:, 0] = s0[0][a]
        st[:, 1] = s0[1][a]
        g = model.gm_sigma_mps * rng.standard_normal(M)
        wn = rng.standard_normal((N, M, 2))
        wg = rng.standard_normal((N, M))
        for k in range(N):
            if k > 0:
                st = st @ Fcv.T + wn[k] @ Lcv.T
                g = phi * g + sw * wg[k]
            pos[:, k, a] = st[:, 0]
            vel[:, k, a] = st[:, 1]
            dv[:, k, a] = g
    r_true = np.hypot(pos[..., 0], pos[..., 1])
    az_true = np.arctan2(pos[..., 0], pos[..., 1])
    rng_m = r_true + model.sigma_range_m * rng.standard_normal((M, N))
    az = wrap_angle(az_true + model.sigma_azimuth_rad * rng.standard_normal((M, N)))
    air = vel + dv + model.sigma_air_mps * rng.standard_normal((M, N, 2))
    return PaperScenario(t, pos, vel, dv, rng_m, az, air)
