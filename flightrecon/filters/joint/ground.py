"""The joint smoother's ground rows: which input samples are on the ground, and the runway's
constraints on a roll (zero cross-track velocity, the centreline); docs/joint.md,
"Measurements"."""

from __future__ import annotations

from typing import Any

import numpy as np

from flightrecon.filters.joint import layout as jl
from flightrecon.filters.joint.inputs import JointInputs
from flightrecon.filters.joint.settings import JointSettings
from flightrecon.geo.frames import geodetic_to_ecef
from flightrecon.geo.navframe import ned_to_ecef_matrix


def decimate_mask(t: np.ndarray, rate_hz: float, origin: float | None = None) -> np.ndarray:
    """True for the first sample of each 1/rate_hz bin, bins counted from ``origin`` (default
    the first sample) (keeps each measurement used once)."""
    if rate_hz <= 0:
        return np.zeros(len(t), bool)
    b = np.floor((t - (t[0] if origin is None else origin)) * rate_hz + 1e-9).astype(np.int64)
    keep = np.ones(len(t), bool)
    keep[1:] = b[1:] != b[:-1]
    return keep


def on_ground_mask(inp: JointInputs, settings: JointSettings) -> np.ndarray:
    """Input samples used for the ground constraints: before lift-off and after touchdown (2 s
    margins), at the ground-constraint rate, with a heading."""
    t_in = inp.t_in
    on_ground = np.zeros(len(t_in), bool)
    if np.isfinite(inp.liftoff_t):
        on_ground |= t_in < inp.liftoff_t - 2.0
    if np.isfinite(inp.touchdown_t):
        on_ground |= t_in > inp.touchdown_t + 2.0
    return on_ground & decimate_mask(t_in, settings.ground_rate_hz) & np.isfinite(inp.heading_rad)


#: heading change that ends a landing roll [deg] (the phases' line-up rule, 10 deg)
RUNWAY_EXIT_DEG = 10.0


def on_runway_mask(inp: JointInputs, departure: bool, exit_deg: float = RUNWAY_EXIT_DEG
                   ) -> np.ndarray:
    """Input samples that can be on the departure (``departure``) or arrival runway.

    Departure: from the line-up (``inp.lineup_t``, the cleaning phases': the start of the last
    stretch within 10 deg of the take-off run's heading), the whole record before lift-off
    where it is not known.  Arrival: from touchdown to the runway exit, the first sample after
    which the heading is more than ``exit_deg`` from the landing roll's (its circular mean
    from 2 to 6 s after touchdown, when the crab is gone), to the end where it does not turn
    off.  Before, the record could start at the stand and end there: the runway's centreline
    rows then held the taxi (issue #36: 233 m off at lift-off on the Garmin export with a
    24 m sd).
    """
    t = inp.t_in
    if departure:
        if np.isfinite(inp.lineup_t):
            return t >= inp.lineup_t
        return np.ones(len(t), bool)
    m = np.ones(len(t), bool)
    td = inp.touchdown_t
    psi = inp.heading_rad
    if not np.isfinite(td):
        return m
    w = (t >= td + 2.0) & (t <= td + 6.0) & np.isfinite(psi)
    if not w.any():
        return m
    psi_rw = float(np.arctan2(np.mean(np.sin(psi[w])), np.mean(np.cos(psi[w]))))
    off = np.degrees(np.abs(np.angle(np.exp(1j * (psi - psi_rw)))))
    out = np.flatnonzero((t > td + 2.0) & np.isfinite(psi) & (off > exit_deg))
    if len(out):
        m &= t < t[out[0]]
    return m


