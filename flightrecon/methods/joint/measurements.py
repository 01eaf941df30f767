"""The joint smoother's measurement table (:class:`~flightrecon.methods.joint.layout.Measurements`):
every source's scalar measurements, each at its own time (docs/joint.md, "Measurements").  What no
pass changes is built once (:func:`static_measurements`); each pass adds the rows that depend on
the linearisation and the clock offsets (:func:`build_measurements`).  Also here: where the air-data
heading stands for the air velocity's direction (:func:`nose_along_air`, :func:`nose_offset`) and
the ground rows (:func:`ground_rolls`, :func:`runway_measurements`)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numba as nb
import numpy as np

from flightrecon.geo.frames import ecef_to_geodetic, geodetic_to_ecef
from flightrecon.geo.navframe import ned_to_ecef_matrix
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.inputs import (
    EndPoint,
    JointInputs,
    TakeoffRoll,
    airborne_samples,
    end_points_at,
    nearest_index,
    per_fix_sd,
)
from flightrecon.methods.joint.layout import Measurements
from flightrecon.methods.joint.settings import SOURCES, JointSettings


class _Part(NamedTuple):
    """One call's rows of the table (:meth:`_MeasBuilder.add`), with their state steps (None only
    while the static table is built: :func:`static_measurements` finds them once)."""

    source: np.ndarray
    mtype: np.ndarray
    t: np.ndarray
    z: np.ndarray
    r: np.ndarray
    hrow: np.ndarray
    d: np.ndarray
    ok: np.ndarray
    rate: np.ndarray
    step: np.ndarray | None


class _MeasBuilder:
    """The table's rows as they are added (:meth:`add`), each part with its steps on the state grid
    ``T``; :meth:`build` sorts them by step.  A pass's builder starts from the static parts and
    rows of H (:class:`StaticTable`: immutable, their steps found once)."""

    def __init__(self, T: np.ndarray, n: int = jl.N_STATE, parts: tuple[_Part, ...] = (),
                 H: tuple[np.ndarray, ...] = ()):
        self.T = T
        self.n = n
        self.parts = list(parts)
        self.H = list(H)
        self.n_rows = sum(len(h) for h in H)

    def add(self, source: str, mtype: int, t, z, r, H=None, d=None, index=None, rate=None,
            step: np.ndarray | None = None) -> None:
        """Rows at times ``t`` (their state steps ``step``, where known)."""
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
        self.parts.append(_Part(np.full(m, SOURCES.index(source)), np.full(m, mtype), t, z, r,
                                hrow, dm, ok, rt, step))

    def add_state(self, source: str, t: np.ndarray, z, r, col: int,
                  step: np.ndarray | None = None) -> None:
        """``LINEAR`` rows on the state component ``col`` alone: h = x[col]."""
        H = np.zeros((len(t), self.n))
        H[:, col] = 1.0
        self.add(source, jl.LINEAR, t, z, r, H, step=step)

    def build(self) -> Measurements:
        """The table, its rows sorted by state step (every part added with its steps)."""
        T = self.T
        N = len(T)
        cat = (_Part(*map(np.concatenate, zip(*self.parts))) if self.parts
               else _Part(*[np.zeros(0)] * len(_Part._fields)))
        half_first = 0.5 * (T[1] - T[0] if N > 1 else 1)
        half_last = 0.5 * (T[-1] - T[-2] if N > 1 else 1)
        ok = cat.ok.astype(bool) & (cat.t >= T[0] - half_first) & (cat.t <= T[-1] + half_last)
        step = np.asarray(cat.step)[ok]
        order = np.flatnonzero(ok)[np.lexsort((cat.t[ok], step))]
        step = np.sort(step, kind="stable")
        start = np.searchsorted(step, np.arange(N + 1), side="left")
        H = np.concatenate(self.H) if self.H else np.zeros((0, self.n))
        return Measurements(step=step.astype(np.int64), source=cat.source[order].astype(np.int64),
                            mtype=cat.mtype[order].astype(np.int64), z=cat.z[order],
                            r=cat.r[order], t=cat.t[order], H=np.ascontiguousarray(H),
                            hrow=cat.hrow[order].astype(np.int64), d=cat.d[order],
                            start=start.astype(np.int64), rate=cat.rate[order])


@nb.njit(cache=True, nogil=True)
def _wind_prior_picks(t, h, corr_s, corr_m, spacing):
    """Indices of the winds-aloft pseudo-measurements and their correlation with the previous one: a
    new one whenever dt / corr_s + |dh| / corr_m since the last reaches ``spacing`` (one pass over
    the candidate samples)."""
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
    """The winds-aloft prior (``--wind``) as sparse pseudo-measurements of the wind states: one at
    the first airborne air-data sample, then one whenever |dt| / tau + |dz| / L since the last
    reaches ``spacing`` (``settings.wind_prior`` = (tau, L, spacing)), each later one's variance
    inflated by (1 + rho) / (1 - rho) (docs/wind.md, "The prior in the joint smoother").

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
          & (inp.tas >= settings.min_airspeed_mps) & airborne_samples(inp))
    cand = np.flatnonzero(ok)
    if len(cand) == 0:
        return empty
    tau, L, spacing = (float(v) for v in settings.wind_prior)
    pick, rho = _wind_prior_picks(t_in[cand], inp.baro_rel_m[cand], tau, L, spacing)
    i = cand[pick]
    sd = wa[i, 2] * np.sqrt((1.0 + rho) / (1.0 - rho))
    return t_in[i], wa[i, :2], sd, rho


