"""What the joint smoother reads (:class:`JointInputs`, read from a cleaned flight by
:func:`flightrecon.methods.joint.problem.joint_inputs`): its end points (:class:`EndPoint`, built
once with the inputs), the take-off roll (the detection itself:
:func:`flightrecon.cleaning.ground_roll.takeoff_roll`; from the flight phases: :func:`phases_roll`;
refined with the smoothed lift-off speed: :func:`refined_roll`) and the airspeed-floor windows of a
derived ``n_long_g``."""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.cleaning.ground_roll import TakeoffRoll, takeoff_roll
from flightrecon.geo.frames import offset_latlon
from flightrecon.geo.kinematics import body_to_ned_matrix
from flightrecon.geo.navframe import ned_to_ecef_matrix
from flightrecon.ingest.derive import N_LONG_HALF_WINDOW_S
from flightrecon.methods.joint.layout import G0 as G0_MPS2
from flightrecon.methods.joint.settings import JointNoise


def enu_to_ecef_matrix(lat_deg: float, lon_deg: float) -> np.ndarray:
    """(3, 3) rotation whose columns are the east, north, up unit vectors in ECEF."""
    C = ned_to_ecef_matrix(lat_deg, lon_deg)[0]
    return np.column_stack([C[:, 1], C[:, 0], -C[:, 2]])


@dataclass(frozen=True)
class JointInputs:
    """Everything the smoother needs, in SI, on the state grid / at measurement times.

    Attributes
    ----------
    t_in : input grid times (Ni,)
    acc_ned : measured kinematic acceleration on the input grid (Ni, 3), NaN where missing
    attitude_deg : roll, pitch, heading on the input grid, each missing sample held at the
        nearest recorded one (Ni, 3) [deg]; its body-to-NED rotations: :meth:`body_to_ned`
        (kept as angles: the (Ni, 3, 3) matrices of a 10-hour flight at 16 Hz are 41 MB)
    tas, heading_rad : airspeed and (unwrapped) true heading on the input grid
    baro_rel_m : pressure altitude minus the departure field's pressure altitude (input grid)
    gnss : DataFrame t_s, lat_deg, lon_deg, h_m (ellipsoidal; NaN: a horizontal-only fix),
        vn_mps, ve_mps, optionally h_sd_m, v_sd_m, vel_sd_mps (per-fix sd) (may be empty)
    radar : DataFrame t_s, range_m, azimuth_rad, elevation_rad (NaN if absent) (may be empty)
    station : (lat, lon, h_ellipsoidal) or None
    departure, arrival : (lat, lon, h_ellipsoidal) or None
    liftoff_t, touchdown_t : NaN where not in the record
    field_h : ellipsoidal height of the departure field (reference of baro_rel_m)
    lever_arm : GNSS antenna in body FRD [m]
    wind_ne : recorded wind (Ni, 2) where the air moves to, or None
    doppler_gs, drift_rad : Doppler ground speed [m/s] and drift angle [rad] (Ni,), or None
    f_body_g : measured specific force in body FRD axes [n_long, n_lat, -n_norm] (Ni, 3) [g]
    runway_rad : true directions of the departure and arrival runways [rad], ``None`` each
        where unknown
    thresholds : (lat, lon, h_ellipsoidal) of the departure and arrival runway thresholds,
        ``None`` each where unknown (used only with the runway's direction)
    roll : the take-off roll and the rest before it (:func:`takeoff_roll`)
    lineup_t : when the aircraft lined up on the take-off runway (cleaning phases); nothing
        before it is taken as at rest on the runway (NaN: no limit)
    notes : what the input builder had to assume (missing attitude held, ...), for the summary
    ends_airborne : the record ends in the air or at an impact (cleaning phases): the arrival is
        then the last known position at the last sample (a radar hand-off, the wreckage), not
        an airfield (:func:`end_points`)
    fixes : known positions (``--fix``) (F, 5): t_s, lat_deg, lon_deg, h_ellipsoidal (NaN: a
        horizontal-only fix), sd_m (per axis), or None
    wind_aloft : winds-aloft prior (``--wind``) at the recorded altitude on the input grid
        (Ni, 3): north, east (where the air moves to) [m/s] and sd per component [m/s], or None
    missing_psd : white-acceleration PSD [(m/s^2)^2/Hz] standing for each input sample's
        acceleration where it is missing (Ni,), or None: 1 everywhere (the dynamics'
        ``qv_extra``; a derived ``n_long_g`` where the airspeed comes alive: larger,
        :func:`airspeed_floor_psd`)
    end_points : where and when the record is tied to its airfields (:class:`EndPoint`,
        :func:`end_points`), built once by
        :func:`~flightrecon.methods.joint.problem.joint_inputs`; empty: none
    """

    t_in: np.ndarray
    acc_ned: np.ndarray
    attitude_deg: np.ndarray
    tas: np.ndarray
    heading_rad: np.ndarray
    baro_rel_m: np.ndarray
    gnss: pd.DataFrame
    radar: pd.DataFrame
    station: tuple[float, float, float] | None
    departure: tuple[float, float, float] | None
    arrival: tuple[float, float, float] | None
    liftoff_t: float
    touchdown_t: float
    field_h: float
    lever_arm: tuple[float, float, float] = (0.0, 0.0, 0.0)
    wind_ne: np.ndarray | None = None
    doppler_gs: np.ndarray | None = None
    drift_rad: np.ndarray | None = None
    f_body_g: np.ndarray | None = None
    runway_rad: tuple[float | None, float | None] = (None, None)
    thresholds: tuple[tuple[float, float, float] | None,
                      tuple[float, float, float] | None] = (None, None)
    roll: TakeoffRoll = field(default_factory=TakeoffRoll)
    lineup_t: float = np.nan
    notes: tuple[str, ...] = ()
    ends_airborne: bool = False
    fixes: np.ndarray | None = None
    wind_aloft: np.ndarray | None = None
    missing_psd: np.ndarray | None = None
    end_points: tuple[EndPoint, ...] = ()

    def body_to_ned(self, i: int | np.ndarray | slice = slice(None)) -> np.ndarray:
        """Body-to-NED rotations C = R_z(heading) R_y(pitch) R_x(roll) of the input samples ``i``
        (all by default), shape (len(i), 3, 3), or (3, 3) for one sample
        (:func:`flightrecon.geo.body_to_ned_matrix`)."""
        a = self.attitude_deg[i]
        C = body_to_ned_matrix(a[..., 0], a[..., 1], a[..., 2])
        return C[0] if a.ndim == 1 else C


