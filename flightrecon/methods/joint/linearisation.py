"""Linearisation of the joint smoother: the nominal path (the state grid, the increments of the held
inputs, the attitude step means, the initial state, the iteration-0 trajectory), what the passes
hold fixed (:class:`SmootherFlight`, built once per problem by :func:`smoother_flight`) and the
models built about a nominal or about an iterate (:class:`PassModels`, with the local-level
components re-expressed in the iterate's own frames), and the MAP cost of an iterate
(:func:`pass_cost`, the kernel :func:`~flightrecon.methods.joint.model.map_cost`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numba as nb
import numpy as np

from flightrecon.geo.frames import ecef_to_geodetic, geodetic_to_ecef
from flightrecon.geo.navframe import (
    frame_rate_acceleration,
    integrate_local_level,
    ned_to_ecef_matrix,
)
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.inputs import EndPoint, JointInputs, TakeoffRoll, enu_to_ecef_matrix
from flightrecon.methods.joint.layout import Cost, Measurements
from flightrecon.methods.joint.measurements import (
    build_measurements,
    noise_groups,
    static_measurements,
)
from flightrecon.methods.joint.model import map_cost
from flightrecon.methods.joint.settings import PRIOR_STATES, JointNoise, JointSettings
from flightrecon.methods.joint.tilt import tilt_psd


def state_grid(t_in: np.ndarray, rate_hz: float) -> np.ndarray:
    """Indices of the input grid that are state steps (every ``stride``-th sample, and the last)."""
    dt_in = float(np.median(np.diff(t_in))) if len(t_in) > 1 else 1.0
    stride = max(1, int(round(1.0 / (rate_hz * dt_in))))
    idx = np.arange(0, len(t_in), stride)
    if idx[-1] != len(t_in) - 1:
        idx = np.append(idx, len(t_in) - 1)
    return idx


def _half_holds(t_in: np.ndarray, idx: np.ndarray):
    """Each input sample i held on [t_i - d_{i-1}/2, t_i + d_i/2) (centred on its own time, d_i =
    t_{i+1} - t_i): its right half lies in step ``k_r[i]`` (idx[k-1] <= i < idx[k]), its left half
    in step ``k_l[i] = k_r[i-1]``.  Returns (k_r, k_l, d_r, d_l), the half lengths ``d_r = d_i / 2``
    and ``d_l = d_{i-1} / 2`` (0 before the first and after the last sample).

    Not held on [t_i, t_{i+1}): a recorder's sample is its channel at t_i, and a forward hold
    applies it half an interval late; in a turn the rotated acceleration then lags by omega h / 2
    and the heading bias takes that up (0.09 deg at 3 deg/s and 16 Hz, docs/joint.md
    "Increments")."""
    Ni = len(t_in)
    d = np.diff(t_in, append=t_in[-1])
    k_r = np.searchsorted(idx, np.arange(Ni), side="right")
    k_l = np.r_[len(idx), k_r[:-1]]              # the first sample has no left half
    d_r = 0.5 * d
    d_l = 0.5 * np.r_[0.0, d[:-1]]
    return k_r, k_l, d_r, d_l


def held_increments(t_in, acc, idx, missing_psd=None):
    """Exact velocity and position increments over each state step for accelerations held on their
    samples' centred intervals (:func:`_half_holds`), and per step the missing accelerations' share:
    the seconds of it without an acceleration, each weighted by ``missing_psd`` (per input sample
    [(m/s^2)^2/Hz], ``None``: 1), the dynamics' extra velocity PSD times the step.

    Over step k (from t_in[idx[k-1]] to T_k = t_in[idx[k]]) a constant a on [s0, s1) adds a (s1 -
    s0) to dV and a (s1 - s0)(T_k - (s0 + s1)/2) to dP: the right half of sample i weighs d_r (T_k -
    t_i - d_r/2), its left half d_l (T_k - t_i + d_l/2).
    """
    a = np.where(np.isfinite(acc), acc, 0.0)
    missing = (~np.isfinite(acc)).any(axis=1).astype(float)
    if missing_psd is not None:
        missing = missing * np.asarray(missing_psd, dtype=float)
    N = len(idx)
    T = t_in[idx]
    k_r, k_l, d_r, d_l = _half_holds(t_in, idx)
    dV = np.zeros((N, 3))
    dP = np.zeros((N, 3))
    miss = np.zeros(N)
    for k_h, d_h, sgn in ((k_r, d_r, 1.0), (k_l, d_l, -1.0)):
        ok = k_h < N
        Tk = T[np.minimum(k_h, N - 1)]
        w_p = d_h * (Tk - t_in - sgn * d_h / 2.0)
        for j in range(3):
            dV[:, j] += np.bincount(k_h[ok], weights=(a[:, j] * d_h)[ok], minlength=N)[:N]
            dP[:, j] += np.bincount(k_h[ok], weights=(a[:, j] * w_p)[ok], minlength=N)[:N]
        miss += np.bincount(k_h[ok], weights=(missing * d_h)[ok], minlength=N)[:N]
    return dV, dP, miss


def attitude_jacobian(Cnb: np.ndarray, f_body: np.ndarray) -> np.ndarray:
    """Derivatives of the rotated specific force C_nb f with respect to roll and pitch.

    For C_nb = R_z(psi) R_y(theta) R_x(phi): dC/dphi f = C_nb (e_x x f) and
    dC/dtheta f = R_z R_y (e_y x R_x f) = C_nb (u x f) with u = R_x^T e_y = (0, cos phi,
    -sin phi); phi = atan2(C_32, C_33).  Returns (N, 3, 2): columns roll, pitch (per radian,
    in the units of ``f_body``).
    """
    phi = np.arctan2(Cnb[:, 2, 1], Cnb[:, 2, 2])
    ex = np.zeros_like(f_body)
    ex[:, 1], ex[:, 2] = -f_body[:, 2], f_body[:, 1]
    u = np.c_[np.zeros(len(phi)), np.cos(phi), -np.sin(phi)]
    out = np.empty((len(phi), 3, 2))
    out[:, :, 0] = np.einsum("kij,kj->ki", Cnb, ex)
    out[:, :, 1] = np.einsum("kij,kj->ki", Cnb, np.cross(u, f_body))
    return out


@nb.njit(cache=True, nogil=True)
def attitude_step_means(Cnb, fb, idx, t_in):
    """Step means of C_nb, C_nb diag(f) and :func:`attitude_jacobian` in one pass over the input
    samples, without the per-sample intermediate arrays, weighted as the increments hold them
    (:func:`_half_holds`): over step k the samples idx[k-1] .. idx[k], the two ends for half their
    intervals; the sample idx[0] itself for the first step."""
    N = idx.shape[0]
    Ni = Cnb.shape[0]
    C_m = np.zeros((N, 3, 3))
    S_m = np.zeros((N, 3, 3))
    J_m = np.zeros((N, 3, 2))
    for k in range(N):
        a = idx[k - 1] if k > 0 else idx[0]
        b = idx[k] + 1 if k > 0 else min(idx[0] + 1, Ni)
        cnt = 0.0
        for i in range(a, b):
            if k == 0:
                w = 1.0
            else:
                w = 0.0
                if i < b - 1:                       # right half, inside the step
                    w += 0.5 * (t_in[i + 1] - t_in[i])
                if i > a:                           # left half, inside the step
                    w += 0.5 * (t_in[i] - t_in[i - 1])
            if w == 0.0:
                continue
            cnt += w
            f0, f1, f2 = w * fb[i, 0], w * fb[i, 1], w * fb[i, 2]
            phi = np.arctan2(Cnb[i, 2, 1], Cnb[i, 2, 2])
            uy, uz = np.cos(phi), -np.sin(phi)
            # e_x x f = (0, -f2, f1); u x f = (uy f2 - uz f1, uz f0, -uy f0)
            r0, r1, r2 = 0.0, -f2, f1
            p0, p1, p2 = uy * f2 - uz * f1, uz * f0, -uy * f0
            for r in range(3):
                c0, c1, c2 = Cnb[i, r, 0], Cnb[i, r, 1], Cnb[i, r, 2]
                C_m[k, r, 0] += w * c0
                C_m[k, r, 1] += w * c1
                C_m[k, r, 2] += w * c2
                S_m[k, r, 0] += c0 * f0
                S_m[k, r, 1] += c1 * f1
                S_m[k, r, 2] += c2 * f2
                J_m[k, r, 0] += c0 * r0 + c1 * r1 + c2 * r2
                J_m[k, r, 1] += c0 * p0 + c1 * p1 + c2 * p2
        if cnt > 0:  # element loops, not C_m[k] /= cnt: no shape-check path to compile
            for r in range(3):
                for c in range(3):
                    C_m[k, r, c] /= cnt
                    S_m[k, r, c] /= cnt
                for c in range(2):
                    J_m[k, r, c] /= cnt
    return C_m, S_m, J_m


def q_vector(nz: JointNoise) -> np.ndarray:
    """The process noise's parameters in the kernels' order (:class:`~flightrecon.methods.joint.
    layout.Dynamics` ``q``; docs/joint.md, "State and frame")."""
    return np.array([nz.accel_noise_mps2_sqrt_hz ** 2, nz.wind_rw_mps_sqrt_s ** 2,
                     nz.wind_shear_mps_per_sqrt_m ** 2, nz.accel_bias_g ** 2, nz.accel_bias_tau_s,
                     np.radians(nz.heading_bias_rw_deg_sqrt_s) ** 2,
                     nz.baro_offset_rw_m_sqrt_s ** 2,
                     (nz.wind_gradient_rw_per_km_sqrt_s / 1000.0) ** 2, nz.gust_mps ** 2,
                     *(np.square(np.asarray(nz.accel_sampling_mps2_sqrt_hz, dtype=float)))])


def initial_estimate(inp: JointInputs, nom_ecef: np.ndarray, nz: JointNoise, min_speed: float,
                     priors: tuple[tuple[str, float, float], ...] = ()
                     ) -> tuple[np.ndarray, np.ndarray]:
    """The prior of x_0 (mean, covariance): the nominal's first position ``nom_ecef[0]``, the air
    velocity along the heading from ``min_speed`` on, zero sensor errors, each state's budget of
    ``nz`` as its variance, then the ``priors`` (state, mean, sd) in their place (e.g. an
    aircraft's fleet calibration)."""
    n = jl.N_STATE
    x0 = np.zeros(n)
    x0[jl.S_POS] = nom_ecef[0]
    psi0 = inp.heading_rad[0]
    if np.isfinite(inp.tas[0]) and inp.tas[0] >= min_speed:
        x0[jl.IV:jl.IV + 2] = inp.tas[0] * np.array([np.cos(psi0), np.sin(psi0)])
    P0 = np.zeros((n, n))
    for states, v in ((jl.S_POS, nz.init_pos_m ** 2), (jl.S_VEL, nz.init_vel_mps ** 2),
                      (jl.S_WIND, nz.wind_prior_mps ** 2), (jl.S_ACC_BIAS, nz.accel_bias_g ** 2),
                      (jl.IPSI, np.radians(nz.heading_bias_deg) ** 2), (jl.IS, nz.tas_scale ** 2),
                      (jl.IBH, nz.baro_offset_m ** 2), (jl.IC, nz.baro_scale ** 2),
                      (jl.IDW, nz.doppler_scale ** 2), (jl.IDC, np.radians(nz.drift_bias_deg) ** 2),
                      (jl.S_ACC_SCALE, nz.accel_scale ** 2),
                      (jl.S_ATT_BIAS, np.radians(nz.attitude_bias_deg) ** 2),
                      (jl.S_WIND_GRAD, (nz.wind_gradient_per_km / 1000.0) ** 2),
                      (jl.S_GUST, nz.gust_mps ** 2)):
        d = np.arange(n)[states]
        P0[d, d] = v
    for name, mean, sd in priors:
        i, f, _ = PRIOR_STATES[name]
        x0[i], P0[i, i] = mean * f, (sd * f) ** 2
    return x0, P0


class Nominal(NamedTuple):
    """A linearisation point: the positions ``lat``, ``lon``, ``h``, the velocity ``vnom`` (runway
    rows, take-off roll), the heading bias ``psi_hat`` (the rotation's linearisation) and the
    accelerometer biases ``ba_hat`` (the take-off roll) of the iterate; the first pass's
    (:func:`nominal_trajectory`) has the air data's velocity and no biases (None)."""

    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    vnom: np.ndarray
    psi_hat: np.ndarray | None = None
    ba_hat: np.ndarray | None = None


def nominal_trajectory(inp: JointInputs, idx: np.ndarray) -> Nominal:
    """Iteration-0 linearisation point on the state grid (:class:`Nominal`).

    Air-data dead reckoning (airspeed and heading, plus the recorded wind) integrated on the
    ellipsoid (:func:`flightrecon.geo.navframe.integrate_local_level`, valid on flights of any
    length), heights from pressure altitude; then tied to the data that fix position: to the GNSS
    fixes where there are any (the differences at the fixes, interpolated linearly in time; the
    track between fixes keeps the shape of the dead reckoning), otherwise to the end points
    ``inp.end_points`` (started at the departure one; a correction growing linearly from it to the
    arrival one, as the DR+linear baseline); the velocity the air data's.  Only the starting point
    of the Gauss-Newton iterations: it decides how many are needed, not where they converge.
    """
    t = inp.t_in
    tas = np.where(np.isfinite(inp.tas), inp.tas, 0.0)
    psi = np.where(np.isfinite(inp.heading_rad), inp.heading_rad, 0.0)
    vn, ve = tas * np.cos(psi), tas * np.sin(psi)
    if inp.wind_ne is not None:
        w = np.where(np.isfinite(inp.wind_ne), inp.wind_ne, 0.0)
        vn, ve = vn + w[:, 0], ve + w[:, 1]
    g = inp.gnss
    gok = np.zeros(0, bool)
    if len(g):
        gok = (np.isfinite(g["lat_deg"].to_numpy(float)) & np.isfinite(g["lon_deg"].to_numpy(float))
               & np.isfinite(g["t_s"].to_numpy(float)))
    ends = {ep.which: ep for ep in inp.end_points}
    ref, t_ref = None, t[0]
    if "departure" in ends:
        ref, t_ref = ends["departure"].point, ends["departure"].t_s
    if ref is None and gok.any():
        i0 = int(np.flatnonzero(gok)[0])
        ref = (float(g["lat_deg"].iloc[i0]), float(g["lon_deg"].iloc[i0]),
               float(np.nan_to_num(g["h_m"].iloc[i0])))
        t_ref = float(g["t_s"].iloc[i0])
    if ref is None:
        ref = inp.station if inp.station is not None else (0.0, 0.0, 0.0)
    # state-grid velocities held over each step (the grid is fine enough for a nominal)
    T = t[idx]
    dts = np.diff(T)
    steps = np.maximum(dts, 1e-9)
    lat, lon, _ = integrate_local_level(ref[0], ref[1], 0.0, vn[idx[:-1]], ve[idx[:-1]], 0.0,
                                        steps) if len(idx) > 1 else (np.array([ref[0]]),
                                                                     np.array([ref[1]]), None)
    # the integration starts at the first sample; the reference holds at t_ref
    k_ref = int(np.clip(np.searchsorted(T, t_ref), 0, len(T) - 1))
    lat = lat - lat[k_ref] + ref[0]
    lon = lon - lon[k_ref] + ref[1]
    baro = np.where(np.isfinite(inp.baro_rel_m), inp.baro_rel_m, 0.0)[idx]
    h = inp.field_h + baro
    if gok.any():
        tg = g["t_s"].to_numpy(float)[gok]
        dlat = g["lat_deg"].to_numpy(float)[gok] - np.interp(tg, T, lat)
        dlon = (g["lon_deg"].to_numpy(float)[gok] - np.interp(tg, T, lon) + 180.0) % 360.0 - 180.0
        lat = lat + np.interp(T, tg, dlat)
        lon = lon + np.interp(T, tg, dlon)
        hg = g["h_m"].to_numpy(float)[gok]
        okh = np.isfinite(hg)
        if okh.any():
            h = h + np.interp(T, tg[okh], hg[okh] - np.interp(tg[okh], T, h))
    elif "arrival" in ends and np.isfinite(inp.touchdown_t):
        t_end, (lat_end, lon_end, _) = ends["arrival"].t_s, ends["arrival"].point
        k_end = int(np.clip(np.searchsorted(T, t_end), 0, len(T) - 1))
        dlat = lat_end - lat[k_end]
        dlon = (lon_end - lon[k_end] + 180.0) % 360.0 - 180.0
        frac = np.clip((T - t_ref) / max(t_end - t_ref, 1e-9), 0.0, 1.0)
        lat = lat + frac * dlat
        lon = lon + frac * dlon
    lon = (lon + 180.0) % 360.0 - 180.0
    tas0, psi0 = np.nan_to_num(inp.tas[idx]), np.nan_to_num(inp.heading_rad[idx])
    return Nominal(lat, lon, h, np.c_[tas0 * np.cos(psi0), tas0 * np.sin(psi0), np.zeros(len(idx))])


def relinearised_increments(acc: np.ndarray, dV: np.ndarray, dP: np.ndarray, dt: np.ndarray,
                            psi_hat: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The step accelerations and increments for a transition linearised about the heading bias
    ``psi_hat`` (per step) instead of zero (docs/joint.md, "Filter, smoother, iterations", item 2).

    The true increment is R(-dpsi) dV (the bias rotates the measured horizontal acceleration
    about the vertical); about psi_hat it is R(-psi_hat) dV + (dpsi - psi_hat) J R(-psi_hat) dV
    with J u = (u_E, -u_N, 0). The kernels build F[v, dpsi] = J a h (and J a h^2/2 for the
    position) from the acceleration they are given and add the increments, so they are given
    a' = R(-psi_hat) a, dV' = R(-psi_hat) dV - J a' h psi_hat and dP' = dP + (a' - a) h^2/2 -
    J a' h^2/2 psi_hat (the held-mean part of the position increment rotated, the remainder, second
    order, not): the state keeps the whole bias, and the transition is exact at the solution."""
    c, s = np.cos(psi_hat), np.sin(psi_hat)

    def rot(u: np.ndarray) -> np.ndarray:
        return np.c_[u[:, 0] * c + u[:, 1] * s, -u[:, 0] * s + u[:, 1] * c, u[:, 2]]

    a_r = rot(acc)
    ja = np.c_[a_r[:, 1], -a_r[:, 0], np.zeros(len(a_r))]
    dV_r = rot(dV) - ja * (dt * psi_hat)[:, None]
    # the position increment: its held-mean part a h^2/2 rotated by the bias, the rest (the
    # acceleration's variation within the step, second order) not: then F[p, dpsi] = J a' h^2/2
    # is its exact derivative in the bias, so that the Gauss-Newton step is a descent
    # direction of the MAP cost (with R(-dpsi) dP it missed J (R dP - a' h^2/2), which in a
    # spiral dive made the line search fail: docs/joint.md)
    hh = (0.5 * dt * dt)[:, None]
    dP_r = dP + (a_r - acc) * hh - ja * (hh * psi_hat[:, None])
    return np.ascontiguousarray(a_r), np.ascontiguousarray(dV_r), np.ascontiguousarray(dP_r)


def smoother_flight(inp: JointInputs, settings: JointSettings) -> SmootherFlight:
    """The iteration-independent parts (:class:`SmootherFlight`), built once per problem
    (:mod:`~flightrecon.methods.joint.problem`)."""
    idx = state_grid(inp.t_in, settings.state_rate_hz)
    T = inp.t_in[idx]
    dt = np.diff(T, prepend=T[0])
    dV, dP, miss = held_increments(inp.t_in, inp.acc_ned, idx, inp.missing_psd)
    acc = dV / np.where(dt > 0, dt, 1.0)[:, None]
    fb = np.zeros((len(inp.t_in), 3)) if inp.f_body_g is None else np.nan_to_num(inp.f_body_g)
    # the input samples' rotations only for this (41 MB on a 10-hour flight at 16 Hz)
    Cnb, Csf, Jatt = attitude_step_means(inp.body_to_ned(), np.ascontiguousarray(fb),
                                          idx.astype(np.int64),
                                          np.ascontiguousarray(inp.t_in, dtype=float))
    # missing loads: (1 m/s^2)^2/Hz, or the inputs' missing_psd, over the share of the step
    qv_extra = np.where(dt > 0, miss / np.where(dt > 0, dt, 1.0), 0.0)
    # the attitude reference's tilt after sustained loads (tilt.py, eq. 2)
    qv_extra = qv_extra + tilt_psd(inp.t_in, inp.f_body_g, idx, settings.noise, inp.acc_ned)
    Cst, pst = np.eye(3), np.zeros(3)
    if inp.station is not None:
        Cst = enu_to_ecef_matrix(inp.station[0], inp.station[1])
        sx, sy, sz = geodetic_to_ecef(*inp.station)
        pst = np.array([float(sx), float(sy), float(sz)])
    ga = gust_decay(dt, inp.tas[idx], settings.noise, settings.min_airspeed_mps)
    return SmootherFlight(inp, settings, idx, T, dt, acc, dV, dP, Cnb, Csf, Jatt, qv_extra,
                          q_vector(settings.noise), ga, static_measurements(inp, settings, T), pst,
                          Cst, nominal_trajectory(inp, idx))


def models_at(fl: SmootherFlight, nom: Nominal, clock: dict[str, float],
              roll: TakeoffRoll) -> PassModels:
    """Dynamics, measurements (with their noise groups and the end points at ``roll``) and geometry
    linearised about the nominal ``nom`` (its positions, velocity and heading bias; ``psi_hat``
    None: zero, the first pass), with the clock offsets ``clock`` and the take-off roll ``roll``
    (docs/joint.md, "Filter, smoother, iterations", item 2)."""
    lat, lon, h, vnom, psi_hat = nom.lat, nom.lon, nom.h, nom.vnom, nom.psi_hat
    ex, ey, ez = geodetic_to_ecef(lat, lon, h)
    pnom = np.ascontiguousarray(np.c_[ex, ey, ez])
    Cen = np.ascontiguousarray(ned_to_ecef_matrix(lat, lon))
    dz = np.diff(h, prepend=h[0])   # signed height change: the wind moves along its gradient
    if psi_hat is None:
        acc_k, dV_k, dP_k = fl.acc, fl.dV, fl.dP
    else:
        acc_k, dV_k, dP_k = relinearised_increments(fl.acc, fl.dV, fl.dP, fl.dt, psi_hat)
    acc_k, dV_k, dP_k = _with_frame_rate(acc_k, dV_k, dP_k, fl.dt, lat, h, vnom)
    dyn = jl.Dynamics(fl.dt, Cen, fl.Cnb, fl.Csf, fl.Jatt, acc_k, dP_k, dV_k, dz, fl.qv_extra,
                      fl.q, fl.ga)
    geo = jl.Geometry(pnom, h - fl.inp.field_h, fl.pst, fl.Cst)
    meas, ends = build_measurements(fl.inp, fl.settings, fl.T, Cen, dict(clock), fl.static, pnom,
                              vnom, roll, psi_hat)
    sc = jl.Scalars(meas.start, meas.mtype, meas.z, meas.r, np.ones(len(meas.z)),
                    meas.t - fl.T[meas.step], meas.H, meas.hrow, meas.d)
    return PassModels(lat, lon, h, meas, dyn, geo, roll, ends, dict(clock), noise_groups(meas), sc)


def _with_frame_rate(acc: np.ndarray, dV: np.ndarray, dP: np.ndarray, dt: np.ndarray,
                     lat: np.ndarray, h: np.ndarray, vnom: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The step accelerations and increments with the Coriolis and transport-rate acceleration c =
    -(2 omega_ie + omega_en) x v that the accelerometers do not sense
    (:func:`~flightrecon.geo.navframe.frame_rate_acceleration`, docs/joint.md, "State and frame"),
    at the nominal velocity: the mean of its values at the step's two ends, added as c dt and c dt^2
    / 2.  The nominal is the iterate, so at convergence c is the solution's own; its dependence on
    the velocity (1.5e-4 1/s) is left out of the transition matrix."""
    c = frame_rate_acceleration(lat, h, vnom)
    c = 0.5 * (c + np.vstack([c[:1], c[:-1]]))
    return (np.ascontiguousarray(acc + c), np.ascontiguousarray(dV + c * dt[:, None]),
            np.ascontiguousarray(dP + c * (0.5 * dt * dt)[:, None]))


def _in_frame(X: np.ndarray, Cen_from: np.ndarray, Cen_to: np.ndarray) -> np.ndarray:
    """``X`` with its local-level components (velocity, wind, wind gradient: north-east-down at the
    nominal position ``Cen_from``) re-expressed in the frames ``Cen_to``: v' = C_to^T C_from v per
    step (the wind and its gradient as horizontal vectors, their vertical part, second order in the
    frames' angle, dropped).  A smoothed trajectory is in the frames of the nominal it was
    linearised about; about itself, its own positions' frames hold (the angle is the track's shift
    over the Earth's radius: 0.03 rad for 190 km)."""
    R = np.einsum("kji,kjl->kil", Cen_to, Cen_from)
    Y = X.copy()
    Y[:, jl.S_VEL] = np.einsum("kij,kj->ki", R, X[:, jl.S_VEL])
    for sl in (jl.S_WIND, jl.S_WIND_GRAD):
        Y[:, sl] = np.einsum("kij,kj->ki", R[:, :2, :2], X[:, sl])
    return Y


def models_about(fl: SmootherFlight, X: np.ndarray, like: PassModels, r: np.ndarray,
                 weights: np.ndarray) -> tuple[PassModels, np.ndarray, Cost]:
    """:func:`models_at` about the trajectory ``X`` itself (its positions, velocities and heading
    bias; its local-level components in the frames of ``like``, whose clock offsets and take-off
    roll it keeps), ``X`` in its own frames (:func:`_in_frame`) and its MAP cost in those
    models with the variances ``r`` and weights ``weights`` (:func:`pass_cost`: its nonlinear
    cost; a line-search or Levenberg-Marquardt candidate, docs/joint.md, "Damping")."""
    lat, lon, h = ecef_to_geodetic(X[:, 0], X[:, 1], X[:, 2])
    Cen = np.ascontiguousarray(ned_to_ecef_matrix(lat, lon))
    Y = _in_frame(X, like.dyn.Cen, Cen)
    mdl = models_at(fl, Nominal(lat, lon, h, Y[:, jl.S_VEL], np.ascontiguousarray(Y[:, jl.IPSI])),
                    like.clock, like.roll)
    return mdl, Y, pass_cost(fl, mdl, Y, r, weights)


def nominal_states(fl: SmootherFlight, mdl: PassModels) -> np.ndarray:
    """The starting trajectory of the damped iterations with ``first_pass = "nominal"``: the nominal
    positions, the air-data velocity of the nominal (plus the recorded wind, the wind state holding
    it) and the prior means of the sensor errors."""
    assert fl.x0 is not None
    X = np.repeat(fl.x0[None, :], len(fl.T), axis=0)
    inp, idx = fl.inp, fl.idx
    tas = np.nan_to_num(inp.tas[idx])
    psi = np.nan_to_num(inp.heading_rad[idx])
    w = np.zeros((len(idx), 2))
    if inp.wind_ne is not None:
        w = np.where(np.isfinite(inp.wind_ne[idx]), inp.wind_ne[idx], 0.0)
    # (at least 1 m/s through the air: the airspeed and heading functions are singular at 0)
    tas = np.maximum(tas, 1.0)
    X[:, jl.S_POS] = mdl.geo.pnom
    X[:, jl.IV] = tas * np.cos(psi) + w[:, 0]
    X[:, jl.IV + 1] = tas * np.sin(psi) + w[:, 1]
    X[:, jl.IV + 2] = -np.gradient(mdl.h, fl.T) if len(fl.T) > 1 else 0.0
    X[:, jl.S_WIND] = w
    return X


def pass_cost(fl: SmootherFlight, mdl: PassModels, X: np.ndarray, r: np.ndarray,
              weights: np.ndarray) -> Cost:
    """MAP cost of ``X`` (models built about it) and its residuals and rates
    (:func:`~flightrecon.methods.joint.model.map_cost`)."""
    s = fl.settings
    assert fl.x0 is not None and fl.P0inv is not None
    # the weights only mark left-out measurements (w <= 0); the loss is the robust one
    sc = mdl.scalars._replace(r=r, w=weights)
    try:
        prior, process, data, const, res, rate, n_fail = map_cost(
            X, fl.x0, fl.P0inv, mdl.dyn, sc, mdl.geo, s.huber_c, s.reject_c, s.robust)
    except ZeroDivisionError:
        # a measurement function at a singular point (an air velocity of exactly zero under
        # an airspeed or heading measurement): no finite cost, the candidate is not taken
        M = len(mdl.meas.z)
        prior = process = data = const = np.inf
        res, rate, n_fail = np.full(M, np.nan), np.full(M, np.nan), 0
    cost = {"cost": prior + process + data, "cost_prior": prior, "cost_process": process,
            "cost_data": data, "cost_constant_state_change": const, "cost_q_failures": int(n_fail)}
    return Cost(cost, res, rate)


def gust_decay(dt: np.ndarray, tas_mps: np.ndarray, nz: JointNoise,
               min_airspeed_mps: float) -> np.ndarray:
    """Decay of the gust state over each step, a_k = exp(-V_k dt_k / L) (docs/joint.md, "Wind and
    turbulence").

    The gust is a first-order Gauss-Markov process in the distance flown (the frozen-turbulence view
    of the Dryden model: correlation length L = ``nz.gust_length_m``), so its correlation time is L
    / V with V the recorded airspeed at the step, held at ``min_airspeed_mps`` where it is lower or
    missing (on the ground the gust then decorrelates within seconds and no air data are used
    there).
    """
    v = np.where(np.isfinite(tas_mps), tas_mps, 0.0)
    v = np.maximum(v, min_airspeed_mps)
    return np.exp(-np.asarray(dt, float) * v / nz.gust_length_m)


@dataclass(frozen=True)
class SmootherFlight:
    """What the iterations hold fixed: the state grid, the held-input increments, the attitude step
    means, the process noise, the measurement table's static part, the station, the first pass's
    linearisation point (``nominal``) and the prior of x_0 (None until the first pass's models
    give the nominal's position at step 0)."""

    inp: JointInputs
    settings: JointSettings
    idx: np.ndarray           # input samples that are state steps
    T: np.ndarray
    dt: np.ndarray
    acc: np.ndarray
    dV: np.ndarray
    dP: np.ndarray
    Cnb: np.ndarray
    Csf: np.ndarray
    Jatt: np.ndarray
    qv_extra: np.ndarray
    q: np.ndarray
    ga: np.ndarray            # gust decay over each step (turbulence.gust_decay)
    static: Any
    pst: np.ndarray
    Cst: np.ndarray
    nominal: Nominal
    x0: np.ndarray | None = None
    P0: np.ndarray | None = None
    P0inv: np.ndarray | None = None


@dataclass(frozen=True)
class PassModels:
    """The dynamics, measurements and geometry built about one linearisation point (its ECEF
    positions ``geo.pnom``, its frames ``dyn.Cen``)."""

    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    meas: Measurements
    dyn: jl.Dynamics
    geo: jl.Geometry
    roll: TakeoffRoll
    ends: tuple[EndPoint, ...]   # the end points at ``roll`` (inputs.end_points_at)
    clock: dict[str, float]
    groups: np.ndarray        # index into NOISE_GROUPS of each measurement (-1: none)
    scalars: jl.Scalars       # the kernels' measurements, nominal variances, unit weights: a
    #                           pass's own by ``scalars._replace(r=..., w=...)``
