"""Heading from the body rates where the heading channel is missing or dead.

Flight-test exports often record the body rates ``p_dps, q_dps, r_dps`` (roll, pitch, yaw rate,
FRD body axes) and roll and pitch, but no heading, or a heading that is dead (constant).  The
heading is then propagated from the rates by rotating the recorded attitude with them
(:func:`flightrecon.geo.kinematics.heading_increments`: exact at any attitude, through pitch
+-90 deg), which away from the vertical is the Euler kinematics of the ZYX (yaw-pitch-roll)
attitude (docs/schema.md, "Conventions")::

    psi_dot = (q sin(phi) + r cos(phi)) / cos(theta)

with the recorded roll phi and pitch theta.  Gyro biases b_q, b_r (constant over the record)
make the heading error linear in three unknowns::

    psi_true(t) = psi_int(t) + psi0 - b_q Q(t) - b_r R(t),
    Q(t) = int sin(phi) / cos(theta) dt,   R(t) = int cos(phi) / cos(theta) dt,

``psi_int`` the integral of the measured rates from the first sample.  ``(psi0, b_q, b_r)`` is
estimated by (Gauss-Newton) least squares, with a zero-mean prior on each bias
(``BIAS_PRIOR_DPS``, 0.02 deg/s), from whatever anchors the flight has:

* **runway direction** (``runway_true_deg`` of the departure / arrival in the metadata): the
  mean heading over the take-off roll (roll start to lift-off) and over the landing roll (from
  touchdown while the airspeed is above 20 m/s) equals the runway's direction, sd
  ``RUNWAY_SD_DEG`` (1 deg: aligned with the centre line, crab and nose-wheel steering);
* **GNSS track, wind triangle**: each GNSS velocity fix while airborne (TAS above 30 m/s) gives
  ``v_gnss = TAS (cos psi, sin psi) + wind``; the wind is the recorded wind channel where the
  log has one, else an unknown constant per ``WIND_SEGMENT_S`` (600 s) segment estimated with the
  heading (separable from ``psi0`` in turns, like the heading bias and the wind of SNS);
  velocity sd ``GNSS_TRIANGLE_SD_MPS`` (2 m/s: GNSS velocity noise, airspeed error, wind change
  within a segment).

With no anchor at all the heading has no absolute reference: refused (docs/signals.md).  The
uncertainty grows away from the anchors: ``sd(t)^2 = J(t) C J(t)^T + sigma_arw^2 d(t)`` with
``C`` the covariance of the estimate (scaled by the fit's residual variance when above 1),
``J(t) = [1, -Q(t), -R(t)]`` and ``d(t)`` the time to the nearest anchor, ``sigma_arw`` the
rate noise's angle random walk (the sd of the rates' high-pass residual times sqrt(dt)); with
the GNSS track as anchor a floor of ``TRIANGLE_FLOOR_DEG`` (0.5 deg) is added in quadrature
(sideslip, airspeed scale error).  The
grid gets ``heading_deg`` (unwrapped, like a recorded heading) and ``heading_sd_deg``; the report
says which anchors were used and the estimated biases.
"""

from __future__ import annotations

import warnings
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.cleaning.report import report_entry
from flightrecon.errors import FlightReconWarning, ValidationError
from flightrecon.geo.kinematics import heading_increments
from flightrecon.types import FlightMeta, FlightPhases

__all__ = ["heading_from_rates", "heading_needed", "provisional_heading", "rate_aided_attitude"]

RUNWAY_SD_DEG = 1.0
#: prior sd of each gyro bias (a tactical-grade rate gyro: 0.02 deg/s = 72 deg/h)
BIAS_PRIOR_DPS = 0.02
GNSS_TRIANGLE_SD_MPS = 2.0
#: floor of the heading sd where it rests on the wind triangle: sideslip, the airspeed's scale
#: error (2 % is 1.1 deg of heading error across the wind in a turn) and the wind's change
#: within a segment are systematic and not in the fit's residual scaling
TRIANGLE_FLOOR_DEG = 0.5
WIND_SEGMENT_S = 600.0
MIN_AIR_TAS_MPS = 30.0
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


