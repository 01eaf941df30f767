"""Where the aircraft stands still on the ground, and the gyro biases measured there.

At rest the heading does not change: the body rates integrated over the standstills (on the
grid, and in the part of the record that ``--start`` / ``--end`` cut away) equal the gyro biases
integrated, one anchor on the biases for the heading from the rates
(:mod:`flightrecon.cleaning.attitude`; docs/signals.md, "Heading from the body rates").
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from flightrecon.cleaning.rate_integrals import gap_filled, heading_integrals
from flightrecon.types import FlightPhases


#: at rest on the ground the heading does not change: the mean rates there are the gyro biases.
#: The airspeed at rest is the wind's (a headwind of 15 m/s reads 29 kt); below it the rates and
#: the loads tell standing from taxiing
STANDSTILL_TAS_MPS = 15.0
#: a standstill window: over ``STANDSTILL_WINDOW_S`` the yaw rate's mean within
#: ``STANDSTILL_MEAN_DPS`` of zero and its sd below ``STANDSTILL_SD_DPS``, the longitudinal and
#: lateral loads' sd below ``STANDSTILL_LOAD_SD_G`` (a taxiing aircraft turns, brakes, bumps)
STANDSTILL_WINDOW_S = 10.0
STANDSTILL_MEAN_DPS = 0.05
STANDSTILL_SD_DPS = 0.1
STANDSTILL_LOAD_SD_G = 0.003
#: standstills shorter than this in all are not used
STANDSTILL_MIN_S = 20.0
#: how far the gyro biases may move between the standstill and the flight (temperature, the
#: bias instability of a tactical-grade gyro over an hour: 7 deg/h)
STANDSTILL_BIAS_STABILITY_DPS = 0.002


def _rolling(x: np.ndarray, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Centred rolling mean and sd over ``k`` samples (NaN-tolerant, at least half present)."""
    r = pd.Series(x).rolling(k, center=True, min_periods=max(k // 2, 2))
    return r.mean().to_numpy(), r.std().to_numpy()


def standstill(grid: pd.DataFrame, t: np.ndarray, tas: np.ndarray,
               phases: FlightPhases | None, min_s: float = STANDSTILL_MIN_S) -> np.ndarray:
    """Where the aircraft stands still on the ground (boolean over the grid): outside the
    flight and the take-off roll, the airspeed below ``STANDSTILL_TAS_MPS``, and over
    ``STANDSTILL_WINDOW_S`` a yaw rate that is steady about zero and quiet longitudinal and
    lateral loads; fewer than ``min_s`` seconds in all count as none."""
    if "r_dps" not in grid.columns or len(t) < 3:
        return np.zeros(len(t), bool)
    dt = float(np.median(np.diff(t)))
    k = max(int(round(STANDSTILL_WINDOW_S / dt)), 3) if dt > 0 else 3
    r_mean, r_sd = _rolling(grid["r_dps"].to_numpy(float), k)
    ok = (np.abs(r_mean) < STANDSTILL_MEAN_DPS) & (r_sd < STANDSTILL_SD_DPS)
    for c in ("n_long_g", "n_lat_g"):
        if c in grid.columns:
            _, sd_c = _rolling(grid[c].to_numpy(float), k)
            ok &= sd_c < STANDSTILL_LOAD_SD_G
    ok &= ~(tas > STANDSTILL_TAS_MPS)
    if phases is not None:
        # a record that starts airborne (``--start`` after the lift-off) has neither
        first = min((v for v in (phases.roll_start_t_s, phases.liftoff_t_s) if np.isfinite(v)),
                    default=np.inf)
        ok &= ~((t >= first) & ~(t > phases.touchdown_t_s)) if np.isfinite(first) else ok
        if phases.starts_airborne:
            ok &= t > phases.touchdown_t_s
    ok &= np.isfinite(grid["r_dps"].to_numpy(float))
    if float(np.sum(np.diff(t, append=t[-1])[ok])) < min_s or not ok.any():
        return np.zeros(len(t), bool)
    return ok


def _rest_sums(grid: pd.DataFrame, t: np.ndarray, rest: np.ndarray, psi_int: np.ndarray,
               Q: np.ndarray, R: np.ndarray) -> np.ndarray:
    """Over the intervals with both ends at rest: the sums of ``dpsi_int``, ``dQ``, ``dR``, the
    time at rest and the rate noise's variance times the sample interval (its angle random
    walk per second)."""
    inc = rest[1:] & rest[:-1]
    if not inc.any():
        return np.zeros(5)
    r = np.radians(grid["r_dps"].to_numpy(float))
    dt = float(np.median(np.diff(t)))
    arw2 = float(np.nanvar(np.diff(r)[inc]) / 2.0) * dt
    return np.array([np.sum(np.diff(psi_int)[inc]), np.sum(np.diff(Q)[inc]),
                     np.sum(np.diff(R)[inc]), np.sum(np.diff(t)[inc]), arw2])


def standstill_rows(grid: pd.DataFrame, t: np.ndarray, tas: np.ndarray,
                     phases: FlightPhases | None, psi_int: np.ndarray, Q: np.ndarray,
                     R: np.ndarray, trimmed: pd.DataFrame | None
                     ) -> tuple[float, float, float, float, float] | None:
    """The standstills (on the grid, and in the part of the record trimmed away) as one anchor
    on the gyro biases: at rest the heading does not change, so the rates integrated there
    (``sum dpsi_int``) equal the biases integrated (``b_q sum dQ + b_r sum dR``).  Returns
    ``(sum dpsi_int, sum dQ, sum dR, sd, time at rest)`` [rad, s, s, rad, s], ``None`` with
    less than ``STANDSTILL_MIN_S`` at rest.  The sd is the rate noise's angle random walk over
    the time at rest and the biases' stability between the standstill and the flight
    (``STANDSTILL_BIAS_STABILITY_DPS``) times that time."""
    sums = _rest_sums(grid, t, standstill(grid, t, tas, phases, min_s=0.0), psi_int, Q, R)
    parts = [sums]
    if trimmed is not None and len(trimmed) > 2 and {"t_s", "r_dps", "roll_deg",
                                                     "pitch_deg"} <= set(trimmed.columns):
        tr = trimmed.sort_values("t_s").reset_index(drop=True)
        tr = tr[[c for c in tr.columns if c in ("t_s", "p_dps", "q_dps", "r_dps", "roll_deg",
                                                  "pitch_deg", "n_long_g", "n_lat_g",
                                                  "tas_mps")]]
        # the trimmed part may be two pieces (before the start, after the end): each alone
        t_tr = tr["t_s"].to_numpy(float)
        for piece in (tr[t_tr < t[0]], tr[t_tr > t[-1]]):
            piece = piece[np.isfinite(piece["r_dps"].to_numpy(float))].reset_index(drop=True)
            if len(piece) < 3 or not np.isfinite(piece["roll_deg"].to_numpy(float)).any():
                continue
            if "q_dps" not in piece.columns or not piece["q_dps"].notna().any():
                continue
            tp, psi_p, Q_p, R_p = heading_integrals(piece)
            tas_p = (gap_filled(piece, "tas_mps") if "tas_mps" in piece.columns
                     and piece["tas_mps"].notna().any() else np.zeros(len(tp)))
            rest_p = standstill(piece, tp, tas_p, None, min_s=0.0)
            parts.append(_rest_sums(piece, tp, rest_p, psi_p, Q_p, R_p))
    tot = np.sum(parts, axis=0)
    t_rest = float(tot[3])
    if t_rest < STANDSTILL_MIN_S:
        return None
    arw2 = max((float(p[4]) for p in parts if p[3] > 0), default=0.0)
    stab = np.radians(STANDSTILL_BIAS_STABILITY_DPS)
    sd = float(np.sqrt(arw2 * t_rest + (stab * t_rest) ** 2))
    return float(tot[0]), float(tot[1]), float(tot[2]), max(sd, 1e-12), t_rest
