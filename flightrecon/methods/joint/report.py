"""What the joint smoother's summary reports of a run: its sensor corrections with their
priors, the known positions' offsets from the track, the winds-aloft prior used."""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd

from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.measurements import wind_prior_measurements
from flightrecon.methods.joint.problem import JointProblem, OutputFrame
from flightrecon.methods.joint.settings import JointSettings, prior_of
from flightrecon.methods.joint.state import JointRun
from flightrecon.methods.joint.track import PREFIX


def corrections_at_middle(run: JointRun, settings: JointSettings | None = None) -> dict[str, Any]:
    """Estimated sensor errors (value and sd at the middle of the record) with the prior each
    was given (``prior_mean``, ``prior_sd``, same unit)."""
    k = len(run.t) // 2
    x, v = run.x[k], run.var[k]

    def item(i, scale=1.0, unit=""):
        return {"value": float(x[i] * scale), "sd": float(np.sqrt(max(v[i], 0.0)) * scale),
                "unit": unit}

    out = correction_items(item)
    for name, it in out.items():
        it["prior_mean"], it["prior_sd"] = prior_of(name, settings or JointSettings())
    return out


def correction_items(item) -> dict[str, Any]:
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


def fix_report(frame: OutputFrame, track: pd.DataFrame) -> list[dict[str, Any]]:
    """Per known position (``--fix``): the smoothed track's offset from it at its time, north
    and east [m], with the fix's sd and the track's sd there; ``used`` False (and no offsets)
    for a fix outside the reconstructed span (a record trimmed with ``--start`` / ``--end``)."""
    if not frame.fixes:
        return []
    plane = frame.plane
    t = track["t_s"].to_numpy(float)
    p = PREFIX
    out: list[dict[str, Any]] = []
    h_tr = track[p + "alt_m"].to_numpy(float)
    for f in frame.fixes:
        if not t[0] <= f.t_s <= t[-1]:
            out.append({"t_s": f.t_s, "lat_deg": f.lat_deg, "lon_deg": f.lon_deg,
                        "alt_msl_m": f.alt_msl_m, "sd_m": f.sd_m, "used": False})
            continue
        # the fix at the track's height where it has none (the tangent plane's north and east
        # of a point move with its height: 1.6 m per km of height at 10 km from the origin)
        h = (float(np.interp(f.t_s, t, h_tr)) if f.alt_msl_m is None
             else f.alt_msl_m + frame.geoid_undulation_m)
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


def wind_prior_report(problem: JointProblem) -> dict[str, Any] | None:
    """Which winds-aloft prior the smoother used (docs/wind.md): its levels, the
    pseudo-measurements and their sd."""
    inp, settings = problem.inputs, problem.settings
    if inp.wind_aloft is None or problem.frame is None:
        return None
    tw, _w, sd, rho = wind_prior_measurements(inp, settings)
    lv = problem.frame.wind_levels
    return {"levels": len(lv), "alt_msl_m": [lv[0].alt_msl_m, lv[-1].alt_msl_m],
            "correlation_s_m_spacing": list(settings.wind_prior),
            "pseudo_measurements": len(tw), "t_s": [float(x) for x in tw],
            "sd_mps": [float(x) for x in sd], "rho": [float(x) for x in rho]}
