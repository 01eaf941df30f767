"""The attitude reference's errors after sustained loads, as extra acceleration noise of the
joint smoother (docs/joint.md, "Process noise"; docs/realflights.md, "The attitude after the
manoeuvres").

An attitude and heading reference (AHRS) erects its vertical on the accelerometers: where the
specific force is not gravity alone (a pull-up at 2 g, a zero-g parabola, a long turn) it erects
towards a wrong vertical, and after the manoeuvre it re-erects with its time constant.  A tilt
``delta`` of the recorded roll and pitch turns part of the specific force into the horizontal:
an acceleration error ``g delta`` that the smoother's constant roll and pitch biases cannot
follow.  On the PH-LAB flights (docs/realflights.md) the recorded loads integrated through the
recorded attitude leave the GPS velocity by 1-2 m/s per minute in quiet cruise, 3-12 m/s per
minute in turns and climbs (``| |f| - 1 |`` below 0.3 g), 15-39 m/s per minute in zero-g
parabolas (0.7 g) and 28, 15, 4.5 m/s in the three minutes after them: a tilt of about 3 deg
decaying with a time constant of about a minute.

The model: the load's departure from 1 g, ``u(t) = | |f(t)| - 1 |`` [g] (``f`` the measured
specific force), remembered over the erection time constant ``tau``::

    D(t) = (1 / tau) int_{-inf}^{t} u(s) exp(-(t - s) / tau) ds                    (1)

An AHRS erects towards the specific force's direction, and in a coordinated turn the specific
force is tilted from the vertical by the bank angle while its magnitude departs from 1 g only
by ``1/cos(roll) - 1`` (0.15 g at 30 deg): the horizontal acceleration ``g tan(roll)`` is the
larger driver there.  With the share ``s`` (``ahrs_tilt_horizontal``) of the horizontal
kinematic acceleration ``a_h`` [g]::

    u(t) = sqrt( ( |f(t)| - 1 )^2 + s a_h(t)^2 )                                  (1b)

(``s`` = 1: the aircraft's whole acceleration, the specific force's departure from gravity
alone; ``s`` = 0, the default: the load's departure above).  Either

gives an acceleration error of sd ``a_e(t) = c D(t)`` (``c`` = ``ahrs_tilt_mps2_per_g``, the
horizontal acceleration error per g of sustained departure), correlated over ``tau``.  As a
white acceleration on the velocity, with the same velocity error over a window of ``tau``
(``a_e tau``), its power spectral density is::

    q_tilt(t) = a_e(t)^2 tau = (c D(t))^2 tau                                       (2)

added to the accelerometer noise of every step (``JointNoise.accel_noise_mps2_sqrt_hz``; the
velocity random walk of ``layout.py``).  ``c`` = 1 m/s^2 per g is the PH-LAB figure above
(39 m/s over a minute at D of about 0.6 g), given in the ``[joint]`` table of a noise file
(``flightrecon reconstruct --noise FILE``: ``ahrs_tilt_mps2_per_g = 1.0``).  The default is
0: an attitude from an inertial reference has no erection on the accelerometers, nor has the
simulator's (JSBSim: with c = 1 the joint smoother's RMS error on two circuits went from 158
and 100 m to 291 and 228 m, docs/realflights.md).
"""

from __future__ import annotations

import numpy as np
from scipy.signal import lfilter

from flightrecon.constants import G0 as G0_MPS2
from flightrecon.filters.joint.settings import JointNoise


def load_departure_g(f_body_g: np.ndarray) -> np.ndarray:
    """``u = | |f| - 1 |`` [g] per sample of the measured specific force (N, 3) [g]; 0 where a
    component is missing (the missing loads have their own noise, ``qv_extra``)."""
    f = np.asarray(f_body_g, float)
    ok = np.isfinite(f).all(axis=1)
    u = np.zeros(len(f))
    u[ok] = np.abs(np.linalg.norm(f[ok], axis=1) - 1.0)
    return u


def remembered(t: np.ndarray, u: np.ndarray, tau_s: float) -> np.ndarray:
    """Eq. (1) on the samples ``t`` (causal; exact for ``u`` held over each interval on a
    uniform grid, the cleaned recorder grid): ``D_i = a D_{i-1} + (1 - a) u_i``,
    ``a = exp(-dt / tau)`` with the median interval ``dt``."""
    if len(t) < 2:
        return np.zeros(len(t))
    dt = float(np.median(np.diff(t)))
    a = float(np.exp(-dt / tau_s))
    return lfilter([1.0 - a], [1.0, -a], np.asarray(u, float))


def erection_driver_g(f_body_g: np.ndarray, acc_ned: np.ndarray | None,
                      horizontal: float) -> np.ndarray:
    """Eq. (1b) per sample [g]: the load's departure from 1 g combined with the share
    ``horizontal`` of the horizontal kinematic acceleration ``acc_ned[:, :2]`` [m/s^2] (missing
    samples count 0)."""
    u = load_departure_g(f_body_g)
    if acc_ned is None or horizontal <= 0.0:
        return u
    a = np.asarray(acc_ned, float)
    ah = np.hypot(np.nan_to_num(a[:, 0]), np.nan_to_num(a[:, 1])) / G0_MPS2
    return np.sqrt(u ** 2 + horizontal * ah ** 2)


def tilt_psd(t_in: np.ndarray, f_body_g: np.ndarray | None, idx: np.ndarray,
             nz: JointNoise, acc_ned: np.ndarray | None = None) -> np.ndarray:
    """Eq. (2) at the state steps ``idx`` of the input grid ``t_in`` [(m/s^2)^2/Hz], with the
    driver of eq. (1b) (``acc_ned``: the kinematic acceleration on ``t_in``, north, east,
    down [m/s^2]); zeros without loads or with ``ahrs_tilt_mps2_per_g`` = 0."""
    c = nz.ahrs_tilt_mps2_per_g
    if f_body_g is None or c <= 0.0:
        return np.zeros(len(idx))
    D = remembered(t_in, erection_driver_g(f_body_g, acc_ned, nz.ahrs_tilt_horizontal),
                   nz.ahrs_tilt_tau_s)
    return (c * D[idx]) ** 2 * nz.ahrs_tilt_tau_s
