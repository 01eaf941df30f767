"""Attitude anywhere: roll beyond 90 deg, pitch near +-90 deg, inverted flight.

The joint smoother's attitude Jacobians (methods/joint/nominal.py) against central finite
differences of the rotated specific force, the body -> NED rotation's orthonormality and the
load-factor round trip at the same attitudes, and the roll channel's interpolation across its
+-180 deg wrap (cleaning: unwrapped, interpolated the short way, wrapped back).
"""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from flightrecon.cleaning.resample import resample_inputs, wrap_roll
from flightrecon.cleaning.steps import Despike, ResolveTimestamps, UnwrapAngles, run_steps
from flightrecon.geo.kinematics import (
    body_to_ned_matrix,
    kinematic_acceleration_ned,
    load_factors_from_acceleration,
)
from flightrecon.methods.joint.linearisation import attitude_jacobian, attitude_step_means

# (roll, pitch, heading) [deg]: steep bank, knife edge, inverted, near the vertical both ways
ATTITUDES = [(120.0, 10.0, 30.0), (180.0, 0.0, 200.0), (-150.0, -40.0, 300.0),
             (60.0, 85.0, 10.0), (-30.0, 89.9, 250.0), (170.0, -89.9, 90.0),
             (179.99, 30.0, 359.0), (-95.0, -60.0, 45.0), (45.0, 90.0, 0.0), (-120.0, -90.0, 70.0)]
F_BODY = np.array([[0.3, -0.7, -2.1], [-1.2, 0.4, 1.5], [0.05, 0.02, -0.9]])


def _rotated(phi, theta, psi, f):
    return body_to_ned_matrix(np.degrees(phi), np.degrees(theta), np.degrees(psi))[0] @ f


@pytest.mark.parametrize("att", ATTITUDES)
def test_attitude_jacobian_matches_finite_differences(att):
    phi, th, psi = np.radians(att)
    h = 1e-6
    C = body_to_ned_matrix(*att)
    for f in F_BODY:
        J = attitude_jacobian(C, f[None, :])[0]
        d_phi = (_rotated(phi + h, th, psi, f) - _rotated(phi - h, th, psi, f)) / (2 * h)
        d_th = (_rotated(phi, th + h, psi, f) - _rotated(phi, th - h, psi, f)) / (2 * h)
        # central differences: truncation h^2 |f| / 6 ~ 1e-12, rounding 1e-16 / h ~ 1e-10
        np.testing.assert_allclose(J[:, 0], d_phi, atol=1e-8)
        np.testing.assert_allclose(J[:, 1], d_th, atol=1e-8)


def test_step_means_kernel_equals_the_per_sample_jacobian():
    att = np.array(ATTITUDES)
    C = body_to_ned_matrix(att[:, 0], att[:, 1], att[:, 2])
    fb = np.resize(F_BODY, (len(att), 3))
    idx = np.arange(len(att), dtype=np.int64)  # one sample per step
    t = np.arange(len(att), dtype=float)
    C_m, S_m, J_m = attitude_step_means(np.ascontiguousarray(C), np.ascontiguousarray(fb), idx,
                                         t)
    J = attitude_jacobian(C, fb)
    # step k holds the second half of sample k-1 and the first half of sample k
    np.testing.assert_allclose(J_m[1:], 0.5 * (J[:-1] + J[1:]), atol=1e-12)
    np.testing.assert_allclose(C_m[1:], 0.5 * (C[:-1] + C[1:]), atol=1e-15)
    S = C * fb[:, None, :]
    np.testing.assert_allclose(S_m[1:], 0.5 * (S[:-1] + S[1:]), atol=1e-15)


@pytest.mark.parametrize("att", ATTITUDES)
def test_rotation_orthonormal_and_load_factor_round_trip(att):
    C = body_to_ned_matrix(*att)[0]
    np.testing.assert_allclose(C @ C.T, np.eye(3), atol=1e-14)
    assert np.linalg.det(C) == pytest.approx(1.0, abs=1e-14)
    a = np.array([[3.0, -4.0, 12.0]])
    n = load_factors_from_acceleration(a, *att, lat_deg=45.0)
    back = kinematic_acceleration_ned(*n.T, *att, lat_deg=45.0)
    np.testing.assert_allclose(back, a, atol=1e-12)


def _roll_log(roll_wrapped: np.ndarray, t_roll: np.ndarray) -> pd.DataFrame:
    t_fast = np.arange(0.0, t_roll[-1] + 1e-9, 1.0 / 16.0)
    t = np.union1d(t_fast, t_roll)
    df = pd.DataFrame({"t_s": t})
    df["n_norm_g"] = np.where(np.isin(t, t_fast), 1.0, np.nan)
    df["roll_deg"] = np.nan
    df.loc[np.isin(t, t_roll), "roll_deg"] = roll_wrapped
    return df


