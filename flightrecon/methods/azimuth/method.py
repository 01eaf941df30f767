"""Adapter: the azimuth channel (docs/azimuth.md) on a cleaned flight -> ``MethodResult``.

Pipeline, all on one event timeline (the union of the radar plots' own times and the grid times
inside radar coverage; measurements are used once, at their own time):

1. horizontal range of each plot, in the station's tangent plane
   (:func:`flightrecon.geo.radar.horizontal_range`): ``r = rho cos(elevation)`` when the plot
   has an elevation, else from ``rho`` and the height above the station (pressure altitude to
   MSL with the departure QNH, minus the station elevation) less the plane's drop ``r^2 / (2 R)``;
2. range tracker (:func:`flightrecon.methods.azimuth.track_range`, CV filter + RTS smoother);
3. on-board observation at the downlink rate: (a_N, a_E) from the body load factors and attitude
   with its propagated covariance;
4. azimuth filter and RTS smoother, ``model = "aided"`` or ``"singer"``;
5. output on the grid times inside radar coverage (NaN outside): azimuth, rate, acceleration and
   the implied position (station tangent plane -> geodetic -> output tangent plane at the
   departure airfield) with standard deviations in the output plane's axes, and the ground
   velocity in the local level at the aircraft (rotated from the station plane's axes by
   :func:`flightrecon.geo.navframe.horizontal_rotation`).
"""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.errors import MetadataError, ValidationError
from flightrecon.estimation.consistency import chi_square_verdict
from flightrecon.geo.atmosphere import pressure_to_msl_m
from flightrecon.geo.frames import TangentPlane, msl_to_ellipsoid, output_plane
from flightrecon.geo.navframe import horizontal_rotation
from flightrecon.geo.radar import horizontal_range, plane_drop_m
from flightrecon.methods.azimuth import (
    azimuth_filter,
    horizontal_acceleration,
    horizontal_acceleration_covariance,
    track_range,
)
from flightrecon.tracks import TrackColumns
from flightrecon.types import CleanFlight, MethodResult, Position

__all__ = ["AzimuthSettings", "run_azimuth"]

_LOADS = ("n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg", "heading_deg")


@dataclass(frozen=True)
class AzimuthSettings:
    """Settings of the azimuth channel (all one-sigma errors; written into the summary).

    Attributes
    ----------
    sigma_range_m, sigma_azimuth_deg, sigma_elevation_deg : radar plot errors
    sigma_altitude_m : error of the pressure altitude used for the height above the station when
        the plots carry no elevation (pressure vs geometric height: QNH and temperature)
    onboard_rate_hz : downlink rate of the on-board observation (``None``: every grid sample)
    sigma_load_g, sigma_load_bias_g : load-factor white noise and bias per axis
    sigma_attitude_deg, sigma_heading_deg : roll/pitch and heading errors
    alpha_m, sigma_m_mps2 : Singer model (manoeuvre rate [1/s], acceleration sd [m/s^2])
    q_jerk_m2ps5 : aided model, transverse-jerk spectral density
    q_range_m2ps3 : range tracker, range-acceleration spectral density
    correlation_time_s : correlation time of the slowly varying errors of the on-board
        observation (see :func:`flightrecon.methods.azimuth.azimuth_filter`)
    """

    sigma_range_m: float = 50.0
    sigma_azimuth_deg: float = 0.15
    sigma_elevation_deg: float = 0.2
    sigma_altitude_m: float = 30.0
    onboard_rate_hz: float | None = 1.0
    sigma_load_g: float = 0.01
    sigma_load_bias_g: float = 0.003
    sigma_attitude_deg: float = 0.2
    sigma_heading_deg: float = 0.5
    alpha_m: float = 0.05
    sigma_m_mps2: float = 2.0
    q_jerk_m2ps5: float = 0.2
    q_range_m2ps3: float = 10.0
    correlation_time_s: float = 0.0

    def validate(self) -> None:
        """Raise :class:`ValidationError` for a negative, zero or non-finite setting."""
        for name, v in asdict(self).items():
            if v is None and name == "onboard_rate_hz":
                continue
            if not (np.isfinite(v) and v >= 0):
                raise ValidationError(f"azimuth setting {name} must be finite and >= 0, got {v}")
        for name in ("sigma_range_m", "sigma_azimuth_deg", "alpha_m", "q_jerk_m2ps5",
                     "q_range_m2ps3"):
            if getattr(self, name) <= 0:
                raise ValidationError(f"azimuth setting {name} must be > 0")
        if self.onboard_rate_hz is not None and self.onboard_rate_hz <= 0:
            raise ValidationError("onboard_rate_hz must be > 0 (or None for every grid sample)")


