"""Adapter: the joint post-flight smoother on a cleaned flight (the default result).

Builds :class:`flightrecon.methods.joint.JointInputs` from a
:class:`flightrecon.types.CleanFlight`, runs :func:`flightrecon.methods.joint.smooth_joint` and
returns its track on the input grid with the prefix ``joint_`` (the pipeline writes it as the
unprefixed default result) and a summary with the estimated sensor errors, clock offsets and
per-source innovation statistics.
"""

from __future__ import annotations

import warnings as _warnings
from dataclasses import asdict, replace
from typing import Any

import numba as nb
import numpy as np
import pandas as pd

from flightrecon.cleaning.saturation import saturated_loads
from flightrecon.errors import FlightReconWarning, MetadataError, ValidationError
from flightrecon.estimation.consistency import chi_square_verdict
from flightrecon.geo.atmosphere import field_pressure_altitude_m, height_above_field_m
from flightrecon.geo.frames import ecef_to_geodetic, msl_to_ellipsoid, output_plane
from flightrecon.geo.kinematics import body_to_ned_matrix, kinematic_acceleration_ned
from flightrecon.geo.pressure_height import isa_deviation_k
from flightrecon.geo.wind import wind_toward_ne
from flightrecon.ingest.derive import N_LONG_HALF_WINDOW_S
from flightrecon.ingest.priors import wind_aloft_on_grid
from flightrecon.methods.joint import (
    SOURCES,
    JointInputs,
    JointRun,
    JointSettings,
    TakeoffRoll,
    prior_of,
    smooth_joint,
    source_report,
    takeoff_roll,
)
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.attitude_source import (
    attitude_source_noise,
    gnss_tilt_evidence,
    tilt_noise_open,
)
from flightrecon.methods.joint.diagnostics import (
    clock_warnings,
    far_warning,
    gust_warnings,
    implausible_corrections,
    wind_walk_check,
    wind_walk_warning,
)
from flightrecon.methods.joint.inputs import nearest_index
from flightrecon.methods.joint.measurements import wind_prior_measurements
from flightrecon.types import CleanFlight, FlightMeta, MethodResult

PREFIX = "joint_"


def _held_attitude(t: np.ndarray, *angles_deg: np.ndarray) -> tuple[list[np.ndarray], list[str]]:
    """Roll, pitch, heading with each missing sample replaced by the nearest recorded one.

    The acceleration stays NaN there (the smoother then adds process noise instead of the
    measured acceleration); the rotation of the accelerometer biases and of the ground
    constraints needs an attitude and takes the nearest recorded one.  Returns the angles and
    a note for the summary when any was missing.  An angle never recorded is an error.
    """
    names = ("roll_deg", "pitch_deg", "heading_deg")
    out, notes = [], []
    for name, a in zip(names, angles_deg):
        ok = np.isfinite(a)
        if not ok.any():
            raise ValidationError(f"the joint smoother needs {name}: it has no finite sample",
                                  column=name)
        if ok.all():
            out.append(a)
            continue
        held = a.copy()
        held[~ok] = a[ok][nearest_index(t[ok], t[~ok])]
        out.append(held)
        notes.append(f"joint: {name} missing on {int((~ok).sum())} samples; the acceleration "
                     "there is replaced by process noise and the bias rotation holds the "
                     "nearest recorded attitude")
    return out, notes


