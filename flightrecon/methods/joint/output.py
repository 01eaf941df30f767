"""The joint smoother's output: the track on the input grid (positions by cubic Hermite
interpolation of the states, their sd in the local level frame, each sample's sources:
:func:`joint_track`) and the summary (:func:`joint_summary`: the run, the checks of
:func:`~flightrecon.methods.joint.health.run_health`, the known positions' offsets from the track,
the winds-aloft prior used; docs/output.md, "The summary JSON"; docs/joint.md, "Outputs")."""

from __future__ import annotations

from dataclasses import asdict
from typing import Any

import numba as nb
import numpy as np
import pandas as pd

from flightrecon.geo.frames import TangentPlane, ecef_to_geodetic
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.health import RunHealth
from flightrecon.methods.joint.problem import JointProblem, OutputFrame
from flightrecon.methods.joint.settings import SOURCES
from flightrecon.methods.joint.solve import JointRun
from flightrecon.tracks import TrackColumns

PREFIX = "joint_"


@nb.njit(cache=True, nogil=True)
def near_any(t_out, tm, window):
    """For sorted ``t_out`` and sorted ``tm``: is some tm within +-window of each t_out? One
    merge-like pass, O(len(t_out) + len(tm)) (the searchsorted of numpy is ten times slower on
    a 10-hour 16 Hz grid)."""
    out = np.zeros(t_out.shape[0], dtype=np.bool_)
    j = 0
    m = tm.shape[0]
    for i in range(t_out.shape[0]):
        t = t_out[i]
        while j < m and tm[j] < t - window:
            j += 1
        out[i] = j < m and tm[j] <= t + window
    return out


def provenance(run: JointRun, t_out: np.ndarray, window_s: float = 5.0) -> np.ndarray:
    """Per output sample, the sources with a measurement within +-window_s ('+'-joined)."""
    code = np.zeros(len(t_out), dtype=np.int64)
    for s_i, name in enumerate(SOURCES):
        tm = np.sort(run.meas.t[run.meas.source == s_i])
        if len(tm) == 0:
            continue
        near = near_any(t_out, tm, window_s if name != "endpoint" else 60.0)
        code |= near.astype(np.int64) << s_i
    present = np.flatnonzero(np.bincount(code, minlength=1 << len(SOURCES)))
    lookup = np.zeros(1 << len(SOURCES), dtype=np.int64)
    lookup[present] = np.arange(len(present))
    names = np.array(["+".join(n for i, n in enumerate(SOURCES) if c >> i & 1) for c in present],
                     dtype=object)
    return names[lookup[code]]


def joint_track(t_out: np.ndarray, plane: TangentPlane, run: JointRun,
                remaining_k_m: np.ndarray | None = None) -> pd.DataFrame:
    """The smoothed trajectory at the times ``t_out`` (the input grid's), in the output conventions
    (prefix joint_) on the output tangent ``plane``.  ``remaining_k_m`` (per state): the movement a
    run stopped short of convergence still had ahead
    (:func:`~flightrecon.methods.joint.health.settling`), added in quadrature to the north, east and
    up sd: its direction is unknown, so each axis takes the whole of it."""
    T = run.t
    x = run.x
    sources = provenance(run, t_out)

    def interp(v):
        return np.interp(t_out, T, v)

    def pos_sd(axis):
        sd = interp(sd_pos[:, axis])
        return sd if remaining_k_m is None else np.hypot(sd, interp(remaining_k_m))

    ecef = run.positions_ecef(t_out)
    lat, lon, h = ecef_to_geodetic(ecef[:, 0], ecef[:, 1], ecef[:, 2])
    e, n, u = plane.forward(lat, lon, h)
    C = run.Cen
    # ECEF -> local NED (P_pv holds the position and velocity blocks, in that order)
    Pp = np.einsum("kji,kjl,klm->kim", C, run.P_pv[:, 0:3, 0:3], C)
    sd_pos = np.sqrt(np.maximum(np.einsum("kii->ki", Pp), 0.0))
    sd_vel = np.sqrt(np.maximum(run.var[:, jl.S_VEL], 0.0))
    sd_w = np.sqrt(np.maximum(run.var[:, jl.S_WIND], 0.0))
    # through the one builder (flightrecon/tracks.py): the plane position, its up, latitude,
    # longitude and ellipsoidal height from the smoother's own earth-fixed position
    out = TrackColumns(PREFIX.rstrip("_"), t_out)
    out.add("north", "m", n, pos_sd(0))
    out.add("east", "m", e, pos_sd(1))
    out.add_place(plane, e, n, up=u, up_sd=pos_sd(2), geodetic=(lat, lon, h))
    out.add("vn", "mps", interp(x[:, jl.IV]), interp(sd_vel[:, 0]))
    out.add("ve", "mps", interp(x[:, jl.IV + 1]), interp(sd_vel[:, 1]))
    out.add("vu", "mps", -interp(x[:, jl.IV + 2]), interp(sd_vel[:, 2]))
    out.add("wind_n", "mps", interp(x[:, jl.IW]), interp(sd_w[:, 0]))
    out.add("wind_e", "mps", interp(x[:, jl.IW + 1]), interp(sd_w[:, 1]))
    out.add_text("sources", sources)
    return out.frame()


