"""The heading integrated from the body rates, with its sensitivities to the gyro biases.

``psi_int`` rotates the recorded attitude with the rates from the first sample
(:func:`flightrecon.geo.kinematics.heading_increments`, exact at any attitude), and ``Q``, ``R``
integrate ``sin(phi) / cos(theta)`` and ``cos(phi) / cos(theta)``: the heading error of constant
biases ``b_q``, ``b_r`` is ``-b_q Q(t) - b_r R(t)`` (:mod:`flightrecon.cleaning.attitude`, whose
anchors fit them; :mod:`flightrecon.cleaning.standstill`, where they are measured at rest).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from flightrecon.errors import ValidationError
from flightrecon.geo.kinematics import heading_increments


def gap_filled(grid: pd.DataFrame, name: str) -> np.ndarray:
    v = grid[name].to_numpy(float).copy()
    bad = ~np.isfinite(v)
    if bad.all():
        raise ValidationError(f"heading from the rates needs {name}", column=name)
    if bad.any():
        idx = np.arange(len(v))
        v[bad] = np.interp(idx[bad], idx[~bad], v[~bad])
    return v


def heading_integrals(grid: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``t``, ``psi_int`` [rad], ``Q``, ``R`` [s] (trapezoidal, zero at the first sample)."""
    t = grid["t_s"].to_numpy(float)
    phi = np.radians(gap_filled(grid, "roll_deg"))
    th = np.radians(np.clip(gap_filled(grid, "pitch_deg"), -85.0, 85.0))
    q = np.radians(gap_filled(grid, "q_dps"))
    r = np.radians(gap_filled(grid, "r_dps"))
    sq, sr = np.sin(phi) / np.cos(th), np.cos(phi) / np.cos(th)
    dt = np.diff(t)

    def cum(x):
        out = np.zeros(len(x))
        out[1:] = np.cumsum(0.5 * (x[1:] + x[:-1]) * dt)
        return out

    # the heading itself by rotating the attitude with the rates (exact through the vertical;
    # the bias sensitivities Q, R keep the Euler form with the pitch clipped)
    has_p = "p_dps" in grid.columns and bool(grid["p_dps"].notna().any())
    p_dps = gap_filled(grid, "p_dps") if has_p else np.zeros(len(t))   # second order only
    psi = np.zeros(len(t))
    psi[1:] = np.cumsum(heading_increments(t, gap_filled(grid, "roll_deg"),
                                           gap_filled(grid, "pitch_deg"), p_dps,
                                           np.degrees(q), np.degrees(r)))
    return t, psi, cum(sq), cum(sr)


def provisional_heading(grid: pd.DataFrame) -> np.ndarray:
    """The heading integrated from the rates from 0 deg at the first sample [deg] (for the
    phase detector, whose lift-off rule needs only the vertical; the anchors come after)."""
    _, psi, _, _ = heading_integrals(grid)
    return np.degrees(psi)
