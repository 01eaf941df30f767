"""The range tracker that gives the azimuth channel its horizontal range and range rate."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.estimation.discretise import constant_velocity
from flightrecon.estimation.kalman import kalman_filter, rts_smooth_run

# ---------------------------------------------------------------------------------------------
# Range tracker
# ---------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RangeTrack:
    """Smoothed horizontal range on the event times.

    ``r`` [m], ``r_dot`` [m/s] (N,), ``P`` (N, 2, 2) their smoothed covariance, ``nis`` the
    per-plot normalised innovation squared of the forward pass (NaN where no plot, and at the
    first plot, which is the prior).
    """

    r: np.ndarray
    r_dot: np.ndarray
    P: np.ndarray
    nis: np.ndarray


def track_range(t_s, r_meas_m, r_var_m2, *, q_range_m2ps3: float) -> RangeTrack:
    """Constant-velocity Kalman filter and RTS smoother on the horizontal range.

    Exact CV discretisation (docs/arms.md): ``F = [[1, T], [0, 1]]``,
    ``Q = q [[T^3/3, T^2/2], [T^2/2, T]]``; the generic kernels
    :func:`flightrecon.estimation.kalman.kalman_filter` and :func:`rts_smooth_run`.

    Parameters
    ----------
    t_s : (N,) strictly increasing event times [s]
    r_meas_m : (N,) horizontal range measurements [m], NaN where no plot (the first must be
        present: it initialises the range, and is used once, as the prior)
    r_var_m2 : (N,) their variances [m^2]
    q_range_m2ps3 : white range-acceleration spectral density [m^2/s^3]
    """
    t = np.asarray(t_s, dtype=np.float64)
    r_meas = np.asarray(r_meas_m, dtype=np.float64)
    if not np.isfinite(r_meas[0]):
        raise ValidationError("the range tracker must start at a radar plot")
    if not q_range_m2ps3 > 0:
        raise ValidationError(f"q_range_m2ps3 must be > 0, got {q_range_m2ps3}")
    F, Q = constant_velocity(np.diff(t, prepend=t[0]), q_range_m2ps3)
    # the first plot is the prior (range and its variance; initial velocity sd 300 m/s bounds
    # any aircraft's range rate in a terminal area); it is not used again as a measurement
    P0 = np.diag([float(r_var_m2[0]), 300.0**2])
    R = np.where(np.isfinite(r_meas), np.asarray(r_var_m2, float), 1.0)[:, None, None]
    z = r_meas.copy()
    z[0] = np.nan
    run = kalman_filter(np.array([r_meas[0], 0.0]), P0, F, Q, z[:, None],
                        np.array([[1.0, 0.0]]), R)
    sm = rts_smooth_run(run)
    return RangeTrack(sm.x[:, 0].copy(), sm.x[:, 1].copy(), sm.P, run.diagnostics["nis"])
