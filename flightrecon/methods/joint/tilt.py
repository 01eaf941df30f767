"""The attitude reference's errors after sustained loads, as extra acceleration noise of the joint
smoother (docs/joint.md, "The attitude reference after sustained loads", with the PH-LAB and JSBSim
measurements; docs/realflights.md, "The attitude after the manoeuvres").

An AHRS erects its vertical on the accelerometers: after a sustained load it is tilted by ``delta``
and re-erects with its time constant ``tau``, which puts ``g delta`` of the specific force into the
horizontal, an acceleration error the smoother's constant roll and pitch biases cannot follow.  The
load's departure from 1 g, ``u(t) = | |f(t)| - 1 |`` [g] (``f`` the measured specific force), is
remembered over ``tau``::

    D(t) = (1 / tau) int_{-inf}^{t} u(s) exp(-(t - s) / tau) ds                    (1)

In a coordinated turn the specific force leans by the bank angle while its magnitude departs from 1
g only by ``1/cos(roll) - 1``; with the share ``s`` (``ahrs_tilt_horizontal``; 0, the default: the
load's departure alone) of the horizontal kinematic acceleration ``a_h`` [g]::

    u(t) = sqrt( ( |f(t)| - 1 )^2 + s a_h(t)^2 )                                  (1b)

The acceleration error, of sd ``a_e(t) = c D(t)`` (``c`` = ``ahrs_tilt_mps2_per_g``) correlated over
``tau``, as a white acceleration with the same velocity error over ``tau``, has the power spectral
density::

    q_tilt(t) = a_e(t)^2 tau = (c D(t))^2 tau                                       (2)

added to the accelerometer noise of every step (``JointNoise.accel_noise_mps2_sqrt_hz``).  ``c`` = 1
m/s^2 per g is the PH-LAB figure; the default 0 is an inertial attitude's (and the simulator's).
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flightrecon.constants import G0 as G0_MPS2
from flightrecon.methods.joint.settings import JointNoise


def load_departure_g(f_body_g: np.ndarray) -> np.ndarray:
    """``u = | |f| - 1 |`` [g] per sample of the measured specific force (N, 3) [g]; 0 where a
    component is missing (the missing loads have their own noise, ``qv_extra``)."""
    f = np.asarray(f_body_g, float)
    ok = np.isfinite(f).all(axis=1)
    u = np.zeros(len(f))
    u[ok] = np.abs(np.linalg.norm(f[ok], axis=1) - 1.0)
    return u


@nb.njit(cache=True, nogil=True)
def _first_order_lag(u: np.ndarray, a: float) -> np.ndarray:
    """``D_i = a D_{i-1} + (1 - a) u_i`` from ``D_{-1} = 0``: the recursion of
    ``scipy.signal.lfilter([1 - a], [1, -a], u)`` (its transposed direct form for one pole adds the
    same two products, so the same numbers to the bit) without importing scipy.signal, about 0.6 s
    of every run's start with the scipy.stats it pulls in."""
    D = np.empty(len(u))
    b = 1.0 - a
    z = 0.0
    for i in range(len(u)):
        D[i] = z + b * u[i]
        z = a * D[i]
    return D


def remembered(t: np.ndarray, u: np.ndarray, tau_s: float) -> np.ndarray:
    """Eq. (1) on the samples ``t`` (causal; exact for ``u`` held over each interval on a uniform
    grid, the cleaned recorder grid): ``D_i = a D_{i-1} + (1 - a) u_i``, ``a = exp(-dt / tau)`` with
    the median interval ``dt``."""
    if len(t) < 2:
        return np.zeros(len(t))
    dt = float(np.median(np.diff(t)))
    a = float(np.exp(-dt / tau_s))
    return _first_order_lag(np.ascontiguousarray(u, dtype=float), a)


def erection_driver_g(f_body_g: np.ndarray, acc_ned: np.ndarray | None,
                      horizontal: float) -> np.ndarray:
    """Eq. (1b) per sample [g]: the load's departure from 1 g combined with the share ``horizontal``
    of the horizontal kinematic acceleration ``acc_ned[:, :2]`` [m/s^2] (missing samples count
    0)."""
    u = load_departure_g(f_body_g)
    if acc_ned is None or horizontal <= 0.0:
        return u
    a = np.asarray(acc_ned, float)
    ah = np.hypot(np.nan_to_num(a[:, 0]), np.nan_to_num(a[:, 1])) / G0_MPS2
    return np.sqrt(u ** 2 + horizontal * ah ** 2)


