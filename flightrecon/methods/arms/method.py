"""ADS/ARMS adapter: a cleaned flight in, the ``arms_`` columns and summary out.

docs/arms.md; the estimators are in :mod:`flightrecon.methods.arms`.

Frames.  The filters work in the east-north-up tangent plane at the radar station (x east,
y north).  The aircraft's height above that plane, ``u = dh - r^2 / (2 R_e)``, comes from the
pressure altitude (converted to MSL with ``meta.qnh_departure_hpa`` when known, else with the
standard 1013.25 hPa) minus the station's MSL elevation; it converts slant to horizontal range
(unless the plots carry an elevation angle) and places the estimate in 3-D for the conversion
station plane -> WGS-84 -> output plane (at the departure airfield) through pyproj.  Vectors
(velocities, air-data errors) and covariances are carried across with the local 2x2 Jacobian of
that mapping (positions).  The air-data velocity ``V* = TAS (sin hdg, cos hdg)`` is referred to
true north at the aircraft; it is rotated into the station plane by the meridian convergence
``gamma`` at the aircraft (``hdg + gamma``; ``gamma`` is the azimuth of local true north in the
station plane, negative east of the station in the northern hemisphere), ``gamma`` evaluated at
the plots' converted positions interpolated in time (the angle changes by ~1e-5 rad per 100 m,
so the plots' noise does not matter there; the plots themselves are used once each, by the
filter).  Output vectors (ground velocity, air-data error, air-data-based ground velocity) are
given in local north/east at the aircraft (rotated back by ``-gamma``), the frame of a heading,
a wind or a GNSS velocity; positions are in the output tangent plane.

Output.  The joint form steps through the grid times (thinned to ``output_rate_hz``, default
4 Hz) inside the radar coverage as well (steps without a measurement), so its output there is
the exact smoothed (or, with ``smooth=False``, filtered/predicted) state; grid samples between
those steps are linearly interpolated (for output only; with a Gauss-Markov air-data error as
rough as the paper's, 1.5 m/s per second, the interpolated sd is then slightly optimistic
between steps).  The cascade steps at the plots only; its estimates
are linearly interpolated to the grid times for output only (between plots its sd is then an
interpolation too).  NaN outside the radar coverage (before the first plot, after the last).
Inside a radar outage the estimate is the model's bridge, and its standard deviations say how
good that is.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.errors import MetadataError, SchemaError, ValidationError
from flightrecon.estimation.consistency import chi_square_verdict
from flightrecon.geo.atmosphere import pressure_to_msl_m
from flightrecon.geo.frames import TangentPlane, msl_to_ellipsoid, output_plane
from flightrecon.geo.navframe import north_azimuth_in_plane
from flightrecon.geo.radar import horizontal_range, plane_drop_m
from flightrecon.methods import arms as A
from flightrecon.tracks import TrackColumns
from flightrecon.types import CleanFlight, FlightMeta, MethodResult, Position

__all__ = ["FORMS", "ArmsSettings", "run_arms"]

FORMS = ("joint", "cascade")
"""Estimator forms: the joint model (product default) or the paper's two-stage cascade."""


RANGE_MODES = ("auto", "elevation", "altitude", "slant")
"""Horizontal range from the slant range: with the elevation angle, with the altitude
difference, ``auto`` (elevation where the plot has one, else altitude), or ``slant`` (none)."""