@dataclass(frozen=True)
class StaticTable:
    """What no pass changes (:func:`static_measurements`): the rows of every pass (``parts``, with
    their state steps, and their rows of ``H``), the ground samples' times ``ground_t``
    (:func:`on_ground_mask`), the ground ``rolls``, the known positions (``--fix``: their (F, 5)
    table, state steps and ECEF positions, None where one has no height) or None, each end point's
    ECEF position and NED-to-ECEF rotation (``inp.end_points``' order), the winds-aloft prior's
    pseudo-measurements ``wind_prior`` (:func:`wind_prior_measurements`: t, w, sd, rho; the
    summary reads them) and the ground samples' state steps ``ground_k``."""

    parts: tuple[_Part, ...]
    H: tuple[np.ndarray, ...]
    ground_t: np.ndarray
    rolls: tuple[GroundRoll, ...]
    fixes: tuple[np.ndarray, np.ndarray, np.ndarray | None] | None
    ends: tuple[tuple[np.ndarray, np.ndarray], ...]
    wind_prior: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]
    ground_k: np.ndarray


def _ecef(lat_deg, lon_deg, h_m) -> np.ndarray:
    """(M, 3) ECEF positions [m] of geodetic ones (``geodetic_to_ecef``)."""
    ex, ey, ez = geodetic_to_ecef(lat_deg, lon_deg, h_m)
    return np.c_[ex, ey, ez]


def static_measurements(inp: JointInputs, settings: JointSettings, T: np.ndarray) -> StaticTable:
    """What does not change between Gauss-Newton passes (:class:`StaticTable`): the rows of the air
    data, Doppler, recorded wind, the winds-aloft prior, pressure altitude and the ground's vertical
    velocity, and the parts of the other rows that the data fix (built once)."""
    nz = settings.noise
    b = _MeasBuilder(T)
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
            b.add_state("wind", t_in[okw], inp.wind_ne[okw, i], nz.wind_sensor_mps ** 2, jl.IW + i)
    # the winds-aloft prior (--wind): one pseudo-measurement per correlation length
    wind_prior = wind_prior_measurements(inp, settings)
    tw, ww, sdw, _rho = wind_prior
    for i in range(2):
        b.add_state("wind_aloft", tw, ww[:, i], sdw ** 2, jl.IW + i)
    # pressure altitude
    okb = np.isfinite(inp.baro_rel_m) & decimate_mask(t_in, settings.baro_rate_hz)
    b.add("baro", jl.BARO, t_in[okb], inp.baro_rel_m[okb], nz.baro_m ** 2)
    # on the ground: zero vertical velocity (the cross-track constraints depend on the heading
    # bias and the nominal, see build_measurements)
    tt = t_in[on_ground_mask(inp, settings)]
    b.add_state("ground", tt, np.zeros(len(tt)), nz.ground_mps ** 2, jl.IV + 2)
    rolls = ground_rolls(inp, settings, T)
    fixes = None
    if inp.fixes is not None and len(inp.fixes):
        fx = np.asarray(inp.fixes, float)
        fixes = (fx, nearest_index(T, fx[:, 0]),
                 _ecef(fx[:, 1], fx[:, 2], fx[:, 3]) if np.isfinite(fx[:, 3]).all() else None)
    ends = tuple((_ecef(*e.point)[0], ned_to_ecef_matrix(e.point[0], e.point[1])[0])
                 for e in inp.end_points)
    # the rows' state steps, found once
    parts = tuple(p._replace(step=nearest_index(T, p.t)) for p in b.parts)
    return StaticTable(parts, tuple(b.H), tt, rolls, fixes, ends, wind_prior, nearest_index(T, tt))