def _loads_in_ned(g: pd.DataFrame, t_in: np.ndarray,
                  lat_deg: float) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The (held) recorded attitude (Ni, 3) [deg] and the kinematic acceleration
    (NED) [m/s^2] of the loads on the grid ``g``, NaN where a load factor is saturated, with
    the notes for the summary."""
    def col(name):
        return g[name].to_numpy(dtype=float) if name in g.columns else np.full(len(g), np.nan)

    att, notes = _held_attitude(t_in, col("roll_deg"), col("pitch_deg"), col("heading_deg"))
    Cnb = body_to_ned_matrix(*att)
    # gravity at the departure latitude (normal gravity changes by 5e-6 m/s^2 per km north)
    acc = kinematic_acceleration_ned(col("n_long_g"), col("n_lat_g"), col("n_norm_g"),
                                     col("roll_deg"), col("pitch_deg"), col("heading_deg"),
                                     lat_deg=lat_deg,
                                     h_m=np.nan_to_num(col("baro_alt_m")), C_nb=Cnb)
    sat = saturated_loads(g)   # at the recorder's range: a bound, not a reading (as missing)
    if sat.any():
        acc[sat] = np.nan
        notes.append(f"joint: load factors saturated on {int(sat.sum())} samples; treated as "
                     "missing (process noise instead of the acceleration)")
    return np.column_stack(att), acc, notes


def _gnss_table(gn: pd.DataFrame, meta: FlightMeta) -> pd.DataFrame:
    """The GNSS fixes as the smoother reads them: ``t_s``, ``lat_deg``, ``lon_deg``, ellipsoidal
    ``h_m`` (NaN without a height), velocities and per-fix accuracies where recorded."""
    gnss = pd.DataFrame()
    if len(gn) and {"gnss_lat_deg", "gnss_lon_deg"} <= set(gn.columns):
        alt = (gn["gnss_alt_m"].to_numpy(float) if "gnss_alt_m" in gn.columns
               else np.full(len(gn), np.nan))
        if meta.gnss_alt_datum.lower() == "msl":
            alt = alt + meta.geoid_undulation_m
        gnss = pd.DataFrame({"t_s": gn["t_s"].to_numpy(float), "lat_deg": gn["gnss_lat_deg"],
                             "lon_deg": gn["gnss_lon_deg"], "h_m": alt})
        if {"gnss_vn_mps", "gnss_ve_mps"} <= set(gn.columns):
            gnss["vn_mps"] = gn["gnss_vn_mps"].to_numpy(float)
            gnss["ve_mps"] = gn["gnss_ve_mps"].to_numpy(float)
        # the receiver's per-fix accuracy (docs/ingest.md, "GNSS as receivers write it")
        for src, dst in (("gnss_h_sd_m", "h_sd_m"), ("gnss_v_sd_m", "v_sd_m"),
                         ("gnss_vel_sd_mps", "vel_sd_mps")):
            if src in gn.columns:
                gnss[dst] = gn[src].to_numpy(float)
    return gnss


def _radar_table(rd: pd.DataFrame) -> pd.DataFrame:
    """The radar plots as the smoother reads them: ``t_s``, ``range_m``, ``azimuth_rad``
    (``elevation_rad`` where recorded); empty without range and azimuth."""
    radar = pd.DataFrame()
    if len(rd) and {"arms_range_m", "arms_azimuth_deg"} <= set(rd.columns):
        radar = pd.DataFrame({"t_s": rd["t_s"].to_numpy(float),
                              "range_m": rd["arms_range_m"].to_numpy(float),
                              "azimuth_rad": np.radians(rd["arms_azimuth_deg"].to_numpy(float))})
        if "arms_elevation_deg" in rd.columns:
            radar["elevation_rad"] = np.radians(rd["arms_elevation_deg"].to_numpy(float))
    return radar


def baro_field_reference_m(meta: FlightMeta) -> float:
    """What ``baro_alt_m`` reads on the ground at the departure field, by its datum
    (``meta.baro_datum``, docs/ingest.md): the reference of the smoother's ``baro_rel_m``.

    * ``"pressure"`` (1013.25 hPa): the field's pressure altitude under the departure QNH,
      :func:`flightrecon.geo.atmosphere.field_pressure_altitude_m` (its elevation where the
      QNH is not known, the offset state taking the difference, 8.3 m per hPa);
    * ``"qnh"``: an altimeter set to the field's QNH reads its elevation (MSL) on the ground,
      whatever the QNH: the elevation itself (converting it as if it were a pressure altitude
      would put the offset 8.3 m per hPa of QNH - 1013.25 off);
    * ``"qfe"``: an altimeter set to the field's pressure reads 0 on the ground.

    Above the field all three differ from the height above it by the same temperature scale
    (the hypsometric equation; to 0.3 % for a QNH 10 hPa from standard), the smoother's
    ``baro_scale`` state.  ``meta.departure`` must be set.
    """
    dep = meta.departure
    if dep is None:
        raise MetadataError("the baro channel's field reference needs the departure airfield")
    if meta.baro_datum == "qnh":
        return float(dep.elev_m)
    if meta.baro_datum == "qfe":
        return 0.0
    return float(field_pressure_altitude_m(dep.elev_m, meta.qnh_departure_hpa))


def joint_inputs(clean: CleanFlight) -> JointInputs:
    """Assemble the smoother's inputs from a cleaned flight (SI, recorder time base)."""
    g = clean.grid
    meta = clean.meta
    N_und = meta.geoid_undulation_m

    def col(name):
        return g[name].to_numpy(dtype=float) if name in g.columns else np.full(len(g), np.nan)

    # the departure, or without one the frame origin from the first fix (cleaning/origin.py)
    p0 = meta.departure if meta.departure is not None else getattr(meta, "origin", None)
    if p0 is None:
        raise MetadataError("the joint smoother needs the departure position (--departure) or a "
                            "GNSS / radar fix: it anchors the output plane and the latitude of "
                            "normal gravity")
    t_in = g["t_s"].to_numpy(float)
    att, acc, notes = _loads_in_ned(g, t_in, p0.lat_deg)
    dep = meta.departure
    if dep is not None:
        h_pf = baro_field_reference_m(meta)
        field_h = float(msl_to_ellipsoid(dep.elev_m, N_und))
    else:
        h_pf = 0.0
        field_h = 0.0
    wind = None
    if "wind_speed_mps" in g.columns and "wind_from_deg" in g.columns:
        wind = wind_toward_ne(col("wind_speed_mps"), col("wind_from_deg"))
    gnss = _gnss_table(clean.gnss, meta)
    radar = _radar_table(clean.radar)

    def pos(p):
        if p is None:
            return None
        return (p.lat_deg, p.lon_deg, float(msl_to_ellipsoid(p.elev_m, N_und)))

    ph = clean.phases
    fixes = None
    if meta.fixes:
        fixes = np.array([[f.t_s, f.lat_deg, f.lon_deg,
                           np.nan if f.alt_msl_m is None else f.alt_msl_m + N_und, f.sd_m]
                          for f in meta.fixes], dtype=float)
    wa = wind_aloft_on_grid(g, meta)
    inp = JointInputs(
        t_in=t_in, acc_ned=acc, attitude_deg=att, tas=col("tas_mps"),
        heading_rad=np.radians(col("heading_deg")), baro_rel_m=col("baro_alt_m") - h_pf,
        gnss=gnss, radar=radar, station=pos(meta.station), departure=pos(meta.departure),
        arrival=pos(meta.arrival),
        liftoff_t=float(ph.liftoff_t_s) if ph is not None else np.nan,
        touchdown_t=float(ph.touchdown_t_s) if ph is not None else np.nan,
        field_h=field_h, lever_arm=tuple(meta.gnss_lever_arm_m), wind_ne=wind,
        doppler_gs=col("doppler_gs_mps") if "doppler_gs_mps" in g.columns else None,
        drift_rad=np.radians(col("drift_deg")) if "drift_deg" in g.columns else None,
        f_body_g=np.c_[col("n_long_g"), col("n_lat_g"), -col("n_norm_g")],
        runway_rad=tuple(None if p is None or p.runway_true_deg is None
                         else float(np.radians(p.runway_true_deg))
                         for p in (meta.departure, meta.arrival)),
        thresholds=tuple(None if p is None or p.threshold is None
                         else (*p.threshold, float(msl_to_ellipsoid(p.elev_m, N_und)))
                         for p in (meta.departure, meta.arrival)),
        lineup_t=float(getattr(ph, "lineup_t_s", np.nan)) if ph is not None else np.nan,
        notes=tuple(notes), ends_airborne=bool(ph is not None and ph.ends_airborne),
        fixes=fixes, wind_aloft=None if wa is None else np.c_[wa[0], wa[1]])
    if "n_long_g" in (meta.extra.get("derived_channels") or {}):
        dead = airspeed_floor_windows(inp.t_in, inp.tas)
        if dead.any():
            # before the take-off roll's search: its rest is found by integrating the
            # acceleration back from lift-off, which through these samples is not known
            acc = inp.acc_ned.copy()
            acc[dead] = np.nan
            inp = replace(inp, acc_ned=acc, missing_psd=airspeed_floor_psd(inp.t_in,
                                                                           inp.tas, dead),
                          notes=(*inp.notes, (
                f"joint: n_long_g derived from an airspeed that reads 0 below its floor: the "
                f"loads of {int(dead.sum())} sample(s) where it comes alive or dies "
                "(the derivative's window holds both) are taken as missing, the velocity "
                "change across each such window unknown by the airspeed there")))
    if not (ph is not None and ph.starts_airborne):
        roll = takeoff_roll(inp.t_in, inp.acc_ned, inp.heading_rad, inp.tas, inp.liftoff_t,
                            inp.wind_ne, not_before_t=inp.lineup_t)
        if not np.isfinite(roll.start_t) and ph is not None:
            roll = phases_roll(ph)
        inp = replace(inp, roll=roll)
    return inp