@dataclass(frozen=True)
class ArmsSettings:
    """Settings of the ADS/ARMS method (units in the names; defaults: the paper's radar).

    Attributes
    ----------
    sigma_range_m, sigma_azimuth_deg : radar range and azimuth standard deviations (paper: 50 m,
        0.25 deg)
    q_m2ps3 : CV acceleration power spectral density (0.5 m^2/s^3: velocity random walk of
        0.7 m/s per sqrt(s), enough for transport-category manoeuvres between 1-Hz air data)
    gm_sigma_mps, gm_tau_s : air-data error Gauss-Markov sd and correlation time (paper: 20 m/s,
        360 s)
    sigma_air_mps : white noise on each V* component (TAS and heading noise)
    v0_sd_mps : prior sd of the ground velocity at the first plot
    air_rate_hz : rate at which the joint form uses air-data samples (grid samples, each once);
        ``None``: every grid sample
    output_rate_hz : the joint form also steps (without a measurement) through the grid times
        thinned to this rate, so its output there is exact; grid samples in between are
        linearly interpolated (output only).  ``None``: every grid sample (exact everywhere;
        memory ~2 kB per step, 1.3 GB for 10 h at 16 Hz, hence the 4 Hz default)
    air_max_gap_s : the cascade takes no air data at a plot inside a longer air-data gap
    converted_at : ``predicted`` or ``measured`` (converted-measurement covariance point)
    horizontal_range : one of :data:`RANGE_MODES`
    outage_factor : a plot interval longer than this times the median interval is an outage
    smooth : smoothed (True) or forward-only (False) output
    """

    sigma_range_m: float = 50.0
    sigma_azimuth_deg: float = 0.25
    q_m2ps3: float = 0.5
    gm_sigma_mps: float = 20.0
    gm_tau_s: float = 360.0
    sigma_air_mps: float = 0.5
    v0_sd_mps: float = 300.0
    air_rate_hz: float | None = 1.0
    output_rate_hz: float | None = 4.0
    air_max_gap_s: float = 2.0
    converted_at: str = "predicted"
    horizontal_range: str = "auto"
    outage_factor: float = 3.0
    smooth: bool = True

    def model(self) -> A.ArmsModel:
        """The estimators' noise model (SI, radians)."""
        return A.ArmsModel(sigma_range_m=self.sigma_range_m,
                           sigma_azimuth_rad=float(np.deg2rad(self.sigma_azimuth_deg)),
                           q_m2ps3=self.q_m2ps3, gm_sigma_mps=self.gm_sigma_mps,
                           gm_tau_s=self.gm_tau_s, sigma_air_mps=self.sigma_air_mps,
                           v0_sd_mps=self.v0_sd_mps)


# --------------------------------------------------------------------------------------------
# frames
# --------------------------------------------------------------------------------------------

def station(meta: FlightMeta) -> Position:
    """The radar station's position.

    Raises
    ------
    MetadataError
        If the flight has no station position.
    """
    if meta.station is None:
        raise MetadataError("radar plots but no station position: give --station LAT,LON,ELEV_M "
                            "or a sidecar [station] table")
    return meta.station


def station_plane(meta: FlightMeta) -> TangentPlane:
    """East-north-up tangent plane at the radar station (ellipsoidal height of its MSL elevation).

    Raises
    ------
    MetadataError
        If the flight has no station position.
    """
    s = station(meta)
    return TangentPlane(s.lat_deg, s.lon_deg,
                        float(msl_to_ellipsoid(s.elev_m, meta.geoid_undulation_m)))


def _north_convergence(plane: TangentPlane, x_m, y_m, u_m) -> np.ndarray:
    """Azimuth [rad] of true north at points (x, y, u) of ``plane``, measured in the plane."""
    lat, lon, _ = plane.inverse(x_m, y_m, u_m)
    return north_azimuth_in_plane(plane.lat0_deg, plane.lon0_deg, lat, lon)


def _to_output(src: TangentPlane, dst: TangentPlane, x, y, u):
    """Map points of ``src`` to ``dst``: (east, north) and the 2x2 Jacobian (K, 2, 2) of the
    horizontal mapping (finite difference over 100 m; the mapping is affine to 1e-9 over that),
    and the points' up in ``dst`` with their (lat, lon, ellipsoidal height)."""
    step = 100.0
    xs = np.concatenate([x, x + step, x])
    ys = np.concatenate([y, y, y + step])
    us = np.concatenate([u, u, u])
    lat, lon, h = src.inverse(xs, ys, us)
    e, n, up = dst.forward(lat, lon, h)
    K = len(x)
    e0, e1, e2 = e[:K], e[K:2 * K], e[2 * K:]
    n0, n1, n2 = n[:K], n[K:2 * K], n[2 * K:]
    J = np.empty((K, 2, 2))
    J[:, 0, 0] = (e1 - e0) / step
    J[:, 0, 1] = (e2 - e0) / step
    J[:, 1, 0] = (n1 - n0) / step
    J[:, 1, 1] = (n2 - n0) / step
    return e0, n0, J, up[:K], (lat[:K], lon[:K], h[:K])


# --------------------------------------------------------------------------------------------
# inputs
# --------------------------------------------------------------------------------------------

def _grid_valid(grid: pd.DataFrame, cols: tuple[str, ...]) -> np.ndarray:
    ok = np.ones(len(grid), dtype=bool)
    for c in cols:
        if c not in grid.columns:
            raise SchemaError("the ARMS method needs this grid channel", column=c)
        ok &= np.isfinite(grid[c].to_numpy(dtype=np.float64))
        if f"{c}_valid" in grid.columns:
            ok &= grid[f"{c}_valid"].to_numpy(dtype=bool)
    return ok


