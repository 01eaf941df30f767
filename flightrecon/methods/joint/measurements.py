"""Measurements of the joint smoother: every source's scalar measurements, each at its own time."""

from __future__ import annotations

import numba as nb
import numpy as np

from flightrecon.geo.frames import ecef_to_geodetic, geodetic_to_ecef
from flightrecon.geo.navframe import ned_to_ecef_matrix
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.airdata import nose_along_air, nose_offset
from flightrecon.methods.joint.ground import (
    decimate_mask,
    lineup_heading,
    on_ground_mask,
    runway_measurements,
)
from flightrecon.methods.joint.inputs import (
    JointInputs,
    TakeoffRoll,
    end_points_at,
    nearest_index,
    refined_roll,
)
from flightrecon.methods.joint.layout import Measurements
from flightrecon.methods.joint.settings import SOURCES, JointSettings


def per_fix_sd(g, column: str, default: float) -> np.ndarray:
    """Per-fix standard deviations from ``column`` of the GNSS table (the receiver's own
    accuracy figures), ``default`` where absent or not finite."""
    if column not in g.columns:
        return np.full(len(g), float(default))
    v = g[column].to_numpy(float)
    return np.where(np.isfinite(v) & (v > 0), v, float(default))


class _MeasBuilder:
    def __init__(self, T: np.ndarray, n: int = jl.N_STATE):
        self.T = T
        self.n = n
        self.parts: list[dict[str, np.ndarray]] = []
        self.H: list[np.ndarray] = []
        self.n_rows = 0

    def copy(self) -> _MeasBuilder:
        b = _MeasBuilder(self.T, self.n)
        b.parts = list(self.parts)
        b.H = list(self.H)
        b.n_rows = self.n_rows
        return b

    def add(self, source: str, mtype: int, t, z, r, H=None, d=None, index=None, rate=None):
        t = np.asarray(t, float)
        z = np.asarray(z, float)
        m = len(t)
        if m == 0:
            return
        r = np.broadcast_to(np.asarray(r, float), (m,)).copy()
        dm = np.zeros(m) if d is None else np.broadcast_to(np.asarray(d, float), (m,)).copy()
        ok = np.isfinite(z) & np.isfinite(t) & np.isfinite(r) & np.isfinite(dm)
        hrow = np.full(m, -1 if index is None else index, dtype=np.int64)
        if H is not None:
            Hm = np.asarray(H, float)
            ok &= np.isfinite(Hm).all(axis=1)
            hrow = self.n_rows + np.arange(m)
            self.H.append(Hm)
            self.n_rows += m
        rt = np.zeros(m) if rate is None else np.broadcast_to(np.asarray(rate, float), (m,))
        self.parts.append({"source": np.full(m, SOURCES.index(source)), "mtype": np.full(m, mtype),
                           "t": t, "z": z, "r": r, "hrow": hrow, "d": dm, "ok": ok,
                           "rate": rt})

    def build(self) -> Measurements:
        T = self.T
        N = len(T)
        keys = ("source", "mtype", "t", "z", "r", "hrow", "d", "ok", "rate")
        cat = {k: np.concatenate([p[k] for p in self.parts]) if self.parts else np.zeros(0)
               for k in keys}
        H = np.concatenate(self.H) if self.H else np.zeros((0, self.n))
        ok = cat["ok"].astype(bool) & (cat["t"] >= T[0] - 0.5 * (T[1] - T[0] if N > 1 else 1)) & (
            cat["t"] <= T[-1] + 0.5 * (T[-1] - T[-2] if N > 1 else 1))
        # each part's state steps found once: the static parts (air data, baro, ...) are
        # shared by every pass's builder on the same grid and keep theirs
        for p in self.parts:
            if p.get("grid") is not T:
                p["step"], p["grid"] = nearest_index(T, p["t"]), T
        t = cat["t"][ok]
        step = np.concatenate([p["step"] for p in self.parts])[ok] if self.parts else \
            np.zeros(0, np.int64)
        order = np.flatnonzero(ok)[np.lexsort((t, step))]
        step = np.sort(step, kind="stable")
        start = np.searchsorted(step, np.arange(N + 1), side="left")
        return Measurements(step=step.astype(np.int64),
                            source=cat["source"][order].astype(np.int64),
                            mtype=cat["mtype"][order].astype(np.int64), z=cat["z"][order],
                            r=cat["r"][order], t=cat["t"][order], H=np.ascontiguousarray(H),
                            hrow=cat["hrow"][order].astype(np.int64), d=cat["d"][order],
                            start=start.astype(np.int64), rate=cat["rate"][order])