def phases_roll(ph: Any, settle_s: float = 10.0) -> TakeoffRoll:
    """The take-off roll of the cleaning's phases (``roll_start_t_s`` after ``lineup_t_s``:
    the ground speed integrated back from the fast run on the cleaning's grid), where the
    joint's own search finds none: it integrates the acceleration back from lift-off, which a
    1 Hz record whose ``n_long_g`` is derived from an airspeed that reads 0 below its floor
    does not have through the roll's first seconds (:func:`airspeed_floor_windows`).  The rest
    is the line-up to ``settle_s`` before the roll start, as in
    :func:`flightrecon.cleaning.phases.takeoff_roll`; none where the phases found a rolling
    take-off (the roll starting at the line-up)."""
    start = float(getattr(ph, "roll_start_t_s", np.nan))
    lineup = float(getattr(ph, "lineup_t_s", np.nan))
    if not (np.isfinite(start) and np.isfinite(lineup) and start > lineup):
        return TakeoffRoll()
    end = start - settle_s
    return TakeoffRoll(start, (lineup, end) if end > lineup else (np.nan, np.nan))


#: a recorded airspeed at most this is "below the air-data computer's floor" [m/s] (1 kt: the
#: rounding of an airspeed recorded in whole knots that reads 0)
AIRSPEED_DEAD_MPS = 0.52


def airspeed_floor_windows(t: np.ndarray, tas: np.ndarray,
                           half_window_s: float = N_LONG_HALF_WINDOW_S) -> np.ndarray:
    """Samples whose derived ``n_long_g`` spans an airspeed coming alive or dying.

    An air-data computer reads 0 below its floor (about 30 kt on the Garmin export) and jumps
    to the floor one sample into the take-off roll (0 to 14.9 m/s in 1 s there).  The derived
    channel, ``(dV/dt)/g0 + sin(pitch)`` with ``dV/dt`` the centred difference over
    ``+-half_window_s`` (flightrecon/ingest/derive.py), turns the jump into an acceleration
    (0.25-0.38 g for 6 s where the GPS ground speed shows 0.15 g): the integrated roll then
    has the lift-off ground speed wrong by the airspeed at the floor less the ground speed
    there (the headwind, about 5 m/s), which the smoother takes out of the airspeed scale and
    the wind.  True where the window ``[t - h, t + h]`` holds both an airspeed at most
    :data:`AIRSPEED_DEAD_MPS` and one above it: there the acceleration is not known, and
    the smoother's missing-loads process noise applies.
    """
    ok = np.isfinite(tas)
    out = np.zeros(len(t), bool)
    if ok.sum() < 2:
        return out
    tv, dead = t[ok], (tas[ok] <= AIRSPEED_DEAD_MPS).astype(float)
    # fraction of dead samples within the window (cumulative counts)
    cum = np.r_[0.0, np.cumsum(dead)]
    lo = np.searchsorted(tv, t - half_window_s - 1e-9, side="left")
    hi = np.searchsorted(tv, t + half_window_s + 1e-9, side="right")
    n_dead = cum[hi] - cum[lo]
    return (n_dead > 0) & (n_dead < hi - lo)


def airspeed_floor_psd(t: np.ndarray, tas: np.ndarray, dead: np.ndarray) -> np.ndarray:
    """The missing accelerations' PSD [(m/s^2)^2/Hz] per input sample (``JointInputs.
    missing_psd``): 1 outside the windows of :func:`airspeed_floor_windows`; in each of
    them (a contiguous run of ``dead`` samples, ``W`` seconds) ``V^2 / W``, ``V`` the largest
    airspeed there, so that the velocity change across the window is unknown by about the
    airspeed the indicator comes alive at.  Through such a window the aircraft accelerates
    (a take-off roll: 0.1-0.3 g for the 6 s the derivative's window spans, 6-18 m/s) where the
    default's zero-mean 1 m/s^2/sqrt(Hz) allowed 2.4 m/s: the ground speed after it was held
    short of the truth by most of that, and the smoother took the shortfall as a headwind it
    then kept (the G1000 export with its departure alone: 5.4 m/s of east wind, 3 sd, a track
    15.7 km off at the end, docs/ingest.md)."""
    psd = np.ones(len(t))
    idx = np.flatnonzero(dead)
    if idx.size == 0:
        return psd
    runs = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)
    for r in runs:
        w = float(t[r[-1]] - t[r[0]]) + (float(np.median(np.diff(t))) if len(t) > 1 else 1.0)
        v = float(np.nanmax(tas[r])) if np.isfinite(tas[r]).any() else 0.0
        psd[r] = max(v * v / max(w, 1e-6), 1.0)
    return psd


@nb.njit(cache=True, nogil=True)
def _near_any(t_out, tm, window):
    """For sorted ``t_out`` and sorted ``tm``: is some tm within +-window of each t_out?
    One merge-like pass, O(len(t_out) + len(tm))."""
    out = np.zeros(t_out.shape[0], dtype=np.bool_)
    j = 0
    m = tm.shape[0]
    for i in range(t_out.shape[0]):
        t = t_out[i]
        while j < m and tm[j] < t - window:
            j += 1
        out[i] = j < m and tm[j] <= t + window
    return out


