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
from flightrecon.estimation.filtering import FilterRun
from flightrecon.estimation.smoothing import SmoothedRun
from flightrecon.geo.frames import output_plane
from flightrecon.geo.navframe import north_azimuth_in_plane
from flightrecon.methods import sns as core
from flightrecon.methods.sns.inputs import (  # noqa: F401  (re-exported: tests, scripts)
    FORMS,
    GNSS_COLUMNS,
    MODELS,
    choose_model,
    filter_grid,
    gnss_fixes,
    held_readings,
    initial_state,
    lever_arm_at_fixes,
    lever_arm_ne,
    radii_with_height,
    readings,
    step_inputs,
)
from flightrecon.methods.sns.settings import SNS_NOISE_KEYS, sns_noise_with  # noqa: F401
from flightrecon.types import CleanFlight, MethodResult

HORIZONTAL_COLUMNS = ("sns_north_m", "sns_north_sd_m", "sns_east_m", "sns_east_sd_m",
                      "sns_vn_mps", "sns_vn_sd_mps", "sns_ve_mps", "sns_ve_sd_mps")
#: the track's columns, in order (:func:`sns_track`)
TRACK_COLUMNS = ("t_s", *HORIZONTAL_COLUMNS, "sns_up_m", "sns_lat_deg", "sns_lon_deg", "sns_alt_m")


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
    run: FilterRun
    smoothed: SmoothedRun
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
    noise : :class:`flightrecon.methods.sns.SnsNoise` (default :func:`~sns.default_noise`)

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

    fixes = gnss_fixes(clean, t, notes)
    h_grid = np.interp(t, fixes.tf, fixes.h)
    r = readings(grid, t, m, notes)
    fg = filter_grid(t, fixes.tf, filter_rate_hz, notes)
    inputs, flat, flon = step_inputs(clean, t, h_grid, fixes, fg, r)
    x0, P0 = initial_state(t, r, fixes, flat, flon, noise)
    try:
        run = core.sns_filter(inputs, x0, P0, noise, model=m, form=fm)
        sm = core.sns_smooth(run)
    except np.linalg.LinAlgError as exc:
        raise ConvergenceError(f"SNS filter/smoother failed: {exc} (a covariance became "
                               "singular: check the noise settings)") from exc

    # filter step of each recorder sample: idx = [0, dec, 2 dec, ...] (+ the last sample)
    N, idx, dec = len(fg.idx), fg.idx, fg.dec
    kq = np.minimum(np.arange(len(t)) // dec, N - 1)
    kq[-1] = N - 1
    IA, IU, IW = r.IA, r.IU, r.IW
    lat, lon, P_ne, v_ne, P_v = core.densify(
        m, sm.x, sm.P, kq, t, fg.tk, (IA, IU, IW), (IA[idx], IU[idx], IW[idx]), h_grid,
        (r.a, r.u, r.w), np.asarray(noise.sensor_sd, float))
    if fixes.n_dropped:
        notes.append(f"{fixes.n_dropped} GNSS fixes outside the recorder grid not used")
    if sm.cholesky_fallbacks:
        notes.append(f"{sm.cholesky_fallbacks} steps' predicted covariance failed its Cholesky "
                     "factorisation; their smoother gain came from a general solve")
    return SnsSolution(m, fm, noise, inputs, run, sm, idx, fixes.tf, fixes.n_dropped, lat, lon,
                       h_grid, P_ne, v_ne, P_v, tuple(notes))


GAMMA_STRIDE = 16  # recorder samples between pyproj evaluations of the meridian convergence
PLANE_BLOCK = 1 << 16  # recorder samples per block of :func:`plane_track`


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
    M = len(sol.lat)
    sub = np.arange(0, M, GAMMA_STRIDE)
    if sub[-1] != M - 1:
        sub = np.append(sub, M - 1)
    gam_sub = north_azimuth_in_plane(plane.lat0_deg, plane.lon0_deg, np.rad2deg(sol.lat[sub]),
                                     np.rad2deg(sol.lon[sub]))
    # cos and sin interpolated directly: the chord of the unit circle over one interval
    # (gamma changes by < 1e-5 rad) is shorter than the arc by < 1e-11 relative
    cos_sub, sin_sub = np.cos(gam_sub), np.sin(gam_sub)
    if out is None:
        out = np.empty((4, M))
    # block by block: every operation is per sample, so the blocks give the same numbers as
    # one pass, without a dozen temporaries of the whole flight's length (a 10-hour flight at
    # 16 Hz: 4.6 MB each) beside the estimator running on the other thread
    for a in range(0, M, PLANE_BLOCK):
        b = min(a + PLANE_BLOCK, M)
        e, n, _ = plane.forward(np.rad2deg(sol.lat[a:b]), np.rad2deg(sol.lon[a:b]), sol.h[a:b])
        pos = np.arange(a, b, dtype=float)
        cg = np.interp(pos, sub, cos_sub)
        sg = np.interp(pos, sub, sin_sub)
        P = sol.P_ne[a:b]
        pnn, pne, pee = P[:, 0, 0], 0.5 * (P[:, 0, 1] + P[:, 1, 0]), P[:, 1, 1]
        cs2 = 2.0 * cg * sg * pne
        out[0, a:b] = n
        out[1, a:b] = e
        np.sqrt(cg * cg * pnn - cs2 + sg * sg * pee, out=out[2, a:b])
        np.sqrt(sg * sg * pnn + cs2 + cg * cg * pee, out=out[3, a:b])
    return {"north_m": out[0], "east_m": out[1], "north_sd_m": out[2], "east_sd_m": out[3]}


def sns_track(sol: SnsSolution, plane, t: np.ndarray) -> pd.DataFrame:
    """The track's columns through the one builder (:class:`flightrecon.tracks.TrackColumns`):
    the plane position and its sd (:func:`plane_track`), its up, latitude, longitude and
    ellipsoidal height (the smoother's own latitude and longitude; its height is the GNSS
    height, or the pressure altitude's where a fix has none, that the filter was given), and the
    local-level velocity with its sd."""
    from flightrecon.tracks import TrackColumns

    pt = plane_track(sol, plane)
    lat, lon = np.rad2deg(sol.lat), np.rad2deg(sol.lon)
    _, _, up = plane.forward(lat, lon, sol.h)
    out = TrackColumns("sns", t)
    out.add("north", "m", pt["north_m"], pt["north_sd_m"])
    out.add("east", "m", pt["east_m"], pt["east_sd_m"])
    out.add("vn", "mps", sol.v_ne[:, 0], np.sqrt(sol.P_v[:, 0, 0]))
    out.add("ve", "mps", sol.v_ne[:, 1], np.sqrt(sol.P_v[:, 1, 1]))
    out.add_place(plane, pt["east_m"], pt["north_m"], up=up, geodetic=(lat, lon, sol.h))
    return out.frame()


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



def run_sns(clean: CleanFlight, *, model: str = "auto", form: str = "consistent",
            filter_rate_hz: float = 2.0, noise: core.SnsNoise | None = None,
            noise_overrides: dict[str, float] | None = None) -> MethodResult:
    """Dead reckoning fused with SNS, smoothed, on the recorder grid (docs/sns.md).

    Parameters are those of :func:`solve_sns`; ``noise_overrides`` (:func:`sns_noise_with`)
    change the default noise of the chosen model where ``noise`` is not given.

    Returns
    -------
    MethodResult
        ``name="sns"``; track columns :data:`TRACK_COLUMNS`: ``sns_north_m``, ``sns_east_m``
        (output tangent plane) with their sd, ``sns_vn_mps``, ``sns_ve_mps`` (true
        north/east) with their sd, ``sns_up_m``, ``sns_lat_deg``, ``sns_lon_deg``,
        ``sns_alt_m`` (as the default's columns); summary with model, form, corrections
        and their standard deviations, fixes used, GNSS gaps, innovation statistics.
    """
    if noise is None and noise_overrides:
        noise = sns_noise_with(choose_model(clean.grid, model), noise_overrides)
    sol = solve_sns(clean, model=model, form=form, filter_rate_hz=filter_rate_hz, noise=noise)
    plane = output_plane(clean.meta)
    t = clean.grid["t_s"].to_numpy(float)
    track = sns_track(sol, plane, t)
    # NIS per fix with the rank of its innovation covariance as degrees of freedom
    verdict = chi_square_verdict(sol.run.diagnostics["nis"], sol.run.diagnostics["rank"])
    nis_ratio = verdict.mean
    finite = bool(np.isfinite(track[list(HORIZONTAL_COLUMNS)].to_numpy()).all())
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