def build_measurements(inp: JointInputs, settings: JointSettings, T: np.ndarray, Cen: np.ndarray,
                       clock: dict[str, float], static: StaticTable, pnom: np.ndarray,
                       vnom: np.ndarray, roll: TakeoffRoll, psi_hat: np.ndarray | None
                       ) -> tuple[Measurements, tuple[EndPoint, ...]]:
    """Every source as scalar measurements at its own time (recorder time base): the ``static``
    table's rows (:func:`static_measurements`) and the GNSS, radar, known-position (``--fix``),
    end-point and runway rows, which depend on the linearisation (``Cen``, the nominal ECEF
    positions ``pnom`` and NED velocities ``vnom`` on the state grid), the clock offsets ``clock``
    (seconds *added* to each group's time stamps, as ``flightrecon clean --radar-clock-offset``),
    the pass's take-off roll ``roll`` (:func:`~flightrecon.methods.joint.inputs.refined_roll`) and
    the last pass's heading bias ``psi_hat`` (per state step; None: zero); with the end points at
    the roll (:func:`~flightrecon.methods.joint.inputs.end_points_at`).  What the rows take of the
    inputs is looked up first: the state steps of the GNSS, radar, line-up and end-point rows at
    once (the rest's from the ground samples'), the fixes' sd and the attitude at the fixes."""
    nz = settings.noise
    b = _MeasBuilder(T, parts=static.parts, H=static.H)
    # at rest before the take-off roll (lined up): zero north and east velocity, the line-up row;
    # the radar's and GNSS's times (the velocities' own clock offset, else the positions')
    rest = (static.ground_t >= roll.rest_t[0]) & (static.ground_t <= roll.rest_t[1])
    tt, kt = static.ground_t[rest], static.ground_k[rest]
    line = lineup_heading(inp, tt)
    rd, g = inp.radar, inp.gnss
    radar = len(rd) > 0 and inp.station is not None
    tr = rd["t_s"].to_numpy() + clock.get("radar", 0.0) if radar else np.zeros(0)
    tg, tv = (g["t_s"].to_numpy() + clock.get(c, clock.get("gnss", 0.0)) if len(g) else np.zeros(0)
              for c in ("gnss", "gnss_velocity"))
    # the end points with the runway departure at the start of the pass's roll
    ends = end_points_at(inp.end_points, roll)
    k, kv, kr, ke, kl = np.split(nearest_index(T, np.r_[tg, tv, tr, [e.t_s for e in ends],
                                                        line[:1]]),
                                 np.cumsum([len(tg), len(tv), len(tr), len(ends)]))
    # per-fix accuracy where the receiver gave it (horizontal sd per axis, vertical sd, velocity
    # sd), else the noise settings; the attitude at each fix (nearest input sample) and +-0.5 s
    sds = tuple(per_fix_sd(g, c, d) for c, d in (
        ("h_sd_m", nz.gnss_h_m), ("v_sd_m", nz.gnss_v_m), ("vel_sd_mps", nz.gnss_vel_mps)))
    att = None
    if len(g) and np.any(np.asarray(inp.lever_arm, float) != 0):
        ii, ip, im = nearest_index(inp.t_in, tg + np.array([[0.0], [0.5], [-0.5]]))
        att = (inp.body_to_ned(np.r_[ii, ip, im]).reshape(3, len(tg), 3, 3),
               np.maximum(inp.t_in[ip] - inp.t_in[im], 1e-9)[:, None])
    if len(g):
        _gnss_measurements(b, inp, T, Cen, (tg, k, tv, kv), sds, att, pnom)
    # known positions (--fix): at their own time with their sd, horizontal only without a
    # height (then at the nominal's height, as a GNSS fix without one)
    if static.fixes is not None:
        fx, k, ecef = static.fixes
        no_h = ~np.isfinite(fx[:, 3])
        if ecef is None:
            h = ecef_to_geodetic(pnom[k, 0], pnom[k, 1], pnom[k, 2])[2]
            ecef = _ecef(fx[:, 1], fx[:, 2], np.where(no_h, h, fx[:, 3]))
        sd = fx[:, 4]
        _ned_positions(b, Cen, "fix", fx[:, 0], k, (sd, sd, np.where(no_h, np.nan, sd)), ecef)
    runway_measurements(b, static.rolls, pnom, vnom, psi_hat)
    if radar:
        b.add("radar", jl.RANGE, tr, rd["range_m"].to_numpy(), nz.radar_range_m ** 2, step=kr)
        b.add("radar", jl.AZIMUTH, tr, rd["azimuth_rad"].to_numpy(),
              np.radians(nz.radar_azimuth_deg) ** 2, step=kr)
        if "elevation_rad" in rd.columns:
            b.add("radar", jl.ELEVATION, tr, rd["elevation_rad"].to_numpy(),
                  np.radians(nz.radar_elevation_deg) ** 2, step=kr)
    for i in range(2):
        b.add_state("ground", tt, np.zeros(len(tt)), nz.ground_mps ** 2, jl.IV + i, kt)
    b.add_state("runway", line[:1], line[1:], np.radians(nz.lineup_heading_deg) ** 2, jl.IPSI, kl)
    _endpoint_measurements(b, ends, ke, T, Cen, static.ends)
    return b.build(), ends