def runway_measurements(b: Any, inp: JointInputs, settings: JointSettings,
                         step_of, pnom: np.ndarray, vnom: np.ndarray,
                         psi_hat: np.ndarray | None = None) -> None:
    """Rolling on the runway: zero cross-track velocity, and zero cross-track offset from the
    centreline through the airfield reference point.

    The runway's direction is the airfield's ``runway_true_deg`` where the metadata give it
    (then the ground roll ties the heading reference: the recorded heading minus the heading
    bias must follow the runway). Otherwise it is the true heading, psi_rec - dpsi (the recorded
    heading carries the heading bias): c(psi_rec - dpsi) . v ~ c(psi_rec) . v + dpsi
    a(psi_rec) . v_nom, with c and a the cross- and along-runway unit vectors, linearised at
    dpsi = 0 and the nominal (the neglected term is dpsi^2 / 2 of the along-track value: 3 mm/s
    at 1 deg and 70 m/s). Taking the recorded heading as the runway's direction would tell the
    smoother that the heading bias is zero. ``psi_hat`` (per state step) is the heading bias
    of the last pass: the linearisation is about it, c(psi_rec - dpsi) . v ~ c(psi') . v +
    (dpsi - psi_hat) a(psi') . v_nom with psi' = psi_rec - psi_hat (exact at the solution
    however large the bias).

    Neither the track nor the nose is exactly along the runway on the ground (steering
    corrections and a drift across the runway, the tyres' slip angles in a crosswind, a crab
    kept after touchdown): an angle ``ground_slip_deg`` (sd) common to the whole roll, not a
    noise that averages out over its samples.  Each of a roll's ``m`` cross-track velocity rows
    carries it as the extra variance ``m (s V)^2`` (V: the roll's fastest speed,
    :func:`roll_speed`, from the data and not the iterate, so that the cost function stays the
    same from pass to pass), so that the roll's velocity rows tell the heading bias no more
    than one such angle's worth (``s^2`` against ``s^2 / m`` for independent errors).  The
    centreline rows keep their half-width (25 m: 1.4 deg over 1000 m of roll).  JSBSim's rolls
    run up to 1.7 deg off the runway with the nose up to 3.3 deg off it, and without this the
    heading bias follows the nose's angle on the take-off roll; with it the cross-country
    flights lost more than the upsets gained, so the default is 0 (docs/jsbsim.md).
    """
    nz = settings.noise
    slip = np.radians(nz.ground_slip_deg)
    n = jl.N_STATE
    t_in = inp.t_in
    keep = on_ground_mask(inp, settings)
    if not keep.any():
        return
    for dep_end, (pos, side, rw, t_edge) in enumerate((
            (inp.departure, t_in < (inp.liftoff_t if np.isfinite(inp.liftoff_t) else -np.inf),
             inp.runway_rad[0], inp.liftoff_t),
            (inp.arrival, t_in > (inp.touchdown_t if np.isfinite(inp.touchdown_t) else np.inf),
             inp.runway_rad[1], inp.touchdown_t))):
        known = rw is not None
        if known and inp.thresholds[dep_end] is not None:
            # the centreline runs through the threshold; the airfield's reference point is
            # where the analyst put it (an apron, between two runways)
            pos = inp.thresholds[dep_end]
        # a record from stand to stand: the taxi before the line-up and after the runway exit
        # is on no runway; its rows along the heading (cross-track velocity zero) stay where
        # the runway's direction is not known: they hold on any taxiway
        on_rw = on_runway_mask(inp, dep_end == 0)
        cl_side = side & on_rw
        if known:
            side = cl_side
        sel = keep & side
        if not sel.any():
            continue
        # the direction of the runway (only its line matters: a reversed direction is the same)
        tt = t_in[sel]
        k = step_of(tt)
        ph = np.zeros(len(tt)) if known or psi_hat is None else psi_hat[k]
        psi = np.full(int(sel.sum()), rw) if known else inp.heading_rad[sel] - ph
        H = np.zeros((len(tt), n))
        H[:, jl.IV] = -np.sin(psi)
        H[:, jl.IV + 1] = np.cos(psi)
        r_v = nz.ground_mps ** 2 + len(tt) * (slip * roll_speed(inp, settings, t_edge)) ** 2
        if not known:
            H[:, jl.IPSI] = np.cos(psi) * vnom[k, 0] + np.sin(psi) * vnom[k, 1]
        b.add("ground", jl.LINEAR, tt, np.zeros(len(tt)), r_v, H, -H[:, jl.IPSI] * ph)
        if pos is None:
            continue
        on_cl = cl_side[sel]
        if not on_cl.any():
            continue
        tt, k, psi, ph = tt[on_cl], k[on_cl], psi[on_cl], ph[on_cl]
        ex, ey, ez = geodetic_to_ecef(pos[0], pos[1], pos[2])
        arp = np.array([float(ex), float(ey), float(ez)])
        Ca = ned_to_ecef_matrix(pos[0], pos[1])[0]
        cross = np.c_[-np.sin(psi), np.cos(psi), np.zeros(len(psi))] @ Ca.T  # (m, 3) in ECEF
        along = np.c_[np.cos(psi), np.sin(psi), np.zeros(len(psi))] @ Ca.T
        H = np.zeros((len(tt), n))
        H[:, jl.S_POS] = cross
        if not known:
            H[:, jl.IPSI] = np.einsum("mj,mj->m", along, pnom[k] - arp)
        b.add("runway", jl.LINEAR, tt, np.zeros(len(tt)), nz.runway_halfwidth_m ** 2, H,
              -cross @ arp - H[:, jl.IPSI] * ph)


def roll_speed(inp: JointInputs, settings: JointSettings, t_edge: float) -> float:
    """The fastest speed of a ground roll: the recorded airspeed at its lift-off or touchdown
    ``t_edge``, at least ``min_airspeed_mps`` (a bound on the along-track speed, wind aside)."""
    ok = np.isfinite(inp.tas)
    v = np.nan
    if np.isfinite(t_edge) and ok.any():
        v = float(np.interp(t_edge, inp.t_in[ok], inp.tas[ok]))
    return max(v, settings.min_airspeed_mps) if np.isfinite(v) else settings.min_airspeed_mps
