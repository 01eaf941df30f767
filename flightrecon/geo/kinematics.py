"""Kinematic acceleration in north-east-down from recorded body load factors and attitude.

Conventions (docs/schema.md, "Conventions"): body axes forward-right-down; load factor
n = specific force / g0; ``n_norm_g = -f_z / g0`` (+1 at rest); Euler order yaw-pitch-roll
(ZYX) with heading true from north, pitch nose up, roll right wing down.  The vector
``[n_long, n_lat, n_norm]`` is *not* a right-handed triad: the body specific force is
``g0 [n_long, n_lat, -n_norm]``.

Everything here is vectorised over samples (time-major arrays, angles in degrees at the
interface, SI inside).
"""

from __future__ import annotations

import numpy as np

from flightrecon.constants import G0
from flightrecon.geo.gravity import normal_gravity

__all__ = ["body_to_ned_matrix", "heading_increments", "kinematic_acceleration_ned",
           "load_factors_from_acceleration"]


def body_to_ned_matrix(roll_deg, pitch_deg, heading_deg) -> np.ndarray:
    """Direction-cosine matrices ``C_nb`` (body FRD -> NED), shape (N, 3, 3).

    ``C_nb = R_z(heading) R_y(pitch) R_x(roll)`` (ZYX Euler angles, docs/schema.md, "Conventions";
    Titterton & Weston, *Strapdown Inertial Navigation Technology*, eq. 3.47).

    Parameters
    ----------
    roll_deg, pitch_deg, heading_deg : array_like, shape (N,) or scalars
        Euler angles [deg]; broadcast together.

    Returns
    -------
    numpy.ndarray, shape (N, 3, 3)
        ``C[k] @ v_body`` gives the vector in north-east-down.
    """
    phi, theta, psi = np.broadcast_arrays(*(np.radians(np.atleast_1d(np.asarray(a, float)))
                                            for a in (roll_deg, pitch_deg, heading_deg)))
    sf, cf = np.sin(phi), np.cos(phi)
    st, ct = np.sin(theta), np.cos(theta)
    sp, cp = np.sin(psi), np.cos(psi)
    C = np.empty(phi.shape + (3, 3))
    C[..., 0, 0] = ct * cp
    C[..., 0, 1] = sf * st * cp - cf * sp
    C[..., 0, 2] = cf * st * cp + sf * sp
    C[..., 1, 0] = ct * sp
    C[..., 1, 1] = sf * st * sp + cf * cp
    C[..., 1, 2] = cf * st * sp - sf * cp
    C[..., 2, 0] = -st
    C[..., 2, 1] = sf * ct
    C[..., 2, 2] = cf * ct
    return C


def kinematic_acceleration_ned(n_long_g, n_lat_g, n_norm_g, roll_deg, pitch_deg, heading_deg, *,
                               lat_deg, h_m=0.0, C_nb=None) -> np.ndarray:
    """Kinematic acceleration ``a_NED`` [m/s^2], shape (N, 3), from body load factors.

    ``a_NED = C_nb(heading, pitch, roll) g0 [n_long, n_lat, -n_norm] + [0, 0, g(lat, h)]``
    (docs/schema.md, "Conventions"), with ``g`` the WGS-84 normal gravity
    (:func:`flightrecon.geo.gravity.normal_gravity`).  Zero in level, unaccelerated flight.
    Coriolis and transport-rate terms are not included: this is the acceleration of the
    aircraft relative to the rotating earth's local-level frame up to those terms (about
    2 Omega V ~ 0.03 m/s^2 at 250 m/s), which estimators add where they matter.

    Parameters
    ----------
    n_long_g, n_lat_g, n_norm_g : array_like, shape (N,)
        Body load factors [g]: + forward, + toward the right wing, ``-f_z/g0`` (+1 at rest).
    roll_deg, pitch_deg, heading_deg : array_like, shape (N,)
        Euler attitude [deg] (true heading).
    lat_deg, h_m : array_like, shape (N,) or scalar
        Geodetic latitude [deg] and ellipsoidal height [m] at which gravity is evaluated
        (a pressure altitude is close enough: 100 m of height changes g by 3e-4 m/s^2).  The
        latitude has no default: normal gravity changes by 0.052 m/s^2 from the equator to the
        pole, so a silent default latitude would bias the vertical acceleration.
    C_nb : numpy.ndarray, shape (N, 3, 3), optional
        :func:`body_to_ned_matrix` of the same angles, when the caller has it already; the
        acceleration is NaN wherever an angle is non-finite either way.

    Returns
    -------
    numpy.ndarray, shape (N, 3)
        North, east, down acceleration [m/s^2].
    """
    nl, nt, nn = np.broadcast_arrays(*(np.atleast_1d(np.asarray(a, float))
                                       for a in (n_long_g, n_lat_g, n_norm_g)))
    if C_nb is None:
        C = body_to_ned_matrix(roll_deg, pitch_deg, heading_deg)
    else:
        C = np.asarray(C_nb, float)
        bad = ~(np.isfinite(np.asarray(roll_deg, float)) & np.isfinite(np.asarray(pitch_deg, float))
                & np.isfinite(np.asarray(heading_deg, float)))
        nl = np.where(bad, np.nan, nl)
    f_body = G0 * np.stack([nl, nt, -nn], axis=-1)
    f_body = np.broadcast_to(f_body, C.shape[:-1])
    a = np.empty(C.shape[:-1])
    for i in range(3):  # C f row by row: three fused products instead of a general einsum
        a[..., i] = C[..., i, 0] * f_body[..., 0] + C[..., i, 1] * f_body[..., 1] \
            + C[..., i, 2] * f_body[..., 2]
    a[..., 2] += normal_gravity(lat_deg, h_m)
    return a