def _ned_positions(b: _MeasBuilder, Cen: np.ndarray, source: str, t: np.ndarray, k: np.ndarray,
                   sd, ecef: np.ndarray) -> None:
    """Three ``NED_POS`` rows per position ``ecef`` (M, 3) at times ``t`` (state steps ``k``), sd
    ``sd`` per NED axis: c_i . p + v_i tau, c_i the NED axis i in ECEF at the step (the kernel
    builds the rows from the step's frame with the tau term)."""
    for i in range(3):
        z = np.einsum("mj,mj->m", Cen[k][:, :, i], ecef)
        b.add(source, jl.NED_POS, t, z, np.broadcast_to(sd[i] ** 2, (len(t),)), index=i, step=k)


def _gnss_measurements(b: _MeasBuilder, inp: JointInputs, T: np.ndarray, Cen: np.ndarray,
                       times: tuple[np.ndarray, ...], sds: tuple[np.ndarray, ...],
                       att: tuple[np.ndarray, np.ndarray] | None, pnom: np.ndarray) -> None:
    """The GNSS fixes (antenna moved to the reference point by the lever arm) and velocities at
    their own times and state steps ``times`` (tg, k, tv, kv: the stamps shifted by the clock
    offsets), with their sd ``sds`` (horizontal, vertical, velocity) and the attitude ``att`` (C_nb
    at each fix and +-0.5 s about it, the second's span; None without an arm); the velocities
    carried to their time by their own acceleration (:func:`gnss_acceleration`)."""
    (tg, k, tv, kv), (sd_h, sd_v, sd_vel), g = times, sds, inp.gnss
    L = np.asarray(inp.lever_arm, float)
    arm, v_arm = np.zeros((len(tg), 3)), np.zeros((len(tg), 3))
    if att is not None:
        # the antenna's velocity adds d(C_nb L)/dt (0.26 m/s for a 5 m arm at 3 deg/s of yaw), a
        # central difference of the recorded attitude (its noise, 0.05 deg at 8 Hz, then adds
        # under 0.01 m/s)
        C, span = att
        arm = np.einsum("mij,mj->mi", Cen[k], np.einsum("mij,j->mi", C[0], L))
        v_arm = np.einsum("mij,j->mi", C[1] - C[2], L) / span
    hg = g["h_m"].to_numpy(float)
    no_h = ~np.isfinite(hg)
    if no_h.any():
        # a fix without height is used horizontally: its north and east components only, computed at
        # the nominal's height; the north/east projection of the fix moves by (angle between the
        # verticals at the fix and at the step) x (height error): under 2e-4 m per m at 1 km
        hg = np.where(no_h, ecef_to_geodetic(pnom[k, 0], pnom[k, 1], pnom[k, 2])[2], hg)
    ex, ey, ez = geodetic_to_ecef(g["lat_deg"].to_numpy(), g["lon_deg"].to_numpy(), hg)
    ant = np.c_[ex, ey, ez] - arm   # the antenna moved to the reference point
    # no height: no vertical component
    _ned_positions(b, Cen, "gnss_pos", tg, k, (sd_h, sd_h, np.where(no_h, np.nan, sd_v)), ant)
    if {"vn_mps", "ve_mps"} <= set(g.columns):
        vel = (g["vn_mps"].to_numpy() - v_arm[:, 0], g["ve_mps"].to_numpy() - v_arm[:, 1])
        # each carried to its own time by its acceleration a: h = v_i + a_i tau
        acc = gnss_acceleration(tv, np.column_stack(vel))
        tau = tv - T[kv]
        for i in range(2):
            b.add("gnss_vel", jl.STATE, tv, vel[i], np.broadcast_to(sd_vel ** 2, (len(tv),)),
                  d=acc[:, i] * tau, index=jl.IV + i, rate=acc[:, i], step=kv)


def gnss_acceleration(t: np.ndarray, v: np.ndarray, max_gap_s: float = 2.5) -> np.ndarray:
    """The north and east acceleration at each GNSS velocity (times ``t`` (M,), velocities ``v`` (M,
    2)): the central difference of the neighbouring velocities, one-sided at an end or beside a gap
    longer than ``max_gap_s``, zero without a neighbour within it or where a velocity is missing.
    Fixed by the data (not by the iterate), so the velocity's prediction v_k + a tau is linear in
    the state at its step.  Its noise is small: 0.1 m/s per velocity over 2 s is 0.07 m/s^2, 0.035
    m/s at a quarter second from the step."""
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


