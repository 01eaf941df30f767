"""Are a method's estimated states plausible, and does its track agree with the evidence?  The
evidence check behind method health, beside the envelope of :mod:`flightrecon.envelope`.

Each rule holds where the data allow it (docs/output.md, "Method health"; limits in
:class:`Evidence`): the wind estimate within what the atmosphere has been measured to blow and
to change by, the ground speed within the recorded airspeed plus a plausible wind, the joint
smoother's heading bias within what any heading reference is off, the track's end at the given
arrival and its passage by each known position (``--fix``), and, on a flight without GNSS or
radar between two known ends, the track near dead reckoning with its linear end-point
correction (:func:`corrected_dead_reckoning`).  After a ground impact detected by the cleaning
(``phases.impact_t_s``) the flight-only rules are not checked.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.cleaning.plausibility import time_spans
from flightrecon.envelope import central_rate, half_window, horizontal_track
from flightrecon.methods.baselines import (
    ARRIVAL_POINT_SD_M,
    DR_WALK_MPS_SQRT_S,
    bridge_sd_m,
    profile_wind_sd_m,
)
from flightrecon.types import CleanFlight, MethodResult


@dataclass(frozen=True)
class Evidence:
    """Limits of the estimated states and of the agreement with the evidence (docs/output.md,
    "Method health"; the sources of the meteorological limits are cited there).

    Attributes
    ----------
    wind_surface_mps, wind_per_km_mps, wind_cap_mps : the largest plausible wind speed at a
        pressure altitude h: ``wind_surface_mps + wind_per_km_mps * h / 1000``, at most
        ``wind_cap_mps`` (40 m/s at the ground, 60 m/s at 2 km, 150 m/s from 11 km: the
        strongest jet-stream cores measured by radiosondes are about 100 m/s, the highest
        reports about 150 m/s)
    wind_change_mps, wind_change_window_s, wind_shear_per_s : the wind may change by at most
        ``wind_change_mps`` within ``wind_change_window_s`` plus ``wind_shear_per_s`` times
        the height changed meanwhile (a front, a microburst's outflow, a 50 m/s per km shear)
    air_ground_margin_mps : slack of the ground speed against the horizontal airspeed plus the
        plausible wind (airspeed scale error, the differences' noise)
    min_tas_mps : the airspeed above which the aircraft flies through the air (ground roll and
        taxi below it are not checked)
    span_s : a state outside its limits counts when it is for at least this long in all
    smooth_s : the track's ground speed is taken over this window
    heading_bias_max_deg : the largest plausible heading bias, whatever its prior: 8 times the
        joint smoother's default prior sd (2 deg), the rule that holds for a recorded heading
        (a propagated heading widens the prior to its own sd, a heading that far off is no
        reference)
    end_k : an end point or a fix is met when the track is within ``end_k`` combined sd of it
    arrival_sd_m : sd of the touchdown about the arrival's reference point (the joint
        smoother's ``endpoint_h_m``)
    dr_k, dr_span_s, dr_rms_k, dr_walk_mps_per_sqrt_s, dr_floor_m : agreement with dead
        reckoning and its linear end-point correction: the two tracks may differ by ``dr_k``
        times their combined sd for less than ``dr_span_s`` in all, and by at most ``dr_rms_k``
        combined sd in RMS over the flight (per axis: twice what two consistent estimates
        differ by on average); the sd of the corrected dead reckoning is that
        of a wind random walk of ``dr_walk_mps_per_sqrt_s`` (twice the joint smoother's
        default; twice the walk the joint smoother re-estimated for the flight where it found
        the wind moving faster than its default, summary ``wind_walk``) integrated and pinned
        at both ends, with a floor of ``dr_floor_m``, and that of its one wind over the
        flight's height profile (:func:`flightrecon.methods.baselines.profile_wind_sd_m`): a
        track is refused for claiming more than the two can share, never for being better
        than the baseline where the baseline's own error explains the difference
    """

    wind_surface_mps: float = 40.0
    wind_per_km_mps: float = 10.0
    wind_cap_mps: float = 150.0
    wind_change_mps: float = 25.0
    wind_change_window_s: float = 60.0
    wind_shear_per_s: float = 0.05
    air_ground_margin_mps: float = 10.0
    min_tas_mps: float = 30.0
    span_s: float = 30.0
    smooth_s: float = 10.0
    heading_bias_max_deg: float = 16.0
    end_k: float = 4.0
    arrival_sd_m: float = ARRIVAL_POINT_SD_M
    dr_k: float = 4.0
    dr_walk_mps_per_sqrt_s: float = DR_WALK_MPS_SQRT_S
    dr_floor_m: float = 1000.0
    dr_span_s: float = 60.0
    dr_rms_k: float = 2.0

    def wind_limit_mps(self, h_m: np.ndarray) -> np.ndarray:
        """Largest plausible wind speed [m/s] at pressure altitude ``h_m`` [m]."""
        h = np.maximum(np.asarray(h_m, float), 0.0)
        return np.minimum(self.wind_surface_mps + self.wind_per_km_mps * h / 1000.0,
                          self.wind_cap_mps)


def _on_track(t: np.ndarray, x: np.ndarray, tq: np.ndarray) -> np.ndarray:
    """``x`` at ``tq`` by linear interpolation over its finite samples (NaN outside them)."""
    ok = np.isfinite(x)
    if ok.sum() < 2:
        return np.full(len(np.atleast_1d(tq)), np.nan)
    return np.interp(tq, t[ok], x[ok], left=np.nan, right=np.nan)


def _grid_on(clean: CleanFlight, name: str, t: np.ndarray) -> np.ndarray | None:
    g = clean.grid
    if name not in g.columns:
        return None
    return _on_track(g["t_s"].to_numpy(float), g[name].to_numpy(float), t)


def _sd_or_zero(tr: Any, col: str) -> np.ndarray:
    if col not in tr.columns:
        return np.zeros(len(tr))
    return np.nan_to_num(tr[col].to_numpy(float), nan=0.0)


def _worst_lasting(bad: np.ndarray, excess: np.ndarray, dt: np.ndarray, span_s: float
                   ) -> int | None:
    """The sample where ``excess`` is largest among the ``bad`` ones, when they last at least
    ``span_s`` in all (``dt`` each sample's interval); None for a violation shorter than that."""
    if not bad.any() or float(dt[bad].sum()) < span_s:
        return None
    return int(np.nanargmax(np.where(bad, excess, np.nan)))


def _problem(check: str, what: str, spans: list[list[float]], worst: float, limit: float
             ) -> dict[str, Any]:
    return {"check": check, "what": what, "worst": float(worst), "limit": float(limit),
            "spans_s": spans}


def evidence_problems(res: MethodResult, clean: CleanFlight, ev: Evidence = Evidence()
                      ) -> list[dict[str, Any]]:
    """Where a method's estimated states are implausible or its track disagrees with the
    evidence (docs/output.md, "Method health").

    Checks, each where the data allow it:

    * ``wind_speed``: the method's wind estimate (``<p>wind_n_mps``, ``<p>wind_e_mps``) above
      :meth:`Evidence.wind_limit_mps` at the recorded pressure altitude;
    * ``wind_change``: the wind estimate changing faster than a front or a shear can;
    * ``air_ground``: the track's ground speed differs from the recorded horizontal airspeed by
      more than the plausible wind (whatever the method's wind: ``|v_ground| - |v_air|`` is at
      most the wind's speed);
    * ``heading_bias``: the joint smoother's heading bias beyond
      ``Evidence.heading_bias_max_deg``;
    * ``arrival``: a record that ends on the ground ends farther from the given arrival than
      ``end_k`` combined sd;
    * ``fix``: a known position (``--fix``) missed by more than ``end_k`` combined sd per axis;
    * ``dead_reckoning``: on a flight without GNSS or radar from the departure to a known end
      (the arrival, or a known position at the record's end), the track leaves dead reckoning
      with its linear end-point correction (:func:`corrected_dead_reckoning`) by more than
      ``dr_k`` combined sd for ``dr_span_s``, or by more than ``dr_rms_k`` in RMS.

    Returns
    -------
    list of dict
        ``check``, ``what`` (in words, with the worst value and the limit), ``worst``,
        ``limit``, ``spans_s``.
    """
    hz = horizontal_track(res)
    if hz is None:
        return []
    tr, p, t, north, east = hz
    out: list[dict[str, Any]] = []
    ph = clean.phases
    t_imp = getattr(ph, "impact_t_s", float("nan")) if ph else float("nan")
    flight = ~(t > t_imp) if np.isfinite(t_imp) else np.ones(len(t), bool)
    h = _grid_on(clean, "baro_alt_m", t)
    h = np.zeros(len(t)) if h is None else np.nan_to_num(h, nan=0.0)
    tas = _grid_on(clean, "tas_mps", t)
    w_lim = ev.wind_limit_mps(h)
    with np.errstate(invalid="ignore", divide="ignore"):
        if f"{p}wind_n_mps" in tr.columns and f"{p}wind_e_mps" in tr.columns:
            wn = tr[f"{p}wind_n_mps"].to_numpy(float)
            we = tr[f"{p}wind_e_mps"].to_numpy(float)
            out += _wind_checks(t, wn, we, h, w_lim, flight, ev)
        if tas is not None:
            vel = None
            if f"{p}vn_mps" in tr.columns and f"{p}ve_mps" in tr.columns:
                vel = (tr[f"{p}vn_mps"].to_numpy(float), tr[f"{p}ve_mps"].to_numpy(float))
            out += _air_ground(t, north, east, h, tas, w_lim, flight, ev, vel)
        out += _corrections_check(res, ev)
        out += _end_checks(res, clean, t, north, east, ev)
        out += _dr_check(res, clean, t, north, east, ev)
    return out


def _wind_checks(t: np.ndarray, wn: np.ndarray, we: np.ndarray, h: np.ndarray,
                 w_lim: np.ndarray, flight: np.ndarray, ev: Evidence) -> list[dict[str, Any]]:
    out = []
    speed = np.hypot(wn, we)
    bad = np.isfinite(speed) & (speed > w_lim) & flight
    dt = np.diff(t, append=t[-1])
    i = _worst_lasting(bad, speed - w_lim, dt, ev.span_s)
    if i is not None:
        out.append(_problem(
            "wind_speed",
            f"wind estimated at {speed[i]:.0f} m/s at {h[i]:.0f} m pressure altitude "
            f"(t = {t[i]:.0f} s), beyond the {w_lim[i]:.0f} m/s that the atmosphere has been "
            "measured to blow there: the wind has absorbed a heading or airspeed error",
            time_spans(t, bad), speed[i], w_lim[i]))
    k = half_window(t, ev.wind_change_window_s)
    if len(t) > 2 * k:
        dw = np.full(len(t), np.nan)
        dw[k:-k] = np.hypot(wn[2 * k:] - wn[:-2 * k], we[2 * k:] - we[:-2 * k])
        dh = np.zeros(len(t))
        dh[k:-k] = np.abs(h[2 * k:] - h[:-2 * k])
        lim = ev.wind_change_mps + ev.wind_shear_per_s * dh
        bad = np.isfinite(dw) & (dw > lim) & flight
        i = _worst_lasting(bad, dw - lim, dt, ev.span_s)
        if i is not None:
            out.append(_problem(
                "wind_change",
                f"wind estimate changing by {dw[i]:.0f} m/s within "
                f"{ev.wind_change_window_s:.0f} s at t = {t[i]:.0f} s (limit {lim[i]:.0f} m/s "
                "for the height changed meanwhile)", time_spans(t, bad), dw[i], lim[i]))
    return out


def _air_ground(t: np.ndarray, north: np.ndarray, east: np.ndarray, h: np.ndarray,
                tas: np.ndarray, w_lim: np.ndarray, flight: np.ndarray, ev: Evidence,
                vel: tuple[np.ndarray, np.ndarray] | None = None) -> list[dict[str, Any]]:
    # the ground speed from the method's own local-level velocity where it has one: the rate of
    # the tangent-plane position is not the ground speed far from the plane's origin (8000 km
    # out on a 10-hour flight the plane's north moved at 150 m/s where the aircraft flew 224)
    if vel is not None and np.isfinite(vel[0]).any():
        k = half_window(t, ev.smooth_s)
        gs = _moving_mean(np.hypot(*vel), k)
    else:
        gs = np.hypot(central_rate(t, north, ev.smooth_s), central_rate(t, east, ev.smooth_s))
    vz = central_rate(t, h, ev.smooth_s)
    tas_h = np.sqrt(np.maximum(tas ** 2 - np.nan_to_num(vz) ** 2, 0.0))
    lim = w_lim + ev.air_ground_margin_mps
    diff = np.abs(gs - tas_h)
    bad = np.isfinite(diff) & (tas > ev.min_tas_mps) & (diff > lim) & flight
    dt = np.diff(t, append=t[-1])
    i = _worst_lasting(bad, diff - lim, dt, ev.span_s)
    if i is None:
        return []
    return [_problem(
        "air_ground",
        f"ground speed {gs[i]:.0f} m/s against a horizontal airspeed of {tas_h[i]:.0f} m/s at "
        f"t = {t[i]:.0f} s: no plausible wind (at most {w_lim[i]:.0f} m/s there) makes up the "
        "difference", time_spans(t, bad), diff[i], lim[i])]


def _moving_mean(x: np.ndarray, k: int) -> np.ndarray:
    """Centred mean over 2 k + 1 samples (NaN where the window leaves the record or holds a
    NaN): the velocity on the same footing as :func:`central_rate`'s position difference."""
    if k <= 0 or len(x) <= 2 * k:
        return x.copy()
    c = np.concatenate([[0.0], np.cumsum(x)])
    out = np.full(len(x), np.nan)
    out[k:-k] = (c[2 * k + 1:] - c[:-2 * k - 1]) / (2 * k + 1)
    return out


def _corrections_check(res: MethodResult, ev: Evidence) -> list[dict[str, Any]]:
    c = (res.summary.get("corrections") or {}).get("heading_bias_deg")
    if not isinstance(c, dict) or not np.isfinite(c.get("value", np.nan)):
        return []
    v = float(c["value"])
    if abs(v) <= ev.heading_bias_max_deg:
        return []
    return [_problem("heading_bias",
                     f"heading bias estimated at {v:+.1f} deg (sd {float(c.get('sd', np.nan)):.1f})"
                     f", beyond the {ev.heading_bias_max_deg:.0f} deg any heading reference is "
                     "off: the heading has no usable reference on this flight", [], abs(v),
                     ev.heading_bias_max_deg)]


def _end_checks(res: MethodResult, clean: CleanFlight, t: np.ndarray, north: np.ndarray,
                east: np.ndarray, ev: Evidence) -> list[dict[str, Any]]:
    from flightrecon.geo.frames import output_plane

    out: list[dict[str, Any]] = []
    meta = clean.meta
    tr = res.track
    p = res.name + "_"
    sdn, sde = _sd_or_zero(tr, f"{p}north_sd_m"), _sd_or_zero(tr, f"{p}east_sd_m")
    try:
        plane = output_plane(meta)
    except Exception:   # no frame: nothing to hold the track against
        return out
    ph = clean.phases
    arr = meta.arrival
    if (arr is not None and ph is not None and np.isfinite(ph.touchdown_t_s)
            and not ph.ends_airborne):
        fin = np.flatnonzero(np.isfinite(north) & np.isfinite(east))
        if len(fin):
            i_end = int(fin[-1])
            i_td = int(np.clip(np.searchsorted(t, ph.touchdown_t_s), fin[0], fin[-1]))
            refs = [(arr.lat_deg, arr.lon_deg)]
            if arr.threshold_lat_deg is not None and arr.threshold_lon_deg is not None:
                refs.append((arr.threshold_lat_deg, arr.threshold_lon_deg))
            best = np.inf
            tol = np.inf
            for lat, lon in refs:
                ea, na, _ = plane.forward(lat, lon, arr.elev_m + meta.geoid_undulation_m)
                for i in (i_td, i_end):
                    d = float(np.hypot(north[i] - float(na), east[i] - float(ea)))
                    if d < best:
                        best = d
                        tol = ev.end_k * float(np.sqrt(ev.arrival_sd_m ** 2 + sdn[i] ** 2
                                                       + sde[i] ** 2))
            if best > tol:
                out.append(_problem(
                    "arrival", f"the track ends {best / 1000:.1f} km from the given arrival "
                    f"(tolerance {tol / 1000:.1f} km: {ev.end_k:g} x the combined sd)",
                    [[float(t[i_end]), float(t[i_end])]], best, tol))
    for fx in meta.fixes:
        if not (t[0] <= fx.t_s <= t[-1]):
            continue
        n_t = float(_on_track(t, north, np.array([fx.t_s]))[0])
        e_t = float(_on_track(t, east, np.array([fx.t_s]))[0])
        if not (np.isfinite(n_t) and np.isfinite(e_t)):
            continue
        alt = fx.alt_msl_m if fx.alt_msl_m is not None else 0.0
        ef, nf, _ = plane.forward(fx.lat_deg, fx.lon_deg, alt + meta.geoid_undulation_m)
        s_n = float(np.sqrt(fx.sd_m ** 2 + _on_track(t, sdn, np.array([fx.t_s]))[0] ** 2))
        s_e = float(np.sqrt(fx.sd_m ** 2 + _on_track(t, sde, np.array([fx.t_s]))[0] ** 2))
        z = max(abs(n_t - float(nf)) / s_n, abs(e_t - float(ef)) / s_e)
        if z > ev.end_k:
            d = float(np.hypot(n_t - float(nf), e_t - float(ef)))
            out.append(_problem(
                "fix", f"the track passes {d / 1000:.2f} km from the known position at "
                f"t = {fx.t_s:.0f} s ({z:.1f} combined sd; at most {ev.end_k:g})",
                [[fx.t_s, fx.t_s]], z, ev.end_k))
    return out


def _recorder_only(clean: CleanFlight) -> bool:
    """No GNSS position and no radar plot in the flight."""
    g = clean.gnss
    has_gnss = len(g) > 0 and "gnss_lat_deg" in g.columns and bool(
        np.isfinite(g["gnss_lat_deg"].to_numpy(float)).any())
    return not (has_gnss or len(clean.radar) > 0)


#: a known position this close to the record's end [s] is its end point
END_FIX_S = 60.0


def corrected_dead_reckoning(clean: CleanFlight) -> tuple[pd.DataFrame, float, float] | None:
    """Dead reckoning from the departure at lift-off, corrected linearly to the known end: the
    arrival at touchdown (a record that ends on the ground) or a known position (``--fix``)
    within :data:`END_FIX_S` of the record's end.  Returns the track (``t_s``, ``north_m``,
    ``east_m``), the end's time and the end point's own sd [m]; ``None`` without both ends."""
    from flightrecon.geo.frames import output_plane
    from flightrecon.methods.baselines import dead_reckoning

    ph = clean.phases
    meta = clean.meta
    if (meta.departure is None or ph is None or not np.isfinite(ph.liftoff_t_s)
            or ph.starts_airborne or np.isfinite(getattr(ph, "impact_t_s", float("nan")))
            or not {"heading_deg", "tas_mps"} <= set(clean.grid.columns)):
        return None
    try:
        if (meta.arrival is not None and np.isfinite(ph.touchdown_t_s)
                and not ph.ends_airborne):
            return dead_reckoning(clean, corrected=True), float(ph.touchdown_t_s), 0.0
        t_last = float(clean.grid["t_s"].iloc[-1])
        ends = [f for f in meta.fixes if t_last - END_FIX_S <= f.t_s <= t_last]
        if not ends:
            return None
        fx = ends[-1]
        dr = dead_reckoning(clean)
    except (ValueError, KeyError):
        return None
    tg = dr["t_s"].to_numpy(float)
    n, e = dr["north_m"].to_numpy(float).copy(), dr["east_m"].to_numpy(float).copy()
    fin = np.flatnonzero(np.isfinite(n) & np.isfinite(e))
    if len(fin) < 2:
        return None
    # dead reckoning stops at touchdown: a fix on the landing roll closes it there
    t_end = min(float(fx.t_s), float(tg[fin[-1]]))
    n_end = _on_track(tg, n, np.array([t_end]))[0]
    e_end = _on_track(tg, e, np.array([t_end]))[0]
    alt = fx.alt_msl_m if fx.alt_msl_m is not None else 0.0
    ef, nf, _ = output_plane(meta).forward(fx.lat_deg, fx.lon_deg, alt + meta.geoid_undulation_m)
    frac = np.clip((tg - ph.liftoff_t_s) / max(t_end - ph.liftoff_t_s, 1e-9), 0.0, None)
    n += frac * (float(nf) - n_end)
    e += frac * (float(ef) - e_end)
    return pd.DataFrame({"t_s": tg, "north_m": n, "east_m": e}), t_end, float(fx.sd_m)


def dr_walk(res: MethodResult, ev: Evidence) -> float:
    """The wind random walk [m/s/sqrt(s)] behind the corrected dead reckoning's sd:
    ``ev.dr_walk_mps_per_sqrt_s``, or twice the walk the joint smoother re-estimated for this
    flight where larger (its wind moved faster than the default walk allows, and dead
    reckoning, which holds no wind, is the more wrong for it: JSBSim's holding, 5.5-9.9 km RMS
    against 0.55-1.6 km for the joint)."""
    ww = (res.summary or {}).get("wind_walk") or {}
    est = float(ww.get("wind_rw_mps_sqrt_s", 0.0)) if ww.get("rounds") else 0.0
    return max(ev.dr_walk_mps_per_sqrt_s, 2.0 * est) if np.isfinite(est) else \
        ev.dr_walk_mps_per_sqrt_s


def _dr_check(res: MethodResult, clean: CleanFlight, t: np.ndarray, north: np.ndarray,
              east: np.ndarray, ev: Evidence) -> list[dict[str, Any]]:
    ph = clean.phases
    if ph is None or not _recorder_only(clean):
        return []
    got = corrected_dead_reckoning(clean)
    if got is None:
        return []
    dr, t_end, sd_end = got
    tg = dr["t_s"].to_numpy(float)
    dn = _on_track(tg, dr["north_m"].to_numpy(float), t)
    de = _on_track(tg, dr["east_m"].to_numpy(float), t)
    tr = res.track
    p = res.name + "_"
    sdn, sde = _sd_or_zero(tr, f"{p}north_sd_m"), _sd_or_zero(tr, f"{p}east_sd_m")
    # the baseline's own error carried: its wind's random walk in time and its one wind over
    # the flight's height profile (a climb through a shear: methods/baselines.py)
    hp = _grid_on(clean, "baro_alt_m", t)
    prof = (np.zeros(len(t)) if hp is None
            else profile_wind_sd_m(t, hp, ph.liftoff_t_s, t_end))
    sd_dr = np.sqrt(ev.dr_floor_m ** 2 + sd_end ** 2 + prof ** 2
                    + bridge_sd_m(t, ph.liftoff_t_s, t_end, dr_walk(res, ev)) ** 2)
    # per axis: each axis of the corrected dead reckoning has sd_dr
    zn = np.abs(north - dn) / np.sqrt(sd_dr ** 2 + sdn ** 2)
    ze = np.abs(east - de) / np.sqrt(sd_dr ** 2 + sde ** 2)
    z = np.fmax(zn, ze)
    inside = (t >= ph.liftoff_t_s) & (t <= t_end)
    bad = np.isfinite(z) & (z > ev.dr_k) & inside
    dt = np.diff(t, append=t[-1])
    both = inside & np.isfinite(zn) & np.isfinite(ze)
    z_rms = float(np.sqrt(np.mean(0.5 * (zn[both] ** 2 + ze[both] ** 2)))) if both.any() else 0.0
    far = bad.any() and float(dt[bad].sum()) >= ev.dr_span_s
    if not far and z_rms <= ev.dr_rms_k:
        return []
    i = int(np.nanargmax(np.where(inside, z, np.nan)))
    d = float(np.hypot(north[i] - dn[i], east[i] - de[i]))
    return [_problem(
        "dead_reckoning",
        f"the track leaves dead reckoning with its linear end-point correction by up to "
        f"{d / 1000:.1f} km (t = {t[i]:.0f} s, {z[i]:.1f} combined sd; RMS over the flight "
        f"{z_rms:.1f} sd, at most {ev.dr_rms_k:g}, nowhere {ev.dr_k:g} for "
        f"{ev.dr_span_s:.0f} s): the two cannot both be right, and the simpler one rests on "
        "fewer assumptions", time_spans(t, bad if far else inside), z[i] if far else z_rms,
        ev.dr_k if far else ev.dr_rms_k)]