def fix_report(frame: OutputFrame, track: pd.DataFrame) -> list[dict[str, Any]]:
    """Per known position (``--fix``): the smoothed track's offset from it at its time, north and
    east [m], with the fix's sd and the track's sd there; ``used`` False (and no offsets) for a fix
    outside the reconstructed span (a record trimmed with ``--start`` / ``--end``)."""
    t = track["t_s"].to_numpy(float)
    out: list[dict[str, Any]] = []

    def at(column: str, t_s: float) -> float:
        return float(np.interp(t_s, t, track[PREFIX + column].to_numpy(float)))

    for f in frame.fixes:
        fix = {"t_s": f.t_s, "lat_deg": f.lat_deg, "lon_deg": f.lon_deg, "alt_msl_m": f.alt_msl_m,
               "sd_m": f.sd_m}
        if not t[0] <= f.t_s <= t[-1]:
            out.append({**fix, "used": False})
            continue
        # the fix at the track's height where it has none (the tangent plane's north and east
        # of a point move with its height: 1.6 m per km of height at 10 km from the origin)
        h = at("alt_m", f.t_s) if f.alt_msl_m is None else f.alt_msl_m + frame.geoid_undulation_m
        e, n, _u = frame.plane.forward(f.lat_deg, f.lon_deg, h)
        out.append({**fix, "used": True, "track_minus_fix_north_m": at("north_m", f.t_s) - float(n),
                    "track_minus_fix_east_m": at("east_m", f.t_s) - float(e),
                    "track_north_sd_m": at("north_sd_m", f.t_s),
                    "track_east_sd_m": at("east_sd_m", f.t_s)})
    return out


def wind_prior_report(problem: JointProblem) -> dict[str, Any] | None:
    """Which winds-aloft prior the smoother used (docs/wind.md): its levels, the pseudo-measurements
    (those of the measurement table's static part, :attr:`OutputFrame.wind_prior`) and their sd."""
    frame = problem.frame
    if problem.inputs.wind_aloft is None or frame is None:
        return None
    tw, _w, sd, rho = frame.wind_prior
    lv = frame.wind_levels
    return {"levels": len(lv), "alt_msl_m": [lv[0].alt_msl_m, lv[-1].alt_msl_m],
            "correlation_s_m_spacing": list(problem.settings.wind_prior),
            "pseudo_measurements": len(tw), "t_s": [float(x) for x in tw],
            "sd_mps": [float(x) for x in sd], "rho": [float(x) for x in rho]}


def joint_summary(problem: JointProblem, run: JointRun, track: pd.DataFrame, health: RunHealth, *,
                  wind_rounds: list[dict[str, Any]],
                  gap_calibration: dict[str, Any] | None) -> dict[str, Any]:
    """The joint smoother's summary, the pipeline's ``methods.joint`` (docs/output.md, "The summary
    JSON"; docs/joint.md, "Outputs"): the run's and the problem's figures, the checks of ``health``
    (:func:`~flightrecon.methods.joint.health.run_health`), the calibrations' reports
    (``wind_rounds``, ``gap_calibration``), the known positions against ``track``
    (:func:`fix_report`) and the winds-aloft prior (:func:`wind_prior_report`); ``settling`` last,
    for a run stopped short of the convergence test (the pipeline's status ``stopped`` reads it)."""
    settings, frame = problem.settings, problem.frame
    return {
        "healthy": health.healthy,
        "consistency": health.consistency.as_dict(),
        "converged": health.converged,
        "stop_reason": run.stop_reason,
        "cholesky_fallbacks": run.cholesky_fallbacks,
        "iterations": run.iterations,
        "gust": run.gust,
        "wind_walk": {"wind_rw_mps_sqrt_s": settings.noise.wind_rw_mps_sqrt_s,
                      "rounds": wind_rounds},
        "gap_calibration": gap_calibration,
        "state_rate_hz": settings.state_rate_hz,
        "attitude_tilt": {"source": None if frame is None else frame.attitude_source,
                          "gain_mps2_per_g": settings.noise.ahrs_tilt_mps2_per_g,
                          "gnss_evidence": problem.tilt_evidence},
        "corrections": health.corrections,
        "clock_offsets_s": {k: {"value": o, "sd": sd}
                            for k, (o, sd) in run.clock_offsets_s.items()},
        "noise_scale": run.noise_scale,
        "noise_check": run.noise_check,
        "end_points": [{"which": e.which, "model": e.model, "t_s": e.t_s,
                        "lat_deg": e.point[0], "lon_deg": e.point[1],
                        "runway_true_deg": (None if e.runway_rad is None
                                            else float(np.degrees(e.runway_rad) % 360.0)),
                        "sd_m": list(e.sd_m),
                        **({"flare": asdict(e.flare)} if e.flare is not None else {})}
                       for e in run.end_points],
        "takeoff_roll": {"start_t_s": run.roll.start_t, "rest_t_s": list(run.roll.rest_t)},
        "fixes": [] if frame is None else fix_report(frame, track),
        "wind_prior": wind_prior_report(problem),
        "sources": health.sources,
        "settings": asdict(settings),
        "chosen_settings": [asdict(c) for c in problem.choices],
        "warnings": health.warnings,
        **({} if health.settling is None else {"settling": health.settling}),
    }