def _plots(clean: CleanFlight, s: ArmsSettings, model: A.ArmsModel,
           alt_fn) -> tuple[A.RadarPlots, dict]:
    radar = clean.radar
    for c in ("t_s", "arms_range_m", "arms_azimuth_deg"):
        if c not in radar.columns:
            raise SchemaError("radar plots lack a required column", column=c)
    t = radar["t_s"].to_numpy(dtype=np.float64)
    rho = radar["arms_range_m"].to_numpy(dtype=np.float64)
    az = radar["arms_azimuth_deg"].to_numpy(dtype=np.float64)
    keep = np.isfinite(t) & np.isfinite(rho) & np.isfinite(az)
    dropped = int((~keep).sum())
    t, rho, az = t[keep], rho[keep], az[keep]
    el = (radar["arms_elevation_deg"].to_numpy(dtype=np.float64)[keep]
          if "arms_elevation_deg" in radar.columns else np.full(len(t), np.nan))
    mode = s.horizontal_range
    if mode not in RANGE_MODES:
        raise ValidationError(f"unknown horizontal-range mode '{mode}'; choose from "
                              f"{', '.join(RANGE_MODES)}")
    if mode == "elevation" and not np.isfinite(el).all():
        raise ValidationError("horizontal_range='elevation' but some plots have no elevation",
                              column="arms_elevation_deg")
    use_el = np.isfinite(el) if mode in ("auto", "elevation") else np.zeros(len(t), dtype=bool)
    r = rho.copy()
    sig_r = np.full(len(t), model.sigma_range_m)
    if use_el.any():
        r[use_el] = horizontal_range(rho[use_el], lat_deg=station(clean.meta).lat_deg,
                                     elevation_deg=el[use_el])
    use_alt = ~use_el if mode in ("auto", "altitude") else np.zeros(len(t), dtype=bool)
    if use_alt.any():
        dh = alt_fn(t[use_alt])
        if not np.isfinite(dh).all():
            raise ValidationError("no valid pressure altitude at some radar plot times (needed for "
                                  "the horizontal range); use horizontal_range='slant' or "
                                  "'elevation'", column="baro_alt_m")
        r[use_alt] = horizontal_range(rho[use_alt], lat_deg=station(clean.meta).lat_deg, dh_m=dh)
        # dr/drho = rho / r at fixed height: the range error grows with the slant angle
        sig_r[use_alt] = model.sigma_range_m * rho[use_alt] / r[use_alt]
    plots = A.RadarPlots.from_arrays(t, r, np.deg2rad(az), model, sigma_range_m=sig_r)
    info = {"plots_in": len(radar), "plots_dropped_nonfinite": dropped,
            "plots_with_elevation_range": int(use_el.sum()),
            "plots_with_altitude_range": int(use_alt.sum())}
    return plots, info


def _thin(t: np.ndarray, rate_hz: float | None, name: str) -> np.ndarray:
    """Mask keeping the first sample in each ``1 / rate_hz`` bin of time (all if ``None``)."""
    if rate_hz is None:
        return np.ones(len(t), dtype=bool)
    if not (np.isfinite(rate_hz) and rate_hz > 0):
        raise ValidationError(f"{name} must be positive or None, got {rate_hz}")
    b = np.floor(t * rate_hz + 1e-9)
    return np.concatenate([[True], np.diff(b) > 0])


def _outages(t: np.ndarray, factor: float) -> list[list[float]]:
    d = np.diff(t)
    nominal = float(np.median(d))
    idx = np.flatnonzero(d > factor * nominal)
    return [[float(t[i]), float(t[i + 1])] for i in idx]


# --------------------------------------------------------------------------------------------
# the adapter
# --------------------------------------------------------------------------------------------