def refined_roll(inp: JointInputs, T: np.ndarray, vnom: np.ndarray | None,
                 accel_bias_g: np.ndarray | None = None) -> TakeoffRoll:
    """The take-off roll refined by the smoother:
    :func:`flightrecon.cleaning.ground_roll.takeoff_roll` with the along-track component of the
    nominal (smoothed) ground velocity ``vnom`` (N, 3) at lift-off on the state grid ``T`` as the
    lift-off speed, and the smoothed forward accelerometer bias ``accel_bias_g`` (N, 3) [g] at
    lift-off as its ``accel_bias_mps2``; ``inp.roll`` without a nominal, without a roll, or where
    the refined search finds none."""
    roll = inp.roll
    if vnom is None or not np.isfinite(roll.start_t) or not np.isfinite(inp.liftoff_t):
        return roll
    t_in = inp.t_in
    k_lo = int(nearest_index(T, np.array([inp.liftoff_t]))[0])
    psi_lo = inp.heading_rad[max(int(np.searchsorted(t_in, inp.liftoff_t)) - 1, 0)]
    if not np.isfinite(psi_lo):
        return roll
    bias = 0.0 if accel_bias_g is None else G0_MPS2 * float(accel_bias_g[k_lo, 0])
    refined = takeoff_roll(t_in, inp.acc_ned, inp.heading_rad, inp.tas, inp.liftoff_t,
                           v_lo_mps=float(vnom[k_lo, 0] * np.cos(psi_lo)
                                          + vnom[k_lo, 1] * np.sin(psi_lo)),
                           accel_bias_mps2=bias, not_before_t=inp.lineup_t)
    # a refinement that finds no roll keeps the one found before (the phases' where the
    # recorded loads do not reach back through the roll: phases_roll)
    return refined if np.isfinite(refined.start_t) else roll


@dataclass(frozen=True)
class Flare:
    """The touchdown's distance past the arrival threshold measured from the recorded flare
    (:func:`float_touchdown`): the air distance ``touchdown_m`` flown from the screen height
    (crossed at ``screen_t_s``, ``float_s`` before touchdown), its sd ``sd_m``."""

    touchdown_m: float
    sd_m: float
    screen_t_s: float
    float_s: float


