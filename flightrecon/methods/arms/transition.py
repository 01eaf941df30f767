"""ADS/ARMS transition models: the exact constant-velocity and Gauss-Markov discretisations
of the track ``[x, Vx, y, Vy]`` and the air-data error ``[dVx, dVy]``, stacked over steps
(paper eqs. 7-9; :mod:`flightrecon.estimation.discretise`)."""

from __future__ import annotations

import numpy as np

from flightrecon.estimation.discretise import constant_velocity, gauss_markov


def cv_transition(dt) -> np.ndarray:
    """CV transition of ``[x, Vx, y, Vy]`` for steps ``dt`` (N,): (N, 4, 4), ``[[1, T], [0, 1]]``
    per axis (:func:`flightrecon.estimation.discretise.constant_velocity`)."""
    F1, _ = constant_velocity(dt, 0.0)
    F = np.zeros((len(F1), 4, 4))
    F[:, 0:2, 0:2] = F[:, 2:4, 2:4] = F1
    return F


def cv_process_noise(dt, q_m2ps3: float) -> np.ndarray:
    """Exact CV process noise (N, 4, 4): ``q [[T^3/3, T^2/2], [T^2/2, T]]`` per axis
    (:func:`flightrecon.estimation.discretise.constant_velocity`)."""
    _, Q1 = constant_velocity(dt, q_m2ps3)
    Q = np.zeros((len(Q1), 4, 4))
    Q[:, 0:2, 0:2] = Q[:, 2:4, 2:4] = Q1
    return Q


def gm_transition(dt, alpha_ps: float) -> np.ndarray:
    """Gauss-Markov transition of ``[dVx, dVy]`` (N, 2, 2): ``e^{-alpha T} I`` (paper eq. 9)."""
    phi, _ = gauss_markov(dt, alpha_ps, 0.0)
    return phi[:, None, None] * np.eye(2)


def gm_process_noise(dt, alpha_ps: float, sigma_mps: float) -> np.ndarray:
    """Exact Gauss-Markov process noise (N, 2, 2): ``sigma^2 (1 - e^{-2 alpha T}) I``
    (:func:`flightrecon.estimation.discretise.gauss_markov`)."""
    _, var = gauss_markov(dt, alpha_ps, sigma_mps)
    return var[:, None, None] * np.eye(2)


def joint_transition(dt, alpha_ps: float) -> np.ndarray:
    """Joint transition of ``[x, Vx, y, Vy, dVx, dVy]``: block-diag(CV, GM), (N, 6, 6)."""
    F = np.zeros((len(np.atleast_1d(dt)), 6, 6))
    F[:, 0:4, 0:4] = cv_transition(dt)
    F[:, 4, 4] = F[:, 5, 5] = gauss_markov(dt, alpha_ps, 0.0)[0]
    return F


def joint_process_noise(dt, q_m2ps3: float, alpha_ps: float, sigma_mps: float) -> np.ndarray:
    """Joint process noise: block-diag(CV, GM), (N, 6, 6)."""
    Q = np.zeros((len(np.atleast_1d(dt)), 6, 6))
    Q[:, 0:4, 0:4] = cv_process_noise(dt, q_m2ps3)
    Q[:, 4, 4] = Q[:, 5, 5] = gauss_markov(dt, alpha_ps, sigma_mps)[1]
    return Q