def run_arms(clean: CleanFlight, *, form: str = "joint", linearisation: str = "ekf",
             settings: ArmsSettings = ArmsSettings()) -> MethodResult:
    """Ground track, ground velocity and air-data error from radar plots and air data.

    docs/arms.md.  ``form="joint"`` runs the joint model
    (:func:`flightrecon.methods.arms.run_joint_model`), ``"cascade"`` the paper's two stages
    (:func:`flightrecon.methods.arms.run_cascade`); ``linearisation`` is ``"ekf"`` or
    ``"converted"``.

    Parameters
    ----------
    clean : cleaned flight; ``clean.radar`` has ``t_s``, ``arms_range_m`` (slant),
        ``arms_azimuth_deg`` and optionally ``arms_elevation_deg``; ``clean.grid`` has ``t_s``,
        ``tas_mps``, ``heading_deg`` (true, unwrapped) and ``baro_alt_m``; ``clean.meta`` has
        ``station`` and ``departure``.
    form, linearisation : see above
    settings : :class:`ArmsSettings`

    Returns
    -------
    MethodResult
        ``track`` on the grid times with ``arms_north_m``, ``arms_east_m``, ``arms_vn_mps``,
        ``arms_ve_mps`` (ground velocity), ``arms_dvn_mps``, ``arms_dve_mps`` (air-data error:
        wind plus sensor error, ``V* - W``), ``arms_air_vn_mps``, ``arms_air_ve_mps``
        (``V* - dV_hat``), each with its ``_sd_`` column; positions in the output tangent
        plane, vectors in local north/east at the aircraft (module docstring); NaN
        outside the radar coverage.  ``summary``: form, linearisation, plots used, outages,
        normalised innovation statistics, settings.

    Raises
    ------
    MetadataError
        No station or departure position.
    SchemaError
        A required radar or grid column is missing.
    ValidationError
        Unknown form / linearisation / mode, fewer than two usable plots, inconsistent times.
    """
    if form not in FORMS:
        raise ValidationError(f"unknown ARMS form '{form}'; choose from {', '.join(FORMS)}")
    if linearisation not in A.LINEARISATIONS:
        raise ValidationError(f"unknown ARMS linearisation '{linearisation}'; choose from "
                              f"{', '.join(A.LINEARISATIONS)}")
    meta = clean.meta
    splane = station_plane(meta)
    oplane = output_plane(meta)
    model = settings.model()
    tg = clean.grid["t_s"].to_numpy(dtype=np.float64)
    dh_at = _height_above_station(clean)
    plots, info = _plots(clean, settings, model, dh_at)
    ta, air_all = _air_data(clean, plots, splane, dh_at)
    run, radar_used, air_used, nu, S = _filter(form, linearisation, settings, model, plots,
                                               ta, air_all, tg)
    est = A.estimate_of(run, smoothed=settings.smooth)
    track, inside, dh_k, dvo = _grid_track(clean, est, plots.t_s, splane, oplane, dh_at,
                                           air_all, model, settings)
    summary = {
        "method": "ADS/ARMS (docs/arms.md)",
        "form": form,
        "linearisation": linearisation,
        "converted_at": settings.converted_at if linearisation == "converted" else None,
        "smoothed": settings.smooth,
        "frame": "station east-north-up tangent plane; output: tangent plane at departure",
        "plots_used": radar_used,
        **info,
        "air_samples_used": air_used,
        **_diagnostics(plots.t_s, nu, S, track, inside, dh_k, dvo, settings),
        "settings": asdict(settings),
    }
    return MethodResult("arms", track, summary)


def _height_above_station(clean: CleanFlight) -> Callable[[np.ndarray], np.ndarray]:
    """``dh_at(t)``: the pressure altitude (as MSL height with the departure QNH) minus the
    station's elevation [m] at times ``t``, interpolated over the valid grid samples; NaN
    outside them or without any."""
    grid, meta = clean.grid, clean.meta
    tg = grid["t_s"].to_numpy(dtype=np.float64)
    ok_alt = _grid_valid(grid, ("baro_alt_m",))
    st_elev = station(meta).elev_m
    h_msl = pressure_to_msl_m(grid["baro_alt_m"].to_numpy(dtype=np.float64), meta.qnh_departure_hpa)

    def dh_at(t):
        return np.interp(t, tg[ok_alt], h_msl[ok_alt] - st_elev, left=np.nan, right=np.nan) \
            if ok_alt.any() else np.full(np.shape(t), np.nan)

    return dh_at