@dataclass(frozen=True)
class EndPoint:
    """One end-point constraint of the record (:func:`end_points`): where and when it is tied to an
    airfield or a last known position.

    Attributes
    ----------
    which : "departure" or "arrival"
    model : "runway" (along / across the runway from its threshold), "reference" (the
        airfield reference point) or "last_position" (a record ending in the air or at an
        impact)
    t_s : time of the constraint (the runway departure's: the take-off roll's start, moved
        with the smoother's refined roll by :func:`end_points_at`)
    point : (lat, lon, h_ellipsoidal) of the constrained point's mean
    sd_m : (along, cross, vertical) for the runway model, (north, east, vertical) otherwise
    runway_rad : the runway's true direction (runway model), else None
    flare : the touchdown measured from the recorded flare (runway arrival), else None
    """

    which: str
    model: str
    t_s: float
    point: tuple[float, float, float]
    sd_m: tuple[float, float, float]
    runway_rad: float | None = None
    flare: Flare | None = None


def float_touchdown(inp: JointInputs, nz: JointNoise, look_back_s: float = 90.0,
                    smooth_s: float = 1.0) -> Flare | None:
    """The touchdown's distance past the arrival threshold from the recorded flare (docs/joint.md,
    "End points", issue #38): the air distance flown from the screen height ``screen_height_m``,

    .. math:: d_{td} = \\int_{t_s}^{t_{td}} V_{TAS}\\,dt, \\qquad
              \\sigma_{td}^2 = \\sigma_s^2 + (w\\,(t_{td} - t_s))^2

    :math:`t_s` the last time before touchdown that the height above it (the pressure altitude's
    ``smooth_s`` running mean less its median over the first 2 s on the ground) was at least the
    screen height, :math:`\\sigma_s` = ``screen_along_sd_m``, :math:`w` = ``float_wind_mps``.

    Returns
    -------
    Flare or None
        ``None`` (the fixed ``touchdown_m``) without a touchdown, a pressure altitude or an
        airspeed there, or when the record does not climb above the screen height within
        ``look_back_s``.
    """
    td = inp.touchdown_t
    h_s = nz.screen_height_m
    if not (np.isfinite(td) and h_s > 0):
        return None
    t, h, v = inp.t_in, inp.baro_rel_m, inp.tas
    ground = (t >= td) & (t <= td + 2.0) & np.isfinite(h)
    win = (t >= td - look_back_s) & (t <= td) & np.isfinite(h)
    if ground.sum() < 2 or win.sum() < 4:
        return None
    h_td = float(np.median(h[ground]))
    tw, hw = t[win], h[win] - h_td
    dt = float(np.median(np.diff(tw))) if len(tw) > 1 else 1.0
    n = max(int(round(smooth_s / max(dt, 1e-6))), 1)
    hs = np.convolve(hw, np.ones(n) / n, mode="same") if n > 1 else hw
    above = np.flatnonzero(hs >= h_s)
    if above.size == 0:
        return None
    t_s = float(tw[above[-1]])
    seg = (t >= t_s) & (t <= td)
    vv = v[seg]
    if seg.sum() < 2 or not np.all(np.isfinite(vv)):
        return None
    dist = float(np.trapezoid(vv, t[seg]))
    sd = float(np.hypot(nz.screen_along_sd_m, nz.float_wind_mps * (td - t_s)))
    return Flare(touchdown_m=dist, sd_m=sd, screen_t_s=t_s, float_s=float(td - t_s))


def runway_end(inp: JointInputs, nz: JointNoise, which: str, t_run: float,
               threshold: tuple[float, float, float], runway_rad: float) -> EndPoint:
    """The runway model of end ``which``: the take-off roll starts at the departure threshold
    (along-runway sd ``roll_start_sd_m``), the touchdown is ``touchdown_m`` past the arrival
    threshold (sd ``touchdown_sd_m``) or the distance measured from the recorded flare
    (:func:`float_touchdown`); across the runway the centreline (``runway_halfwidth_m``), vertically
    the airfield elevation (``endpoint_v_m``)."""
    dist, sd = ((0.0, nz.roll_start_sd_m) if which == "departure"
                else (nz.touchdown_m, nz.touchdown_sd_m))
    flare = float_touchdown(inp, nz) if which == "arrival" else None
    if flare is not None:
        dist, sd = flare.touchdown_m, flare.sd_m
    # dist down the runway from its threshold
    lat, lon = offset_latlon(threshold[0], threshold[1], dist * np.cos(runway_rad),
                             dist * np.sin(runway_rad))
    return EndPoint(which, "runway", float(t_run), (lat, lon, float(threshold[2])),
                    (sd, nz.runway_halfwidth_m, nz.endpoint_v_m), float(runway_rad), flare)