def _provenance(run: JointRun, t_out: np.ndarray, window_s: float = 5.0) -> np.ndarray:
    """Per output sample, the sources with a measurement within +-window_s ('+'-joined)."""
    code = np.zeros(len(t_out), dtype=np.int64)
    for s_i, name in enumerate(SOURCES):
        tm = np.sort(run.meas.t[run.meas.source == s_i])
        if len(tm) == 0:
            continue
        near = _near_any(t_out, tm, window_s if name != "endpoint" else 60.0)
        code |= near.astype(np.int64) << s_i
    present = np.flatnonzero(np.bincount(code, minlength=1 << len(SOURCES)))
    lookup = np.zeros(1 << len(SOURCES), dtype=np.int64)
    lookup[present] = np.arange(len(present))
    names = np.array(["+".join(n for i, n in enumerate(SOURCES) if c >> i & 1) for c in present],
                     dtype=object)
    return names[lookup[code]]


def _hermite_positions(t_out: np.ndarray, T: np.ndarray, p: np.ndarray, v: np.ndarray
                       ) -> np.ndarray:
    """Cubic Hermite interpolation of positions ``p`` (N, 3) with their velocities ``v`` (N, 3)
    from the state times ``T`` to ``t_out`` (error O(dt^4) instead of the a dt^2 / 8 of linear
    interpolation: 0.6 m in a 25-degree turn at a 1 s state step)."""
    if len(T) < 2:
        return np.repeat(p[:1], len(t_out), axis=0)
    return _hermite_kernel(np.asarray(t_out, float), np.asarray(T, float),
                           np.ascontiguousarray(p, dtype=float),
                           np.ascontiguousarray(v, dtype=float))


@nb.njit(cache=True, nogil=True)
def _hermite_kernel(t_out, T, p, v):
    n = t_out.shape[0]
    out = np.empty((n, 3))
    N = T.shape[0]
    k = 0
    for i in range(n):
        t = t_out[i]
        if k > 0 and t < T[k]:      # t_out not sorted: search again from the start
            k = 0
        while k < N - 2 and T[k + 1] <= t:
            k += 1
        h = T[k + 1] - T[k]
        s = (t - T[k]) / h if h > 0 else 0.0
        s = min(max(s, 0.0), 1.0)
        s2 = s * s
        s3 = s2 * s
        h00 = 2 * s3 - 3 * s2 + 1
        h10 = (s3 - 2 * s2 + s) * h
        h01 = -2 * s3 + 3 * s2
        h11 = (s3 - s2) * h
        for j in range(3):
            out[i, j] = h00 * p[k, j] + h10 * v[k, j] + h01 * p[k + 1, j] + h11 * v[k + 1, j]
    return out


def joint_track(clean: CleanFlight, run: JointRun) -> pd.DataFrame:
    """The smoothed trajectory on the input grid, in the output conventions (prefix joint_)."""
    t_out = clean.grid["t_s"].to_numpy(float)
    T = run.t
    x = run.x

    def interp(v):
        return np.interp(t_out, T, v)

    ecef = _hermite_positions(t_out, T, x[:, jl.S_POS],
                              np.einsum("kij,kj->ki", run.Cen, x[:, jl.S_VEL]))
    lat, lon, h = ecef_to_geodetic(ecef[:, 0], ecef[:, 1], ecef[:, 2])
    plane = output_plane(clean.meta)
    e, n, u = plane.forward(lat, lon, h)
    C = run.Cen
    # ECEF -> local NED (P_pv holds the position and velocity blocks, in that order)
    Pp = np.einsum("kji,kjl,klm->kim", C, run.P_pv[:, 0:3, 0:3], C)
    sd_pos = np.sqrt(np.maximum(np.einsum("kii->ki", Pp), 0.0))
    sd_vel = np.sqrt(np.maximum(run.var[:, jl.S_VEL], 0.0))
    sd_w = np.sqrt(np.maximum(run.var[:, jl.S_WIND], 0.0))
    p = PREFIX
    cols = {"t_s": t_out,
            p + "north_m": n, p + "east_m": e, p + "up_m": u,
            p + "north_sd_m": interp(sd_pos[:, 0]), p + "east_sd_m": interp(sd_pos[:, 1]),
            p + "up_sd_m": interp(sd_pos[:, 2]),
            p + "vn_mps": interp(x[:, jl.IV]), p + "ve_mps": interp(x[:, jl.IV + 1]),
            p + "vu_mps": -interp(x[:, jl.IV + 2]),
            p + "vn_sd_mps": interp(sd_vel[:, 0]), p + "ve_sd_mps": interp(sd_vel[:, 1]),
            p + "vu_sd_mps": interp(sd_vel[:, 2]),
            p + "lat_deg": lat, p + "lon_deg": lon, p + "alt_m": h,
            p + "wind_n_mps": interp(x[:, jl.IW]), p + "wind_e_mps": interp(x[:, jl.IW + 1]),
            p + "wind_n_sd_mps": interp(sd_w[:, 0]), p + "wind_e_sd_mps": interp(sd_w[:, 1])}
    out = pd.DataFrame(cols, copy=False)
    out[p + "sources"] = pd.array(_provenance(run, t_out), dtype="string")
    return out


def _corrections(run: JointRun, settings: JointSettings | None = None) -> dict[str, Any]:
    """Estimated sensor errors (value and sd at the middle of the record) with the prior each
    was given (``prior_mean``, ``prior_sd``, same unit)."""
    k = len(run.t) // 2
    x, v = run.x[k], run.var[k]

    def item(i, scale=1.0, unit=""):
        return {"value": float(x[i] * scale), "sd": float(np.sqrt(max(v[i], 0.0)) * scale),
                "unit": unit}

    out = _correction_items(item)
    for name, it in out.items():
        it["prior_mean"], it["prior_sd"] = prior_of(name, settings or JointSettings())
    return out


