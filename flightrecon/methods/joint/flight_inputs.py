"""The joint smoother's inputs from a cleaned flight: the held attitude, the loads in the
local level frame, the GNSS and radar tables, the baro channel's field reference, the take-off
roll from the flight phases and the airspeed-floor windows of a derived ``n_long_g``."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.cleaning.saturation import saturated_loads
from flightrecon.errors import MetadataError, ValidationError
from flightrecon.geo.atmosphere import field_pressure_altitude_m
from flightrecon.geo.frames import msl_to_ellipsoid
from flightrecon.geo.kinematics import body_to_ned_matrix, kinematic_acceleration_ned
from flightrecon.geo.wind import wind_toward_ne
from flightrecon.ingest.derive import N_LONG_HALF_WINDOW_S
from flightrecon.ingest.priors import wind_aloft_on_grid
from flightrecon.methods.joint import (
    JointInputs,
    TakeoffRoll,
    takeoff_roll,
)
from flightrecon.methods.joint.inputs import nearest_index
from flightrecon.types import CleanFlight, FlightMeta


def held_attitude(t: np.ndarray, *angles_deg: np.ndarray) -> tuple[list[np.ndarray], list[str]]:
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


def loads_in_ned(g: pd.DataFrame, t_in: np.ndarray,
                  lat_deg: float) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The (held) recorded attitude (Ni, 3) [deg] and the kinematic acceleration
    (NED) [m/s^2] of the loads on the grid ``g``, NaN where a load factor is saturated, with
    the notes for the summary."""
    def col(name):
        return g[name].to_numpy(dtype=float) if name in g.columns else np.full(len(g), np.nan)

    att, notes = held_attitude(t_in, col("roll_deg"), col("pitch_deg"), col("heading_deg"))
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


def gnss_table(gn: pd.DataFrame, meta: FlightMeta) -> pd.DataFrame:
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


def radar_table(rd: pd.DataFrame) -> pd.DataFrame:
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
    att, acc, notes = loads_in_ned(g, t_in, p0.lat_deg)
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
    gnss = gnss_table(clean.gnss, meta)
    radar = radar_table(clean.radar)

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
    la = meta.gnss_lever_arm_m

    def runway(p):
        return None if p is None or p.runway_true_deg is None else float(
            np.radians(p.runway_true_deg))

    def threshold(p):
        if p is None or p.threshold is None:
            return None
        return (float(p.threshold[0]), float(p.threshold[1]),
                float(msl_to_ellipsoid(p.elev_m, N_und)))

    inp = JointInputs(
        t_in=t_in, acc_ned=acc, attitude_deg=att, tas=col("tas_mps"),
        heading_rad=np.radians(col("heading_deg")), baro_rel_m=col("baro_alt_m") - h_pf,
        gnss=gnss, radar=radar, station=pos(meta.station), departure=pos(meta.departure),
        arrival=pos(meta.arrival),
        liftoff_t=float(ph.liftoff_t_s) if ph is not None else np.nan,
        touchdown_t=float(ph.touchdown_t_s) if ph is not None else np.nan,
        field_h=field_h, lever_arm=(float(la[0]), float(la[1]), float(la[2])), wind_ne=wind,
        doppler_gs=col("doppler_gs_mps") if "doppler_gs_mps" in g.columns else None,
        drift_rad=np.radians(col("drift_deg")) if "drift_deg" in g.columns else None,
        f_body_g=np.c_[col("n_long_g"), col("n_lat_g"), -col("n_norm_g")],
        runway_rad=(runway(meta.departure), runway(meta.arrival)),
        thresholds=(threshold(meta.departure), threshold(meta.arrival)),
        lineup_t=float(getattr(ph, "lineup_t_s", np.nan)) if ph is not None else np.nan,
        notes=tuple(notes), ends_airborne=bool(ph is not None and ph.ends_airborne),
        fixes=fixes, wind_aloft=None if wa is None else np.c_[wa[0], wa[1]])
    if "n_long_g" in (meta.extra.get("derived_channels") or {}):
        inp = _without_floor_loads(inp)
    if not (ph is not None and ph.starts_airborne):
        roll = takeoff_roll(inp.t_in, inp.acc_ned, inp.heading_rad, inp.tas, inp.liftoff_t,
                            inp.wind_ne, not_before_t=inp.lineup_t)
        if not np.isfinite(roll.start_t) and ph is not None:
            roll = phases_roll(ph)
        inp = replace(inp, roll=roll)
    return inp


def _without_floor_loads(inp: JointInputs) -> JointInputs:
    """A derived ``n_long_g``'s loads taken as missing through the airspeed-floor windows
    (:func:`airspeed_floor_windows`), with the PSD of the unknown velocity change there
    (:func:`airspeed_floor_psd`); before the take-off roll's search: its rest is found by
    integrating the acceleration back from lift-off, which through these samples is not
    known."""
    dead = airspeed_floor_windows(inp.t_in, inp.tas)
    if not dead.any():
        return inp
    acc = inp.acc_ned.copy()
    acc[dead] = np.nan
    return replace(inp, acc_ned=acc, missing_psd=airspeed_floor_psd(inp.t_in, inp.tas, dead),
                   notes=(*inp.notes, (
                       f"joint: n_long_g derived from an airspeed that reads 0 below its floor: "
                       f"the loads of {int(dead.sum())} sample(s) where it comes alive or dies "
                       "(the derivative's window holds both) are taken as missing, the velocity "
                       "change across each such window unknown by the airspeed there")))


def phases_roll(ph: Any, settle_s: float = 10.0) -> TakeoffRoll:
    """The take-off roll of the cleaning's phases (``roll_start_t_s`` after ``lineup_t_s``:
    the ground speed integrated back from the fast run on the cleaning's grid), where the
    joint's own search finds none: it integrates the acceleration back from lift-off, which a
    1 Hz record whose ``n_long_g`` is derived from an airspeed that reads 0 below its floor
    does not have through the roll's first seconds (:func:`airspeed_floor_windows`).  The rest
    is the line-up to ``settle_s`` before the roll start, as in
    :func:`flightrecon.cleaning.ground_roll.takeoff_roll`; none where the phases found a rolling
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