def end_points(inp: JointInputs, nz: JointNoise) -> tuple[EndPoint, ...]:
    """The end-point constraints (docs/joint.md, "End points"; docs/wind.md, "End points"), built
    once with the inputs: with a runway's threshold and direction :func:`runway_end` (the departure
    at the start of the take-off roll ``inp.roll``, the arrival at touchdown), else the airfield
    reference point at lift-off / touchdown (or the first / last sample), ``endpoint_h_m``
    horizontally and ``endpoint_v_m`` vertically; a record ending in the air or at an impact
    (``inp.ends_airborne``): the last known position at the last sample (``last_position_h_m``).
    """
    out = []
    t_in = inp.t_in
    for which, pos, thr, rw in (("departure", inp.departure, inp.thresholds[0], inp.runway_rad[0]),
                                ("arrival", inp.arrival, inp.thresholds[1], inp.runway_rad[1])):
        if pos is None:
            continue
        point = (float(pos[0]), float(pos[1]), float(pos[2]))
        if which == "arrival" and inp.ends_airborne:
            out.append(EndPoint(which, "last_position", float(t_in[-1]), point,
                                (nz.last_position_h_m, nz.last_position_h_m, nz.endpoint_v_m)))
            continue
        t_run = inp.roll.start_t if which == "departure" else inp.touchdown_t
        if thr is not None and rw is not None and np.isfinite(t_run):
            out.append(runway_end(inp, nz, which, t_run, thr, rw))
            continue
        if which == "departure":
            tt = inp.liftoff_t if np.isfinite(inp.liftoff_t) else t_in[0]
        else:
            tt = inp.touchdown_t if np.isfinite(inp.touchdown_t) else t_in[-1]
        out.append(EndPoint(which, "reference", float(tt), point,
                            (nz.endpoint_h_m, nz.endpoint_h_m, nz.endpoint_v_m)))
    return tuple(out)


def end_points_at(ends: tuple[EndPoint, ...], roll: TakeoffRoll) -> tuple[EndPoint, ...]:
    """The end points ``ends`` with the runway departure at the start of ``roll`` (the smoother's
    refined take-off roll, :func:`refined_roll`: it has a start wherever the inputs' roll has one,
    so the model chosen at the build holds)."""
    return tuple(replace(e, t_s=float(roll.start_t))
                 if e.which == "departure" and e.model == "runway" else e for e in ends)


def airborne_samples(inp: JointInputs) -> np.ndarray:
    """Input samples from lift-off to touchdown (the whole record where either is unknown)."""
    t = inp.t_in
    air = np.ones(len(t), bool)
    if np.isfinite(inp.liftoff_t):
        air &= t >= inp.liftoff_t
    if np.isfinite(inp.touchdown_t):
        air &= t <= inp.touchdown_t
    return air


def per_fix_sd(g: pd.DataFrame, column: str, default: float) -> np.ndarray:
    """Per-fix standard deviations from ``column`` of the GNSS table ``g`` (the receiver's own
    accuracy figures: ``JointInputs.gnss``), ``default`` where absent or not finite."""
    if column not in g.columns:
        return np.full(len(g), float(default))
    v = g[column].to_numpy(float)
    return np.where(np.isfinite(v) & (v > 0), v, float(default))


def nearest_index(t: np.ndarray, tq: np.ndarray) -> np.ndarray:
    """Index of the sample of sorted ``t`` nearest to each of ``tq`` (a tie goes to the later
    sample); the state step of a measurement, the input sample of a fix."""
    j = np.clip(np.searchsorted(t, tq), 0, len(t) - 1)
    p = np.clip(j - 1, 0, len(t) - 1)
    return np.where(np.abs(tq - t[p]) < np.abs(tq - t[j]), p, j)