def test_roll_interpolated_the_short_way_across_180_and_not_despiked():
    # a slow roll through inverted at 4 Hz, 5 deg/s: 170 -> 180 -> -170 (wrapped as recorded),
    # with samples either side of the wrap jittering around +-180
    t_roll = np.arange(0.0, 4.0 + 1e-9, 0.25)
    truth = 170.0 + 5.0 * t_roll
    rec = (truth + 180.0) % 360.0 - 180.0
    work, rep = run_steps(_roll_log(rec, t_roll), [ResolveTimestamps(), UnwrapAngles(),
                                                   Despike()])
    assert not [r for r in rep if r["action"] == "despike" and r["channel"] == "roll_deg"]
    grid, _, _ = resample_inputs(work, 16.0, 2.0)
    g = wrap_roll(grid)
    tg = g["t_s"].to_numpy()
    want = (170.0 + 5.0 * tg + 180.0) % 360.0 - 180.0
    r = g["roll_deg"].to_numpy()
    ok = np.isfinite(r)
    # the short way: every interpolated value on the wrapped truth (a long-way interpolation
    # through 0 deg would be up to 180 deg off on the interval across the wrap)
    err = (r[ok] - want[ok] + 180.0) % 360.0 - 180.0
    assert np.max(np.abs(err)) < 1e-9
    assert np.all((r[ok] >= -180.0) & (r[ok] < 180.0))
    assert np.min(np.abs(r[ok])) >= 170.0 - 1e-9


def _euler_from_dcm(C):
    theta = np.degrees(np.arcsin(np.clip(-C[:, 2, 0], -1.0, 1.0)))
    phi = np.degrees(np.arctan2(C[:, 2, 1], C[:, 2, 2]))
    psi = np.degrees(np.arctan2(C[:, 1, 0], C[:, 0, 0]))
    return phi, theta, psi


def _integrate_body_rates(t, w_dps, C0):
    """Truth attitude from constant-per-sample body rates, exact rotation per step."""
    from scipy.spatial.transform import Rotation

    C = [C0]
    for k in range(len(t) - 1):
        d = np.radians(0.5 * (w_dps[k] + w_dps[k + 1])) * (t[k + 1] - t[k])
        C.append(C[-1] @ Rotation.from_rotvec(d).as_matrix())
    return np.array(C)


@pytest.mark.parametrize(("pitch0", "rates"), [(0.0, (0.0, 20.0, 0.0)),
                                              (80.0, (3.0, 15.0, 0.0))])
def test_heading_from_rates_through_the_vertical(pitch0, rates):
    """A loop, and a climb over the vertical while rolling at 3 deg/s: the heading from
    the body-rate increments (direction-cosine rotation) with the recorded roll and pitch gives
    the truth's attitude, its ZYX heading stepping by 180 deg over the top; the Euler form
    psi' = (q sin phi + r cos phi) / cos theta cannot pass the vertical."""
    from flightrecon.geo.kinematics import heading_increments

    t = np.arange(0.0, 20.0, 1.0 / 16.0) + 0.013   # no sample exactly at the vertical
    w = np.tile(np.array(rates, float), (len(t), 1))
    C = _integrate_body_rates(t, w, body_to_ned_matrix(0.0, pitch0, 40.0)[0])
    phi, theta, psi = _euler_from_dcm(C)
    assert theta.max() > 89.0                        # it passed the vertical
    dpsi = heading_increments(t, phi, theta, *w.T)
    est = 40.0 + np.degrees(np.r_[0.0, np.cumsum(dpsi)])
    # the attitude rebuilt with the estimated heading is the truth's (near the vertical the
    # heading alone is ill-conditioned, the rotation is not); 1e-5: the test's own pitch,
    # arcsin(-C_31), resolves only sqrt(eps) ~ 1.5e-8 rad next to the vertical and the heading
    # step there carries it (a recorder's 0.05 deg quantum is far coarser)
    C_est = body_to_ned_matrix(phi, theta, est)
    assert np.max(np.abs(C_est - C)) < 1e-5
    err = (est - psi + 180.0) % 360.0 - 180.0
    away = np.abs(theta) < 85.0
    assert np.max(np.abs(err[away])) < 1e-3
    # the Euler-rate integral with the pitch clipped at 85 deg (the former rule) is far off
    # past the top
    th = np.radians(np.clip(theta, -85.0, 85.0))
    ph = np.radians(phi)
    rate = (np.radians(w[:, 1]) * np.sin(ph) + np.radians(w[:, 2]) * np.cos(ph)) / np.cos(th)
    euler = 40.0 + np.degrees(np.r_[0.0, np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))])
    assert np.max(np.abs(body_to_ned_matrix(phi, theta, euler) - C)) > 0.5