def heading_needed(grid: pd.DataFrame) -> str | None:
    """Why the heading must come from the rates (``None``: the recorded heading is usable)."""
    if not {"q_dps", "r_dps", "roll_deg", "pitch_deg"} <= set(grid.columns):
        return None
    if "heading_deg" not in grid.columns:
        return "no heading channel"
    h = grid["heading_deg"].to_numpy(float)
    ok = np.isfinite(h)
    if ok.mean() < 0.5:
        return f"heading missing on {100 * (1 - ok.mean()):.0f} % of the grid"
    if np.nanmax(h) - np.nanmin(h) < 1e-6:
        return "heading never changes (a dead channel)"
    return None


def _filled(grid: pd.DataFrame, name: str) -> np.ndarray:
    v = grid[name].to_numpy(float).copy()
    bad = ~np.isfinite(v)
    if bad.all():
        raise ValidationError(f"heading from the rates needs {name}", column=name)
    if bad.any():
        idx = np.arange(len(v))
        v[bad] = np.interp(idx[bad], idx[~bad], v[~bad])
    return v


def _integrals(grid: pd.DataFrame) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``t``, ``psi_int`` [rad], ``Q``, ``R`` [s] (trapezoidal, zero at the first sample)."""
    t = grid["t_s"].to_numpy(float)
    phi = np.radians(_filled(grid, "roll_deg"))
    th = np.radians(np.clip(_filled(grid, "pitch_deg"), -85.0, 85.0))
    q = np.radians(_filled(grid, "q_dps"))
    r = np.radians(_filled(grid, "r_dps"))
    sq, sr = np.sin(phi) / np.cos(th), np.cos(phi) / np.cos(th)
    dt = np.diff(t)

    def cum(x):
        out = np.zeros(len(x))
        out[1:] = np.cumsum(0.5 * (x[1:] + x[:-1]) * dt)
        return out

    # the heading itself by rotating the attitude with the rates (exact through the vertical;
    # the bias sensitivities Q, R keep the Euler form with the pitch clipped)
    has_p = "p_dps" in grid.columns and bool(grid["p_dps"].notna().any())
    p_dps = _filled(grid, "p_dps") if has_p else np.zeros(len(t))   # second order only
    psi = np.zeros(len(t))
    psi[1:] = np.cumsum(heading_increments(t, _filled(grid, "roll_deg"),
                                           _filled(grid, "pitch_deg"), p_dps,
                                           np.degrees(q), np.degrees(r)))
    return t, psi, cum(sq), cum(sr)


def provisional_heading(grid: pd.DataFrame) -> np.ndarray:
    """The heading integrated from the rates from 0 deg at the first sample [deg] (for the
    phase detector, whose lift-off rule needs only the vertical; the anchors come after)."""
    _, psi, _, _ = _integrals(grid)
    return np.degrees(psi)


def _roll_window(t, tas, phases: FlightPhases | None, which: str):
    if phases is None:
        return None
    if which == "departure":
        t0 = phases.roll_start_t_s if np.isfinite(phases.roll_start_t_s) else phases.liftoff_t_s - 20
        t1 = phases.liftoff_t_s
    else:
        t0 = phases.touchdown_t_s
        slow = np.flatnonzero((t > t0) & (tas < 20.0))
        t1 = t[slow[0]] if len(slow) else t0 + 20.0
    if not (np.isfinite(t0) and np.isfinite(t1)) or t1 <= t0:
        return None
    sel = (t >= t0) & (t <= t1)
    return sel if sel.sum() >= 3 else None


def heading_from_rates(grid: pd.DataFrame, gnss: pd.DataFrame, meta: FlightMeta,
                       phases: FlightPhases | None, why: str,
                       trimmed: pd.DataFrame | None = None) -> tuple[pd.DataFrame, list[dict]]:
    """The grid with ``heading_deg`` (and ``heading_valid``) from the rates and
    ``heading_sd_deg``; the report entry (module docstring).

    ``trimmed`` is the part of the record that ``--start`` / ``--end`` cut away (raw canonical
    rows): a standstill there still measures the gyro biases (:func:`standstill`).

    Raises
    ------
    ValidationError
        No anchor for the heading (no runway direction in the metadata, no GNSS velocity).
    """
    t, psi_int, Q, R = _integrals(grid)
    tas = _filled(grid, "tas_mps") if "tas_mps" in grid.columns else np.zeros(len(t))
    rows_psi, used, anchor_t = _runway_anchors(meta, t, tas, phases)
    tri = _gnss_triangle(grid, gnss, t, tas, psi_int, Q, R, used, anchor_t)
    rest_row = _standstill_rows(grid, t, tas, phases, psi_int, Q, R, trimmed)
    if not rows_psi and tri is None:
        raise ValidationError(f"{why}: the heading can be propagated from the body rates, but the "
                              "flight has nothing to anchor it (give the departure's "
                              "runway_true_deg in the sidecar, or a log with GNSS velocity)",
                              column="heading_deg")
    n_w = 0 if tri is None or tri["wind"] is not None else int(tri["seg"].max()) + 1
    npar = 3 + 2 * n_w

    def residuals(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        r_, J_ = _anchor_residuals(x, npar, rows_psi, tri, psi_int, Q, R)
        if rest_row is None:
            return r_, J_
        dpsi, dq, dr, sd, _ = rest_row
        row = np.zeros(npar)
        row[1], row[2] = -dq / sd, -dr / sd
        return (np.r_[r_, (dpsi - x[1] * dq - x[2] * dr) / sd], np.vstack([J_, row[None, :]]))

    x, s2, Cfull = _fit_offset_and_biases(residuals, npar)
    psi = psi_int + x[0] - x[1] * Q - x[2] * R
    sd = _heading_sd(t, psi_int, Q, R, Cfull, anchor_t, tri is not None)
    rolls = [{"which": which, "runway_true_deg": float(np.degrees(val) % 360.0),
              "t_s": [float(t[w > 0][0]), float(t[w > 0][-1])],
              "residual_deg": float(np.degrees(np.angle(np.exp(1j * (np.sum(w * psi) - val)))))}
             for w, val, _, which in rows_psi]
    extra: dict[str, Any] = {"runway_rolls": rolls}
    # the Euler kinematics integrate the heading against a fixed direction: without the
    # transport rate (dlambda/dt sin phi) it stays referred to the anchor's meridian, i.e. the
    # grid north of the departure's tangent plane (docs/signals.md, "Heading from the body
    # rates"); a GNSS track anchors it to the local north along the flight instead
    extra["heading_reference"] = ("grid" if tri is None and rows_psi else "true")
    calibrated = _standstill_calibration(rest_row, x, Cfull, used, extra)
    _announce_heading(why, used, rolls, calibrated, t, sd)
    g = grid.copy()
    g["heading_deg"] = np.degrees(psi)
    g["heading_valid"] = True
    g["heading_sd_deg"] = sd
    rep = report_entry(
        "heading_deg", "heading_from_rates",
        f"{why}: heading propagated from the body rates (psi_dot = (q sin phi + r cos phi) / "
        f"cos theta) and anchored by {'; '.join(used)}", count=len(t),
        gyro_bias_q_dps=float(np.degrees(x[1])), gyro_bias_r_dps=float(np.degrees(x[2])),
        gyro_bias_sd_dps=float(np.degrees(np.sqrt(max(Cfull[2, 2], 0.0)))),
        heading_sd_median_deg=float(np.median(sd)), heading_sd_max_deg=float(np.max(sd)),
        fit_rms=float(np.sqrt(s2)))
    rep.update(extra)
    return g, [rep]


def _standstill_calibration(rest_row: tuple | None, x: np.ndarray, Cfull: np.ndarray,
                            used: list[str], extra: dict[str, Any]) -> str:
    """With a standstill in the fit: its anchor named in ``used``, its length and yaw rate in
    ``extra``, and the text saying the gyro biases were calibrated there ("" without one)."""
    if rest_row is None:
        return ""
    t_rest = rest_row[4]
    used.append(f"the gyro biases at rest on the ground ({t_rest:.0f} s)")
    extra.update(standstill_s=t_rest,
                 standstill_yaw_rate_dps=float(np.degrees(rest_row[0]
                                                          / max(rest_row[2], 1e-9))))
    return (f"; gyro biases calibrated on {t_rest:.0f} s at rest on the ground "
            f"(yaw-rate bias {np.degrees(x[2]):+.4f} deg/s, sd "
            f"{np.degrees(np.sqrt(max(Cfull[2, 2], 0.0))):.4f})")


def _announce_heading(why: str, used: list[str], rolls: list[dict], calibrated: str,
                      t: np.ndarray, sd: np.ndarray) -> None:
    """Warn that the heading is no measurement but an integral whose error grows away from its
    anchors (docs/signals.md, "Heading from the body rates"); raised at the caller of
    :func:`heading_from_rates`."""
    aligned = "; ".join(f"the {r['which']} roll aligned with runway {r['runway_true_deg']:.1f} "
                        f"deg (mean heading over it {r['residual_deg']:+.2f} deg off after the "
                        f"fit)" for r in rolls)
    warnings.warn(
        f"heading from the body rates ({why}): anchored by {'; '.join(used)}"
        + (f"; {aligned}" if aligned else "") + calibrated
        + f"; its sd grows away from the anchors: {float(np.min(sd)):.1f} deg at them, "
        f"median {float(np.median(sd)):.1f}, at most {float(np.max(sd)):.1f} deg "
        f"(t = {float(t[int(np.argmax(sd))]):.0f} s)", FlightReconWarning, stacklevel=3)


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


def _standstill_rows(grid: pd.DataFrame, t: np.ndarray, tas: np.ndarray,
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
            tp, psi_p, Q_p, R_p = _integrals(piece)
            tas_p = (_filled(piece, "tas_mps") if "tas_mps" in piece.columns
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


_Anchor = tuple[np.ndarray, float, float, str]   # (weights over the grid, value, sd, which)


def _convergence_rad(meta: FlightMeta, pos: Any) -> float:
    """Meridian convergence ``gamma = dlambda sin(phi)`` [rad] at ``pos`` against the departure's
    meridian (mean latitude): a true bearing ``psi`` there is the grid bearing ``psi - gamma``
    of the departure's tangent plane, the frame in which the rates propagate the heading
    (module docstring); 0 at the departure and at an arrival on the same field."""
    dep = meta.departure
    if dep is None or pos is dep:
        return 0.0
    dlon = np.radians((pos.lon_deg - dep.lon_deg + 180.0) % 360.0 - 180.0)
    return float(dlon * np.sin(np.radians(0.5 * (pos.lat_deg + dep.lat_deg))))


def _runway_anchors(meta: FlightMeta, t: np.ndarray, tas: np.ndarray,
                    phases: FlightPhases | None) -> tuple[list[_Anchor], list[str], list[float]]:
    """Runway rolls as anchors (mean heading over the roll = the runway direction): the rows,
    what was used (for the report) and the anchors' time spans."""
    rows_psi: list[_Anchor] = []
    used: list[str] = []
    anchor_t: list[float] = []
    for which in ("departure", "arrival"):
        pos = getattr(meta, which)
        if pos is None or pos.runway_true_deg is None:
            continue
        sel = _roll_window(t, tas, phases, which)
        if sel is None:
            continue
        w = sel / sel.sum()
        rows_psi.append((w, float(np.radians(pos.runway_true_deg)) - _convergence_rad(meta, pos),
                         np.radians(RUNWAY_SD_DEG), which))
        used.append(f"{which} runway {pos.runway_true_deg:g} deg")
        anchor_t += [float(t[sel][0]), float(t[sel][-1])]
    return rows_psi, used, anchor_t