def without_floor_loads(inp: JointInputs) -> JointInputs:
    """A derived ``n_long_g``'s loads taken as missing through the airspeed-floor windows
    (:func:`airspeed_floor_windows`), with the PSD of the unknown velocity change there
    (:func:`airspeed_floor_psd`); before the take-off roll's search: its rest is found by
    integrating the acceleration back from lift-off, which through these samples is not known."""
    dead = airspeed_floor_windows(inp.t_in, inp.tas)
    if not dead.any():
        return inp
    acc = inp.acc_ned.copy()
    acc[dead] = np.nan
    return replace(inp, acc_ned=acc, missing_psd=airspeed_floor_psd(inp.t_in, inp.tas, dead),
                   notes=(*inp.notes, (
                       f"joint: n_long_g derived from an airspeed that reads 0 below its floor: "
                       f"the loads of {int(dead.sum())} sample(s) where it comes alive or dies "
                       "(the derivative's window holds both) are taken as missing, the velocity "
                       "change across each such window unknown by the airspeed there")))


def phases_roll(ph: Any, settle_s: float = 10.0) -> TakeoffRoll:
    """The take-off roll of the cleaning's phases (``roll_start_t_s`` after ``lineup_t_s``), where
    the joint's own search finds none (through a derived ``n_long_g``'s airspeed-floor windows the
    acceleration it integrates back from lift-off is not known: :func:`airspeed_floor_windows`); the
    rest from the line-up to ``settle_s`` before the start; none for a rolling take-off."""
    start = float(getattr(ph, "roll_start_t_s", np.nan))
    lineup = float(getattr(ph, "lineup_t_s", np.nan))
    if not (np.isfinite(start) and np.isfinite(lineup) and start > lineup):
        return TakeoffRoll()
    end = start - settle_s
    return TakeoffRoll(start, (lineup, end) if end > lineup else (np.nan, np.nan))


#: a recorded airspeed at most this is "below the air-data computer's floor" [m/s] (1 kt: the
#: rounding of an airspeed recorded in whole knots that reads 0)
AIRSPEED_DEAD_MPS = 0.52


def airspeed_floor_windows(t: np.ndarray, tas: np.ndarray,
                           half_window_s: float = N_LONG_HALF_WINDOW_S) -> np.ndarray:
    """Samples whose derived ``n_long_g`` (a centred difference of the airspeed over
    ``+-half_window_s``, flightrecon/ingest/derive.py) spans an airspeed coming alive or dying
    (docs/joint.md, "A derived `n_long_g` where the airspeed comes alive"): True where the window
    ``[t - h, t + h]`` holds both an airspeed at most :data:`AIRSPEED_DEAD_MPS` and one above it."""
    ok = np.isfinite(tas)
    out = np.zeros(len(t), bool)
    if ok.sum() < 2:
        return out
    tv, dead = t[ok], (tas[ok] <= AIRSPEED_DEAD_MPS).astype(float)
    # fraction of dead samples within the window (cumulative counts)
    cum = np.r_[0.0, np.cumsum(dead)]
    lo = np.searchsorted(tv, t - half_window_s - 1e-9, side="left")
    hi = np.searchsorted(tv, t + half_window_s + 1e-9, side="right")
    n_dead = cum[hi] - cum[lo]
    return (n_dead > 0) & (n_dead < hi - lo)


def airspeed_floor_psd(t: np.ndarray, tas: np.ndarray, dead: np.ndarray) -> np.ndarray:
    """The missing accelerations' PSD [(m/s^2)^2/Hz] per input sample (``JointInputs.missing_psd``):
    1 outside the windows of :func:`airspeed_floor_windows`; in each (a contiguous run of ``dead``
    samples, ``W`` seconds) ``V^2 / W``, ``V`` the largest airspeed there (docs/joint.md, "A derived
    `n_long_g` where the airspeed comes alive")."""
    psd = np.ones(len(t))
    idx = np.flatnonzero(dead)
    if idx.size == 0:
        return psd
    runs = np.split(idx, np.flatnonzero(np.diff(idx) > 1) + 1)
    for r in runs:
        w = float(t[r[-1]] - t[r[0]]) + (float(np.median(np.diff(t))) if len(t) > 1 else 1.0)
        v = float(np.nanmax(tas[r])) if np.isfinite(tas[r]).any() else 0.0
        psd[r] = max(v * v / max(w, 1e-6), 1.0)
    return psd