@nb.njit(cache=True, nogil=True)
def _wind_prior_picks(t, h, corr_s, corr_m, spacing):
    """Indices of the winds-aloft pseudo-measurements and their correlation with the previous
    one: a new one whenever dt / corr_s + |dh| / corr_m since the last reaches ``spacing``
    (one pass over the candidate samples)."""
    n = t.shape[0]
    idx = np.empty(n, dtype=np.int64)
    rho = np.empty(n)
    m = 0
    for i in range(n):
        if m == 0:
            idx[0] = i
            rho[0] = 0.0
            m = 1
            continue
        j = idx[m - 1]
        d = (t[i] - t[j]) / corr_s + abs(h[i] - h[j]) / corr_m
        if d >= spacing:
            idx[m] = i
            rho[m] = np.exp(-d)
            m += 1
    return idx[:m], rho[:m]


def wind_prior_measurements(inp: JointInputs, settings: JointSettings
                            ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The winds-aloft prior (``--wind``) as sparse pseudo-measurements of the wind states.

    The forecast's error e(t, z) is taken as correlated in time and height,
    corr = exp(-|dt| / tau - |dz| / L) (``settings.wind_prior`` = (tau, L, spacing)).  Using the
    table at every sample as an independent measurement would count the same error hundreds
    of times.  Instead one pseudo-measurement is placed at the first airborne air-data sample
    and a new one whenever |dt| / tau + |dz| / L since the last reaches ``spacing``; each
    after the first has its variance inflated by (1 + rho) / (1 - rho), rho its correlation
    with the previous one.  For an AR(1) chain of n measurements of a constant with
    correlation rho between neighbours, the information is
    [1 + (n - 1)(1 - rho) / (1 + rho)] / sigma^2 (the tridiagonal inverse of the AR(1)
    covariance), which these inflated, independently treated measurements reproduce exactly:
    the forecast is counted once per correlation length, however densely it is sampled
    (docs/wind.md, "The prior in the joint smoother").

    Returns
    -------
    t : (m,) times [s]
    w : (m, 2) north and east wind (where the air moves to) [m/s]
    sd : (m,) standard deviation per component after the inflation [m/s]
    rho : (m,) correlation with the previous pseudo-measurement (0 for the first)
    """
    empty = (np.zeros(0), np.zeros((0, 2)), np.zeros(0), np.zeros(0))
    if inp.wind_aloft is None:
        return empty
    t_in = inp.t_in
    wa = np.asarray(inp.wind_aloft, float)
    ok = (np.isfinite(wa).all(axis=1) & np.isfinite(inp.baro_rel_m) & np.isfinite(inp.tas)
          & (inp.tas >= settings.min_airspeed_mps))
    if np.isfinite(inp.liftoff_t):
        ok &= t_in >= inp.liftoff_t
    if np.isfinite(inp.touchdown_t):
        ok &= t_in <= inp.touchdown_t
    cand = np.flatnonzero(ok)
    if len(cand) == 0:
        return empty
    tau, L, spacing = (float(v) for v in settings.wind_prior)
    pick, rho = _wind_prior_picks(t_in[cand], inp.baro_rel_m[cand], tau, L, spacing)
    i = cand[pick]
    sd = wa[i, 2] * np.sqrt((1.0 + rho) / (1.0 - rho))
    return t_in[i], wa[i, :2], sd, rho


def static_measurements(inp: JointInputs, settings: JointSettings, T: np.ndarray) -> _MeasBuilder:
    """The measurements that do not change between Gauss-Newton iterations: air data, Doppler,
    recorded wind, the winds-aloft prior, pressure altitude, ground and runway constraints
    (built once)."""
    nz = settings.noise
    b = _MeasBuilder(T)
    n = jl.N_STATE
    t_in = inp.t_in

    # air data: airspeed and heading, decimated, airborne speeds only
    ok = (np.isfinite(inp.tas) & np.isfinite(inp.heading_rad)
          & (inp.tas >= settings.min_airspeed_mps))
    keep = ok & decimate_mask(t_in, settings.airdata_rate_hz)
    # a first-order lag delays a ramp by its time constant: the airspeed recorded at t is the
    # airspeed at t - lag; sampled at the state steps plus the lag, so that it is used at a step
    lag = nz.airspeed_lag_s
    keep_tas = ok & decimate_mask(t_in, settings.airdata_rate_hz, t_in[0] + lag) if lag else keep
    b.add("air", jl.TAS, t_in[keep_tas] - lag, inp.tas[keep_tas], nz.tas_mps ** 2)
    # the heading is the air velocity's direction only in the air: on the runway the nose
    # follows the runway (a crosswind of 5 m/s at 40 m/s is 7 deg), and the crab is taken up
    # within seconds after lift-off and taken out in the flare; none within crab_s of them
    air = keep & nose_along_air(inp.attitude_deg, settings)
    if np.isfinite(inp.liftoff_t):
        air &= t_in > inp.liftoff_t + settings.crab_s
    if np.isfinite(inp.touchdown_t):
        air &= t_in < inp.touchdown_t - settings.crab_s
    psi = inp.heading_rad[air]
    if settings.heading_attack_offset:
        psi = psi - nose_offset(inp, at=air)
    b.add("air", jl.HEADING, t_in[air], psi, np.radians(nz.heading_deg) ** 2,
          d=inp.tas[air])   # d: the recorded airspeed (the cross-track gust's angle u_c / V)
    # Doppler ground speed and drift (track = heading + drift), at the air-data rate
    if inp.doppler_gs is not None:
        okd = np.isfinite(inp.doppler_gs) & (inp.doppler_gs >= settings.min_airspeed_mps)
        okd &= decimate_mask(t_in, settings.airdata_rate_hz)
        b.add("doppler", jl.DOPPLER, t_in[okd], inp.doppler_gs[okd], nz.doppler_gs_mps ** 2)
        if inp.drift_rad is not None:
            okc = okd & np.isfinite(inp.drift_rad) & np.isfinite(inp.heading_rad)
            b.add("doppler", jl.TRACK, t_in[okc], inp.heading_rad[okc] + inp.drift_rad[okc],
                  np.radians(nz.drift_deg) ** 2 + np.radians(nz.heading_deg) ** 2)
    # recorded (or forecast) wind, sparsely: its errors are correlated over minutes
    if inp.wind_ne is not None:
        okw = np.isfinite(inp.wind_ne).all(axis=1) & decimate_mask(t_in, settings.wind_rate_hz)
        for i in range(2):
            H = np.zeros((int(okw.sum()), n))
            H[:, jl.IW + i] = 1.0
            b.add("wind", jl.LINEAR, t_in[okw], inp.wind_ne[okw, i], nz.wind_sensor_mps ** 2, H)
    # the winds-aloft prior (--wind): one pseudo-measurement per correlation length
    tw, ww, sdw, _rho = wind_prior_measurements(inp, settings)
    for i in range(2):
        H = np.zeros((len(tw), n))
        H[:, jl.IW + i] = 1.0
        b.add("wind_aloft", jl.LINEAR, tw, ww[:, i], sdw ** 2, H)
    # pressure altitude
    okb = np.isfinite(inp.baro_rel_m) & decimate_mask(t_in, settings.baro_rate_hz)
    b.add("baro", jl.BARO, t_in[okb], inp.baro_rel_m[okb], nz.baro_m ** 2)
    # on the ground: zero vertical velocity (the cross-track constraints depend on the heading
    # bias and the nominal, see build_measurements)
    keep = on_ground_mask(inp, settings)
    if keep.any():
        tt = t_in[keep]
        H = np.zeros((len(tt), n))
        H[:, jl.IV + 2] = 1.0
        b.add("ground", jl.LINEAR, tt, np.zeros(len(tt)), nz.ground_mps ** 2, H)
    return b


def build_measurements(inp: JointInputs, settings: JointSettings, T: np.ndarray, Cen: np.ndarray,
                       Cnb_T: np.ndarray, clock: dict[str, float],
                       static: _MeasBuilder | None = None, pnom: np.ndarray | None = None,
                       vnom: np.ndarray | None = None,
                       roll: TakeoffRoll | None = None,
                       psi_hat: np.ndarray | None = None) -> Measurements:
    """Every source as scalar measurements at its own time (recorder time base).

    ``static`` is :func:`static_measurements` (computed here if not given); the GNSS, radar,
    known-position (``--fix``), end-point and runway measurements depend on the linearisation
    (``Cen``, the nominal ECEF positions ``pnom`` and NED velocities ``vnom`` on the state
    grid) and on the clock offsets
    ``clock`` (seconds *added* to each group's time stamps, the convention of
    ``flightrecon clean --radar-clock-offset``) and are rebuilt on each call.  ``roll`` is
    :func:`refined_roll` (computed here if not given); ``psi_hat`` the heading bias of the last
    pass (per state step), about which the ground constraints are linearised.
    """
    nz = settings.noise
    b = (static if static is not None else static_measurements(inp, settings, T)).copy()
    _gnss_measurements(b, inp, settings, T, Cen, clock, pnom)
    # known positions (--fix): at their own time with their sd, horizontal only without a
    # height (then at the substitute height, as a GNSS fix without one)
    if inp.fixes is not None and len(inp.fixes):
        fx = np.asarray(inp.fixes, float)
        tf = fx[:, 0]
        hf = fx[:, 3].copy()
        no_hf = ~np.isfinite(hf)
        if no_hf.any():
            hf = np.where(no_hf, _substitute_height(inp, T, tf, pnom), hf)
        ex, ey, ez = geodetic_to_ecef(fx[:, 1], fx[:, 2], hf)
        sd_f = fx[:, 4]
        _add_ned_components(b, T, Cen, "fix", tf, None, (sd_f, sd_f, np.where(no_hf, np.nan, sd_f)),
                        "pos", np.c_[ex, ey, ez])
    if pnom is not None and vnom is not None:
        runway_measurements(b, inp, settings, lambda t: nearest_index(T, t), pnom, vnom, psi_hat)
    # radar
    rd = inp.radar
    if len(rd) and inp.station is not None:
        tr = rd["t_s"].to_numpy() + clock.get("radar", 0.0)
        b.add("radar", jl.RANGE, tr, rd["range_m"].to_numpy(), nz.radar_range_m ** 2)
        b.add("radar", jl.AZIMUTH, tr, rd["azimuth_rad"].to_numpy(),
              np.radians(nz.radar_azimuth_deg) ** 2)
        if "elevation_rad" in rd.columns:
            b.add("radar", jl.ELEVATION, tr, rd["elevation_rad"].to_numpy(),
                  np.radians(nz.radar_elevation_deg) ** 2)
    # the take-off roll, with the smoothed lift-off speed once there is one (the recorded
    # airspeed carries the head wind); at rest before it (lined up): zero north and east velocity
    if roll is None:
        roll = refined_roll(inp, T, vnom)
    r0, r1 = roll.rest_t
    if np.isfinite(r0):
        t_in = inp.t_in
        tt = t_in[on_ground_mask(inp, settings) & (t_in >= r0) & (t_in <= r1)]
        for i in range(2):
            H = np.zeros((len(tt), jl.N_STATE))
            H[:, jl.IV + i] = 1.0
            b.add("ground", jl.LINEAR, tt, np.zeros(len(tt)), nz.ground_mps ** 2, H)
        lineup_heading(b, inp, settings, tt)
    _endpoint_measurements(b, inp, settings, T, Cen, roll)
    return b.build()


def _add_ned_components(b: _MeasBuilder, T: np.ndarray, Cen: np.ndarray, source: str, t, comp_vals,
                    sd, kind: str = "pos", ecef=None, acc: np.ndarray | None = None) -> None:
    """Add the NED components of a position (given in ECEF, ``kind="pos"``: three ``NED_POS``
    measurements, whose rows the kernel builds from the step's frame with the tau term) or a
    velocity (``kind="vel"``: north and east, two ``STATE`` measurements) at times ``t`` to
    ``b``.  A velocity is carried to its own time as the position is: h = v_i + a_i tau with
    ``acc`` (M, 2) the north and east acceleration at each (None: h = v_i, the velocity at the
    step)."""
    k = nearest_index(T, t)
    tau = np.asarray(t, float) - T[k]
    for i in range(3 if kind == "pos" else 2):
        r = np.broadcast_to(sd[i] ** 2, (len(t),))
        if kind == "pos":   # c_i . p + v_i tau, c_i the NED axis i in ECEF at the step
            z = np.einsum("mj,mj->m", Cen[k][:, :, i], ecef)
            b.add(source, jl.NED_POS, t, z, r, index=i)
        else:
            a_i = np.zeros(len(t)) if acc is None else acc[:, i]
            b.add(source, jl.STATE, t, comp_vals[i], r, d=a_i * tau, index=jl.IV + i, rate=a_i)


def _substitute_height(inp: JointInputs, T: np.ndarray, t: np.ndarray,
                       pnom: np.ndarray | None) -> np.ndarray:
    """Ellipsoidal height [m] for a position given without one at times ``t``: the nominal
    track's at the nearest state step, else the field's plus the recorded pressure height."""
    if pnom is not None:
        k = nearest_index(T, t)
        return ecef_to_geodetic(pnom[k, 0], pnom[k, 1], pnom[k, 2])[2]
    ii = nearest_index(inp.t_in, t)
    return inp.field_h + np.nan_to_num(inp.baro_rel_m[ii])


def _gnss_measurements(b: _MeasBuilder, inp: JointInputs, settings: JointSettings,
                       T: np.ndarray, Cen: np.ndarray, clock: dict[str, float],
                       pnom: np.ndarray | None) -> None:
    """The GNSS fixes (antenna moved to the reference point by the lever arm) and velocities,
    at their own times shifted by ``clock["gnss"]`` and ``clock["gnss_velocity"]``, with the
    receiver's per-fix accuracy.

    Each is carried from its state step to its own time, the fixes by the state's velocity,
    the velocities by their own acceleration (:func:`gnss_acceleration`; not the iterate's,
    which would make the measurement function depend on the trajectory beyond the state at
    its step: the Gauss-Newton step was then no descent direction of the cost, and the line
    search failed on two real G1000 exports).  A velocity taken 0.4 s from its step in a
    3 m/s^2 turn differs from the step's by 1.2 m/s; compared at the step, the velocities held
    the clock offset's estimate near zero (a circuit with its GNSS stamped 0.375 s late:
    -0.05 s, the track 23 m RMS from the truth; test ``test_gnss_clock_offset_recovered``)."""
    nz = settings.noise
    g = inp.gnss
    if not len(g):
        return
    t_in = inp.t_in
    tg = g["t_s"].to_numpy() + clock.get("gnss", 0.0)
    k = nearest_index(T, tg)
    hg = g["h_m"].to_numpy(float)
    no_h = ~np.isfinite(hg)
    if no_h.any():
        # a fix without height is used horizontally: its north and east components only,
        # computed at a substitute height (the nominal's, else the field's plus the pressure
        # height); the north/east projection of the fix moves by (angle between the
        # verticals at the fix and at the step) x (height error): under 2e-4 m per m at 1 km
        hg = np.where(no_h, _substitute_height(inp, T, tg, pnom), hg)
    ex, ey, ez = geodetic_to_ecef(g["lat_deg"].to_numpy(), g["lon_deg"].to_numpy(), hg)
    ant = np.c_[ex, ey, ez]
    L = np.asarray(inp.lever_arm, float)
    v_arm = np.zeros((len(tg), 3))
    if np.any(L != 0):
        # attitude at the fix: nearest input sample
        ii = nearest_index(t_in, tg)
        arm_ned = np.einsum("mij,j->mi", inp.body_to_ned(ii), L)
        ant = ant - np.einsum("mij,mj->mi", Cen[k], arm_ned)
        # the antenna's velocity adds d(C_nb L)/dt (0.26 m/s for a 5 m arm at 3 deg/s of
        # yaw): a central difference over +-0.5 s of the recorded attitude (its noise,
        # 0.05 deg at 8 Hz, then adds under 0.01 m/s)
        ip, im = nearest_index(t_in, tg + 0.5), nearest_index(t_in, tg - 0.5)
        span = np.maximum(t_in[ip] - t_in[im], 1e-9)[:, None]
        v_arm = np.einsum("mij,j->mi", inp.body_to_ned(ip) - inp.body_to_ned(im), L) / span
    # per-fix accuracy where the receiver gave it (horizontal sd per axis, vertical sd),
    # else the noise settings; no height: no vertical component
    sd_h = per_fix_sd(g, "h_sd_m", nz.gnss_h_m)
    sd_v = np.where(no_h, np.nan, per_fix_sd(g, "v_sd_m", nz.gnss_v_m))
    _add_ned_components(b, T, Cen, "gnss_pos", tg, None, (sd_h, sd_h, sd_v), "pos", ant)
    if {"vn_mps", "ve_mps"} <= set(g.columns):
        sd_vel = per_fix_sd(g, "vel_sd_mps", nz.gnss_vel_mps)
        vel = (g["vn_mps"].to_numpy() - v_arm[:, 0], g["ve_mps"].to_numpy() - v_arm[:, 1])
        # the velocities' own clock offset (the positions' where none is given)
        tv = g["t_s"].to_numpy() + clock.get("gnss_velocity", clock.get("gnss", 0.0))
        acc = gnss_acceleration(tv, np.column_stack(vel))
        _add_ned_components(b, T, Cen, "gnss_vel", tv, vel, (sd_vel, sd_vel), "vel", acc=acc)


def gnss_acceleration(t: np.ndarray, v: np.ndarray, max_gap_s: float = 2.5) -> np.ndarray:
    """The north and east acceleration at each GNSS velocity (times ``t`` (M,), velocities
    ``v`` (M, 2)): the central difference of the neighbouring velocities, one-sided at an end
    or beside a gap longer than ``max_gap_s``, zero without a neighbour within it or where a
    velocity is missing.  Fixed by the data (not by the iterate), so the velocity's
    prediction v_k + a tau is linear in the state at its step.  Its noise is small: 0.1 m/s
    per velocity over 2 s is 0.07 m/s^2, 0.035 m/s at a quarter second from the step."""
    t = np.asarray(t, float)
    v = np.asarray(v, float)
    M = len(t)
    a = np.zeros((M, v.shape[1]))
    if M < 2:
        return a
    dt = np.diff(t)
    dv = np.diff(v, axis=0)
    ok = (dt > 0) & (dt <= max_gap_s) & np.all(np.isfinite(dv), axis=1)
    slope = np.where(ok[:, None], dv / np.where(dt > 0, dt, 1.0)[:, None], np.nan)
    left = np.r_[[np.full(v.shape[1], np.nan)], slope]     # slope to the previous velocity
    right = np.r_[slope, [np.full(v.shape[1], np.nan)]]    # slope to the next
    both = np.isfinite(left) & np.isfinite(right)
    a = np.where(both, 0.5 * (left + right), np.where(np.isfinite(left), left,
                                                       np.where(np.isfinite(right), right, 0.0)))
    return a


def _endpoint_measurements(b: _MeasBuilder, inp: JointInputs, settings: JointSettings,
                           T: np.ndarray, Cen: np.ndarray, roll: TakeoffRoll) -> None:
    """The end points (``inp.end_points``, the runway departure at the start of ``roll``:
    :func:`end_points_at`): the runway model along / across the runway and vertically, the
    reference model in north, east, down."""
    for ep in end_points_at(inp.end_points, roll):
        lat, lon, h = ep.point
        pe = np.array(geodetic_to_ecef(lat, lon, h), float).reshape(3)
        tt = np.array([ep.t_s])
        if ep.model in ("reference", "last_position") or ep.runway_rad is None:
            _add_ned_components(b, T, Cen, "endpoint", tt, None, ep.sd_m, "pos", pe[None, :])
            continue
        k = nearest_index(T, tt)[0]
        tau = tt[0] - T[k]
        psi = ep.runway_rad
        Ca = ned_to_ecef_matrix(lat, lon)[0]
        for u, sd in zip(([np.cos(psi), np.sin(psi), 0.0], [-np.sin(psi), np.cos(psi), 0.0],
                          [0.0, 0.0, 1.0]), ep.sd_m):
            u = np.asarray(u)
            H = np.zeros((1, jl.N_STATE))
            H[0, jl.S_POS] = Ca @ u
            H[0, jl.S_VEL] = u * tau
            b.add("endpoint", jl.LINEAR, tt, np.zeros(1), sd ** 2, H, -(Ca @ u) @ pe)
