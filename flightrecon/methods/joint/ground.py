"""The joint smoother's ground rows: which input samples are on the ground, and the runway's
constraints on a roll (zero cross-track velocity, the centreline); docs/joint.md,
"Measurements"."""

from __future__ import annotations

from typing import Any

import numpy as np

from flightrecon.geo.frames import geodetic_to_ecef
from flightrecon.geo.navframe import ned_to_ecef_matrix
from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.inputs import JointInputs
from flightrecon.methods.joint.settings import JointSettings


def decimate_mask(t: np.ndarray, rate_hz: float, origin: float | None = None) -> np.ndarray:
    """True for the first sample of each 1/rate_hz bin, bins counted from ``origin`` (default
    the first sample) (keeps each measurement used once)."""
    return first_in_bin(t, rate_hz, np.arange(len(t)), origin)


def first_in_bin(t: np.ndarray, rate_hz: float, i: np.ndarray, origin: float | None = None
                 ) -> np.ndarray:
    """:func:`decimate_mask` at the sample indices ``i`` only (each judged against its
    predecessor in ``t``), for a few samples of a long record."""
    if rate_hz <= 0:
        return np.zeros(len(i), bool)
    t0 = t[0] if origin is None else origin
    b = np.floor((t[i] - t0) * rate_hz + 1e-9).astype(np.int64)
    b_prev = np.floor((t[np.maximum(i - 1, 0)] - t0) * rate_hz + 1e-9).astype(np.int64)
    return (i == 0) | (b != b_prev)


def on_ground_mask(inp: JointInputs, settings: JointSettings) -> np.ndarray:
    """Input samples used for the ground constraints: before lift-off and after touchdown (2 s
    margins), at the ground-constraint rate, with a heading."""
    t_in = inp.t_in
    on_ground = np.zeros(len(t_in), bool)
    if np.isfinite(inp.liftoff_t):
        on_ground |= t_in < inp.liftoff_t - 2.0
    if np.isfinite(inp.touchdown_t):
        on_ground |= t_in > inp.touchdown_t + 2.0
    # the rate's bins judged on the ground samples only (a long flight's record is mostly
    # airborne, and this runs on every pass)
    i = np.flatnonzero(on_ground)
    i = i[first_in_bin(t_in, settings.ground_rate_hz, i) & np.isfinite(inp.heading_rad[i])]
    keep = np.zeros(len(t_in), bool)
    keep[i] = True
    return keep


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
    # the heading's distance from the roll's on the samples after it only (a long flight's
    # record before touchdown is most of it, and this runs on every pass)
    after = np.flatnonzero((t > td + 2.0) & np.isfinite(psi))
    off = np.degrees(np.abs(np.angle(np.exp(1j * (psi[after] - psi_rw)))))
    out = after[off > exit_deg]
    if len(out):
        m &= t < t[out[0]]
    return m