def _correction_items(item) -> dict[str, Any]:
    return {
        "heading_bias_deg": item(jl.IPSI, np.degrees(1.0), "deg (measured - true)"),
        "tas_scale": item(jl.IS, 1.0, "TAS_measured = (1 + s) TAS_true"),
        "baro_offset_m": item(jl.IBH, 1.0, "m"),
        "baro_scale": item(jl.IC, 1.0, "h_p - h_p,field = (1 + c)(h - h_field) + b_h"),
        "accel_bias_x_g": item(jl.IBA, 1.0, "g (body forward, measured - true)"),
        "accel_bias_y_g": item(jl.IBA + 1, 1.0, "g (body right)"),
        "accel_bias_z_g": item(jl.IBA + 2, 1.0, "g (body down, of -n_norm)"),
        "doppler_scale": item(jl.IDW, 1.0, "W_measured = (1 + k) W_true"),
        "accel_scale_x": item(jl.IKS, 1.0, "f_measured = (1 + s) f_true + b, body forward"),
        "accel_scale_y": item(jl.IKS + 1, 1.0, "body right"),
        "accel_scale_z": item(jl.IKS + 2, 1.0, "body down"),
        "drift_bias_deg": item(jl.IDC, np.degrees(1.0), "deg (measured - true)"),
        "roll_bias_deg": item(jl.IATT, np.degrees(1.0), "deg (measured - true)"),
        "pitch_bias_deg": item(jl.IATT + 1, np.degrees(1.0), "deg (measured - true)"),
        "wind_gradient_n_per_km": item(jl.IG, 1000.0, "(m/s)/km: change of the north wind "
                                       "with height (at the middle of the record)"),
        "wind_gradient_e_per_km": item(jl.IG + 1, 1000.0, "(m/s)/km, east"),
    }


def _fix_report(clean: CleanFlight, track: pd.DataFrame) -> list[dict[str, Any]]:
    """Per known position (``--fix``): the smoothed track's offset from it at its time, north
    and east [m], with the fix's sd and the track's sd there; ``used`` False (and no offsets)
    for a fix outside the reconstructed span (a record trimmed with ``--start`` / ``--end``)."""
    if not clean.meta.fixes:
        return []
    plane = output_plane(clean.meta)
    t = track["t_s"].to_numpy(float)
    p = PREFIX
    out: list[dict[str, Any]] = []
    h_tr = track[p + "alt_m"].to_numpy(float)
    for f in clean.meta.fixes:
        if not t[0] <= f.t_s <= t[-1]:
            out.append({"t_s": f.t_s, "lat_deg": f.lat_deg, "lon_deg": f.lon_deg,
                        "alt_msl_m": f.alt_msl_m, "sd_m": f.sd_m, "used": False})
            continue
        # the fix at the track's height where it has none (the tangent plane's north and east
        # of a point move with its height: 1.6 m per km of height at 10 km from the origin)
        h = (float(np.interp(f.t_s, t, h_tr)) if f.alt_msl_m is None
             else f.alt_msl_m + clean.meta.geoid_undulation_m)
        e, n, _u = plane.forward(f.lat_deg, f.lon_deg, h)
        dn = float(np.interp(f.t_s, t, track[p + "north_m"].to_numpy(float)) - float(n))
        de = float(np.interp(f.t_s, t, track[p + "east_m"].to_numpy(float)) - float(e))
        item = {"t_s": f.t_s, "lat_deg": f.lat_deg, "lon_deg": f.lon_deg,
                "alt_msl_m": f.alt_msl_m, "sd_m": f.sd_m, "used": True,
                "track_minus_fix_north_m": dn, "track_minus_fix_east_m": de,
                "track_north_sd_m": float(np.interp(f.t_s, t,
                                                    track[p + "north_sd_m"].to_numpy(float))),
                "track_east_sd_m": float(np.interp(f.t_s, t,
                                                   track[p + "east_sd_m"].to_numpy(float)))}
        out.append(item)
    return out


def _wind_prior_report(inp: JointInputs, settings: JointSettings,
                       clean: CleanFlight) -> dict[str, Any] | None:
    """Which winds-aloft prior the smoother used (docs/wind.md): its levels, the
    pseudo-measurements and their sd."""
    if inp.wind_aloft is None:
        return None
    tw, _w, sd, rho = wind_prior_measurements(inp, settings)
    lv = clean.meta.wind_aloft
    return {"levels": len(lv), "alt_msl_m": [lv[0].alt_msl_m, lv[-1].alt_msl_m],
            "correlation_s_m_spacing": list(settings.wind_prior),
            "pseudo_measurements": len(tw), "t_s": [float(x) for x in tw],
            "sd_mps": [float(x) for x in sd], "rho": [float(x) for x in rho]}


def _derived_heading_noise(clean: CleanFlight, settings: JointSettings) -> JointSettings:
    """A heading propagated from the body rates (``heading_sd_deg`` on the grid, cleaning's
    ``heading_from_rates``) has a slowly varying error (anchor offset, gyro-bias drift): the
    heading-bias state's prior is widened to its largest sd and its random walk to what lets
    the bias follow that sd's growth over the record (both never below the settings)."""
    g = clean.grid
    if "heading_sd_deg" not in g.columns:
        return settings
    sd = g["heading_sd_deg"].to_numpy(float)
    if not np.isfinite(sd).any():
        return settings
    nz = settings.noise
    span = max(float(g["t_s"].iloc[-1] - g["t_s"].iloc[0]), 1.0)
    prior = max(nz.heading_bias_deg, float(np.nanmax(sd)))
    rw = max(nz.heading_bias_rw_deg_sqrt_s, float(np.nanmax(sd)) / np.sqrt(span))
    return replace(settings, noise=replace(nz, heading_bias_deg=prior,
                                           heading_bias_rw_deg_sqrt_s=rw))


#: prior sd of the forward accelerometer's scale error and bias when ``n_long_g`` was not
#: recorded but derived from airspeed and pitch at ingest (flightrecon/ingest/derive.py): its
#: error is no sensor's, but the missed angle-of-attack and along-track wind terms (order
#: 0.01 g, a few per cent of the channel); the sensor budget (0.5 %, 0.003 g) is too tight
DERIVED_LONG_SCALE_SD = 0.1
DERIVED_LONG_BIAS_G = 0.01


def _derived_long_priors(clean: CleanFlight, settings: JointSettings) -> JointSettings:
    """Wider priors of the forward accelerometer's scale and bias for a derived ``n_long_g``
    (ingest's ``derived_channels``); a prior the user gave for them is kept."""
    if "n_long_g" not in (clean.meta.extra.get("derived_channels") or {}):
        return settings
    given = {p[0] for p in settings.priors}
    extra = tuple(p for p in (("accel_scale_x", 0.0, DERIVED_LONG_SCALE_SD),
                              ("accel_bias_x_g", 0.0, DERIVED_LONG_BIAS_G)) if p[0] not in given)
    return replace(settings, priors=(*settings.priors, *extra))