def _radar_plots(clean: CleanFlight) -> pd.DataFrame:
    radar = clean.radar
    need = ("t_s", "arms_range_m", "arms_azimuth_deg")
    if len(radar) == 0 or any(c not in radar.columns for c in need):
        raise ValidationError("the azimuth channel needs radar plots with t_s, arms_range_m and "
                              "arms_azimuth_deg", column="arms_azimuth_deg")
    ok = np.isfinite(radar["arms_range_m"].to_numpy(float)) & np.isfinite(
        radar["arms_azimuth_deg"].to_numpy(float)) & np.isfinite(radar["t_s"].to_numpy(float))
    plots = radar.loc[ok].sort_values("t_s", kind="stable")
    if len(plots) < 2:
        raise ValidationError("the azimuth channel needs at least two complete radar plots")
    t = plots["t_s"].to_numpy(float)
    dup = np.flatnonzero(np.diff(t) <= 0)
    if dup.size:
        raise ValidationError(f"{dup.size} radar plot(s) share a time stamp with another "
                              f"(first at t = {t[dup[0]]:.3f} s)", column="t_s")
    if np.any(plots["arms_range_m"].to_numpy(float) <= 0):
        raise ValidationError("radar range must be positive", column="arms_range_m")
    return plots


def _horizontal_range(plots: pd.DataFrame, clean: CleanFlight, s: AzimuthSettings,
                      station: Position) -> tuple[np.ndarray, np.ndarray, np.ndarray, str]:
    """Horizontal range [m], its variance and the height above the station plane [m]."""
    h_station_m = station.elev_m
    rho = plots["arms_range_m"].to_numpy(float)
    el = (plots["arms_elevation_deg"].to_numpy(float) if "arms_elevation_deg" in plots.columns
          else np.full(rho.size, np.nan))
    if np.all(np.isfinite(el)):
        e = np.radians(el)
        r = rho * np.cos(e)
        var = (np.cos(e) * s.sigma_range_m) ** 2 + (
            rho * np.sin(e) * np.radians(s.sigma_elevation_deg)) ** 2
        return r, var, rho * np.sin(e), "elevation"
    grid = clean.grid
    if "baro_alt_m" not in grid.columns:
        raise ValidationError("radar plots without elevation need baro_alt_m for the height "
                              "above the station", column="arms_elevation_deg")
    tg = grid["t_s"].to_numpy(float)
    # pressure altitude to MSL with the departure QNH (as ADS/ARMS does), minus the station's
    # MSL elevation: the height above the station
    hb = pressure_to_msl_m(grid["baro_alt_m"].to_numpy(float), clean.meta.qnh_departure_hpa)
    good = np.isfinite(hb)
    dh = np.interp(plots["t_s"].to_numpy(float), tg[good], hb[good]) - h_station_m
    if np.any(rho ** 2 - dh ** 2 <= 0):
        raise ValidationError("radar slant range shorter than the altitude difference to the "
                              "station (check the station elevation and baro datum)",
                              column="arms_range_m")
    lat_st = station.lat_deg
    r = horizontal_range(rho, lat_deg=lat_st, dh_m=dh)
    up = dh - plane_drop_m(r, lat_st)  # height above the station's tangent plane
    var = (rho / r) ** 2 * s.sigma_range_m**2 + (up / r) ** 2 * s.sigma_altitude_m**2
    return r, var, up, "pressure altitude"


