"""Truth-consistent synthetic flights for the Sabziev tests (and checks of the generator itself).

The other ``test_sabziev_*`` files import :func:`synthetic_flight` from here.  The flight is
built from smooth analytic truth: height ``y = H sin^2(pi t / T)``, true airspeed ``V``, heading
``psi(t) = psi0 + A sin(2 pi t / (T/3))``, constant wind; the ground velocity is the air
velocity (horizontal part ``sqrt(V^2 - y'^2)``) plus the wind, and the accelerations are its
exact derivatives.  Sensor errors (biases, scale factor, noise) are added on request.
"""

from __future__ import annotations

import numpy as np
from scipy.integrate import cumulative_simpson


def synthetic_flight(T: float = 3600.0, rate_hz: float = 16.0, seed: int = 0, *,
                     H: float = 3000.0, V: float = 120.0, wind_ne=(8.0, -5.0),
                     acc_bias=(0.003, -0.002, 0.004), acc_noise: float = 0.02,
                     baro_bias: float = 5.0, baro_noise: float = 2.0,
                     tas_scale: float = 0.99, tas_noise: float = 0.3,
                     hdg_bias_deg: float = 0.5) -> dict:
    """Inputs and truth of a synthetic flight on a uniform grid (module docstring).

    Returns a dict with ``t`` (N,), ``a_ned`` (N, 3), ``tas``, ``hdg`` [rad], ``h`` (baro height
    relative to lift-off), ``v0`` (NED at lift-off), ``end`` (NED end point), ``wind`` (N, 2),
    ``truth`` (N, 3) as [north, up, east] and ``truth_v`` (N, 3) likewise.
    """
    rng = np.random.default_rng(seed)
    n = round(T * rate_hz) + 1
    t = np.arange(n) / rate_hz
    w1 = np.pi / T
    y = H * np.sin(w1 * t) ** 2
    yd = H * w1 * np.sin(2 * w1 * t)
    ydd = 2 * H * w1**2 * np.cos(2 * w1 * t)
    Th = T / 3.0
    psi = 0.3 + 1.5 * np.sin(2 * np.pi * t / Th)
    psid = 1.5 * 2 * np.pi / Th * np.cos(2 * np.pi * t / Th)
    vh = np.sqrt(V**2 - yd**2)
    vhd = -yd * ydd / vh
    vn = vh * np.cos(psi) + wind_ne[0]
    ve = vh * np.sin(psi) + wind_ne[1]
    an = vhd * np.cos(psi) - vh * np.sin(psi) * psid
    ae = vhd * np.sin(psi) + vh * np.cos(psi) * psid
    north = cumulative_simpson(vn, x=t, initial=0.0)
    east = cumulative_simpson(ve, x=t, initial=0.0)
    a_ned = np.column_stack([an + acc_bias[0], ae + acc_bias[1], -ydd + acc_bias[2]])
    a_ned = a_ned + acc_noise * rng.standard_normal((n, 3))
    tas = V * tas_scale + tas_noise * rng.standard_normal(n)
    h = y + baro_bias * t / T + baro_noise * rng.standard_normal(n)
    return {
        "t": t, "a_ned": a_ned, "tas": tas, "hdg": psi + np.radians(hdg_bias_deg), "h": h,
        "v0": np.array([vn[0], ve[0], -yd[0]]),
        "end": np.array([north[-1], east[-1], -y[-1]]),
        "wind": np.tile(np.asarray(wind_ne, float), (n, 1)),
        "truth": np.column_stack([north, y, east]),
        "truth_v": np.column_stack([vn, yd, ve]),
    }


def test_generator_accelerations_integrate_to_truth():
    """Guards the generator: its error-free accelerations are the derivative of its velocity.

    Finite differences of the truth velocity at 16 Hz agree with the analytic acceleration to
    O(dt^2 v''' / 6) ~ 1e-5 m/s^2 (v''' ~ V psi'^3 ~ 0.013 m/s^4); tolerance 5e-5 m/s^2.
    """
    f = synthetic_flight(T=600.0, acc_bias=(0, 0, 0), acc_noise=0.0)
    dt = f["t"][1] - f["t"][0]
    v = f["truth_v"]
    fd = (v[2:] - v[:-2]) / (2 * dt)
    a = f["a_ned"][1:-1]
    np.testing.assert_allclose(fd[:, 0], a[:, 0], atol=5e-5)
    np.testing.assert_allclose(fd[:, 1], -a[:, 2], atol=5e-5)
    np.testing.assert_allclose(fd[:, 2], a[:, 1], atol=5e-5)


def test_generator_positions_integrate_velocity():
    """The truth track is the integral of the truth velocity (Simpson, error ~1e-9 m here)."""
    f = synthetic_flight(T=600.0)
    dt = f["t"][1] - f["t"][0]
    fd = (f["truth"][2:] - f["truth"][:-2]) / (2 * dt)
    # central differences of a smooth track: O(dt^2 x''') ~ 1e-4 m/s at most here
    np.testing.assert_allclose(fd, f["truth_v"][1:-1], atol=1e-3)