def tilt_psd(t_in: np.ndarray, f_body_g: np.ndarray | None, idx: np.ndarray,
             nz: JointNoise, acc_ned: np.ndarray | None = None) -> np.ndarray:
    """Eq. (2) at the state steps ``idx`` of the input grid ``t_in`` [(m/s^2)^2/Hz], with the driver
    of eq. (1b) (``acc_ned``: the kinematic acceleration on ``t_in``, north, east, down [m/s^2]);
    zeros without loads or with ``ahrs_tilt_mps2_per_g`` = 0."""
    c = nz.ahrs_tilt_mps2_per_g
    if f_body_g is None or c <= 0.0:
        return np.zeros(len(idx))
    D = remembered(t_in, erection_driver_g(f_body_g, acc_ned, nz.ahrs_tilt_horizontal),
                   nz.ahrs_tilt_tau_s)
    return (c * D[idx]) ** 2 * nz.ahrs_tilt_tau_s


def _gnss_fit_ne(gnss_t: np.ndarray, lat_deg: np.ndarray, lon_deg: np.ndarray, tq: np.ndarray,
                 half_s: float, min_fixes: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Position (latitude, longitude [rad]) and local-level velocity (north, east [m/s]) at the
    times ``tq``: a cubic fitted by least squares to the fixes within ``half_s`` of each, its
    derivative scaled by the WGS-84 radii of curvature there (the velocity in the local north and
    east, not in a map plane whose north turns by the meridian convergence: 6 deg over 700 km, 50
    m/s on a 180 deg turn at 250 m/s).  A straight line's slope is biased over a turn (over +-15 s
    of a 3 deg/s turn by 6 %, 4 m/s at 60 m/s); the cubic leaves the fifth-order term, 0.1 %.  NaN
    where fewer than ``min_fixes`` fixes or they do not reach ``half_s / 2`` on both sides."""
    from flightrecon.geo.navframe import radii_of_curvature

    t = np.asarray(gnss_t, float)
    ll = np.radians(np.column_stack([lat_deg, lon_deg]))
    pos = np.full((len(tq), 2), np.nan)
    vel = np.full((len(tq), 2), np.nan)
    lo = np.searchsorted(t, np.asarray(tq, float) - half_s, side="left")
    hi = np.searchsorted(t, np.asarray(tq, float) + half_s, side="right")
    for q, (i, j) in enumerate(zip(lo, hi)):
        if j - i < min_fixes:
            continue
        s = (t[i:j] - tq[q]) / half_s
        if s[0] > -0.5 or s[-1] < 0.5:
            continue
        ref = ll[i]
        coef = np.linalg.lstsq(np.vander(s, 4, increasing=True), ll[i:j] - ref, rcond=None)[0]
        pos[q] = coef[0] + ref
        vel[q] = coef[1] / half_s
    rm, rn = radii_of_curvature(np.degrees(pos[:, 0]))
    vel[:, 0] *= rm
    vel[:, 1] *= rn * np.cos(pos[:, 0])
    return pos, vel


def _constant_error_integrands(acc_h: np.ndarray, heading_rad: np.ndarray,
                               f_ned_h: np.ndarray | None) -> list[np.ndarray]:
    """Per constant error of the loads' integration, its effect on the north-east acceleration per
    unit error (N, 2): a heading bias [rad] (the horizontal acceleration ``acc_h`` turned by 90
    deg), north and east acceleration biases [m/s^2], pitch and roll biases [rad] (``g`` along the
    body's forward and lateral axes, turned by the heading) and, with ``f_ned_h`` (N, 2, 3: the
    north-east part of each body axis's specific force [m/s^2]), the three accelerometers' scale
    errors."""
    n = len(acc_h)
    psi = np.nan_to_num(np.asarray(heading_rad, float))
    cols = [np.column_stack([-acc_h[:, 1], acc_h[:, 0]]),
            np.column_stack([np.ones(n), np.zeros(n)]), np.column_stack([np.zeros(n), np.ones(n)]),
            G0_MPS2 * np.column_stack([np.cos(psi), np.sin(psi)]),
            G0_MPS2 * np.column_stack([-np.sin(psi), np.cos(psi)])]
    if f_ned_h is not None:
        cols += [np.nan_to_num(np.asarray(f_ned_h, float)[:, :, k]) for k in range(3)]
    return cols


def _rotation_terms(pos_start: np.ndarray, pos_end: np.ndarray, window_s: float) -> np.ndarray:
    """The Coriolis and transport-rate terms the loads do not hold, horizontal part, integrated over
    each window (m, 2) [m/s]: ``dv_n += -k v_e``, ``dv_e += k v_n`` with ``k = 2 Omega sin(lat) +
    v_e tan(lat) / R_N`` (Groves eq. 5.54 without the vertical velocity's terms), integrated: ``k``
    times the window's displacement (east, north); ``pos_*`` latitude and longitude [rad] at the
    windows' ends."""
    from flightrecon.constants import WGS84_OMEGA
    from flightrecon.geo.navframe import radii_of_curvature

    lat_mid = 0.5 * (pos_start[:, 0] + pos_end[:, 0])
    rm, rn = radii_of_curvature(np.degrees(lat_mid))
    d_n = (pos_end[:, 0] - pos_start[:, 0]) * rm
    d_e = (pos_end[:, 1] - pos_start[:, 1]) * rn * np.cos(lat_mid)
    k = 2.0 * WGS84_OMEGA * np.sin(lat_mid) + (d_e / window_s) * np.tan(lat_mid) / rn
    return np.column_stack([-k * d_e, k * d_n])


def tilt_evidence(t_in: np.ndarray, acc_ned: np.ndarray, f_body_g: np.ndarray,
                  heading_rad: np.ndarray, f_ned_h: np.ndarray | None, gnss_t: np.ndarray,
                  gnss_lat_deg: np.ndarray, gnss_lon_deg: np.ndarray, t0_s: float, t1_s: float, *,
                  window_s: float = 60.0, half_s: float = 15.0, tau_s: float = 60.0,
                  horizontal: float = 1.0, busy_g: float = 0.1) -> dict | None:
    """What the GNSS says of the attitude reference: the tilt gain ``c`` of eq. (2) that the
    recorded loads, integrated through the recorded attitude, need to meet the GNSS velocity.

    Over consecutive windows of ``window_s`` between ``t0_s`` and ``t1_s``: the change of velocity
    the loads give (``acc_ned`` integrated, trapezoidal, with the Coriolis and transport-rate terms:
    :func:`_rotation_terms`) minus the change of the GNSS velocity (a cubic fitted to the fixes over
    ``2 half_s``, in the local north and east: :func:`_gnss_fit_ne`), a 2-vector per window.  The
    errors that stay constant over the flight (:func:`_constant_error_integrands`: heading,
    acceleration, roll and pitch biases, with ``f_ned_h`` the accelerometers' scale errors, a 1 %
    error of the normal load in a 2 g, 60 deg turn being 10 m/s per minute) are fitted to it by
    least squares and removed. What is left, ``r`` [m/s] per window, against the rms over the window
    of the remembered driver ``D`` (eq. 1, 1b) [g]: ``r0`` the lower quartile of ``r`` (the GNSS
    slope's noise and what the constants do not take), and each window with ``D >= busy_g`` gives
    ``c_i = sqrt(max(r^2 - r0^2, 0)) / (D window_s)`` [m/s^2 per g], the gain that explains its
    excess; ``c`` is their median.  An attitude whose errors are constant (an inertial reference,
    the simulator's sensors) gives ``c`` near 0 (JSBSim: 0.04-0.18); the PH-LAB AHRS 0.27-0.40
    (docs/joint.md).  ``None`` with fewer than three busy windows or ten windows in all.
    """
    t = np.asarray(t_in, float)
    starts = np.arange(t0_s, t1_s - window_s, window_s)
    if len(t) < 2 or len(gnss_t) < 10 or len(starts) < 10:
        return None
    ends = starts + window_s
    dt = np.diff(t)[:, None]

    def window_integral(x: np.ndarray) -> np.ndarray:
        cum = np.zeros((len(t), 2))
        cum[1:] = np.cumsum(0.5 * (x[1:] + x[:-1]) * dt, axis=0)
        return np.column_stack([np.interp(ends, t, cum[:, k]) - np.interp(starts, t, cum[:, k])
                                for k in range(2)])

    a = np.nan_to_num(np.asarray(acc_ned, float)[:, :2])
    pg, vg = _gnss_fit_ne(np.asarray(gnss_t, float), np.asarray(gnss_lat_deg, float),
                          np.asarray(gnss_lon_deg, float), np.r_[starts, ends], half_s)
    m = len(starts)
    y = (window_integral(a) + _rotation_terms(pg[:m], pg[m:], window_s) - (vg[m:] - vg[:m]))
    X = np.stack([window_integral(c) for c in _constant_error_integrands(a, heading_rad,
                                                                         f_ned_h)], axis=-1)
    D = remembered(t, erection_driver_g(f_body_g, acc_ned, horizontal), tau_s)
    csum = np.r_[0.0, np.cumsum(D ** 2)]
    i, j = np.searchsorted(t, starts), np.searchsorted(t, ends)
    d_rms = np.sqrt((csum[j] - csum[i]) / np.maximum(j - i, 1))
    ok = np.isfinite(y).all(axis=1) & (j > i)
    busy = ok & (d_rms >= busy_g)
    if ok.sum() < 10 or busy.sum() < 3:
        return None
    beta = np.linalg.lstsq(X[ok].reshape(-1, X.shape[-1]), y[ok].reshape(-1), rcond=None)[0]
    r = np.full(m, np.nan)
    r[ok] = np.hypot(*(y[ok] - X[ok] @ beta).T)
    r0 = float(np.percentile(r[ok], 25))
    ci = np.sqrt(np.maximum(r[busy] ** 2 - r0 ** 2, 0.0)) / (d_rms[busy] * window_s)
    return {"gain_mps2_per_g": float(np.median(ci)), "floor_mps": r0,
            "windows": int(ok.sum()), "busy_windows": int(busy.sum()),
            "heading_bias_deg": float(np.degrees(beta[0])), "window_s": window_s}