def load_factors_from_acceleration(a_ned, roll_deg, pitch_deg, heading_deg, *, lat_deg,
                                   h_m=0.0) -> np.ndarray:
    """Body load factors ``[n_long, n_lat, n_norm]`` [g], shape (N, 3), for a given ``a_NED``.

    The exact inverse of :func:`kinematic_acceleration_ned`:
    ``f_body = C_nb^T (a_NED - [0, 0, g])``, ``n = [f_x, f_y, -f_z] / g0``.  Used to build
    consistent synthetic load factors from a trajectory.

    Parameters
    ----------
    a_ned : array_like, shape (N, 3)
        Kinematic acceleration north, east, down [m/s^2].
    roll_deg, pitch_deg, heading_deg : array_like, shape (N,)
        Euler attitude [deg].
    lat_deg, h_m : array_like or scalar
        Where gravity is evaluated (see :func:`kinematic_acceleration_ned`).
    """
    a = np.atleast_2d(np.asarray(a_ned, float))
    C = body_to_ned_matrix(roll_deg, pitch_deg, heading_deg)
    f_ned = a.copy()
    f_ned[..., 2] -= normal_gravity(lat_deg, h_m)
    f_body = np.einsum("...ji,...j->...i", C, np.broadcast_to(f_ned, C.shape[:-1]))
    out = f_body / G0
    out[..., 2] = -out[..., 2]
    return out


def heading_increments(t_s, roll_deg, pitch_deg, p_dps, q_dps, r_dps) -> np.ndarray:
    """Heading change [rad] over each sample interval from the body rates, by exact rotation of
    the direction-cosine matrix (valid at any attitude, through pitch +-90 deg).

    Over ``[t_k, t_k+1]`` the body turns by ``theta = w dt`` with ``w`` the mean of the two
    samples' body rates (FRD: roll, pitch, yaw rate); starting from ``C_k = C_nb(roll_k,
    pitch_k, 0)`` the rotated ``C' = C_k exp([theta]x)`` (Rodrigues' formula; Titterton &
    Weston, *Strapdown Inertial Navigation Technology*, sec. 11.2.1) has the heading
    ``atan2(C'_21, C'_11)``: the increment.  Unlike the Euler kinematics
    ``psi' = (q sin phi + r cos phi) / cos theta`` it has no singularity at the vertical: over
    the top of a loop the heading steps by 180 deg, as the recorded ZYX angles do (roll and
    heading flip while the pitch passes 90 deg).

    Parameters
    ----------
    t_s : array_like, shape (N,)
        Sample times [s].
    roll_deg, pitch_deg : array_like, shape (N,)
        Recorded roll and pitch [deg] (finite).
    p_dps, q_dps, r_dps : array_like, shape (N,)
        Body rates [deg/s] (finite).

    Returns
    -------
    numpy.ndarray, shape (N - 1,)
        Heading increments [rad], each in (-pi, pi].
    """
    t = np.asarray(t_s, float)
    if len(t) < 2:
        return np.zeros(0)
    w = np.radians(np.c_[np.asarray(p_dps, float), np.asarray(q_dps, float),
                         np.asarray(r_dps, float)])
    d = 0.5 * (w[1:] + w[:-1]) * np.diff(t)[:, None]           # rotation vector per interval
    a2 = np.einsum("ij,ij->i", d, d)
    a = np.sqrt(a2)
    small = a < 1e-4
    s1 = np.where(small, 1.0 - a2 / 6.0, np.sin(a) / np.where(small, 1.0, a))
    s2 = np.where(small, 0.5 - a2 / 24.0, (1.0 - np.cos(a)) / np.where(small, 1.0, a2))
    K = np.zeros((len(d), 3, 3))
    K[:, 0, 1], K[:, 0, 2] = -d[:, 2], d[:, 1]
    K[:, 1, 0], K[:, 1, 2] = d[:, 2], -d[:, 0]
    K[:, 2, 0], K[:, 2, 1] = -d[:, 1], d[:, 0]
    R = np.eye(3)[None] + s1[:, None, None] * K + s2[:, None, None] * (K @ K)
    C0 = body_to_ned_matrix(np.asarray(roll_deg, float)[:-1], np.asarray(pitch_deg, float)[:-1],
                            0.0)
    # only the first two rows' first column of C0 R are needed: C'_11, C'_21
    c11 = np.einsum("ij,ij->i", C0[:, 0, :], R[:, :, 0])
    c21 = np.einsum("ij,ij->i", C0[:, 1, :], R[:, :, 0])
    return np.arctan2(c21, c11)
