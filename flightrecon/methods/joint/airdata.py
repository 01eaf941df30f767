"""The air-data heading of the joint smoother: where it stands for the air velocity's direction
(:func:`nose_along_air`) and the angle between the two that the angle of attack makes in a bank
(:func:`nose_offset`); docs/joint.md, "Measurements"."""

from __future__ import annotations

import numpy as np

from flightrecon.methods.joint.inputs import JointInputs
from flightrecon.methods.joint.settings import JointSettings


def nose_along_air(attitude_deg: np.ndarray, settings: JointSettings) -> np.ndarray:
    """Samples whose attitude lets the heading stand for the air velocity's direction.

    The air velocity in body axes is V (cos a cos b, sin b, sin a cos b) (angle of attack a,
    sideslip b); its horizontal direction differs from the heading by about a sin(roll) /
    cos(pitch) plus the sideslip: a few degrees in a 30 deg bank (the part
    :func:`nose_offset` takes out), tens of degrees in a spiral dive or a spin, where neither
    the offset's no-sideslip geometry nor the pitot holds.  Kept: |roll| <=
    ``heading_max_roll_deg`` and |pitch| <= ``heading_max_pitch_deg``, the angles of the
    body-to-NED rotation C = R_z R_y R_x of the recorded attitude ``attitude_deg`` (Ni, 3),
    from its last row C[2] = (-sin(pitch), sin(roll) cos(pitch), cos(roll) cos(pitch)): a
    roll of 190 deg counts as -170 deg and a pitch of 100 deg (inverted) as 80 deg.
    """
    phi, theta = np.radians(attitude_deg[:, 0]), np.radians(attitude_deg[:, 1])
    st, ct = np.sin(theta), np.cos(theta)
    pitch = -np.arcsin(np.clip(-st, -1.0, 1.0))
    roll = np.arctan2(np.sin(phi) * ct, np.cos(phi) * ct)
    return ((np.abs(roll) <= np.radians(settings.heading_max_roll_deg))
            & (np.abs(pitch) <= np.radians(settings.heading_max_pitch_deg)))


def nose_offset(inp: JointInputs, climb_window_s: float = 2.0,
                alpha_range_deg: tuple[float, float] = (-10.0, 20.0),
                at: np.ndarray | None = None) -> np.ndarray:
    """Heading minus the air velocity's horizontal direction on the input grid [rad] (at the
    input samples ``at``, a boolean mask or indices, when given: the same numbers as the whole
    grid's there), from the angle of attack that the recorded attitude, pressure-altitude rate
    and airspeed imply (docs/joint.md, "Measurements").

    With no sideslip the air velocity in body axes is V (cos a, 0, sin a); rotated by
    C = R_z(psi) R_y(theta) R_x(phi) its horizontal direction is the heading minus

        delta = atan2(sin phi sin a, cos theta cos a + cos phi sin theta sin a),

    about a sin(phi): 1 deg at a = 2.5 deg in a 25 deg bank, to the inside of the turn.  The
    angle of attack comes from the air-relative flight-path angle g, sin g = h' / V (vertical
    wind neglected; h' the pressure-altitude rate, a central difference over
    ``climb_window_s``), through sin g = cos a sin theta - sin a cos phi cos theta
    (the body's geometry with no sideslip): a = arccos(sin g / R) - d, R = hypot(A, B),
    d = atan2(B, A), A = sin theta, B = cos phi cos theta.  Where the angles are not finite or
    ``a`` falls outside ``alpha_range_deg`` (a stall, a spin: the heading is not used there
    anyway) the offset is 0.
    """
    t_all = inp.t_in
    sel = slice(None) if at is None else at
    t = t_all[sel]
    att = inp.attitude_deg[sel]
    phi, theta = np.radians(att[:, 0]), np.radians(att[:, 1])
    h = inp.baro_rel_m
    ok_h = np.isfinite(h)
    if ok_h.sum() < 2:
        return np.zeros(len(t))
    half = 0.5 * climb_window_s
    hp = np.interp(t + half, t_all[ok_h], h[ok_h])
    hm = np.interp(t - half, t_all[ok_h], h[ok_h])
    span = np.minimum(t + half, t_all[-1]) - np.maximum(t - half, t_all[0])
    with np.errstate(invalid="ignore", divide="ignore"):
        sin_g = np.clip((hp - hm) / np.where(span > 0, span, np.nan) / inp.tas[sel], -1.0, 1.0)
        A, B = np.sin(theta), np.cos(phi) * np.cos(theta)
        alpha = np.arccos(np.clip(sin_g / np.hypot(A, B), -1.0, 1.0)) - np.arctan2(B, A)
        delta = np.arctan2(np.sin(phi) * np.sin(alpha),
                           np.cos(theta) * np.cos(alpha)
                           + np.cos(phi) * np.sin(theta) * np.sin(alpha))
    lo, hi = np.radians(alpha_range_deg)
    good = np.isfinite(delta) & (alpha >= lo) & (alpha <= hi)
    return np.where(good, delta, 0.0)
