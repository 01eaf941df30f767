"""SNS method inputs: the dead-reckoning readings, the GNSS fixes reduced to the centre of mass,
the filter grid and the per-step integrals the filter consumes (docs/sns.md).

Everything here is vectorised preparation for :func:`flightrecon.methods.sns.sns_filter`; the
method itself (:func:`flightrecon.methods.sns.method.solve_sns`) only strings the steps together.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
import pandas as pd

from flightrecon.errors import SchemaError, ValidationError
from flightrecon.geo.ellipsoid import radii_from_sin
from flightrecon.geo.frames import msl_to_ellipsoid
from flightrecon.geo.wind import wind_toward_ne
from flightrecon.methods import sns as core
from flightrecon.types import CleanFlight

MODELS = {"airspeed": core.MODEL_AIRSPEED, "doppler": core.MODEL_DOPPLER}
FORMS = {"consistent": core.FORM_CONSISTENT, "seed": core.FORM_SEED}
GNSS_COLUMNS = ("t_s", "gnss_lat_deg", "gnss_lon_deg")


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


def held_readings(grid: pd.DataFrame, model: int, notes: list[str]):
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


def lever_arm_at_fixes(grid: pd.DataFrame, t: np.ndarray, tf: np.ndarray, jf: np.ndarray,
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


def radii_with_height(lat: np.ndarray, h: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """:func:`flightrecon.methods.sns.radii` on arrays: ``(M + h, N + h)`` [m]."""
    # numpy on arrays (the same operations, the same numbers): no compiled array version
    m, n = radii_from_sin.py_func(np.sin(lat))
    return m + h, n + h


class GnssFixes(NamedTuple):
    """The GNSS fixes the filter uses: the frame (sorted, finite, quality > 0, inside the grid),
    their times ``tf`` [s], ellipsoidal heights ``h`` [m] and the count dropped outside the grid."""

    g: pd.DataFrame
    tf: np.ndarray
    h: np.ndarray
    n_dropped: int


def gnss_fixes(clean: CleanFlight, t: np.ndarray, notes: list[str]) -> GnssFixes:
    """Select the usable fixes and give each an ellipsoidal height.

    Fixes without a height are used horizontally (the filter is horizontal; the height only sets
    the earth radii and the lever arm): the pressure altitude stands in, as MSL height, at the fix
    time (a 300 m error changes the radii by 5e-5).

    Raises
    ------
    SchemaError
        A GNSS column of :data:`GNSS_COLUMNS` is missing.
    ValidationError
        Fewer than two fixes inside the recorder grid.
    """
    grid = clean.grid
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
        h_sub: np.ndarray | float
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
    return GnssFixes(g, tf, h_fix, n_drop)


class FilterGrid(NamedTuple):
    """The filter's time grid: every ``dec``-th recorder sample (``idx``, times ``tk``), the
    recorder sample ``jf`` held at each fix and the filter step ``kf`` the fix falls in."""

    dec: int
    idx: np.ndarray
    tk: np.ndarray
    kf: np.ndarray
    jf: np.ndarray


def filter_grid(t: np.ndarray, tf: np.ndarray, filter_rate_hz: float, notes: list[str]
                ) -> FilterGrid:
    """Every ``dec``-th sample (about ``filter_rate_hz``), ``dec`` halved until each step's
    fixes share one recorder sample (the observation holds one reading per step)."""
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
    return FilterGrid(dec, idx, tk, kf, jf)


class Readings(NamedTuple):
    """Held readings per recorder sample (``a`` velocity, ``u`` its unit vector, ``w`` wind
    toward, each (M, 2)), their cumulative integrals and ``CQ`` (the summed-error integrals of
    :func:`flightrecon.methods.sns.integrate_readings`)."""

    a: np.ndarray
    u: np.ndarray
    w: np.ndarray
    IA: np.ndarray
    IU: np.ndarray
    IW: np.ndarray
    CQ: np.ndarray


def readings(grid: pd.DataFrame, t: np.ndarray, model: int, notes: list[str]) -> Readings:
    """The readings of ``model`` and, in one compiled pass, their cumulative integrals and
    ``CQ[j]`` = sum over samples < j of ``dt^2 [u u^T, (Ja)(Ja)^T, 1]``."""
    a, u, w = held_readings(grid, model, notes)
    IA, IU, IW, CQ = core.integrate_readings(t, a, u, w)
    return Readings(a, u, w, IA, IU, IW, CQ)


def step_inputs(clean: CleanFlight, t: np.ndarray, h_grid: np.ndarray, fixes: GnssFixes,
                fg: FilterGrid, r: Readings) -> tuple[core.StepInputs, np.ndarray, np.ndarray]:
    """The filter's per-step integrals and the fixes reduced to the centre of mass
    (``h_grid``: the fixes' height interpolated to the recorder grid [m]).

    Returns the :class:`flightrecon.methods.sns.StepInputs`, and the fixes' centre-of-mass
    latitude and longitude [rad] (the initial state starts from the first).
    """
    idx, tk, kf, jf = fg.idx, fg.tk, fg.kf, fg.jf
    a, u, w, IA, IU, IW, CQ = r
    g, tf, h_fix = fixes.g, fixes.tf, fixes.h
    N = len(idx)
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
    arm_f, darm_f = lever_arm_at_fixes(clean.grid, t, tf, jf, clean.meta.gnss_lever_arm_m)
    lat_a = np.deg2rad(g["gnss_lat_deg"].to_numpy(float))
    lon_a = np.deg2rad(g["gnss_lon_deg"].to_numpy(float))
    mh, nh = radii_with_height(lat_a, h_fix)
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
    return inputs, flat, flon


def initial_state(t: np.ndarray, r: Readings, fixes: GnssFixes, flat: np.ndarray,
                  flon: np.ndarray, noise: core.SnsNoise) -> tuple[np.ndarray, np.ndarray]:
    """``x0, P0``: the first fix moved back to the first sample by the uncorrected dead
    reckoning, with a position sd of three fix sds plus a tenth of the distance moved back."""
    tf, h_fix = fixes.tf, fixes.h
    back = (_at(t, r.IA, r.a, tf[:1]) + _at(t, r.IW, r.w, tf[:1]) - r.IA[:1] - r.IW[:1])[0]
    lat0, lon0 = core.boxplus(flat[0], flon[0], -back[0], -back[1], h_fix[0])
    sd0 = 3.0 * noise.pos_sd_m + 0.1 * float(np.hypot(*back)) + 1.0
    x0 = np.array([lat0, lon0, 0.0, 0.0, 0.0])
    P0 = np.diag([sd0 ** 2, sd0 ** 2, *np.square(noise.prior_sd)])
    return x0, P0
