"""The joint smoother's output track on the input grid: positions by cubic Hermite
interpolation of the states, their sd in the local level frame, and each sample's sources."""

from __future__ import annotations

import numba as nb
import numpy as np
import pandas as pd

from flightrecon.geo.frames import TangentPlane, ecef_to_geodetic
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.settings import SOURCES
from flightrecon.methods.joint.state import JointRun
from flightrecon.tracks import TrackColumns

PREFIX = "joint_"


@nb.njit(cache=True, nogil=True)
def near_any(t_out, tm, window):
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


def hermite_positions(t_out: np.ndarray, T: np.ndarray, p: np.ndarray, v: np.ndarray
                       ) -> np.ndarray:
    """Cubic Hermite interpolation of positions ``p`` (N, 3) with their velocities ``v`` (N, 3)
    from the state times ``T`` to ``t_out`` (error O(dt^4) instead of the a dt^2 / 8 of linear
    interpolation: 0.6 m in a 25-degree turn at a 1 s state step)."""
    if len(T) < 2:
        return np.repeat(p[:1], len(t_out), axis=0)
    return hermite_kernel(np.asarray(t_out, float), np.asarray(T, float),
                           np.ascontiguousarray(p, dtype=float),
                           np.ascontiguousarray(v, dtype=float))


@nb.njit(cache=True, nogil=True)
def hermite_kernel(t_out, T, p, v):
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


def joint_track(t_out: np.ndarray, plane: TangentPlane, run: JointRun) -> pd.DataFrame:
    """The smoothed trajectory at the times ``t_out`` (the input grid's), in the output
    conventions (prefix joint_) on the output tangent ``plane``."""
    T = run.t
    x = run.x

    def interp(v):
        return np.interp(t_out, T, v)

    ecef = hermite_positions(t_out, T, x[:, jl.S_POS],
                              np.einsum("kij,kj->ki", run.Cen, x[:, jl.S_VEL]))
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
    out.add("north", "m", n, interp(sd_pos[:, 0]))
    out.add("east", "m", e, interp(sd_pos[:, 1]))
    out.add_place(plane, e, n, up=u, up_sd=interp(sd_pos[:, 2]), geodetic=(lat, lon, h))
    out.add("vn", "mps", interp(x[:, jl.IV]), interp(sd_vel[:, 0]))
    out.add("ve", "mps", interp(x[:, jl.IV + 1]), interp(sd_vel[:, 1]))
    out.add("vu", "mps", -interp(x[:, jl.IV + 2]), interp(sd_vel[:, 2]))
    out.add("wind_n", "mps", interp(x[:, jl.IW]), interp(sd_w[:, 0]))
    out.add("wind_e", "mps", interp(x[:, jl.IW + 1]), interp(sd_w[:, 1]))
    track = out.frame()
    track[PREFIX + "sources"] = pd.array(provenance(run, t_out), dtype="string")
    return track