def _air_data(clean: CleanFlight, plots: A.RadarPlots, splane, dh_at
              ) -> tuple[np.ndarray, A.AirData]:
    """The valid air-data samples (times, and TAS/heading as a vector) with the heading rotated
    into the station plane by the meridian convergence at the radar track."""
    grid, meta = clean.grid, clean.meta
    tg = grid["t_s"].to_numpy(dtype=np.float64)
    tp = plots.t_s
    ok_air = _grid_valid(grid, ("tas_mps", "heading_deg"))
    ta = tg[ok_air]
    if len(ta) < 2:
        raise ValidationError("fewer than two valid air-data samples (tas_mps, heading_deg)")
    conv = A.converted_measurement(plots.range_m, plots.azimuth_rad)
    xa = np.interp(ta, tp, conv[:, 0])
    ya = np.interp(ta, tp, conv[:, 1])
    ua = np.nan_to_num(dh_at(ta)) - plane_drop_m(np.hypot(xa, ya), station(meta).lat_deg)
    gamma = _north_convergence(splane, xa, ya, ua)
    hdg = grid["heading_deg"].to_numpy(dtype=np.float64)[ok_air] + np.rad2deg(gamma)
    air_all = A.AirData.from_tas_heading(ta, grid["tas_mps"].to_numpy(dtype=np.float64)[ok_air],
                                         hdg)
    return ta, air_all


def _filter(form: str, linearisation: str, settings: ArmsSettings, model: A.ArmsModel,
            plots: A.RadarPlots, ta: np.ndarray, air_all: A.AirData, tg: np.ndarray
            ) -> tuple[A.ArmsRun | A.CascadeResult, int, int, np.ndarray, np.ndarray]:
    """Run the joint model or the cascade; returns the run, the radar plots and air-data
    samples used, and the forward innovations ``nu`` (K, 4) with their covariances ``S``
    (radar block first, air data second)."""
    if form == "joint":
        sel = _thin(ta, settings.air_rate_hz, "air_rate_hz")
        air = A.AirData(ta[sel], air_all.vx_mps[sel], air_all.vy_mps[sel])
        jr = A.run_joint_model(plots, air, model, linearisation=linearisation,
                               converted_at=settings.converted_at, smooth=settings.smooth,
                               extra_times=tg[_thin(tg, settings.output_rate_hz,
                                                    "output_rate_hz")])
        d = jr.filt.diagnostics
        return jr, int(d["radar_used"].sum()) + 1, int(d["air_used"].sum()), d["nu"], d["S"]
    cr = A.run_cascade(plots, air_all, model, linearisation=linearisation,
                       converted_at=settings.converted_at, smooth=settings.smooth,
                       air_max_gap_s=settings.air_max_gap_s)
    d1, d2 = cr.stage1.filt.diagnostics, cr.stage2.filt.diagnostics
    radar_used = int(d1["radar_used"].sum()) + 1
    air_used = int(d2["n_meas"].astype(bool).sum())
    nu = np.concatenate([d1["nu"][:, :2], d2["nu"]], axis=1)
    S = np.full((len(plots.t_s), 4, 4), np.nan)
    S[:, :2, :2] = d1["S"][:, :2, :2]
    S[:, 2:, 2:] = d2["S"]
    return cr, radar_used, air_used, nu, S