def _airborne(inp: JointInputs) -> np.ndarray:
    """Input samples from lift-off to touchdown (the whole record where either is unknown)."""
    t = inp.t_in
    air = np.ones(len(t), bool)
    if np.isfinite(inp.liftoff_t):
        air &= t >= inp.liftoff_t
    if np.isfinite(inp.touchdown_t):
        air &= t <= inp.touchdown_t
    return air


def temperature_baro_prior(inp: JointInputs, sat_degc: np.ndarray, h_p_field_m: float,
                           settings: JointSettings) -> JointSettings:
    """The prior of the pressure-altitude scale ``c`` from the recorded static air temperature.

    The smoother's baro row is ``h_p - h_p,f = (1 + c)(h - h_field) + b_h``.  In air warmer
    than the ISA by ``dT`` the height above the field exceeds the pressure-altitude difference
    by ``dT / T`` (:func:`flightrecon.geo.atmosphere.height_above_field_m`, eq. 1-2): ``c``
    is the temperature's, not an unknown of 5 % (a 15 K deviation) to be found from the
    accelerations.  With the deviation ``dT_k = SAT_k - T_ISA(h_p,k)`` of the airborne samples
    (lift-off to touchdown; ``h_p,k = baro_rel_k + h_p,f``), their mean ``dT`` gives each
    sample's height above the field ``H_k`` (eq. 2) and ``c`` is the least-squares fit of
    ``h_p,k - h_p,f = (1 + c) H_k``::

        1 + c = sum(dh_p,k H_k) / sum(H_k^2)

    Its sd is that fit's change per kelvin times ``sqrt(s^2 + sat_column_k^2)``: ``s`` the
    spread of the samples' ``dT`` (the column is not one deviation everywhere),
    ``JointNoise.sat_column_k`` what the recorded SAT does not tell of the column (probe,
    humidity).  Fewer than :data:`flightrecon.geo.pressure_height.MIN_SAT_SAMPLES` samples
    (:func:`~flightrecon.geo.pressure_height.isa_deviation_k`), or a ``baro_scale`` prior given in
    ``settings.priors`` (the user's, a fleet's): unchanged.
    """
    if any(p[0] == "baro_scale" for p in settings.priors):
        return settings
    h_p_all = inp.baro_rel_m + h_p_field_m
    deviation = isa_deviation_k(h_p_all, sat_degc, _airborne(inp))
    if deviation is None:
        return settings
    ok = _airborne(inp) & np.isfinite(np.asarray(sat_degc, dtype=float)) & np.isfinite(h_p_all)
    dh_p = inp.baro_rel_m[ok]
    h_p = h_p_all[ok]
    if not np.any(np.abs(dh_p) > 0):
        return settings

    def scale(dt_k: float) -> float:
        H = height_above_field_m(h_p, h_p_field_m, dt_k)
        return float(np.sum(dh_p * H) / np.sum(H * H)) - 1.0

    d_mean, spread = deviation
    sd_t = float(np.hypot(spread, settings.noise.sat_column_k))
    c0 = scale(d_mean)
    sd_c = 0.5 * abs(scale(d_mean + sd_t) - scale(d_mean - sd_t))
    if not (np.isfinite(c0) and np.isfinite(sd_c) and sd_c > 0):
        return settings
    return replace(settings, priors=(*settings.priors, ("baro_scale", c0, sd_c)))


#: fewest airborne sample-to-sample differences of the loads for :func:`sampled_loads_noise`
MIN_LOAD_DIFFERENCES = 60


def sampled_loads_noise(inp: JointInputs, settings: JointSettings) -> JointSettings:
    """The white-acceleration PSD per NED axis that the loads' own sampling implies.

    The smoother integrates the recorded acceleration a_k over each input interval dt as
    a_k dt.  Of a record sampled slower than the aircraft's accelerations vary (a 1 Hz
    glass-cockpit export: turbulence, control inputs, an attitude and a load factor not taken
    at the same instant) the part that changes from one sample to the next is not resolved:
    if it is w_k, uncorrelated from sample to sample with variance s^2, the velocity
    increment over each interval is wrong by w_k dt, a velocity random walk of PSD

        q_s = s^2 dt,    s^2 = E[(a_{k+1} - a_k)^2] / 2

    (the difference of two independent samples has twice their variance; the slow part of the
    acceleration adds little to it at the record's rate and makes q_s an upper bound).  It
    also holds the sensor's own white noise, so q_s replaces the budget
    ``accel_noise_mps2_sqrt_hz`` where it is larger: the extra PSD per axis is
    max(0, q_s - q_acc) (``JointNoise.accel_sampling_mps2_sqrt_hz``, its square root).
    Measured over the airborne steps (lift-off to touchdown, or the whole record), on the
    NED acceleration the smoother is given; a record of recorder rate (8 Hz and more) gives
    q_s below the budget and is left as it is.  Fewer than ``MIN_LOAD_DIFFERENCES``
    differences, or an extra set by the user: unchanged.
    """
    nz = settings.noise
    if any(v > 0 for v in nz.accel_sampling_mps2_sqrt_hz):
        return settings
    t = inp.t_in
    air = _airborne(inp)
    a = inp.acc_ned
    ok = air[1:] & air[:-1] & np.isfinite(a[1:]).all(axis=1) & np.isfinite(a[:-1]).all(axis=1)
    if ok.sum() < MIN_LOAD_DIFFERENCES:
        return settings
    dt = np.diff(t)[ok]
    d = np.diff(a, axis=0)[ok]
    q_s = np.mean(d ** 2 * dt[:, None], axis=0) / 2.0   # s^2 dt per axis, dt-weighted
    extra = np.sqrt(np.maximum(q_s - nz.accel_noise_mps2_sqrt_hz ** 2, 0.0))
    if not np.all(np.isfinite(extra)) or not np.any(extra > 0):
        return settings
    return replace(settings, noise=replace(
        nz, accel_sampling_mps2_sqrt_hz=(float(extra[0]), float(extra[1]), float(extra[2]))))