def run_azimuth(clean: CleanFlight, *, model: str = "aided",
                settings: AzimuthSettings | None = None) -> MethodResult:
    """Azimuth channel of the approach radar, Singer or load-factor aided (docs/azimuth.md).

    Parameters
    ----------
    clean : cleaned flight; ``clean.radar`` one row per plot (``t_s``, ``arms_range_m``,
        ``arms_azimuth_deg``, optional ``arms_elevation_deg``), ``clean.grid`` with the loads and
        attitude (aided model), ``meta.station`` and ``meta.departure`` set
    model : ``"aided"`` (load-factor aided, seed 002 eqs. (5)-(9)) or ``"singer"``
    settings : :class:`AzimuthSettings` (default values if ``None``)

    Returns
    -------
    MethodResult
        ``track`` on the grid times: ``azimuth_azimuth_deg`` [0, 360), ``azimuth_rate_dps``,
        ``azimuth_accel_dps2``, ``azimuth_range_m`` (horizontal), ``azimuth_north_m``,
        ``azimuth_east_m``, ``azimuth_vn_mps``, ``azimuth_ve_mps``, each with its ``_sd_``
        column (smoothed estimates; NaN outside radar coverage).  ``summary``: model,
        settings, NIS of both observations, counts.

    Raises
    ------
    MetadataError
        No station or departure position.
    ValidationError
        Unusable radar or on-board data, or an unknown model.
    """
    s = settings if settings is not None else AzimuthSettings()
    s.validate()
    if model not in ("aided", "singer"):
        raise ValidationError(f"unknown azimuth model '{model}': choose 'aided' or 'singer'")
    meta = clean.meta
    if meta.station is None:
        raise MetadataError("the azimuth channel needs the radar station position (--station)")
    plane_out = output_plane(meta)
    st = meta.station
    plots = _radar_plots(clean)
    tp = plots["t_s"].to_numpy(float)
    r_p, r_var_p, up_p, range_from = _horizontal_range(plots, clean, s, st)

    grid = clean.grid
    tg = grid["t_s"].to_numpy(float)
    ig = np.flatnonzero((tg >= tp[0]) & (tg <= tp[-1]))
    io = _onboard_samples(grid, tg, ig, tp, s) if model == "aided" else np.empty(0, np.int64)
    t_ev, pos_p, pos_g = _timeline(tp, tg[ig])
    n = t_ev.size
    eps_meas = np.full(n, np.nan)
    eps_meas[pos_p] = np.radians(plots["arms_azimuth_deg"].to_numpy(float))
    eps_var = np.full(n, np.radians(s.sigma_azimuth_deg) ** 2)
    r_meas = np.full(n, np.nan)
    r_var = np.full(n, np.nan)
    r_meas[pos_p] = r_p
    r_var[pos_p] = r_var_p
    rt = track_range(t_ev, r_meas, r_var, q_range_m2ps3=s.q_range_m2ps3)

    a_ne = a_cov = a_corr = None
    if model == "aided":
        a_ne, a_cov, a_corr = _aided_inputs(grid, io, pos_g[np.searchsorted(ig, io)], n, s)
    run = azimuth_filter(t_ev, eps_meas, eps_var, rt, model=model, a_ne=a_ne, a_ne_cov=a_cov,
                         a_ne_cov_corr=a_corr, alpha_m=s.alpha_m, sigma_m_mps2=s.sigma_m_mps2,
                         q_jerk_m2ps5=s.q_jerk_m2ps5, correlation_time_s=s.correlation_time_s)
    h_station = float(msl_to_ellipsoid(st.elev_m, meta.geoid_undulation_m))
    stp = TangentPlane(st.lat_deg, st.lon_deg, h_station)
    track = _grid_track(run, rt, pos_g, tg, ig, np.interp(tg[ig], tp, up_p), stp, plane_out)
    summary = _summary(run, rt, model, s, range_from, tp, len(clean.radar), io)
    return MethodResult(name="azimuth", track=track, summary=summary)


