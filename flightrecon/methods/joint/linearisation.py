"""Linearisation of the joint smoother's iterations: what the passes hold fixed
(:class:`SmootherFlight`), the models built about a nominal or about an iterate
(:class:`PassModels`, with the local-level components re-expressed in the iterate's own
frames) and the MAP cost of an iterate (:func:`pass_cost`, the kernel in
:mod:`~flightrecon.methods.joint.cost`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from flightrecon.geo.frames import ecef_to_geodetic, geodetic_to_ecef
from flightrecon.geo.navframe import frame_rate_acceleration, ned_to_ecef_matrix
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.cost import map_cost
from flightrecon.methods.joint.inputs import JointInputs, TakeoffRoll, enu_to_ecef_matrix
from flightrecon.methods.joint.measurements import build_measurements, static_measurements
from flightrecon.methods.joint.noise import noise_groups
from flightrecon.methods.joint.nominal import (
    attitude_step_means,
    held_increments,
    q_vector,
    relinearised_increments,
    state_grid,
)
from flightrecon.methods.joint.settings import JointSettings
from flightrecon.methods.joint.state import PassModels, SmootherFlight
from flightrecon.methods.joint.tilt import tilt_psd
from flightrecon.methods.joint.turbulence import gust_decay


def smoother_flight(inp: JointInputs, settings: JointSettings) -> SmootherFlight:
    """The iteration-independent parts (:class:`SmootherFlight`)."""
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
    Cst = np.eye(3)
    pst = np.zeros(3)
    if inp.station is not None:
        Cst = enu_to_ecef_matrix(inp.station[0], inp.station[1])
        sx, sy, sz = geodetic_to_ecef(*inp.station)
        pst = np.array([float(sx), float(sy), float(sz)])
    ga = gust_decay(dt, inp.tas[idx], settings.noise, settings.min_airspeed_mps)
    return SmootherFlight(inp, settings, idx, T, dt, acc, dV, dP, Cnb, Csf, Jatt, qv_extra,
                   q_vector(settings.noise), ga, static_measurements(inp, settings, T), pst,
                   Cst)


def models_at(fl: SmootherFlight, lat: np.ndarray, lon: np.ndarray, h: np.ndarray,
               vnom: np.ndarray, psi_hat: np.ndarray | None, clock: dict[str, float],
               roll: TakeoffRoll) -> PassModels:
    """Dynamics, measurements and geometry linearised about the nominal (lat, lon, h, vnom,
    heading bias ``psi_hat``; None: zero, the first pass)."""
    inp = fl.inp
    ex, ey, ez = geodetic_to_ecef(lat, lon, h)
    pnom = np.ascontiguousarray(np.c_[ex, ey, ez])
    Cen = np.ascontiguousarray(ned_to_ecef_matrix(lat, lon))
    dz = np.diff(h, prepend=h[0])   # signed height change: the wind moves along its gradient
    meas = build_measurements(inp, fl.settings, fl.T, Cen, fl.Cnb, dict(clock), fl.static, pnom,
                              vnom, roll, psi_hat)
    if psi_hat is None:
        acc_k, dV_k, dP_k = fl.acc, fl.dV, fl.dP
    else:
        acc_k, dV_k, dP_k = relinearised_increments(fl.acc, fl.dV, fl.dP, fl.dt, psi_hat)
    acc_k, dV_k, dP_k = _with_frame_rate(acc_k, dV_k, dP_k, fl.dt, lat, h, vnom)
    dyn = jl.Dynamics(fl.dt, Cen, fl.Cnb, fl.Csf, fl.Jatt, acc_k, dP_k, dV_k, dz, fl.qv_extra,
                      fl.q, fl.ga)
    geo = jl.Geometry(pnom, h - inp.field_h, fl.pst, fl.Cst)
    return PassModels(lat, lon, h, pnom, Cen, meas, dyn, geo, roll, dict(clock),
                   noise_groups(meas))


def _with_frame_rate(acc: np.ndarray, dV: np.ndarray, dP: np.ndarray, dt: np.ndarray,
                     lat: np.ndarray, h: np.ndarray, vnom: np.ndarray
                     ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The step accelerations and increments with the Coriolis and transport-rate acceleration
    c = -(2 omega_ie + omega_en) x v that the accelerometers do not sense
    (:func:`~flightrecon.geo.navframe.frame_rate_acceleration`, docs/joint.md, "State and
    frame"), at the nominal velocity: the mean of its values at the step's two ends, added as
    c dt and c dt^2 / 2.  The nominal is the iterate, so at convergence c is the solution's own;
    its dependence on the velocity (1.5e-4 1/s) is left out of the transition matrix."""
    c = frame_rate_acceleration(lat, h, vnom)
    c = 0.5 * (c + np.vstack([c[:1], c[:-1]]))
    return (np.ascontiguousarray(acc + c), np.ascontiguousarray(dV + c * dt[:, None]),
            np.ascontiguousarray(dP + c * (0.5 * dt * dt)[:, None]))


def _in_frame(X: np.ndarray, Cen_from: np.ndarray, Cen_to: np.ndarray) -> np.ndarray:
    """``X`` with its local-level components (velocity, wind, wind gradient: north-east-down
    at the nominal position ``Cen_from``) re-expressed in the frames ``Cen_to``:
    v' = C_to^T C_from v per step (the wind and its gradient as horizontal vectors, their
    vertical part, second order in the frames' angle, dropped).  A smoothed trajectory is in
    the frames of the nominal it was linearised about; about itself, its own positions' frames
    hold (the angle is the track's shift over the Earth's radius: 0.03 rad for 190 km)."""
    R = np.einsum("kji,kjl->kil", Cen_to, Cen_from)
    Y = X.copy()
    Y[:, jl.S_VEL] = np.einsum("kij,kj->ki", R, X[:, jl.S_VEL])
    for sl in (jl.S_WIND, jl.S_WIND_GRAD):
        Y[:, sl] = np.einsum("kij,kj->ki", R[:, :2, :2], X[:, sl])
    return Y


