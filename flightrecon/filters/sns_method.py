"""Adapter: heading-airspeed / heading-Doppler dead reckoning fused with SNS fixes (docs/sns.md).

:func:`run_sns` takes a :class:`flightrecon.types.CleanFlight` and returns a
:class:`flightrecon.types.MethodResult` with the smoothed track on the recorder grid;
:func:`solve_sns` returns everything (forward run, smoothed run, inputs) for diagnostics.

Preparation (all vectorised):

* model chosen from the channels: ``doppler_gs_mps`` and ``drift_deg`` present -> heading-Doppler,
  else heading-airspeed with the wind channels (``wind_speed_mps``, ``wind_from_deg``, FROM:
  the vector used blows toward ``wind_from + 180 deg``) or zero forecast wind;
* the readings are held between recorder samples (zero-order hold) and integrated exactly
  (cumulative integrals); the filter runs on every ``decimation``-th recorder sample (default:
  about 2 Hz), each filter step using the exact integral of the held readings over the step;
* GNSS fixes are used once each at their own time (the observation maps the state at the start of
  the step to the fix time with the partial integral); the antenna is reduced to the centre of mass
  with the lever arm: ``r_cm = r_ant - C_nb l`` and ``v_cm = v_ant - d(C_nb l)/dt``, the latter
  from the attitude on the recorder grid (central differences), i.e. the rotation-rate term is
  included;
* the height for the metres-to-radians conversion is the GNSS height interpolated to the grid
  (a scale factor only: 100 m of height error is 1.6e-5 of the distance flown).

Output positions are in the output tangent plane at the departure airfield (north/east with the
covariance rotated into the plane's axes); velocities are true north/east at the aircraft.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.errors import ConvergenceError, SchemaError, ValidationError
from flightrecon.estimation.consistency import chi_square_verdict
from flightrecon.filters import sns as core
from flightrecon.geo.ellipsoid import radii_from_sin
from flightrecon.geo.frames import msl_to_ellipsoid, output_plane
from flightrecon.geo.navframe import north_azimuth_in_plane
from flightrecon.geo.wind import wind_toward_ne
from flightrecon.types import CleanFlight, MethodResult

MODELS = {"airspeed": core.MODEL_AIRSPEED, "doppler": core.MODEL_DOPPLER}
FORMS = {"consistent": core.FORM_CONSISTENT, "seed": core.FORM_SEED}
GNSS_COLUMNS = ("t_s", "gnss_lat_deg", "gnss_lon_deg")
TRACK_COLUMNS = ("t_s", "sns_north_m", "sns_east_m", "sns_north_sd_m", "sns_east_sd_m",
                 "sns_vn_mps", "sns_ve_mps", "sns_vn_sd_mps", "sns_ve_sd_mps")


@dataclass(frozen=True)
class SnsSolution:
    """Full result of :func:`solve_sns`.

    ``idx`` are the recorder-grid indices of the filter points; ``fix_t`` the times of the fixes
    used; ``lat``/``lon`` (rad), ``P_ne``, ``v_ne``, ``P_v`` the smoothed output on the grid.
    """

    model: int
    form: int
    noise: core.SnsNoise
    inputs: core.StepInputs
    run: core.SnsRun
    smoothed: core.SnsSmoothed
    idx: np.ndarray
    fix_t: np.ndarray
    n_fix_dropped: int
    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    P_ne: np.ndarray
    v_ne: np.ndarray
    P_v: np.ndarray
    notes: tuple[str, ...]


def choose_model(grid: pd.DataFrame, model: str = "auto") -> int:
    """The dead-reckoning model for ``model`` (``auto``, ``airspeed`` or ``doppler``).

    Raises
    ------
    SchemaError
        ``doppler`` asked without the Doppler channels, or an unknown model name.
    """
    has_doppler = all(c in grid.columns and np.isfinite(grid[c].to_numpy(float)).any()
                      for c in ("doppler_gs_mps", "drift_deg"))
    if model == "auto":
        return core.MODEL_DOPPLER if has_doppler else core.MODEL_AIRSPEED
    if model not in MODELS:
        raise SchemaError(f"unknown SNS model '{model}': choose auto, airspeed or doppler")
    if model == "doppler" and not has_doppler:
        raise SchemaError("heading-Doppler model needs the doppler_gs_mps and drift_deg channels")
    return MODELS[model]


def _channel(grid: pd.DataFrame, name: str, notes: list[str], fill: float | None = None
             ) -> np.ndarray:
    """A grid channel as float array; NaN gaps filled by linear interpolation (noted)."""
    if name not in grid.columns:
        if fill is None:
            raise SchemaError("the SNS method needs this channel", column=name)
        return np.full(len(grid), fill)
    x = grid[name].to_numpy(dtype=float).copy()
    bad = ~np.isfinite(x)
    if bad.all():
        if fill is None:
            raise ValidationError("channel has no valid sample", column=name)
        notes.append(f"{name}: no valid sample, {fill} used")
        return np.full(len(grid), fill)
    if bad.any():
        i = np.arange(len(x))
        x[bad] = np.interp(i[bad], i[~bad], x[~bad])
        notes.append(f"{name}: {int(bad.sum())} missing samples interpolated for dead reckoning")
    return x


def _readings(grid: pd.DataFrame, model: int, notes: list[str]):
    """Per recorder sample: measured velocity vector a, its unit vector u, wind (toward) w."""
    psi = np.deg2rad(_channel(grid, "heading_deg", notes))
    if model == core.MODEL_DOPPLER:
        gs = _channel(grid, "doppler_gs_mps", notes)
        ang = psi + np.deg2rad(_channel(grid, "drift_deg", notes))
        u = np.column_stack([np.cos(ang), np.sin(ang)])
        return u * gs[:, None], u, np.zeros_like(u)
    tas = _channel(grid, "tas_mps", notes)
    u = np.column_stack([np.cos(psi), np.sin(psi)])
    if "wind_speed_mps" in grid.columns and "wind_from_deg" in grid.columns:
        w = wind_toward_ne(_channel(grid, "wind_speed_mps", notes, fill=0.0),
                           _channel(grid, "wind_from_deg", notes, fill=0.0))
    else:
        notes.append("no wind channel: zero forecast wind, the wind correction is the whole wind")
        w = np.zeros_like(u)
    return u * tas[:, None], u, w


def lever_arm_ne(grid: pd.DataFrame, lever_arm_m: tuple[float, float, float]) -> np.ndarray:
    """North/east components (N, 2) of ``C_nb(heading, pitch, roll) l`` on the grid [m].

    ZYX Euler rotation of the body (FRD) lever arm; roll and pitch zero where not recorded.
    """
    n = len(grid)
    notes: list[str] = []
    psi = np.deg2rad(_channel(grid, "heading_deg", notes))
    th = np.deg2rad(_channel(grid, "pitch_deg", notes, fill=0.0))
    ph = np.deg2rad(_channel(grid, "roll_deg", notes, fill=0.0))
    l0, l1, l2 = (float(v) for v in lever_arm_m)
    b1 = np.cos(ph) * l1 - np.sin(ph) * l2
    b2 = np.sin(ph) * l1 + np.cos(ph) * l2
    c0 = np.cos(th) * l0 + np.sin(th) * b2
    c1 = b1
    out = np.empty((n, 2))
    out[:, 0] = np.cos(psi) * c0 - np.sin(psi) * c1
    out[:, 1] = np.sin(psi) * c0 + np.cos(psi) * c1
    return out


def _lever_arm_rows(grid: pd.DataFrame, rows: np.ndarray,
                    lever_arm_m: tuple[float, float, float]) -> np.ndarray:
    """:func:`lever_arm_ne` at the grid rows ``rows`` only (same arithmetic, same NaN filling)."""
    notes: list[str] = []
    psi = np.deg2rad(_channel(grid, "heading_deg", notes)[rows])
    th = np.deg2rad(_channel(grid, "pitch_deg", notes, fill=0.0)[rows])
    ph = np.deg2rad(_channel(grid, "roll_deg", notes, fill=0.0)[rows])
    l0, l1, l2 = (float(v) for v in lever_arm_m)
    cph, sph = np.cos(ph), np.sin(ph)
    b1 = cph * l1 - sph * l2
    b2 = sph * l1 + cph * l2
    c0 = np.cos(th) * l0 + np.sin(th) * b2
    c1 = b1
    cpsi, spsi = np.cos(psi), np.sin(psi)
    out = np.empty((len(rows), 2))
    out[:, 0] = cpsi * c0 - spsi * c1
    out[:, 1] = spsi * c0 + cpsi * c1
    return out


def _lever_arm_at(grid: pd.DataFrame, t: np.ndarray, tf: np.ndarray, jf: np.ndarray,
                  lever_arm_m: tuple[float, float, float]) -> tuple[np.ndarray, np.ndarray]:
    """Lever arm ``C_nb l`` (north/east) and its time derivative at the fix times ``tf``.

    Equal to ``np.interp(tf, t, arm)`` and ``np.interp(tf, t, np.gradient(arm, t))`` with
    ``arm = lever_arm_ne(grid, l)`` on the whole grid, but the attitude is rotated only at the
    rows those need: the samples ``jf``, ``jf + 1`` bracketing each fix (``jf`` the sample held at
    the fix) and their neighbours for the central differences (numpy's second-order
    non-uniform formula inside, one-sided at the ends).
    """
    M = len(t)
    mask = np.zeros(M, dtype=bool)
    for off in (-1, 0, 1, 2):
        mask[np.clip(jf + off, 0, M - 1)] = True
    need = np.flatnonzero(mask)
    arm = _lever_arm_rows(grid, need, lever_arm_m)
    tr = t[need]
    # derivative at the rows whose grid neighbours are also computed (jf and jf + 1 always are)
    darm = np.zeros_like(arm)
    ip = np.minimum(np.searchsorted(need, need - 1), len(need) - 1)
    inx = np.minimum(np.searchsorted(need, need + 1), len(need) - 1)
    has_p = need[ip] == need - 1
    has_n = need[inx] == need + 1
    mid = has_p & has_n
    dx1 = tr[mid] - tr[ip[mid]]
    dx2 = tr[inx[mid]] - tr[mid]
    ca = -(dx2) / (dx1 * (dx1 + dx2))
    cb = (dx2 - dx1) / (dx1 * dx2)
    cc = dx1 / (dx2 * (dx1 + dx2))
    darm[mid] = (ca[:, None] * arm[ip[mid]] + cb[:, None] * arm[mid]
                 + cc[:, None] * arm[inx[mid]])
    first = (need == 0) & has_n
    darm[first] = (arm[inx[first]] - arm[first]) / (tr[inx[first]] - tr[first])[:, None]
    last = (need == M - 1) & has_p
    darm[last] = (arm[last] - arm[ip[last]]) / (tr[last] - tr[ip[last]])[:, None]
    arm_f = np.column_stack([np.interp(tf, tr, arm[:, i]) for i in range(2)])
    darm_f = np.column_stack([np.interp(tf, tr, darm[:, i]) for i in range(2)])
    return arm_f, darm_f


def _at(t: np.ndarray, cum: np.ndarray, v: np.ndarray, tq: np.ndarray,
        j: np.ndarray | None = None) -> np.ndarray:
    """Integral of the held series up to arbitrary times ``tq`` (within ``[t[0], t[-1]]``).

    ``j`` (optional) are the samples held at ``tq`` if already known.
    """
    if j is None:
        j = np.clip(np.searchsorted(t, tq, side="right") - 1, 0, len(t) - 1)
    return cum[j] + v[j] * (tq - t[j])[:, None]


def _gaps(t_fix: np.ndarray, t0: float, t1: float, min_gap_s: float) -> list[dict[str, float]]:
    """GNSS gaps longer than ``min_gap_s`` (also before the first and after the last fix)."""
    edges = np.concatenate([[t0], t_fix, [t1]])
    dt = np.diff(edges)
    out = []
    for i in np.flatnonzero(dt > min_gap_s):
        out.append({"start_s": float(edges[i]), "end_s": float(edges[i + 1]),
                    "duration_s": float(dt[i])})
    return out


def solve_sns(clean: CleanFlight, *, model: str = "auto", form: str = "consistent",
              filter_rate_hz: float = 2.0, noise: core.SnsNoise | None = None) -> SnsSolution:
    """Filter and smooth a cleaned flight (see module docstring).

    Parameters
    ----------
    clean : cleaned flight (grid with ``t_s``, ``tas_mps``, ``heading_deg``, ...; GNSS fixes)
    model : ``auto``, ``airspeed`` or ``doppler``
    form : ``consistent`` (correlated-noise terms) or ``seed`` (the paper's form)
    filter_rate_hz : rate of the filter grid (every ``round(rate / filter_rate_hz)``-th recorder
        sample, raised if two fixes of one step would fall in different recorder samples);
        the answer does not depend on it beyond rounding and linearisation (sensor noise is
        per recorder sample and split exactly between the steps and the fixes)
    noise : :class:`flightrecon.filters.sns.SnsNoise` (default :func:`~sns.default_noise`)

    Raises
    ------
    SchemaError, ValidationError, MetadataError
        Missing channels, too few fixes, bad settings, no departure airfield.
    ConvergenceError
        A predicted covariance became singular (the smoother cannot proceed).
    """
    notes: list[str] = []
    if form not in FORMS:
        raise ValidationError(f"unknown SNS form '{form}': choose consistent or seed")
    if not np.isfinite(filter_rate_hz) or filter_rate_hz <= 0:
        raise ValidationError(f"filter_rate_hz must be positive, got {filter_rate_hz}")
    output_plane(clean.meta)  # MetadataError early if there is no departure airfield
    grid = clean.grid
    if "t_s" not in grid.columns or len(grid) < 2:
        raise SchemaError("the recorder grid needs t_s and at least two samples", column="t_s")
    t = grid["t_s"].to_numpy(float)
    if not np.all(np.diff(t) > 0):
        raise ValidationError("grid times must increase strictly", column="t_s")
    m = choose_model(grid, model)
    fm = FORMS[form]
    noise = noise or core.default_noise(m)

    g = clean.gnss
    for c in GNSS_COLUMNS:
        if c not in g.columns:
            raise SchemaError("the SNS method needs GNSS fixes with this column", column=c)
    g = g[np.isfinite(g[list(GNSS_COLUMNS)].to_numpy(float)).all(axis=1)].sort_values("t_s")
    if "gnss_quality" in g.columns:
        g = g[g["gnss_quality"].isna() | (g["gnss_quality"] > 0)]
    inside = (g["t_s"] >= t[0]) & (g["t_s"] <= t[-1])
    n_drop = int((~inside).sum())
    g = g[inside]
    if len(g) < 2:
        raise ValidationError("fewer than two GNSS fixes inside the recorder grid")
    tf = g["t_s"].to_numpy(float)
    h_fix = (g["gnss_alt_m"].to_numpy(float) if "gnss_alt_m" in g.columns
             else np.full(len(g), np.nan))
    if clean.meta.gnss_alt_datum == "msl":
        h_fix = msl_to_ellipsoid(h_fix, clean.meta.geoid_undulation_m)
    no_h = ~np.isfinite(h_fix)
    if no_h.any():
        # fixes without height are used horizontally (the filter is horizontal; the height
        # only sets the earth radii and the lever arm): the pressure altitude stands in, as
        # MSL height, at the fix time (a 300 m error changes the radii by 5e-5)
        if "baro_alt_m" in grid.columns and np.isfinite(grid["baro_alt_m"].to_numpy(float)).any():
            b = grid["baro_alt_m"].to_numpy(float)
            okb = np.isfinite(b)
            h_sub = msl_to_ellipsoid(np.interp(tf[no_h], t[okb], b[okb]),
                                     clean.meta.geoid_undulation_m)
        else:
            h_sub = 0.0
        h_fix = h_fix.copy()
        h_fix[no_h] = h_sub
        notes.append(f"{int(no_h.sum())} GNSS fixes without height used horizontally (height "
                     "for the earth radii from the pressure altitude)")
    h_grid = np.interp(t, tf, h_fix)

    a, u, w = _readings(grid, m, notes)
    # cumulative integrals of the held readings, and CQ[j] = sum over samples < j of
    # dt^2 [u u^T, (Ja)(Ja)^T, 1] for the summed errors of whole samples (one compiled pass)
    IA, IU, IW, CQ = core.integrate_readings(t, a, u, w)

    # filter grid: every dec-th sample, dec reduced until each step's fixes share one sample
    jf = np.clip(np.searchsorted(t, tf, side="right") - 1, 0, len(t) - 1)
    rate = 1.0 / np.median(np.diff(t))
    dec = max(1, round(rate / filter_rate_hz))
    while True:
        idx = np.arange(0, len(t), dec)
        if idx[-1] != len(t) - 1:
            idx = np.append(idx, len(t) - 1)
        tk = t[idx]
        N = len(idx)
        kf = np.clip(np.searchsorted(tk, tf, side="right") - 1, 0, N - 1)
        same_step = kf[1:] == kf[:-1]
        if dec == 1 or not np.any(same_step & (jf[1:] != jf[:-1])):
            break
        dec = max(1, dec // 2)
    if dec != max(1, round(rate / filter_rate_hz)):
        notes.append(f"filter grid raised to {rate / dec:.3g} Hz so that each step's GNSS fixes "
                     "fall in one recorder sample")
    A = np.zeros((N, 2))
    U = np.zeros((N, 2))
    W = np.zeros((N, 2))
    A[:-1], U[:-1], W[:-1] = np.diff(IA[idx], axis=0), np.diff(IU[idx], axis=0), np.diff(
        IW[idx], axis=0)
    ks = np.arange(N)
    fstart = np.searchsorted(kf, ks, side="left")
    fend = np.searchsorted(kf, ks, side="right")
    has = fend > fstart
    jstar = np.where(has, jf[np.minimum(fstart, len(jf) - 1)], idx)
    nxt = np.append(idx[1:], idx[-1])  # first sample of the next step
    star = np.zeros((N, 3, 2))
    star[has] = np.stack([a[jstar[has]], u[jstar[has]], w[jstar[has]]], axis=1)
    dt_star = np.zeros(N)
    inner = has & (jstar < nxt)
    dt_star[inner] = t[np.minimum(jstar[inner] + 1, len(t) - 1)] - t[jstar[inner]]
    Qb = np.where(has[:, None], CQ[jstar] - CQ[idx], CQ[nxt] - CQ[idx])
    Qa = np.where(inner[:, None], CQ[nxt] - CQ[np.minimum(jstar + 1, len(t))], 0.0)

    # fixes: centre of mass, step, partial integrals, held readings
    arm_f, darm_f = _lever_arm_at(grid, t, tf, jf, clean.meta.gnss_lever_arm_m)
    lat_a = np.deg2rad(g["gnss_lat_deg"].to_numpy(float))
    lon_a = np.deg2rad(g["gnss_lon_deg"].to_numpy(float))
    mh, nh = _radii_np(lat_a, h_fix)
    flat = lat_a - arm_f[:, 0] / mh
    flon = lon_a - arm_f[:, 1] / (nh * np.cos(lat_a))
    fv = np.full((len(tf), 2), np.nan)
    for i, c in enumerate(("gnss_vn_mps", "gnss_ve_mps")):
        if c in g.columns:
            fv[:, i] = g[c].to_numpy(float) - darm_f[:, i]
    inputs = core.StepInputs(
        t=tk, h=h_grid[idx], A=A, U=U, W=W, fix_start=fstart, fix_end=fend,
        fix_lat=flat, fix_lon=flon, fix_v=fv, fix_tau=tf - tk[kf],
        fix_PA=_at(t, IA, a, tf, jf) - IA[idx[kf]], fix_PU=_at(t, IU, u, tf, jf) - IU[idx[kf]],
        fix_PW=_at(t, IW, w, tf, jf) - IW[idx[kf]],
        fix_a=a[jf], fix_u=u[jf], fix_w=w[jf], star=star, dt_star=dt_star, Qb=Qb, Qa=Qa,
        fix_tau_in=tf - t[jf],
        fix_pos_sd=(g["gnss_h_sd_m"].to_numpy(float) if "gnss_h_sd_m" in g.columns else None),
        fix_vel_sd=(g["gnss_vel_sd_mps"].to_numpy(float) if "gnss_vel_sd_mps" in g.columns
                    else None))

    # initial state: first fix moved back by the uncorrected dead reckoning
    back = (_at(t, IA, a, tf[:1]) + _at(t, IW, w, tf[:1]) - IA[:1] - IW[:1])[0]
    lat0, lon0 = core.boxplus(flat[0], flon[0], -back[0], -back[1], h_fix[0])
    sd0 = 3.0 * noise.pos_sd_m + 0.1 * float(np.hypot(*back)) + 1.0
    x0 = np.array([lat0, lon0, 0.0, 0.0, 0.0])
    P0 = np.diag([sd0 ** 2, sd0 ** 2, *np.square(noise.prior_sd)])
    try:
        run = core.sns_filter(inputs, x0, P0, noise, model=m, form=fm)
        sm = core.sns_smooth(run)
    except np.linalg.LinAlgError as exc:
        raise ConvergenceError(f"SNS filter/smoother failed: {exc} (a covariance became "
                               "singular: check the noise settings)") from exc

    # filter step of each recorder sample: idx = [0, dec, 2 dec, ...] (+ the last sample)
    kq = np.minimum(np.arange(len(t)) // dec, N - 1)
    kq[-1] = N - 1
    lat, lon, P_ne, v_ne, P_v = core.densify(
        m, sm.x, sm.P, kq, t, tk, (IA, IU, IW), (IA[idx], IU[idx], IW[idx]), h_grid, (a, u, w),
        np.asarray(noise.sensor_sd, float))
    if n_drop:
        notes.append(f"{n_drop} GNSS fixes outside the recorder grid not used")
    if sm.cholesky_fallbacks:
        notes.append(f"{sm.cholesky_fallbacks} steps' predicted covariance failed its Cholesky "
                     "factorisation; their smoother gain came from a general solve")
    return SnsSolution(m, fm, noise, inputs, run, sm, idx, tf, n_drop, lat, lon, h_grid, P_ne,
                       v_ne, P_v, tuple(notes))


def _radii_np(lat: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`flightrecon.filters.sns.radii` on arrays: ``(M + h, N + h)`` [m]."""
    m, n = radii_from_sin(np.sin(lat))
    return m + h, n + h


GAMMA_STRIDE = 16  # recorder samples between pyproj evaluations of the meridian convergence


def plane_track(sol: SnsSolution, plane, *, out: np.ndarray | None = None
                ) -> dict[str, np.ndarray]:
    """Positions and their standard deviations in the output tangent plane's axes.

    The local north/east covariance is rotated by the angle ``gamma`` between local north and the
    plane's north (meridian convergence, exact:
    :func:`flightrecon.geo.navframe.north_azimuth_in_plane`).  ``gamma`` is a smooth function of
    position (its second derivative along the track is of order ``1 / R_earth^2``), so it is
    evaluated every ``GAMMA_STRIDE`` recorder samples (and at the last) and interpolated linearly:
    over 16 samples (one second at 16 Hz, about 250 m) the interpolation error is below ``250^2 / 8
    / R^2``, 2e-10 rad, which changes a standard deviation by less than 1e-9 of itself.  The rotated
    variances are written in closed form: ``north = cg^2 Pnn - 2 cg sg Pne + sg^2 Pee``, ``east =
    sg^2 Pnn + 2 cg sg Pne + cg^2 Pee``.  ``out`` (4, M), if given, receives ``north_m, east_m,
    north_sd_m, east_sd_m``.
    """
    latd, lond = np.rad2deg(sol.lat), np.rad2deg(sol.lon)
    M = len(latd)
    e, n, _ = plane.forward(latd, lond, sol.h)
    sub = np.arange(0, M, GAMMA_STRIDE)
    if sub[-1] != M - 1:
        sub = np.append(sub, M - 1)
    gam_sub = north_azimuth_in_plane(plane.lat0_deg, plane.lon0_deg, latd[sub], lond[sub])
    # cos and sin interpolated directly: the chord of the unit circle over one interval
    # (gamma changes by < 1e-5 rad) is shorter than the arc by < 1e-11 relative
    pos = np.arange(M, dtype=float)
    cg = np.interp(pos, sub, np.cos(gam_sub))
    sg = np.interp(pos, sub, np.sin(gam_sub))
    pnn, pne, pee = sol.P_ne[:, 0, 0], 0.5 * (sol.P_ne[:, 0, 1] + sol.P_ne[:, 1, 0]), \
        sol.P_ne[:, 1, 1]
    cs2 = 2.0 * cg * sg * pne
    if out is None:
        out = np.empty((4, M))
    out[0] = n
    out[1] = e
    np.sqrt(cg * cg * pnn - cs2 + sg * sg * pee, out=out[2])
    np.sqrt(sg * sg * pnn + cs2 + cg * cg * pee, out=out[3])
    return {"north_m": out[0], "east_m": out[1], "north_sd_m": out[2], "east_sd_m": out[3]}


def corrections_summary(sol: SnsSolution, k: int = -1) -> dict[str, Any]:
    """Estimated corrections (true minus measured) with standard deviations at filter step k.

    The smoothed estimate at the last step uses every fix.  Heading-Doppler also reports the
    track-angle correction ``corr_c + corr_psi``, the combination the data determine.
    """
    x = sol.smoothed.x[k]
    P = sol.smoothed.P[k]
    sd = np.sqrt(np.diag(P))
    deg = np.rad2deg
    if sol.model == core.MODEL_AIRSPEED:
        return {"heading_corr_deg": float(deg(x[4])), "heading_corr_sd_deg": float(deg(sd[4])),
                "wind_corr_n_mps": float(x[2]), "wind_corr_n_sd_mps": float(sd[2]),
                "wind_corr_e_mps": float(x[3]), "wind_corr_e_sd_mps": float(sd[3])}
    track_sd = np.sqrt(P[3, 3] + P[4, 4] + 2 * P[3, 4])
    return {"doppler_scale_corr": float(x[2]), "doppler_scale_corr_sd": float(sd[2]),
            "drift_corr_deg": float(deg(x[3])), "drift_corr_sd_deg": float(deg(sd[3])),
            "heading_corr_deg": float(deg(x[4])), "heading_corr_sd_deg": float(deg(sd[4])),
            "track_corr_deg": float(deg(x[3] + x[4])), "track_corr_sd_deg": float(deg(track_sd))}


#: SNS noise settings a user can override (``[sns]`` table of ``--noise``), in natural units
SNS_NOISE_KEYS = ("pos_sd_m", "vel_sd_mps", "speed_sd_mps", "heading_sd_deg", "wind_sd_mps",
                  "drift_sd_deg", "heading_bias_prior_deg")


def sns_noise_with(model: int, overrides: dict[str, float] | None) -> core.SnsNoise:
    """:func:`~flightrecon.filters.sns.default_noise` of ``model`` with ``overrides`` applied
    (keys :data:`SNS_NOISE_KEYS`: GNSS position / velocity sd per component, the speed reading's
    sd (TAS or Doppler ground speed), heading sd, wind reading sd (airspeed model), drift sd
    (Doppler model), the heading-bias prior).

    Raises
    ------
    MetadataError
        An unknown key, or a value that is not a positive number.
    """
    from dataclasses import replace

    from flightrecon.errors import MetadataError

    nz = core.default_noise(model)
    if not overrides:
        return nz
    sens = list(nz.sensor_sd)
    prior = list(nz.prior_sd)
    kw: dict = {}
    for k, v in overrides.items():
        if k not in SNS_NOISE_KEYS:
            raise MetadataError(f"unknown SNS noise setting '{k}' (known: "
                                f"{', '.join(SNS_NOISE_KEYS)})")
        if isinstance(v, bool) or not isinstance(v, (int, float)) or not np.isfinite(v) or v <= 0:
            raise MetadataError(f"SNS noise setting '{k}' must be a positive number, got {v!r}")
        v = float(v)
        if k in ("pos_sd_m", "vel_sd_mps"):
            kw[k] = v
        elif k == "speed_sd_mps":
            sens[0] = v
        elif k == "heading_sd_deg":
            sens[1 if model == core.MODEL_AIRSPEED else 2] = float(np.deg2rad(v))
        elif k == "wind_sd_mps" and model == core.MODEL_AIRSPEED:
            sens[2] = sens[3] = v
        elif k == "drift_sd_deg" and model == core.MODEL_DOPPLER:
            sens[1] = float(np.deg2rad(v))
        elif k == "heading_bias_prior_deg":
            prior[2] = float(np.deg2rad(v))
    return replace(nz, sensor_sd=(sens[0], sens[1], sens[2], sens[3]),
                   prior_sd=(prior[0], prior[1], prior[2]), **kw)


def run_sns(clean: CleanFlight, *, model: str = "auto", form: str = "consistent",
            filter_rate_hz: float = 2.0, noise: core.SnsNoise | None = None,
            noise_overrides: dict[str, float] | None = None) -> MethodResult:
    """Dead reckoning fused with SNS, smoothed, on the recorder grid (docs/sns.md).

    Parameters are those of :func:`solve_sns`; ``noise_overrides`` (:func:`sns_noise_with`)
    change the default noise of the chosen model where ``noise`` is not given.

    Returns
    -------
    MethodResult
        ``name="sns"``; track columns ``t_s``, ``sns_north_m``, ``sns_east_m`` (output tangent
        plane), ``sns_north_sd_m``, ``sns_east_sd_m``, ``sns_vn_mps``, ``sns_ve_mps`` (true
        north/east), ``sns_vn_sd_mps``, ``sns_ve_sd_mps``; summary with model, form, corrections
        and their standard deviations, fixes used, GNSS gaps, innovation statistics.
    """
    if noise is None and noise_overrides:
        noise = sns_noise_with(choose_model(clean.grid, model), noise_overrides)
    sol = solve_sns(clean, model=model, form=form, filter_rate_hz=filter_rate_hz, noise=noise)
    plane = output_plane(clean.meta)
    t = clean.grid["t_s"].to_numpy(float)
    # one (columns, rows) block filled in place and wrapped without a copy
    block = np.empty((len(TRACK_COLUMNS), len(t)))
    block[0] = t
    plane_track(sol, plane, out=block[1:5])
    block[5] = sol.v_ne[:, 0]
    block[6] = sol.v_ne[:, 1]
    np.sqrt(sol.P_v[:, 0, 0], out=block[7])
    np.sqrt(sol.P_v[:, 1, 1], out=block[8])
    track = pd.DataFrame(block.T, columns=list(TRACK_COLUMNS), copy=False)
    # NIS per fix with the rank of its innovation covariance as degrees of freedom
    verdict = chi_square_verdict(sol.run.nis, sol.run.rank)
    nis_ratio = verdict.mean
    finite = bool(np.isfinite(block).all())
    dt_fix = np.diff(sol.fix_t)
    min_gap = 3.0 * float(np.median(dt_fix)) if len(dt_fix) else 0.0
    summary: dict[str, Any] = {
        "model": "doppler" if sol.model == core.MODEL_DOPPLER else "airspeed",
        "form": form,
        "filter_rate_hz": float(1.0 / np.median(np.diff(sol.inputs.t))),
        "corrections": corrections_summary(sol),
        "n_fixes_used": len(sol.fix_t),
        "n_fixes_dropped": sol.n_fix_dropped,
        "gaps": _gaps(sol.fix_t, float(t[0]), float(t[-1]), min_gap),
        "nis_per_dof": nis_ratio,
        "consistency": verdict.as_dict(),
        "cholesky_fallbacks": sol.smoothed.cholesky_fallbacks,
        "converged": finite,
        # a mean NIS per degree of freedom far above 1 means the noise settings do not fit
        "healthy": finite and verdict.count > 0 and not verdict.gross,
        "notes": list(sol.notes),
    }
    return MethodResult(name="sns", track=track, summary=summary)
