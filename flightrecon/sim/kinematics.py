"""Attitude matrices and the load-factor relation (docs/schema.md, "Conventions").

``a_NED = C_nb(heading, pitch, roll) g0 [n_long, n_lat, -n_norm] + [0, 0, g(lat, h)]``;
:func:`loads_from_acceleration` is its exact inverse,
``[n_long, n_lat, -n_norm] = C_nb^T (a_NED - [0, 0, g]) / g0``.  Euler order yaw-pitch-roll
(ZYX), body axes forward-right-down.  (:mod:`flightrecon.geo.kinematics` holds the same relation
for the estimators, in degrees; this module works in radians for the simulator and is tested
against it.)  All functions are vectorised over time (arrays (N,),
matrices (N, 3, 3)).
"""

from __future__ import annotations

import numpy as np

from flightrecon.constants import G0

__all__ = [
    "acceleration_from_loads",
    "attitude_from_air",
    "coordinated_roll_rad",
    "dcm_body_to_ned",
    "loads_from_acceleration",
]


def dcm_body_to_ned(heading_rad, pitch_rad, roll_rad) -> np.ndarray:
    """``C_nb = R_z(heading) R_y(pitch) R_x(roll)``, shape (N, 3, 3)."""
    cy, sy = np.cos(heading_rad), np.sin(heading_rad)
    cp, sp = np.cos(pitch_rad), np.sin(pitch_rad)
    cr, sr = np.cos(roll_rad), np.sin(roll_rad)
    c = np.empty(np.shape(heading_rad) + (3, 3))
    c[..., 0, 0] = cy * cp
    c[..., 0, 1] = cy * sp * sr - sy * cr
    c[..., 0, 2] = cy * sp * cr + sy * sr
    c[..., 1, 0] = sy * cp
    c[..., 1, 1] = sy * sp * sr + cy * cr
    c[..., 1, 2] = sy * sp * cr - cy * sr
    c[..., 2, 0] = -sp
    c[..., 2, 1] = cp * sr
    c[..., 2, 2] = cp * cr
    return c


def loads_from_acceleration(a_ned_mps2, g_mps2, heading_rad, pitch_rad, roll_rad) -> np.ndarray:
    """Body load factors ``[n_long, n_lat, n_norm]`` [g], shape (N, 3), from kinematic
    acceleration ``a_ned_mps2`` (N, 3) (north, east, down), local gravity and attitude."""
    f = np.asarray(a_ned_mps2, float).copy()
    f[:, 2] -= g_mps2
    c = dcm_body_to_ned(heading_rad, pitch_rad, roll_rad)
    fb = np.einsum("nji,nj->ni", c, f) / G0
    fb[:, 2] = -fb[:, 2]
    return fb


def acceleration_from_loads(n_g, g_mps2, heading_rad, pitch_rad, roll_rad) -> np.ndarray:
    """Kinematic acceleration (north, east, down) [m/s^2], shape (N, 3), from body load factors
    ``n_g`` (N, 3) = ``[n_long, n_lat, n_norm]`` (docs/schema.md, "Conventions" formula)."""
    v = np.asarray(n_g, float) * G0
    v = np.column_stack([v[:, 0], v[:, 1], -v[:, 2]])
    a = np.einsum("nij,nj->ni", dcm_body_to_ned(heading_rad, pitch_rad, roll_rad), v)
    a[:, 2] += g_mps2
    return a


def coordinated_roll_rad(a_ned_mps2, g_mps2, heading_rad, pitch_rad) -> np.ndarray:
    """Roll that puts the specific force in the body x-z plane (coordinated flight, n_lat = 0).

    With ``f = a_NED - [0, 0, g]`` rotated by heading and pitch into ``f2``, the body lateral
    component ``cos(roll) f2_y + sin(roll) f2_z`` vanishes for ``roll = atan2(f2_y, -f2_z)``.
    In a level turn at zero pitch this is ``tan(roll) = V psi_dot / g``.
    """
    a = np.asarray(a_ned_mps2, float)
    fn, fe, fd = a[:, 0], a[:, 1], a[:, 2] - g_mps2
    f1x = np.cos(heading_rad) * fn + np.sin(heading_rad) * fe
    f1y = -np.sin(heading_rad) * fn + np.cos(heading_rad) * fe
    f2z = np.sin(pitch_rad) * f1x + np.cos(pitch_rad) * fd
    return np.arctan2(f1y, -f2z)


def attitude_from_air(heading_air_rad, gamma_rad, alpha_rad, a_ned_mps2, g_mps2
                      ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Heading, pitch and roll of a coordinated aircraft (no sideslip, n_lat = 0) whose air
    velocity points along ``heading_air_rad`` (its horizontal direction) and ``gamma_rad`` (its
    flight-path angle), at angle of attack ``alpha_rad``.

    The wind axes: ``x_w`` along the air velocity, banked by ``mu`` about it so that the specific
    force ``f = a_NED - [0, 0, g]`` has no component along ``y_w`` (``tan mu = -(f . y_h) /
    (f . z_h)``, ``y_h`` the horizontal right, ``z_h = x_w x y_h``); the body axes are the wind
    axes pitched up by alpha about ``y_w``: ``x_b = cos a x_w - sin a z_w``, ``y_b = y_w``,
    ``z_b = sin a x_w + cos a z_w``, so that the air velocity in body axes is
    ``V (cos a, 0, sin a)``.  In a bank the nose's horizontal direction is then off the air
    velocity's by about ``alpha sin(roll)`` to the inside of the turn, and the pitch is
    ``gamma + alpha cos(roll)`` rather than ``gamma + alpha``.  At alpha = 0 the roll is
    :func:`coordinated_roll_rad`'s.
    """
    hx, g_ = np.asarray(heading_air_rad, float), np.asarray(gamma_rad, float)
    al = np.asarray(alpha_rad, float)
    cg = np.cos(g_)
    x_w = np.column_stack([cg * np.cos(hx), cg * np.sin(hx), -np.sin(g_)])
    y_h = np.column_stack([-np.sin(hx), np.cos(hx), np.zeros_like(hx)])
    z_h = np.cross(x_w, y_h)
    f = np.asarray(a_ned_mps2, float).copy()
    f[:, 2] -= g_mps2
    mu = np.arctan2(np.einsum("ij,ij->i", f, y_h), -np.einsum("ij,ij->i", f, z_h))
    y_w = np.cos(mu)[:, None] * y_h + np.sin(mu)[:, None] * z_h
    z_w = np.cross(x_w, y_w)
    ca, sa = np.cos(al)[:, None], np.sin(al)[:, None]
    x_b = ca * x_w - sa * z_w
    z_b = sa * x_w + ca * z_w
    heading = np.arctan2(x_b[:, 1], x_b[:, 0])
    pitch = -np.arcsin(np.clip(x_b[:, 2], -1.0, 1.0))
    roll = np.arctan2(y_w[:, 2], z_b[:, 2])
    return heading, pitch, roll
