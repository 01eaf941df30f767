"""The aided observation of the azimuth channel: horizontal kinematic acceleration from load
factors and attitude, its Jacobian and covariance, and the transverse acceleration."""

from __future__ import annotations

import numpy as np

from flightrecon.constants import G0
from flightrecon.errors import ValidationError

# ---------------------------------------------------------------------------------------------
# The aided observation
# ---------------------------------------------------------------------------------------------


def _attitude_terms(n_long_g, n_lat_g, n_norm_g, roll_deg, pitch_deg):
    f = G0 * np.stack(np.broadcast_arrays(n_long_g, n_lat_g, -np.asarray(n_norm_g, float)), -1)
    phi = np.radians(roll_deg)
    th = np.radians(pitch_deg)
    sf, cf, st, ct = np.sin(phi), np.cos(phi), np.sin(th), np.cos(th)
    fx, fy, fz = f[..., 0], f[..., 1], f[..., 2]
    vx = ct * fx + st * (sf * fy + cf * fz)
    vy = cf * fy - sf * fz
    return f, (sf, cf, st, ct), vx, vy


def horizontal_acceleration(n_long_g, n_lat_g, n_norm_g, roll_deg, pitch_deg,
                            heading_deg) -> np.ndarray:
    """Horizontal kinematic acceleration (a_N, a_E) from body load factors and Euler attitude.

    docs/schema.md, "Conventions": ``a_NED = C_nb(heading, pitch, roll) g0 [n_long, n_lat, -n_norm]
    + [0, 0, g]``; gravity is vertical, so the horizontal rows need neither latitude nor height:
    ``[a_N, a_E] = Rz(heading) [v_x, v_y]`` with ``v = Ry(pitch) Rx(roll) g0 [n_long, n_lat,
    -n_norm]`` (ZYX order).

    Parameters
    ----------
    n_long_g, n_lat_g, n_norm_g : body load factors [g] (FRD, ``n_norm = -f_z/g0``), shape (N,)
    roll_deg, pitch_deg, heading_deg : Euler angles [deg], shape (N,)

    Returns
    -------
    (N, 2) array [m/s^2]: columns a_N, a_E

    Notes
    -----
    Delegates to :func:`flightrecon.geo.kinematics.kinematic_acceleration_ned`; the Jacobian
    below is written out here and checked against finite differences of this function.
    """
    from flightrecon.geo.kinematics import kinematic_acceleration_ned

    # gravity is vertical: the horizontal rows do not depend on the latitude it is evaluated
    # at (0 here), only the dropped vertical row would
    return kinematic_acceleration_ned(n_long_g, n_lat_g, n_norm_g, roll_deg, pitch_deg,
                                      heading_deg, lat_deg=0.0)[..., :2]


def horizontal_acceleration_jacobian(n_long_g, n_lat_g, n_norm_g, roll_deg, pitch_deg,
                                     heading_deg) -> np.ndarray:
    """Jacobian of :func:`horizontal_acceleration` with respect to its inputs.

    Columns: d/d n_long, d/d n_lat, d/d n_norm [m/s^2 per g], d/d roll, d/d pitch, d/d heading
    [m/s^2 per **rad**].  Analytic; checked against finite differences in the tests.

    Returns
    -------
    (N, 2, 6) array
    """
    f, (sf, cf, st, ct), vx, vy = _attitude_terms(n_long_g, n_lat_g, n_norm_g, roll_deg,
                                                   pitch_deg)
    fx, fy, fz = f[..., 0], f[..., 1], f[..., 2]
    ps = np.radians(heading_deg)
    sp, cp = np.sin(ps), np.cos(ps)
    zero = np.zeros_like(vx)
    # d(vx, vy)/d(fx, fy, fz, roll, pitch)
    dvx = [ct, st * sf, st * cf, st * vy, -st * fx + ct * (sf * fy + cf * fz)]
    dvy = [zero, cf, -sf, -sf * fy - cf * fz, zero]
    scale = [G0, G0, -G0, 1.0, 1.0]  # f = g0 [n_long, n_lat, -n_norm]
    J = np.empty(vx.shape + (2, 6))
    for c in range(5):
        J[..., 0, c] = (cp * dvx[c] - sp * dvy[c]) * scale[c]
        J[..., 1, c] = (sp * dvx[c] + cp * dvy[c]) * scale[c]
    aN = cp * vx - sp * vy
    aE = sp * vx + cp * vy
    J[..., 0, 5] = -aE
    J[..., 1, 5] = aN
    return J


def horizontal_acceleration_covariance(n_long_g, n_lat_g, n_norm_g, roll_deg, pitch_deg,
                                       heading_deg, *, sigma_load_g: float,
                                       sigma_attitude_deg: float,
                                       sigma_heading_deg: float) -> np.ndarray:
    """First-order covariance of (a_N, a_E) from sensor errors: ``J Sigma J^T``.

    ``Sigma = diag(s_n^2 (x3), s_att^2, s_att^2, s_hdg^2)`` with ``s_n`` the load-factor error
    per axis, ``s_att`` the roll/pitch error and ``s_hdg`` the heading error (angles converted to
    radians), ``J`` from :func:`horizontal_acceleration_jacobian`.  Called once for the white
    errors and once for the correlated ones (load-factor bias), which the filter weights
    differently (see :func:`azimuth_filter`).

    Returns
    -------
    (N, 2, 2) array [m^2/s^4]
    """
    for name, v in (("sigma_load_g", sigma_load_g), ("sigma_attitude_deg", sigma_attitude_deg),
                    ("sigma_heading_deg", sigma_heading_deg)):
        if not (np.isfinite(v) and v >= 0):
            raise ValidationError(f"{name} must be finite and >= 0, got {v}")
    J = horizontal_acceleration_jacobian(n_long_g, n_lat_g, n_norm_g, roll_deg, pitch_deg,
                                         heading_deg)
    s_load = sigma_load_g**2
    var = np.array([s_load, s_load, s_load, np.radians(sigma_attitude_deg) ** 2,
                    np.radians(sigma_attitude_deg) ** 2, np.radians(sigma_heading_deg) ** 2])
    return (J * var) @ np.swapaxes(J, -1, -2)


def transverse_acceleration(a_ne: np.ndarray, eps_rad) -> np.ndarray:
    """``z = a_E cos(eps) - a_N sin(eps)``: horizontal acceleration across the line of sight.

    By the kinematics in polar coordinates (docs/azimuth.md) ``z = 2 r_dot omega + r a``.

    Parameters
    ----------
    a_ne : (N, 2) [m/s^2] (a_N, a_E)
    eps_rad : azimuth [rad], (N,)
    """
    a_ne = np.asarray(a_ne, dtype=np.float64)
    return a_ne[..., 1] * np.cos(eps_rad) - a_ne[..., 0] * np.sin(eps_rad)


def wrap_pi(x):
    """Wrap angles [rad] to (-pi, pi]."""
    return np.pi - np.mod(np.pi - np.asarray(x, dtype=np.float64), 2 * np.pi)
