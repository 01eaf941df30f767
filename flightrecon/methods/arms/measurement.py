"""ADS/ARMS measurement model: the radar's range and azimuth (paper eqs. 10-12), the converted
measurement and its covariance (eqs. 13, 15), and the rows a plot adds to a step's update in the
compiled track filter (:func:`radar_rows_into`)."""

from __future__ import annotations

import numba as nb
import numpy as np


def range_azimuth(X: np.ndarray) -> np.ndarray:
    """Measurement function h(X) = [sqrt(x^2 + y^2), atan2(x, y)] (paper eq. 10).

    ``X`` is (..., n) with x at index 0 and y at index 2; returns (..., 2).
    """
    X = np.asarray(X, dtype=np.float64)
    return np.stack([np.hypot(X[..., 0], X[..., 2]), np.arctan2(X[..., 0], X[..., 2])], axis=-1)


def range_azimuth_jacobian(X: np.ndarray) -> np.ndarray:
    """Jacobian H = dh/dX (paper eq. 12): ``[[x/r, 0, y/r, 0], [y/r^2, 0, -x/r^2, 0]]``.

    ``X`` is (..., n), n >= 4 (extra states get zero columns); returns (..., 2, n).
    """
    X = np.asarray(X, dtype=np.float64)
    x, y = X[..., 0], X[..., 2]
    r2 = x * x + y * y
    r = np.sqrt(r2)
    H = np.zeros(X.shape[:-1] + (2, X.shape[-1]))
    H[..., 0, 0] = x / r
    H[..., 0, 2] = y / r
    H[..., 1, 0] = y / r2
    H[..., 1, 2] = -x / r2
    return H


def wrap_angle(a):
    """Wrap angles [rad] to (-pi, pi] (used for the azimuth innovation)."""
    a = np.asarray(a, dtype=np.float64)
    return np.pi - np.mod(np.pi - a, 2.0 * np.pi)


def converted_measurement(range_m, azimuth_rad) -> np.ndarray:
    """Converted measurement ``[x*, y*] = rho* [sin theta*, cos theta*]`` (paper eq. 13),
    (..., 2)."""
    r = np.asarray(range_m, dtype=np.float64)
    a = np.asarray(azimuth_rad, dtype=np.float64)
    return np.stack([r * np.sin(a), r * np.cos(a)], axis=-1)


def converted_covariance(range_m, azimuth_rad, sigma_range_m, sigma_azimuth_rad) -> np.ndarray:
    """Covariance of the converted measurement error (paper eq. 15, first order), (..., 2, 2).

    ``s_x^2 = s_r^2 sin^2 t + r^2 s_t^2 cos^2 t``, ``s_y^2 = s_r^2 cos^2 t + r^2 s_t^2 sin^2 t``,
    ``s_xy = sin t cos t (s_r^2 - r^2 s_t^2)`` (docs/arms.md), evaluated at the range and
    azimuth given (measured or predicted: see :data:`CONVERTED_AT`).
    """
    r = np.asarray(range_m, dtype=np.float64)
    t = np.asarray(azimuth_rad, dtype=np.float64)
    sr2 = np.asarray(sigma_range_m, dtype=np.float64) ** 2
    ct2 = r ** 2 * np.asarray(sigma_azimuth_rad, dtype=np.float64) ** 2
    s, c = np.sin(t), np.cos(t)
    shape = np.broadcast(r, t, sr2, ct2).shape
    R = np.empty(shape + (2, 2))
    R[..., 0, 0] = sr2 * s * s + ct2 * c * c
    R[..., 1, 1] = sr2 * c * c + ct2 * s * s
    R[..., 0, 1] = R[..., 1, 0] = s * c * (sr2 - ct2)
    return R


@nb.njit(cache=True, nogil=True, inline="always")
def radar_rows_into(lin, rho, th, sr2, st2, x, nu, Hk, Rk):
    """The radar plot ``[rho*, theta*]`` (variances ``sr2``, ``st2``) as rows 0-1 of the step's
    innovation ``nu``, Jacobian ``Hk`` and noise ``Rk`` at the state ``x`` (paper eqs. 10-15).

    ``lin`` 0: EKF on ``[rho, theta]``, ``H`` of eq. 12, azimuth innovation wrapped to
    (-pi, pi]; 1 / 2: converted measurement ``[x*, y*]`` (eq. 13) with ``H`` selecting x, y and
    the covariance of eq. 15 at the measured (1) or predicted (2) range and azimuth.  Returns
    False (rows untouched) for a predicted position within 1 m of the station, where the
    azimuth is undefined.  Inlined into the model's update.
    """
    px = x[0]
    py = x[2]
    r2 = px * px + py * py
    if r2 <= 1.0:  # at the station the azimuth is undefined: skip such a plot
        return False
    rp = np.sqrt(r2)
    if lin == 0:
        nu[0] = rho - rp
        d = th - np.arctan2(px, py)
        nu[1] = np.pi - np.mod(np.pi - d, 2.0 * np.pi)
        Hk[0, 0] = px / rp
        Hk[0, 2] = py / rp
        Hk[1, 0] = py / r2
        Hk[1, 2] = -px / r2
        Rk[0, 0] = sr2
        Rk[1, 1] = st2
    else:
        nu[0] = rho * np.sin(th) - px
        nu[1] = rho * np.cos(th) - py
        Hk[0, 0] = 1.0
        Hk[1, 2] = 1.0
        if lin == 1:
            re = rho
            te = th
        else:
            re = rp
            te = np.arctan2(px, py)
        s = np.sin(te)
        co = np.cos(te)
        ct2 = re * re * st2
        Rk[0, 0] = sr2 * s * s + ct2 * co * co
        Rk[1, 1] = sr2 * co * co + ct2 * s * s
        Rk[0, 1] = s * co * (sr2 - ct2)
        Rk[1, 0] = Rk[0, 1]
    return True