def runway_measurements(b: Any, inp: JointInputs, settings: JointSettings,
                         step_of, pnom: np.ndarray, vnom: np.ndarray,
                         psi_hat: np.ndarray | None = None) -> None:
    """Rolling on the runway: zero cross-track velocity, and zero cross-track offset from the
    centreline through the runway's threshold, or through the airfield reference point where
    no threshold is given.  That point need not lie on the runway (an apron, a stand, an ARP
    between runways): its distance from the centreline is one error for the whole roll,
    known no better than the reference itself (``endpoint_h_m``), so each of the roll's m
    centreline rows carries ``runway_halfwidth_m^2 + m endpoint_h_m^2`` (as the slip below:
    the roll tells the cross-track position one reference's worth, not m of them).

    ``settings.roll_velocity`` = "runway" (the default): the velocity rows hold the velocity
    along the runway's direction, the airfield's ``runway_true_deg`` where the metadata give
    it (then the ground roll ties the heading reference: the recorded heading minus the
    heading bias must follow the runway).  Otherwise, and with ``roll_velocity`` = "nose",
    along the true heading, psi_rec - dpsi (the recorded heading carries the heading bias;
    the wheels roll where the nose points, the tyres' slip angles a fraction of a degree):
    c(psi_rec - dpsi) . v ~ c(psi_rec) . v + dpsi a(psi_rec) . v_nom, with c and a the cross-
    and along-heading unit vectors, linearised at dpsi = 0 and the nominal (the neglected term
    is dpsi^2 / 2 of the along-track value: 3 mm/s at 1 deg and 70 m/s). Taking the recorded
    heading itself would tell the smoother that the heading bias is zero. ``psi_hat`` (per
    state step) is the heading bias of the last pass: the linearisation is about it,
    c(psi_rec - dpsi) . v ~ c(psi') . v + (dpsi - psi_hat) a(psi') . v_nom with psi' = psi_rec -
    psi_hat (exact at the solution however large the bias).  With "nose" the runway's
    direction reaches the bias through the centreline rows and the line-up
    (:func:`lineup_heading`) only: a roll's track leaves the runway's direction where the
    aircraft is steered (JSBSim's Cessna 310 swerves 5-14 deg on its take-off roll, 1-3 m/s
    across the runway), and the runway rows then make the heading bias take up the swerve
    (docs/jsbsim.md, "Fleet study": 4.9 +- 0.4 deg for a true -0.6); measured on the fleet,
    the nose rows cost the long flights more than they gave the circuits, so the default
    stays "runway".

    ``ground_slip_deg`` (default 0): an angle between track and runway common to the whole
    roll (steering corrections, the tyres' slip angles in a crosswind, a crab kept after
    touchdown), not a noise that averages out over its samples.  Each of a roll's ``m``
    cross-track velocity rows carries it as the extra variance ``m (s V)^2`` (V: the roll's
    fastest speed, :func:`roll_speed`, from the data and not the iterate, so that the cost
    function stays the same from pass to pass), so that the roll's velocity rows tell the
    heading bias no more than one such angle's worth (``s^2`` against ``s^2 / m`` for
    independent errors).  The centreline rows keep their half-width (25 m: 1.4 deg over
    1000 m of roll).  With it the cross-country flights lost more than the upsets gained, so
    the default is 0 (docs/jsbsim.md).
    """
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
        on_line = known and inp.thresholds[dep_end] is not None
        if on_line:
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
        tt, k, ph, psi = _roll_velocity_rows(b, inp, settings, sel, (dep_end, rw, t_edge),
                                             step_of, vnom, psi_hat)
        if pos is None:
            continue
        on_cl = cl_side[sel]
        if on_cl.any():
            _centreline_rows(b, settings, pos, (tt[on_cl], k[on_cl], ph[on_cl], psi[on_cl]),
                             rw, on_line, pnom)


