"""Attitude between its samples shaped by the body rates (docs/signals.md, "Rates between
attitude samples"), where the rates are sampled faster than roll, pitch or heading."""

from __future__ import annotations

import numpy as np
import pandas as pd

from flightrecon.cleaning.report import report_entry


#: the body rates must be sampled at least this many times faster than an attitude channel
#: for the rate-aided interpolation of that channel
RATE_AID_RATIO = 1.5


def _euler_rates_dps(grid: pd.DataFrame) -> dict[str, np.ndarray]:
    """Euler-angle rates [deg/s] on the grid from the body rates and the (interpolated) roll and
    pitch: ZYX kinematics ``phi' = p + (q sin phi + r cos phi) tan theta``,
    ``theta' = q cos phi - r sin phi``, ``psi' = (q sin phi + r cos phi) / cos theta``.  NaN
    where a rate or an angle is missing."""
    phi = np.radians(grid["roll_deg"].to_numpy(float))
    th = np.radians(np.clip(grid["pitch_deg"].to_numpy(float), -85.0, 85.0))
    p, q, r = (grid[c].to_numpy(float) for c in ("p_dps", "q_dps", "r_dps"))
    a = q * np.sin(phi) + r * np.cos(phi)
    return {"roll_deg": p + a * np.tan(th), "pitch_deg": q * np.cos(phi) - r * np.sin(phi),
            "heading_deg": a / np.cos(th)}


def rate_aided_attitude(grid: pd.DataFrame, work: pd.DataFrame, max_gap_s: float
                        ) -> tuple[pd.DataFrame, list[dict]]:
    """Attitude between its samples shaped by the body rates (where both are recorded).

    Between two samples ``v_k`` (at ``t_k``) and ``v_k+1`` of an attitude channel sampled more
    slowly than the rates, the grid value is the rate integral from ``t_k`` with a linear
    correction that makes it end on ``v_k+1``::

        v(t) = v_k + (I(t) - I(t_k)) - f (v_k + I(t_k+1) - I(t_k) - v_k+1),
        f = (t - t_k) / (t_k+1 - t_k),   I = int of the Euler-angle rate

    exact at the samples (a measurement is never moved), and between them it follows the
    rates instead of a straight line; a gyro bias over one interval (b dt) is removed by the
    correction.  Intervals longer than ``max_gap_s``, with a missing rate, or outside the
    channel's samples keep the linear interpolation.  ``grid`` angles are unwrapped, as are
    ``work``'s (cleaning's UnwrapAngles step).
    """
    need = {"p_dps", "q_dps", "r_dps", "roll_deg", "pitch_deg"}
    if not need <= set(grid.columns) or not need <= set(work.columns):
        return grid, []
    tw = work["t_s"].to_numpy(float)
    tp = tw[work["q_dps"].notna().to_numpy()]
    if len(tp) < 3:
        return grid, []
    rate_period = float(np.median(np.diff(tp)))
    t = grid["t_s"].to_numpy(float)
    rates = _euler_rates_dps(grid)
    g = grid.copy()
    report: list[dict] = []
    for c in ("roll_deg", "pitch_deg", "heading_deg"):
        if c not in grid.columns or c not in work.columns:
            continue
        ok = work[c].notna().to_numpy()
        tc, vc = tw[ok], work[c].to_numpy(float)[ok]
        if len(tc) < 2:
            continue
        period = float(np.median(np.diff(tc)))
        if not period > RATE_AID_RATIO * rate_period:
            continue
        rate = rates[c]
        bad = ~np.isfinite(rate)
        I = np.zeros(len(t))
        rr = np.where(bad, 0.0, rate)
        I[1:] = np.cumsum(0.5 * (rr[1:] + rr[:-1]) * np.diff(t))
        nbad = np.cumsum(bad)
        Ic = np.interp(tc, t, I)
        k = np.clip(np.searchsorted(tc, t, side="right") - 1, 0, len(tc) - 2)
        t0, t1 = tc[k], tc[k + 1]
        j0 = np.clip(np.searchsorted(t, t0), 0, len(t) - 1)
        j1 = np.clip(np.searchsorted(t, t1), 0, len(t) - 1)
        inside = (t >= tc[0]) & (t <= tc[-1]) & ((t1 - t0) <= max_gap_s) \
            & (nbad[j1] - nbad[np.maximum(j0 - 1, 0)] == 0)
        if f"{c}_valid" in g.columns:
            inside &= g[f"{c}_valid"].to_numpy(bool)
        f = (t - t0) / np.maximum(t1 - t0, 1e-12)
        aided = vc[k] + (I - Ic[k]) - f * (vc[k] + Ic[k + 1] - Ic[k] - vc[k + 1])
        v = g[c].to_numpy(float).copy()
        change = np.where(inside, aided - v, 0.0)
        v[inside] = aided[inside]
        g[c] = v
        n = int(inside.sum())
        if n:
            report.append(report_entry(
                c, "rate_aided_interpolation",
                f"between its samples ({1 / period:.3g} Hz) shaped by the body rates "
                f"({1 / rate_period:.3g} Hz), corrected to end on each sample", count=n,
                rms_change_deg=float(np.sqrt(np.mean(change[inside] ** 2)))))
    return g, report