def _onboard_samples(grid: pd.DataFrame, tg: np.ndarray, ig: np.ndarray, tp: np.ndarray,
                     s: AzimuthSettings) -> np.ndarray:
    """Grid rows of the on-board observations: inside the radar coverage (rows ``ig``), at the
    downlink rate, with valid loads and attitude."""
    missing = [c for c in _LOADS if c not in grid.columns]
    if missing:
        raise ValidationError(f"the aided azimuth model needs {', '.join(missing)}",
                              column=missing[0])
    if s.onboard_rate_hz is None:
        cand = ig
    else:
        tick = np.floor((tg[ig] - tp[0]) * s.onboard_rate_hz + 1e-9)
        cand = ig[np.r_[True, np.diff(tick) > 0]] if ig.size else ig
    vals = np.stack([grid[c].to_numpy(float)[cand] for c in _LOADS], -1)
    io = cand[np.isfinite(vals).all(axis=1)]
    if io.size == 0:
        raise ValidationError("no valid load-factor/attitude sample inside radar coverage")
    return io


def _timeline(tp: np.ndarray, tg_in: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The event times: plots ``tp`` and grid samples ``tg_in``, merged where they coincide (to
    the nanosecond); returns the times and the events of the plots and of the samples."""
    t_all = np.concatenate([tp, tg_in])
    key = np.round(t_all * 1e9)
    uniq, inv = np.unique(key, return_inverse=True)
    return uniq * 1e-9, inv[: tp.size], inv[tp.size:]


def _aided_inputs(grid: pd.DataFrame, io: np.ndarray, pos_o: np.ndarray, n: int,
                  s: AzimuthSettings) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The on-board horizontal acceleration at events ``pos_o`` (grid rows ``io``), its white
    covariance and the covariance of its slowly varying (bias) part (docs/azimuth.md)."""
    args = [grid[c].to_numpy(float)[io] for c in _LOADS]
    a_ne = np.full((n, 2), np.nan)
    a_ne[pos_o] = horizontal_acceleration(*args)
    a_cov = np.zeros((n, 2, 2))
    a_cov[pos_o] = horizontal_acceleration_covariance(
        *args, sigma_load_g=s.sigma_load_g, sigma_attitude_deg=s.sigma_attitude_deg,
        sigma_heading_deg=s.sigma_heading_deg)
    a_corr = np.zeros((n, 2, 2))
    a_corr[pos_o] = horizontal_acceleration_covariance(
        *args, sigma_load_g=s.sigma_load_bias_g, sigma_attitude_deg=0.0,
        sigma_heading_deg=0.0)
    return a_ne, a_cov, a_corr


def _grid_track(run, rt, pos_g: np.ndarray, tg: np.ndarray, ig: np.ndarray,
                up_st: np.ndarray, stp: TangentPlane, plane_out: TangentPlane) -> pd.DataFrame:
    """The smoothed estimate at the grid samples ``ig`` (events ``pos_g``) as track columns:
    azimuth channel, range, and position / velocity from the station plane into the output's
    axes (``up_st``: the height above the station plane there)."""
    x = run.smooth.x[pos_g]
    P = run.smooth.P[pos_g]
    r = rt.r[pos_g]
    rd = rt.r_dot[pos_g]
    Pr = rt.P[pos_g]
    eps, om = x[:, 0], x[:, 1]
    sd = np.sqrt(np.diagonal(P, axis1=1, axis2=2))
    se, ce = np.sin(eps), np.cos(eps)
    # station-plane position and velocity; range and azimuth channels are independent
    n_st, e_st = r * ce, r * se
    var_r = Pr[:, 0, 0]
    # position covariance in the station plane's (north, east) axes, from (r, eps)
    Jp = np.stack([np.stack([ce, -r * se], -1), np.stack([se, r * ce], -1)], -2)
    C_re = np.zeros((len(r), 2, 2))
    C_re[:, 0, 0], C_re[:, 1, 1] = var_r, P[:, 0, 0]
    Cp = Jp @ C_re @ Jp.transpose(0, 2, 1)
    vn_st = rd * ce - r * om * se
    ve_st = rd * se + r * om * ce
    # first-order: d(vn, ve)/d(r, r_dot) and /d(eps, omega)
    Jr = np.stack([np.stack([-om * se, ce], -1), np.stack([om * ce, se], -1)], -2)
    Je = np.stack([np.stack([-rd * se - r * om * ce, -r * se], -1),
                   np.stack([rd * ce - r * om * se, r * ce], -1)], -2)
    Cv = Jr @ Pr @ Jr.transpose(0, 2, 1) + Je @ P[:, :2, :2] @ Je.transpose(0, 2, 1)
    lat, lon, h = stp.inverse(e_st, n_st, up_st)
    e_out, n_out, u_out = plane_out.forward(lat, lon, h)
    # into the output's axes: positions' covariance into the output plane's (north, east),
    # velocities and theirs into the local level at the aircraft (true north there)
    Mp = horizontal_rotation(stp.lat0_deg, stp.lon0_deg, plane_out.lat0_deg,
                             plane_out.lon0_deg)[0]
    Mv = horizontal_rotation(stp.lat0_deg, stp.lon0_deg, lat, lon)

    out = TrackColumns("azimuth", tg, ig)
    out.add("azimuth", "deg", np.mod(np.degrees(eps), 360.0), np.degrees(sd[:, 0]))
    out.add("rate", "dps", np.degrees(om), np.degrees(sd[:, 1]))
    out.add("accel", "dps2", np.degrees(x[:, 2]), np.degrees(sd[:, 2]))
    out.add("range", "m", r, np.sqrt(var_r))
    out.add_horizontal("north", "east", "m", np.c_[n_out, e_out], Cp, Mp, value_is_output=True)
    out.add_horizontal("vn", "ve", "mps", np.c_[vn_st, ve_st], Cv, Mv)
    out.add_place(plane_out, e_out, n_out, up=u_out, geodetic=(lat, lon, h))
    return out.frame()


def _summary(run, rt, model: str, s: AzimuthSettings, range_from: str, tp: np.ndarray,
             n_plots: int, io: np.ndarray) -> dict[str, Any]:
    """Counts, innovation statistics and the health verdict of the three filters."""
    nis_e = run.nis_eps[np.isfinite(run.nis_eps)]
    nis_z = run.nis_z[np.isfinite(run.nis_z)]
    finite = bool(np.all(np.isfinite(run.smooth.x)) and np.all(np.isfinite(run.smooth.P)))
    # every scalar innovation of the three filters (azimuth, transverse acceleration, range)
    verdict = chi_square_verdict(np.r_[nis_e, nis_z, rt.nis])
    gaps = np.diff(tp)
    summary: dict[str, Any] = {
        "model": model,
        "settings": asdict(s),
        "range_from": range_from,
        "radar_plots_used": int(tp.size),
        "radar_plots_dropped": int(n_plots - tp.size),
        "longest_radar_gap_s": float(gaps.max()),
        "onboard_observations": int(io.size),
        "coverage_s": [float(tp[0]), float(tp[-1])],
        "nis_azimuth_mean": float(nis_e.mean()) if nis_e.size else None,
        "nis_transverse_mean": float(nis_z.mean()) if nis_z.size else None,
        "nis_range_mean": float(np.nanmean(rt.nis)),
        "correlated_error_inflation": float(run.n_corr),
        "consistency": verdict.as_dict(),
        "healthy": finite and not verdict.gross,
    }
    if not finite:
        summary["warning"] = "non-finite estimates: the filter diverged"
    elif verdict.gross:
        summary["warning"] = (f"mean NIS per measurement {verdict.mean:.1f} (expected 1): the "
                              "noise settings or the motion model do not fit this flight")
    return summary