def _gnss_triangle(grid: pd.DataFrame, gnss: pd.DataFrame, t: np.ndarray, tas: np.ndarray,
                   psi_int: np.ndarray, Q: np.ndarray, R: np.ndarray, used: list[str],
                   anchor_t: list[float]) -> dict[str, Any] | None:
    """GNSS velocity fixes while airborne as anchors through the wind triangle (recorded wind,
    or one wind per :data:`WIND_SEGMENT_S`); ``None`` with fewer than 10 usable fixes.  What
    was used is appended to ``used`` and the fix times to ``anchor_t``."""
    if not (len(gnss) and {"gnss_vn_mps", "gnss_ve_mps"} <= set(gnss.columns)):
        return None
    tg = gnss["t_s"].to_numpy(float)
    vn, ve = gnss["gnss_vn_mps"].to_numpy(float), gnss["gnss_ve_mps"].to_numpy(float)
    inside = (tg >= t[0]) & (tg <= t[-1]) & np.isfinite(vn) & np.isfinite(ve)
    V = np.interp(tg, t, tas)
    ok = inside & (V > MIN_AIR_TAS_MPS)
    if ok.sum() < 10:
        return None
    tg, vn, ve, V = tg[ok], vn[ok], ve[ok], V[ok]
    wind = None
    if {"wind_speed_mps", "wind_from_deg"} <= set(grid.columns):
        ws = np.interp(tg, t, _filled(grid, "wind_speed_mps"))
        to = np.radians(np.interp(tg, t, _filled(grid, "wind_from_deg")) + 180.0)
        wind = np.c_[ws * np.cos(to), ws * np.sin(to)]
    seg = np.floor((tg - tg[0]) / WIND_SEGMENT_S).astype(int)
    used.append(f"GNSS track: {int(ok.sum())} velocity fixes"
                + (" with the recorded wind" if wind is not None else
                   f", wind estimated per {WIND_SEGMENT_S:g} s"))
    anchor_t += list(tg)
    return {"t": tg, "vn": vn, "ve": ve, "V": V, "wind": wind, "seg": seg,
            "pi": np.interp(tg, t, psi_int), "Q": np.interp(tg, t, Q), "R": np.interp(tg, t, R)}