def _endpoint_measurements(b: _MeasBuilder, ends: tuple[EndPoint, ...], ks: np.ndarray,
                           T: np.ndarray, Cen: np.ndarray,
                           ecef: tuple[tuple[np.ndarray, np.ndarray], ...]) -> None:
    """The end points ``ends`` (the runway departure at the start of the pass's roll:
    :func:`~flightrecon.methods.joint.inputs.end_points_at`; ``ks``: their state steps; ``ecef``:
    each one's ECEF position and NED-to-ECEF rotation): the runway model along / across the runway
    and vertically, the reference model in north, east, down."""
    for j, (ep, (pe, Ca)) in enumerate(zip(ends, ecef)):
        tt, k = np.array([ep.t_s]), ks[j:j + 1]
        if ep.model in ("reference", "last_position") or ep.runway_rad is None:
            _ned_positions(b, Cen, "endpoint", tt, k, ep.sd_m, pe[None, :])
            continue
        tau = tt[0] - T[k[0]]
        psi = ep.runway_rad
        for row, sd in zip(([np.cos(psi), np.sin(psi), 0.0], [-np.sin(psi), np.cos(psi), 0.0],
                            [0.0, 0.0, 1.0]), ep.sd_m):
            u = np.asarray(row)
            H = np.zeros((1, jl.N_STATE))
            H[0, jl.S_POS] = Ca @ u
            H[0, jl.S_VEL] = u * tau
            b.add("endpoint", jl.LINEAR, tt, np.zeros(1), sd ** 2, H, -(Ca @ u) @ pe, step=k)


def nose_along_air(attitude_deg: np.ndarray, settings: JointSettings) -> np.ndarray:
    """Samples whose attitude lets the heading stand for the air velocity's direction (beyond, the
    angle of attack times sin(roll), a spin's sideslip: docs/joint.md, "Measurements"): |roll| <=
    ``heading_max_roll_deg`` and |pitch| <= ``heading_max_pitch_deg``, the angles of the body-to-NED
    rotation C = R_z R_y R_x of the recorded attitude ``attitude_deg`` (Ni, 3), from its last row
    C[2] = (-sin(pitch), sin(roll) cos(pitch), cos(roll) cos(pitch)): a roll of 190 deg counts as
    -170 deg and a pitch of 100 deg (inverted) as 80 deg."""
    phi, theta = np.radians(attitude_deg[:, 0]), np.radians(attitude_deg[:, 1])
    st, ct = np.sin(theta), np.cos(theta)
    pitch = -np.arcsin(np.clip(-st, -1.0, 1.0))
    roll = np.arctan2(np.sin(phi) * ct, np.cos(phi) * ct)
    return ((np.abs(roll) <= np.radians(settings.heading_max_roll_deg))
            & (np.abs(pitch) <= np.radians(settings.heading_max_pitch_deg)))


def nose_offset(inp: JointInputs, climb_window_s: float = 2.0,
                alpha_range_deg: tuple[float, float] = (-10.0, 20.0),
                at: np.ndarray | None = None) -> np.ndarray:
    """Heading minus the air velocity's horizontal direction on the input grid [rad] (at the input
    samples ``at``, a boolean mask or indices, when given: the same numbers as the whole grid's
    there): delta = atan2(sin phi sin a, cos theta cos a + cos phi sin theta sin a) with the angle
    of attack a from sin g = cos a sin theta - sin a cos phi cos theta, sin g = h' / V (h' the
    pressure-altitude rate over ``climb_window_s``): a = arccos(sin g / R) - d, R = hypot(A, B),
    d = atan2(B, A), A = sin theta, B = cos phi cos theta (docs/joint.md, "Measurements": the
    heading measures the nose).  0 where not finite or a is outside ``alpha_range_deg``."""
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


def decimate_mask(t: np.ndarray, rate_hz: float, origin: float | None = None) -> np.ndarray:
    """True for the first sample of each 1/rate_hz bin, bins counted from ``origin`` (default the
    first sample) (keeps each measurement used once)."""
    return first_in_bin(t, rate_hz, np.arange(len(t)), origin)


def first_in_bin(t: np.ndarray, rate_hz: float, i: np.ndarray, origin: float | None = None
                 ) -> np.ndarray:
    """:func:`decimate_mask` at the sample indices ``i`` only (each judged against its predecessor
    in ``t``), for a few samples of a long record."""
    if rate_hz <= 0:
        return np.zeros(len(i), bool)
    t0 = t[0] if origin is None else origin
    b = np.floor((t[i] - t0) * rate_hz + 1e-9).astype(np.int64)
    b_prev = np.floor((t[np.maximum(i - 1, 0)] - t0) * rate_hz + 1e-9).astype(np.int64)
    return (i == 0) | (b != b_prev)