def models_about(fl: SmootherFlight, X: np.ndarray, Cen_from: np.ndarray, clock: dict[str, float],
                  roll: TakeoffRoll) -> tuple[PassModels, np.ndarray]:
    """:func:`models_at` about the trajectory ``X`` itself (its positions, velocities and
    heading bias; its local-level components in the frames ``Cen_from``), and ``X`` in its
    own frames (:func:`_in_frame`): the models in which the cost of ``X`` is its nonlinear
    cost."""
    lat, lon, h = ecef_to_geodetic(X[:, 0], X[:, 1], X[:, 2])
    Cen = np.ascontiguousarray(ned_to_ecef_matrix(lat, lon))
    Y = _in_frame(X, Cen_from, Cen)
    return models_at(fl, lat, lon, h, Y[:, jl.S_VEL], np.ascontiguousarray(Y[:, jl.IPSI]),
                      clock, roll), Y


def nominal_states(fl: SmootherFlight, mdl: PassModels) -> np.ndarray:
    """The starting trajectory of the damped iterations with ``first_pass = "nominal"``: the
    nominal positions, the air-data velocity of the nominal (plus the recorded wind, the
    wind state holding it) and the prior means of the sensor errors."""
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
    X[:, jl.S_POS] = mdl.pnom
    X[:, jl.IV] = tas * np.cos(psi) + w[:, 0]
    X[:, jl.IV + 1] = tas * np.sin(psi) + w[:, 1]
    X[:, jl.IV + 2] = -np.gradient(mdl.h, fl.T) if len(fl.T) > 1 else 0.0
    X[:, jl.S_WIND] = w
    return X


def scaled_variances(mdl: PassModels, scale: np.ndarray) -> np.ndarray:
    """Nominal measurement variances with the noise factors of their groups."""
    g = mdl.groups
    return mdl.meas.r * np.where(g >= 0, scale[np.maximum(g, 0)], 1.0)


def pass_scalars(mdl: PassModels, T: np.ndarray, r: np.ndarray, weights: np.ndarray) -> jl.Scalars:
    m = mdl.meas
    return jl.Scalars(m.start, m.mtype, m.z, r, weights, m.t - T[m.step], m.H, m.hrow, m.d)


def pass_cost(fl: SmootherFlight, mdl: PassModels, X: np.ndarray, r: np.ndarray,
          weights: np.ndarray) -> tuple[dict[str, Any], np.ndarray, np.ndarray]:
    """MAP cost of ``X`` (models built about it) and its residuals and rates
    (:func:`~flightrecon.methods.joint.cost.map_cost`)."""
    s = fl.settings
    assert fl.x0 is not None and fl.P0inv is not None
    # the weights only mark left-out measurements (w <= 0); the loss is the robust one
    try:
        prior, process, data, const, res, rate, n_fail = map_cost(
            X, fl.x0, fl.P0inv, mdl.dyn, pass_scalars(mdl, fl.T, r, weights), mdl.geo,
            s.huber_c, s.reject_c, s.robust)
    except ZeroDivisionError:
        # a measurement function at a singular point (an air velocity of exactly zero under
        # an airspeed or heading measurement): no finite cost, the candidate is not taken
        M = len(mdl.meas.z)
        prior = process = data = const = np.inf
        res, rate, n_fail = np.full(M, np.nan), np.full(M, np.nan), 0
    cost = {"cost": prior + process + data, "cost_prior": prior, "cost_process": process,
            "cost_data": data, "cost_constant_state_change": const,
            "cost_q_failures": int(n_fail)}
    return cost, res, rate


def with_pseudo(sc: jl.Scalars, X: np.ndarray, sd: np.ndarray, lam: float) -> jl.Scalars:
    """``sc`` with the Levenberg-Marquardt pseudo-measurements x_k,i = X_k,i of variance
    sd_i^2 / lam appended to every step's measurements (Sarkka & Svensson 2020, section 3: the
    smoother then minimises the linearised cost plus lam/2 sum_k |x_k - X_k|^2_D, D =
    diag(1/sd^2), the states scaled by their prior sd)."""
    N, n = X.shape
    M = len(sc.z)
    step = np.repeat(np.arange(N), np.diff(sc.start))
    start = sc.start + n * np.arange(N + 1)
    pos = np.arange(M) + n * step
    pseudo = ((start[1:] - n)[:, None] + np.arange(n)[None, :]).ravel()

    def put(orig: np.ndarray, extra: np.ndarray | float) -> np.ndarray:
        out = np.empty(M + N * n, dtype=orig.dtype)
        out[pos] = orig
        out[pseudo] = np.broadcast_to(extra, (N, n)).ravel()
        return out

    K = sc.H.shape[0]
    return jl.Scalars(start, put(sc.mtype, jl.LINEAR), put(sc.z, X), put(sc.r, sd ** 2 / lam),
                      put(sc.w, 1.0), put(sc.tau, 0.0), np.vstack([sc.H, np.eye(n)]),
                      put(sc.row, K + np.arange(n)), put(sc.d, 0.0))