def _anchor_residuals(x: np.ndarray, npar: int, rows_psi: list[_Anchor],
                      tri: dict[str, Any] | None, psi_int: np.ndarray, Q: np.ndarray,
                      R: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weighted residuals and Jacobian of the anchors for ``x = (offset, q bias, r bias,
    winds...)``: the biases' zero-mean prior, the runway rolls, the GNSS wind triangle."""
    res, J = [], []
    # prior of the gyro biases (zero mean): the biases stay defined with one anchor
    sb = np.radians(BIAS_PRIOR_DPS)
    for i in (1, 2):
        row = np.zeros(npar)
        row[i] = 1.0 / sb
        res.append(np.array([x[i] / sb]))
        J.append(row[None, :])
    for w, val, sd, _ in rows_psi:
        psi_m = np.sum(w * (psi_int + x[0] - x[1] * Q - x[2] * R))
        d = np.angle(np.exp(1j * (psi_m - val)))
        row = np.zeros(npar)
        row[0], row[1], row[2] = 1.0, -np.sum(w * Q), -np.sum(w * R)
        res.append(np.array([d / sd]))
        J.append(row[None, :] / sd)
    if tri is not None:
        psi = tri["pi"] + x[0] - x[1] * tri["Q"] - x[2] * tri["R"]
        if tri["wind"] is not None:
            wn, we = tri["wind"][:, 0], tri["wind"][:, 1]
        else:
            wn = x[3 + 2 * tri["seg"]]
            we = x[4 + 2 * tri["seg"]]
        c, s = np.cos(psi), np.sin(psi)
        sdv = GNSS_TRIANGLE_SD_MPS
        rn = (tri["V"] * c + wn - tri["vn"]) / sdv
        re = (tri["V"] * s + we - tri["ve"]) / sdv
        m = len(psi)
        Jn, Je = np.zeros((m, npar)), np.zeros((m, npar))
        dpsi = np.c_[np.ones(m), -tri["Q"], -tri["R"]]
        Jn[:, :3] = (-tri["V"] * s)[:, None] * dpsi / sdv
        Je[:, :3] = (tri["V"] * c)[:, None] * dpsi / sdv
        if tri["wind"] is None:
            Jn[np.arange(m), 3 + 2 * tri["seg"]] = 1.0 / sdv
            Je[np.arange(m), 4 + 2 * tri["seg"]] = 1.0 / sdv
        res += [rn, re]
        J += [Jn, Je]
    return np.concatenate(res), np.vstack(J)


def _fit_offset_and_biases(residuals, npar: int) -> tuple[np.ndarray, float, np.ndarray]:
    """Gauss-Newton on the anchors from the best start of a coarse search of the offset (every
    15 deg, biases held at zero, winds solved); returns ``x``, the residual variance factor
    ``s2`` and the covariance of ``x`` (scaled by ``max(s2, 1)``)."""
    best = None
    for psi0 in np.radians(np.arange(0.0, 360.0, 15.0)):
        x = np.zeros(npar)
        x[0] = psi0
        for _ in range(3):
            r_, J_ = residuals(x)
            # biases kept at zero in the search: only psi0 and the winds move
            cols = [0] + list(range(3, npar))
            dx, *_ = np.linalg.lstsq(J_[:, cols], -r_, rcond=None)
            x[cols] += dx
        cost = float(np.sum(residuals(x)[0] ** 2))
        if best is None or cost < best[0]:
            best = (cost, x.copy())
    assert best is not None  # the loop above runs at least once
    x = best[1]
    free = list(range(npar))
    for _ in range(20):
        r_, J_ = residuals(x)
        dx, *_ = np.linalg.lstsq(J_[:, free], -r_, rcond=None)
        x[free] += dx
        if np.max(np.abs(dx)) < 1e-9:
            break
    r_, J_ = residuals(x)
    dof = max(len(r_) - len(free), 1)
    s2 = float(np.sum(r_ ** 2) / dof)
    Jf = J_[:, free]
    C = np.linalg.pinv(Jf.T @ Jf) * max(s2, 1.0)
    Cfull = np.zeros((npar, npar))
    Cfull[np.ix_(free, free)] = C
    return x, s2, Cfull


def _heading_sd(t: np.ndarray, psi_int: np.ndarray, Q: np.ndarray, R: np.ndarray,
                Cfull: np.ndarray, anchor_t: list[float], triangle: bool) -> np.ndarray:
    """Heading sd [deg]: the fitted offset and biases, plus the angle random walk of the rate
    noise with the distance in time to the nearest anchor, plus the triangle's floor."""
    Jt = np.c_[np.ones(len(t)), -Q, -R]
    var = np.einsum("ij,jk,ik->i", Jt, Cfull[:3, :3], Jt)
    # angle random walk of the rate noise away from the anchors
    rate = np.gradient(psi_int, t)
    k = max(int(round(2.0 / max(np.median(np.diff(t)), 1e-9))), 3)
    smooth = pd.Series(rate).rolling(k, center=True, min_periods=1).mean().to_numpy()
    dt = float(np.median(np.diff(t)))
    arw2 = float(np.var(rate - smooth)) * dt
    at = np.sort(np.asarray(anchor_t, float))
    j = np.clip(np.searchsorted(at, t), 1, len(at) - 1) if len(at) > 1 else np.zeros(len(t), int)
    dist = (np.minimum(np.abs(t - at[j - 1]), np.abs(t - at[j])) if len(at) > 1
            else np.abs(t - at[0]))
    floor = np.radians(TRIANGLE_FLOOR_DEG) ** 2 if triangle else 0.0
    return np.degrees(np.sqrt(var + arw2 * dist + floor))


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