def on_ground_mask(inp: JointInputs, settings: JointSettings) -> np.ndarray:
    """Input samples used for the ground constraints: before lift-off and after touchdown (2 s
    margins), at the ground-constraint rate, with a heading."""
    t_in = inp.t_in
    on_ground = np.zeros(len(t_in), bool)
    if np.isfinite(inp.liftoff_t):
        on_ground |= t_in < inp.liftoff_t - 2.0
    if np.isfinite(inp.touchdown_t):
        on_ground |= t_in > inp.touchdown_t + 2.0
    # the rate's bins judged on the ground samples only (a long flight's record is mostly
    # airborne, and this runs on every pass)
    i = np.flatnonzero(on_ground)
    i = i[first_in_bin(t_in, settings.ground_rate_hz, i) & np.isfinite(inp.heading_rad[i])]
    keep = np.zeros(len(t_in), bool)
    keep[i] = True
    return keep


#: heading change that ends a landing roll [deg] (the phases' line-up rule, 10 deg)
RUNWAY_EXIT_DEG = 10.0


def on_runway_mask(inp: JointInputs, departure: bool, exit_deg: float = RUNWAY_EXIT_DEG
                   ) -> np.ndarray:
    """Input samples that can be on the departure (``departure``) or arrival runway: from the
    line-up (``inp.lineup_t``; the whole record where not known); from touchdown to the first
    sample after which the heading is more than ``exit_deg`` from the landing roll's (its circular
    mean 2-6 s after touchdown), to the end where it does not turn off (issue #36)."""
    t = inp.t_in
    if departure:
        if np.isfinite(inp.lineup_t):
            return t >= inp.lineup_t
        return np.ones(len(t), bool)
    m = np.ones(len(t), bool)
    td = inp.touchdown_t
    psi = inp.heading_rad
    if not np.isfinite(td):
        return m
    w = (t >= td + 2.0) & (t <= td + 6.0) & np.isfinite(psi)
    if not w.any():
        return m
    psi_rw = float(np.arctan2(np.mean(np.sin(psi[w])), np.mean(np.cos(psi[w]))))
    # the heading's distance from the roll's on the samples after it only (a long flight's
    # record before touchdown is most of it, and this runs on every pass)
    after = np.flatnonzero((t > td + 2.0) & np.isfinite(psi))
    off = np.degrees(np.abs(np.angle(np.exp(1j * (psi[after] - psi_rw)))))
    out = after[off > exit_deg]
    if len(out):
        m &= t < t[out[0]]
    return m


@dataclass(frozen=True)
class GroundRoll:
    """One end's ground roll as the data fix it (:func:`ground_rolls`): its samples' times, state
    steps and recorded headings, the runway's direction (None: not known), whether the velocity
    rows run along the true heading (``nose``), their variance, the centreline samples (a mask),
    the centreline's point (ECEF; None: no centreline rows), its NED-to-ECEF rotation and the
    centreline rows' variance."""

    t: np.ndarray
    k: np.ndarray
    heading_rad: np.ndarray
    runway_rad: float | None
    nose: bool
    r_v: np.ndarray | float
    centre: np.ndarray
    point: np.ndarray | None
    Ca: np.ndarray
    r_cl: float