def inertial_wind_share(inp: JointInputs, settings: JointSettings) -> float:
    """The PSD ``r`` of the loads' velocity random walk where a record sampled slower than
    its accelerations (:func:`sampled_loads_noise` set) has the loads as the wind's only
    witness, else 0 [m^2/s^3].

    Without GNSS, radar, known fixes, a recorded wind, Doppler or a winds-aloft prior, the
    smoother learns the wind's change only as the ground velocity's change from the loads
    less the air velocity's; the loads' error integrates to a velocity random walk of PSD
    ``r = accel_noise_mps2_sqrt_hz^2 + (s_n^2 + s_e^2) / 2`` with ``s`` the horizontal
    ``accel_sampling_mps2_sqrt_hz``.  The smoothed wind change is then the share
    ``kappa = Q / (Q + r L)`` of the observed one (``Q`` the wind model's variance over L;
    :func:`~flightrecon.methods.joint.diagnostics.wind_walk_check`): of a 1 Hz export
    ``r`` is about 0.08 m^2/s^3 (JSBSim's fleet; 0.011 the shipped G1000 export) and over
    ten minutes of the default walk (``Q`` = 1.5 m^2/s^2) ``kappa`` is 0.03 (0.19), where a
    wind that turns moves the smoothed wind by little.  A recorder-rate log (no sampling
    term; ``r`` the budget 0.0025, ``kappa`` 1/2) or any other source of the wind: 0 (the
    check's bound, ``kappa = 1``, within a factor 2 there)."""
    nz = settings.noise
    s = nz.accel_sampling_mps2_sqrt_hz
    if (not (s[0] > 0 or s[1] > 0) or len(inp.gnss) or len(inp.radar)
            or (inp.fixes is not None and len(inp.fixes)) or inp.wind_ne is not None
            or inp.doppler_gs is not None or inp.wind_aloft is not None):
        return 0.0
    return float(nz.accel_noise_mps2_sqrt_hz ** 2 + 0.5 * (s[0] ** 2 + s[1] ** 2))


#: how long after lift-off and before touchdown the rolls still witness the wind where the
#: loads are its only other witness: a derived ``n_long_g``'s bias prior (0.01 g) alone
#: integrates to 6 m/s in a minute, beyond the wind walk's 0.4 m/s (0.05 m/s/sqrt(s))
ROLL_WITNESS_S = 60.0
#: false-alarm probability of the wind-walk check where the loads are the wind's only
#: witness: the share kappa leaves out the other witnesses (the end points, the estimated
#: load biases), so its chi-square overstates a change and the check asks for stronger
#: evidence than the bound's 1 %
LOADS_WITNESS_P_FALSE = 1e-4


def _wind_walk_rounds(inp: JointInputs, settings: JointSettings, run: JointRun
                      ) -> tuple[JointRun, JointSettings, list[dict[str, Any]]]:
    """Where the smoothed wind moved faster than its random walk allows
    (:func:`~flightrecon.methods.joint.diagnostics.wind_walk_check`, with the loads' PSD
    ``r`` of :func:`inertial_wind_share`), the walk re-estimated from the flight and the
    smoother run again, at most ``settings.wind_rounds`` times.

    The check's worst window (length L, the model's variance ``Q`` of which ``Q_h`` from
    the height flown through, the loads' ``r L``) has ``z^2 = |dw|^2 / (kappa Q)`` with
    ``kappa = Q / (Q + r L)``: the observed change ``|do|^2 = |dw|^2 / kappa^2`` is
    ``z^2 (Q + r L)``.  With ``r = 0`` (another witness of the wind) the walk is scaled so
    that this window would be a typical one, its chi-square at the mean 2 of chi-square(2):
    ``q' = q z^2 / 2`` (the smoothed change of a walk shrinks towards zero by the data's
    weight, so an estimate can be low and the rounds climb).  Where the loads are the only
    witness (``r > 0``) the worst window's change is mostly the loads' error, and the walk is
    the smallest that the check accepts, ``|do|^2 = limit (Q' + r L)``:

        q' L = z^2 (Q + r L) / limit - r L - Q_h

    Never below ``q``, kept below ``wind_rw_max_mps_sqrt_s``, until the smoothed wind is
    within the walk (docs/joint.md, "Wind and turbulence": JSBSim's holding, 22 m/s turning
    100 deg in 30 minutes).  Returns the last run, its settings and the rounds (the walk each
    started from, the check's chi-square and limit, the loads' PSD)."""
    rounds: list[dict[str, Any]] = []
    r = inertial_wind_share(inp, settings)
    within = None
    if r > 0:   # windows clear of the rolls (a record without both: the check as it is)
        if not (np.isfinite(inp.liftoff_t) and np.isfinite(inp.touchdown_t)):
            r = 0.0
        else:
            within = (inp.liftoff_t + ROLL_WITNESS_S, inp.touchdown_t - ROLL_WITNESS_S)
    for _ in range(max(0, settings.wind_rounds)):
        nz = settings.noise
        c = wind_walk_check(run, nz.wind_rw_mps_sqrt_s, nz.wind_shear_mps_per_sqrt_m,
                            loads_psd_m2ps3=r, within_s=within,
                            p_false=LOADS_WITNESS_P_FALSE if r > 0 else 0.01)
        if c is None or nz.wind_rw_mps_sqrt_s >= settings.wind_rw_max_mps_sqrt_s:
            break
        rounds.append({"wind_rw_mps_sqrt_s": nz.wind_rw_mps_sqrt_s, "z2": c["z2"],
                       "limit": c["limit"], "loads_psd_m2ps3": r})
        L = c["t1_s"] - c["t0_s"]
        q = nz.wind_rw_mps_sqrt_s ** 2
        q_h = c["walk_var_m2ps2"] - q * L
        if r > 0:
            q_new = (c["z2"] * (c["walk_var_m2ps2"] + c["loads_var_m2ps2"]) / c["limit"]
                     - c["loads_var_m2ps2"] - q_h) / L
        else:
            q_new = q * 0.5 * c["z2"]
        q_new = max(q_new, q)
        settings = replace(settings, noise=replace(nz, wind_rw_mps_sqrt_s=min(
            float(np.sqrt(q_new)), settings.wind_rw_max_mps_sqrt_s)))
        run = smooth_joint(inp, settings)
    return run, settings, rounds