def _grid_track(clean: CleanFlight, est, tp: np.ndarray, splane, oplane, dh_at,
                air_all: A.AirData, model, settings: ArmsSettings):
    """The estimate on the grid times inside the radar coverage (output only), station plane
    to output plane: the track columns, the coverage mask, the height above the station
    there and the air-data error in local north/east axes."""
    meta = clean.meta
    tg = clean.grid["t_s"].to_numpy(dtype=np.float64)
    inside = (tg >= tp[0]) & (tg <= tp[-1])
    tk = tg[inside]

    def interp(a):
        return np.column_stack([np.interp(tk, est.t_s, a[:, i]) for i in range(a.shape[1])])

    def interp_cov(P):
        flat = P.reshape(len(P), -1)
        return interp(flat).reshape(-1, 2, 2)

    pos = interp(est.pos)
    vel = interp(est.vel)
    dv = interp(est.dv)
    Cp, Cv, Cd = interp_cov(est.pos_cov), interp_cov(est.vel_cov), interp_cov(est.dv_cov)
    dh_k = dh_at(tk)
    uk = np.nan_to_num(dh_k) - plane_drop_m(np.hypot(pos[:, 0], pos[:, 1]),
                                           station(meta).lat_deg)
    east, north, J, up, geodetic = _to_output(splane, oplane, pos[:, 0], pos[:, 1], uk)
    Vs = air_all.at(tk, max_gap_s=settings.air_max_gap_s)
    airv = Vs - dv
    Ca = Cd + model.sigma_air_mps ** 2 * np.eye(2)

    # vectors to local north/east at the aircraft: azimuth_local = azimuth_station - gamma
    gk = _north_convergence(splane, pos[:, 0], pos[:, 1], uk)
    Rl = np.empty((len(tk), 2, 2))
    Rl[:, 0, 0] = Rl[:, 1, 1] = np.cos(gk)
    Rl[:, 0, 1] = -np.sin(gk)
    Rl[:, 1, 0] = np.sin(gk)

    # station-plane (east, north) vectors: positions through the map to the output plane
    # (its Jacobian J rotates their covariance), velocities into the local level (Rl)
    out = TrackColumns("arms", tg, inside)
    out.add_horizontal("north", "east", "m", np.c_[east, north], Cp, J, order="en",
                       value_is_output=True)
    out.add_horizontal("vn", "ve", "mps", vel, Cv, Rl, order="en")
    out.add_horizontal("dvn", "dve", "mps", dv, Cd, Rl, order="en")
    out.add_horizontal("air_vn", "air_ve", "mps", airv, Ca, Rl, order="en")
    # the height: the pressure altitude's above the station (0 where it has none: no alt_m)
    fin = np.isfinite(dh_k)
    out.add_place(oplane, east, north, up=np.where(fin, up, np.nan),
                  geodetic=(geodetic[0], geodetic[1], np.where(fin, geodetic[2], np.nan)))
    return out.frame(), inside, dh_k, np.einsum("kij,kj->ki", Rl, dv)


def _diagnostics(tp: np.ndarray, nu: np.ndarray, S: np.ndarray, track: pd.DataFrame,
                 inside: np.ndarray, dh_k: np.ndarray, dvo: np.ndarray,
                 settings: ArmsSettings) -> dict[str, Any]:
    """The summary's coverage, outages, innovation statistics, health and warnings."""
    nis_r = _nis_block(nu[:, :2], S[:, :2, :2])
    nis_a = _nis_block(nu[:, 2:], S[:, 2:, 2:])
    n_r, n_a = int(np.isfinite(nis_r).sum()), int(np.isfinite(nis_a).sum())
    verdict = chi_square_verdict(np.r_[nis_r, nis_a], 2.0)  # both blocks are 2-dimensional
    nis_per_component = verdict.mean if verdict.count else 0.0
    outs = _outages(tp, settings.outage_factor)
    warnings: list[str] = []
    if not np.isfinite(dh_k).all():
        warnings.append("no pressure altitude at the start or end of the radar coverage: there "
                        "the aircraft's height above the station is taken as 0 for the frame "
                        "conversion (horizontal error ~ height x tilt between the planes)")
    finite = bool(np.isfinite(track.loc[inside, "arms_north_m"]).all())
    healthy = finite
    if verdict.gross:
        healthy = False
        warnings.append(f"mean NIS per measurement component {nis_per_component:.1f} (expected "
                        "1): the noise settings or the motion model do not fit this flight")
    if not finite:
        warnings.append("non-finite ARMS estimates")
    return {
        "coverage_s": [float(tp[0]), float(tp[-1])],
        "median_plot_interval_s": float(np.median(np.diff(tp))),
        "outages": len(outs),
        "outage_intervals_s": outs[:50],
        "longest_outage_s": float(max((b - a for a, b in outs), default=0.0)),
        "radar_nis_mean": float(np.nanmean(nis_r)) if n_r else None,
        "air_nis_mean": float(np.nanmean(nis_a)) if n_a else None,
        "nis_note": "forward-filter NIS; radar and air-data blocks expect 2 each, "
                    "mean_nis_per_component expects 1",
        "mean_nis_per_component": nis_per_component,
        "consistency": verdict.as_dict(),
        "dv_mean_mps": {"north": float(np.mean(dvo[:, 1])), "east": float(np.mean(dvo[:, 0]))},
        "healthy": healthy,
        "warnings": warnings,
    }


def _nis_block(nu: np.ndarray, S: np.ndarray) -> np.ndarray:
    """NIS of one measurement block per step (NaN where the block is absent)."""
    ok = np.isfinite(nu).all(axis=1)
    out = np.full(len(nu), np.nan)
    if ok.any():
        L = np.linalg.cholesky(S[ok])
        w = np.linalg.solve(L, nu[ok][..., None])[..., 0]
        out[ok] = np.einsum("ki,ki->k", w, w)
    return out
