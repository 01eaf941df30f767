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

from flightrecon.cleaning.rate_integrals import gap_filled, heading_integrals
from flightrecon.cleaning.report import report_entry
from flightrecon.cleaning.standstill import standstill_rows
from flightrecon.errors import FlightReconWarning, ValidationError
from flightrecon.types import FlightMeta, FlightPhases

__all__ = ["heading_from_rates", "heading_needed"]

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
    t, psi_int, Q, R = heading_integrals(grid)
    tas = gap_filled(grid, "tas_mps") if "tas_mps" in grid.columns else np.zeros(len(t))
    rows_psi, used, anchor_t = _runway_anchors(meta, t, tas, phases)
    tri = _gnss_triangle(grid, gnss, t, tas, psi_int, Q, R, used, anchor_t)
    rest_row = standstill_rows(grid, t, tas, phases, psi_int, Q, R, trimmed)
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
        ws = np.interp(tg, t, gap_filled(grid, "wind_speed_mps"))
        to = np.radians(np.interp(tg, t, gap_filled(grid, "wind_from_deg")) + 180.0)
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