def _roll_velocity_rows(b: Any, inp: JointInputs, settings: JointSettings, sel: np.ndarray,
                        ends: tuple[int, float | None, float], step_of, vnom: np.ndarray,
                        psi_hat: np.ndarray | None
                        ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The roll's cross-track velocity rows (:func:`runway_measurements`) on the samples
    ``sel``; ``ends`` the departure (0) or arrival (1) end, its runway direction (None: not
    known) and the lift-off or touchdown time.  Returns the rows' times, state steps, heading
    bias of the linearisation and direction (for the centreline rows)."""
    nz = settings.noise
    slip = np.radians(nz.ground_slip_deg)
    n = jl.N_STATE
    dep_end, rw, t_edge = ends
    known = rw is not None
    # along the runway's direction (only its line matters: a reversed direction is the
    # same), or the true heading psi_rec - dpsi linearised about the last pass's bias
    tt = inp.t_in[sel]
    k = step_of(tt)
    nose = not known or settings.roll_velocity == "nose"
    ph = np.zeros(len(tt)) if psi_hat is None or not nose else psi_hat[k]
    psi = inp.heading_rad[sel] - ph if nose else np.full(len(tt), rw)
    H = np.zeros((len(tt), n))
    H[:, jl.IV] = -np.sin(psi)
    H[:, jl.IV + 1] = np.cos(psi)
    v_roll = roll_speed(inp, settings, t_edge)
    r_v = nz.ground_mps ** 2 + len(tt) * (slip * v_roll) ** 2
    if nose:
        H[:, jl.IPSI] = np.cos(psi) * vnom[k, 0] + np.sin(psi) * vnom[k, 1]
    else:
        # the wheels roll where the nose points: the track leaves the runway's direction
        # by the nose's angle to the heading lined up at rest before a take-off roll, or,
        # on a landing roll (no rest before it) and a take-off without one, by its angle
        # to the runway itself (the heading bias inside it: a fraction of the swerves)
        ref = rest_heading(inp) if dep_end == 0 else None
        if ref is None and rw is not None:
            ref = float(rw)
        r_v = r_v + steering_variance(inp.heading_rad[sel], v_roll, ref)
    b.add("ground", jl.LINEAR, tt, np.zeros(len(tt)), r_v, H, -H[:, jl.IPSI] * ph)
    return tt, k, ph, psi


def _centreline_rows(b: Any, settings: JointSettings, pos: tuple[float, float, float],
                     rows: tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray],
                     rw: float | None, on_line: bool, pnom: np.ndarray) -> None:
    """The roll's cross-track offset rows from the centreline through ``pos`` (the threshold,
    ``on_line``, or the airfield's reference point) on the rows ``(tt, k, ph, psi)`` of the
    centreline samples (:func:`runway_measurements`)."""
    nz = settings.noise
    n = jl.N_STATE
    known = rw is not None
    tt, k, ph, psi = rows
    # the centreline: the runway's direction where known (only its line matters: a
    # reversed direction is the same), else the true heading
    if known:
        psi, ph = np.full(len(tt), rw), np.zeros(len(tt))
    ex, ey, ez = geodetic_to_ecef(pos[0], pos[1], pos[2])
    arp = np.array([float(ex), float(ey), float(ez)])
    Ca = ned_to_ecef_matrix(pos[0], pos[1])[0]
    cross = np.c_[-np.sin(psi), np.cos(psi), np.zeros(len(psi))] @ Ca.T  # (m, 3) in ECEF
    along = np.c_[np.cos(psi), np.sin(psi), np.zeros(len(psi))] @ Ca.T
    H = np.zeros((len(tt), n))
    H[:, jl.S_POS] = cross
    if not known:
        H[:, jl.IPSI] = np.einsum("mj,mj->m", along, pnom[k] - arp)
    # without a threshold the line runs through the airfield's reference point, whose
    # distance from the centreline is not known better than the reference itself
    # (endpoint_h_m): one error common to the roll's m rows, m endpoint_h_m^2 on each
    r_cl = nz.runway_halfwidth_m ** 2 + (0.0 if on_line else len(tt) * nz.endpoint_h_m ** 2)
    b.add("runway", jl.LINEAR, tt, np.zeros(len(tt)), r_cl, H,
          -cross @ arp - H[:, jl.IPSI] * ph)


def rest_heading(inp: JointInputs) -> float | None:
    """The circular mean recorded heading [rad] over the rest before the take-off roll
    (``inp.roll.rest_t``), None where no rest was found."""
    r0, r1 = inp.roll.rest_t
    if not (np.isfinite(r0) and np.isfinite(r1)):
        return None
    m = (inp.t_in >= r0) & (inp.t_in <= r1) & np.isfinite(inp.heading_rad)
    if not m.any():
        return None
    h = inp.heading_rad[m]
    return float(np.arctan2(np.mean(np.sin(h)), np.mean(np.cos(h))))


def steering_variance(heading_rad: np.ndarray, v_roll_mps: float,
                      ref_rad: float | None = None) -> np.ndarray:
    """Variance [m^2/s^2] of the velocity across the runway that steering makes at each of a
    roll's samples: the wheels roll where the nose points, so where the recorded heading
    leaves the lined-up heading ``ref_rad`` (at rest before the roll: :func:`rest_heading`;
    else the roll's own mean) by d, the heading bias dropping out of the difference, the
    track leaves the runway by about d: ``(V sin d)^2``, V the roll's fastest speed
    (:func:`roll_speed`, from the data and not the iterate; at least the speed at the sample,
    so never less than the swerve's cross-track velocity).  JSBSim's Cessna 310 swings 5-14 deg
    on its take-off roll and its velocity rows then held the heading bias 4.9 +- 0.4 deg off
    (docs/jsbsim.md, "Fleet study").

    Parameters
    ----------
    heading_rad : recorded headings of the roll's samples [rad]
    v_roll_mps : the roll's fastest speed [m/s]
    ref_rad : the lined-up heading [rad]; None: the samples' circular mean
    """
    h = np.asarray(heading_rad, dtype=float)
    if h.size == 0:
        return np.zeros(0)
    ref = (float(np.arctan2(np.mean(np.sin(h)), np.mean(np.cos(h)))) if ref_rad is None
           else float(ref_rad))
    d = np.angle(np.exp(1j * (h - ref)))
    return (v_roll_mps * np.sin(d)) ** 2


def lineup_heading(b: Any, inp: JointInputs, settings: JointSettings, t_rest: np.ndarray
                   ) -> None:
    """Lined up at rest before the take-off roll, the nose points along the departure runway:
    one row on the heading bias, dpsi = mean(psi_rec - psi_rw) (the circular mean over the
    rest's samples ``t_rest``, wrapped to the runway's line: a reversed direction is the same
    runway), sd ``lineup_heading_deg`` (how straight an aircraft is lined up).  Only where the
    metadata give the runway's direction and ``settings.roll_velocity`` is "nose".

    The "nose" velocity rows of :func:`runway_measurements` hold the roll's velocity along
    the nose, which says nothing about the bias; the runway's direction reaches it through the
    centreline rows and this row.  At rest the heading is what the line-up left, before any
    steering on the roll (JSBSim's aircraft: along the runway at rest, 2-8 deg off it for
    10-20 s of their rolls, docs/jsbsim.md).
    """
    rw = inp.runway_rad[0]
    if rw is None or len(t_rest) == 0:
        return
    psi = np.interp(t_rest, inp.t_in, np.unwrap(np.where(np.isfinite(inp.heading_rad),
                                                         inp.heading_rad, 0.0)))
    ok = np.interp(t_rest, inp.t_in, np.isfinite(inp.heading_rad).astype(float)) > 0.999
    if not ok.any():
        return
    d = psi[ok] - rw
    mean = 0.5 * float(np.arctan2(np.mean(np.sin(2.0 * d)), np.mean(np.cos(2.0 * d))))
    H = np.zeros((1, jl.N_STATE))
    H[0, jl.IPSI] = 1.0
    b.add("runway", jl.LINEAR, [float(np.mean(t_rest[ok]))], [mean],
          np.radians(settings.noise.lineup_heading_deg) ** 2, H)


def roll_speed(inp: JointInputs, settings: JointSettings, t_edge: float) -> float:
    """The fastest speed of a ground roll: the recorded airspeed at its lift-off or touchdown
    ``t_edge``, at least ``min_airspeed_mps`` (a bound on the along-track speed, wind aside)."""
    ok = np.isfinite(inp.tas)
    v = np.nan
    if np.isfinite(t_edge) and ok.any():
        v = float(np.interp(t_edge, inp.t_in[ok], inp.tas[ok]))
    return max(v, settings.min_airspeed_mps) if np.isfinite(v) else settings.min_airspeed_mps