def ground_rolls(inp: JointInputs, settings: JointSettings, T: np.ndarray
                 ) -> tuple[GroundRoll, ...]:
    """The departure's and the arrival's ground rolls (:class:`GroundRoll`) on the state grid ``T``:
    what the data fix of the runway rows (:func:`runway_measurements`; docs/joint.md,
    "Measurements", on the ground).  The velocity rows' variance: ``ground_mps^2 + m (s V)^2`` for
    the m rows (s: ``ground_slip_deg``; V: :func:`roll_speed`), plus along the runway the steering's
    (:func:`steering_variance`); the centreline's, through the airfield reference point where no
    threshold is given, ``runway_halfwidth_m^2 + m endpoint_h_m^2``."""
    nz = settings.noise
    t_in = inp.t_in
    keep = on_ground_mask(inp, settings)
    if not keep.any():
        return ()
    out = []
    for dep_end, (pos, side, rw, t_edge) in enumerate((
            (inp.departure, t_in < (inp.liftoff_t if np.isfinite(inp.liftoff_t) else -np.inf),
             inp.runway_rad[0], inp.liftoff_t),
            (inp.arrival, t_in > (inp.touchdown_t if np.isfinite(inp.touchdown_t) else np.inf),
             inp.runway_rad[1], inp.touchdown_t))):
        known = rw is not None
        on_line = known and inp.thresholds[dep_end] is not None
        if on_line:
            # the centreline runs through the threshold; the airfield's reference point is
            # where the analyst put it (an apron, between two runways)
            pos = inp.thresholds[dep_end]
        # a record from stand to stand: the taxi before the line-up and after the runway exit
        # is on no runway; its rows along the heading (cross-track velocity zero) stay where
        # the runway's direction is not known: they hold on any taxiway
        cl_side = side & on_runway_mask(inp, dep_end == 0)
        sel = keep & (cl_side if known else side)
        if not sel.any():
            continue
        tt = t_in[sel]
        nose = not known or settings.roll_velocity == "nose"
        v_roll = roll_speed(inp, settings, t_edge)
        r_v = nz.ground_mps ** 2 + len(tt) * (np.radians(nz.ground_slip_deg) * v_roll) ** 2
        if not nose:
            # the wheels roll where the nose points: the track leaves the runway's direction
            # by the nose's angle to the heading lined up at rest before a take-off roll, or,
            # on a landing roll (no rest before it) and a take-off without one, by its angle
            # to the runway itself (the heading bias inside it: a fraction of the swerves)
            ref = rest_heading(inp) if dep_end == 0 else None
            r_v = r_v + steering_variance(inp.heading_rad[sel], v_roll, rw if ref is None else ref)
        centre = cl_side[sel]
        point, Ca = None, np.eye(3)
        if pos is not None and centre.any():
            point = _ecef(pos[0], pos[1], pos[2])[0]
            Ca = ned_to_ecef_matrix(pos[0], pos[1])[0]
        # off the line (no threshold): one error of endpoint_h_m common to the roll's m rows
        r_cl = nz.runway_halfwidth_m ** 2 + (0.0 if on_line
                                             else int(centre.sum()) * nz.endpoint_h_m ** 2)
        out.append(GroundRoll(tt, nearest_index(T, tt), inp.heading_rad[sel], rw, nose, r_v,
                              centre, point, Ca, r_cl))
    return tuple(out)


def runway_measurements(b: _MeasBuilder, rolls: tuple[GroundRoll, ...], pnom: np.ndarray,
                        vnom: np.ndarray, psi_hat: np.ndarray | None = None) -> None:
    """Rolling on the runway (the ground ``rolls``; docs/joint.md, "The heading reference:
    runways"): zero cross-track velocity and offset from the centreline, across the runway's
    direction where known (with ``roll_velocity`` "runway", the default), else across the true
    heading psi_rec - dpsi linearised about the last pass's heading bias ``psi_hat`` (per step):
    c(psi_rec - dpsi) . v ~ c(psi') . v + (dpsi - psi_hat) a(psi') . v_nom, psi' = psi_rec -
    psi_hat, c and a the cross- and along-heading unit vectors (exact at the solution), ``vnom``
    and ``pnom`` the nominal velocities and ECEF positions."""
    for g in rolls:
        tt, k = g.t, g.k
        ph = np.zeros(len(tt)) if psi_hat is None or not g.nose else psi_hat[k]
        psi = g.heading_rad - ph if g.nose else np.full(len(tt), g.runway_rad)
        H = np.zeros((len(tt), jl.N_STATE))
        H[:, jl.IV] = -np.sin(psi)
        H[:, jl.IV + 1] = np.cos(psi)
        if g.nose:
            H[:, jl.IPSI] = np.cos(psi) * vnom[k, 0] + np.sin(psi) * vnom[k, 1]
        b.add("ground", jl.LINEAR, tt, np.zeros(len(tt)), g.r_v, H, -H[:, jl.IPSI] * ph, step=k)
        if g.point is None:
            continue
        # the centreline: the runway's direction where known (only its line matters: a
        # reversed direction is the same), else the true heading
        c = g.centre
        tt, k, ph, psi = tt[c], k[c], ph[c], psi[c]
        if g.runway_rad is not None:
            psi, ph = np.full(len(tt), g.runway_rad), np.zeros(len(tt))
        cross = np.c_[-np.sin(psi), np.cos(psi), np.zeros(len(psi))] @ g.Ca.T  # (m, 3) in ECEF
        H = np.zeros((len(tt), jl.N_STATE))
        H[:, jl.S_POS] = cross
        if g.runway_rad is None:
            along = np.c_[np.cos(psi), np.sin(psi), np.zeros(len(psi))] @ g.Ca.T
            H[:, jl.IPSI] = np.einsum("mj,mj->m", along, pnom[k] - g.point)
        b.add("runway", jl.LINEAR, tt, np.zeros(len(tt)), g.r_cl, H,
              -cross @ g.point - H[:, jl.IPSI] * ph, step=k)