def run_joint(clean: CleanFlight, *, settings: JointSettings | None = None) -> MethodResult:
    """Joint smoother of every source on ``clean`` (see :mod:`flightrecon.methods.joint`)."""
    settings = settings or JointSettings()
    settings = _derived_heading_noise(clean, settings)
    settings = _derived_long_priors(clean, settings)
    inp = joint_inputs(clean)
    settings = sampled_loads_noise(inp, settings)
    if clean.meta.departure is not None and "sat_degc" in clean.grid.columns:
        settings = temperature_baro_prior(
            inp, clean.grid["sat_degc"].to_numpy(float),
            field_pressure_altitude_m(clean.meta.departure.elev_m,
                                      clean.meta.qnh_departure_hpa), settings)
    tilt_ev = (gnss_tilt_evidence(clean, inp, settings)
               if tilt_noise_open(clean, inp, settings) else None)
    settings, attitude_note = attitude_source_noise(clean, inp, settings, tilt_ev)
    run = smooth_joint(inp, settings)
    if attitude_note:
        _warnings.warn(attitude_note, FlightReconWarning, stacklevel=2)
    run, settings, wind_rounds = _wind_walk_rounds(inp, settings, run)
    track = joint_track(clean, run)
    finite = np.isfinite(run.x).all() and np.all(run.var[:, jl.IP:jl.IV + 3] > 0)
    sources = source_report(run)
    warnings = list(inp.notes) + ([attitude_note] if attitude_note else [])
    for name, st in sources.items():
        if st["flagged_inconsistent"]:
            warnings.append(f"joint: source '{name}' inconsistent with the others in "
                            f"{st['beyond_5_sigma']} measurements "
                            f"(spans {st['flagged_spans_s'][:5]}"
                            " s); down-weighted")
    nc = run.noise_check
    if nc is not None and not nc["accepted"]:
        warnings.append("joint: the estimated noise did not raise the likelihood of the data "
                        f"(log-likelihood {nc['loglik_estimated']:.1f} vs "
                        f"{nc['loglik_default']:.1f} with the defaults): the default noise is "
                        "kept")
    elif nc is not None and nc["factors_at_bound"]:
        warnings.append(f"joint: noise factors at their bound {nc['bounds']}: "
                        f"{', '.join(nc['factors_at_bound'])} (the noise settings or the data "
                        "of these sources are far off)")
    if settings.estimate_noise and not run.iterations[-1].get("converged"):
        warnings.append(f"joint: noise estimation did not converge in {len(run.iterations)} "
                        "iterations; the last factors are used")
    # converged: the test of smooth_joint (the MAP cost and the track settled; docs/joint.md,
    # "Filter, smoother, iterations"), nothing looser; otherwise a warning with the reason
    converged = run.converged
    if not converged:
        warnings.append(f"joint: not converged after {len(run.iterations)} passes: "
                        f"{run.stop_reason}")
    warnings += clock_warnings(run) + gust_warnings(run, settings.gust_bounds_mps[1])
    if run.cholesky_fallbacks:
        warnings.append(f"joint: on {run.cholesky_fallbacks} steps the predicted covariance was "
                        "not positive definite to rounding (Cholesky failed); the smoother gain "
                        "there came from a general solve")
    # the forward innovations of the measurements the smoother kept at full weight (the
    # robustly down-weighted ones are reported per source above, not held against the noise
    # model)
    full = (run.weights >= 1.0) & (run.innov_var > 0)
    verdict = chi_square_verdict(np.where(full, run.innov ** 2 / np.where(full, run.innov_var,
                                                                          1.0), np.nan))
    if verdict.gross:
        warnings.append(f"joint: mean NIS per measurement {verdict.mean:.1f} (expected 1): the "
                        "noise settings do not fit this flight")
    corrections = _corrections(run, settings)
    far = implausible_corrections(corrections)
    warnings += [far_warning(name, corrections[name], z) for name, z in far.items()]
    wind_walk = wind_walk_check(run, settings.noise.wind_rw_mps_sqrt_s,
                                settings.noise.wind_shear_mps_per_sqrt_m)
    if wind_rounds and wind_walk is None:
        warnings.append(
            f"joint: the wind changed faster than its default random walk "
            f"({wind_rounds[0]['wind_rw_mps_sqrt_s']:g} m/s/sqrt(s)); the walk re-estimated from "
            f"the smoothed wind in {len(wind_rounds)} round(s): "
            f"{settings.noise.wind_rw_mps_sqrt_s:.3g} m/s/sqrt(s)")
    if wind_walk is not None:
        warnings.append(wind_walk_warning(wind_walk))
    summary = {
        "healthy": bool(finite) and not verdict.gross and not far and wind_walk is None,
        "consistency": verdict.as_dict(),
        "converged": bool(finite) and converged,
        "stop_reason": run.stop_reason,
        "cholesky_fallbacks": run.cholesky_fallbacks,
        "iterations": run.iterations,
        "gust": run.gust,
        "wind_walk": {"wind_rw_mps_sqrt_s": settings.noise.wind_rw_mps_sqrt_s,
                      "rounds": wind_rounds},
        "state_rate_hz": settings.state_rate_hz,
        "attitude_tilt": {"source": clean.meta.attitude_source,
                          "gain_mps2_per_g": settings.noise.ahrs_tilt_mps2_per_g,
                          "gnss_evidence": tilt_ev},
        "corrections": corrections,
        "clock_offsets_s": {k: {"value": o, "sd": sd}
                            for k, (o, sd) in run.clock_offsets_s.items()},
        "noise_scale": run.noise_scale,
        "noise_check": run.noise_check,
        "end_points": [{"which": e["which"], "model": e["model"], "t_s": e["t_s"],
                        "lat_deg": e["point"][0], "lon_deg": e["point"][1],
                        "runway_true_deg": (None if e["runway_rad"] is None
                                            else float(np.degrees(e["runway_rad"]) % 360.0)),
                        "sd_m": list(e["sd_m"]),
                        **({"flare": e["flare"]} if "flare" in e else {})}
                       for e in run.end_points],
        "takeoff_roll": {"start_t_s": run.roll.start_t, "rest_t_s": list(run.roll.rest_t)},
        "fixes": _fix_report(clean, track),
        "wind_prior": _wind_prior_report(inp, settings, clean),
        "sources": sources,
        "settings": asdict(settings),
        "warnings": warnings,
    }
    return MethodResult(name="joint", track=track, summary=summary)