def rest_heading(inp: JointInputs) -> float | None:
    """The circular mean recorded heading [rad] over the rest before the take-off roll
    (``inp.roll.rest_t``), None where no rest was found."""
    r0, r1 = inp.roll.rest_t
    if not (np.isfinite(r0) and np.isfinite(r1)):
        return None
    m = (inp.t_in >= r0) & (inp.t_in <= r1) & np.isfinite(inp.heading_rad)
    if not m.any():
        return None
    h = inp.heading_rad[m]
    return float(np.arctan2(np.mean(np.sin(h)), np.mean(np.cos(h))))


def steering_variance(heading_rad: np.ndarray, v_roll_mps: float,
                      ref_rad: float | None = None) -> np.ndarray:
    """Variance [m^2/s^2] of the velocity across the runway that steering makes at each of a roll's
    samples (recorded headings ``heading_rad`` [rad]): ``(V sin d)^2``, d the heading's angle to the
    lined-up heading ``ref_rad`` [rad] (None: the samples' circular mean), V = ``v_roll_mps`` the
    roll's fastest speed (:func:`roll_speed`) (docs/joint.md, "The heading reference: runways")."""
    h = np.asarray(heading_rad, dtype=float)
    if h.size == 0:
        return np.zeros(0)
    ref = (float(np.arctan2(np.mean(np.sin(h)), np.mean(np.cos(h)))) if ref_rad is None
           else float(ref_rad))
    d = np.angle(np.exp(1j * (h - ref)))
    return (v_roll_mps * np.sin(d)) ** 2


def lineup_heading(inp: JointInputs, t_rest: np.ndarray) -> np.ndarray:
    """Lined up at rest before the take-off roll, the nose points along the departure runway: the
    row on the heading bias, dpsi = mean(psi_rec - psi_rw) (the circular mean over the rest's
    samples ``t_rest``, wrapped to the runway's line: a reversed direction is the same runway),
    where the metadata give the runway's direction: (time, dpsi), else empty (its sd
    ``lineup_heading_deg``: :func:`build_measurements`; docs/joint.md, "The heading reference:
    runways")."""
    rw = inp.runway_rad[0]
    if rw is None or len(t_rest) == 0:
        return np.zeros(0)
    psi = np.interp(t_rest, inp.t_in, np.unwrap(np.where(np.isfinite(inp.heading_rad),
                                                         inp.heading_rad, 0.0)))
    ok = np.interp(t_rest, inp.t_in, np.isfinite(inp.heading_rad).astype(float)) > 0.999
    if not ok.any():
        return np.zeros(0)
    d = psi[ok] - rw
    return np.array([float(np.mean(t_rest[ok])),
                     0.5 * float(np.arctan2(np.mean(np.sin(2.0 * d)), np.mean(np.cos(2.0 * d))))])


def roll_speed(inp: JointInputs, settings: JointSettings, t_edge: float) -> float:
    """The fastest speed of a ground roll: the recorded airspeed at its lift-off or touchdown
    ``t_edge``, at least ``min_airspeed_mps`` (a bound on the along-track speed, wind aside)."""
    ok = np.isfinite(inp.tas)
    v = np.nan
    if np.isfinite(t_edge) and ok.any():
        v = float(np.interp(t_edge, inp.t_in[ok], inp.tas[ok]))
    return max(v, settings.min_airspeed_mps) if np.isfinite(v) else settings.min_airspeed_mps


NOISE_GROUPS = {("air", jl.TAS): "air_tas", ("air", jl.HEADING): "air_heading",
                ("baro", jl.BARO): "baro", ("gnss_pos", jl.NED_POS): "gnss_pos",
                ("gnss_vel", jl.STATE): "gnss_vel", ("radar", jl.RANGE): "radar_range",
                ("radar", jl.AZIMUTH): "radar_azimuth", ("radar", jl.ELEVATION): "radar_elevation",
                ("doppler", jl.DOPPLER): "doppler_speed", ("doppler", jl.TRACK): "doppler_track"}
"""Sensor error variances that ``estimate_noise`` scales, one factor per group (the end points,
ground and runway constraints and the sparse recorded wind are priors, not estimated)."""


def noise_groups(meas: Measurements) -> np.ndarray:
    """Index into NOISE_GROUPS of each measurement, -1 where its variance is not estimated."""
    g = np.full(len(meas.z), -1, dtype=np.int64)
    for i, (src, mt) in enumerate(NOISE_GROUPS):
        g[(meas.source == SOURCES.index(src)) & (meas.mtype == mt)] = i
    return g
