"""The joint smoother's problem, built once from a cleaned flight (:func:`joint_problem`): the
inputs read from its channels (:func:`joint_inputs`: the held attitude, the loads in the local level
frame, the GNSS and radar tables, the baro channel's field reference, the take-off roll, the end
points), the settings as this flight's data call for them, each data-driven choice with the evidence
that made it (:class:`SettingChoice`), the priors and what the output needs of the flight
(:class:`OutputFrame`).  After the build nothing reads the cleaned flight and no setting is
rewritten: a later adjustment (the wind walk re-estimated, the held-out smoothing of the GNSS gaps:
:mod:`~flightrecon.methods.joint.calibration`) is a new problem (:func:`adjusted`) with its choice
appended, and a problem of hand-made inputs is :func:`problem_of` (docs/joint.md, "How the joint
is built and solved", item 1: the data-driven settings, those of the channels alone in
:mod:`~flightrecon.methods.joint.settings`, those of the inputs here)."""

from __future__ import annotations

from dataclasses import dataclass, fields, replace
from typing import Any

import numpy as np
import pandas as pd

from flightrecon.cleaning.ground_roll import takeoff_roll
from flightrecon.cleaning.saturation import saturated_loads
from flightrecon.constants import G0 as G0_MPS2
from flightrecon.errors import MetadataError, ValidationError
from flightrecon.geo.atmosphere import field_pressure_altitude_m, height_above_field_m
from flightrecon.geo.frames import TangentPlane, msl_to_ellipsoid, output_plane
from flightrecon.geo.kinematics import body_to_ned_matrix, kinematic_acceleration_ned
from flightrecon.geo.pressure_height import isa_deviation_k
from flightrecon.geo.wind import wind_toward_ne
from flightrecon.ingest.priors import wind_aloft_on_grid
from flightrecon.methods.joint.inputs import (
    JointInputs,
    airborne_samples,
    end_points,
    nearest_index,
    phases_roll,
    without_floor_loads,
)
from flightrecon.methods.joint.linearisation import (
    SmootherFlight,
    nominal_trajectory,
    q_vector,
    smoother_flight,
)
from flightrecon.methods.joint.settings import (
    JointNoise,
    JointSettings,
    derived_heading_noise,
    derived_lat_noise,
    derived_long_priors,
    prior_table,
)
from flightrecon.methods.joint.tilt import erection_driver_g, remembered, tilt_evidence
from flightrecon.types import CleanFlight, FlightMeta, PositionFix, WindLevel


@dataclass(frozen=True)
class SettingChoice:
    """One setting chosen from the flight's data: ``setting`` (a :class:`JointSettings` field,
    ``noise.<field>`` for :class:`JointNoise`, ``priors.<state>`` for a prior (mean, sd)), its
    ``value`` and ``why`` (the evidence)."""

    setting: str
    value: Any
    why: str


@dataclass(frozen=True)
class OutputFrame:
    """What the output needs of the cleaned flight: the grid times ``t_s`` the track is given on,
    the output tangent ``plane``, the known positions ``fixes`` (``--fix``) and the geoid undulation
    [m] that takes them to ellipsoidal heights, the declared ``attitude_source``, the winds-aloft
    levels ``wind_levels`` (``--wind``) and the pseudo-measurements the measurement table's static
    part made of them, ``wind_prior`` (t, w, sd, rho:
    :func:`~flightrecon.methods.joint.measurements.wind_prior_measurements`)."""

    t_s: np.ndarray
    plane: TangentPlane
    fixes: tuple[PositionFix, ...] = ()
    geoid_undulation_m: float = 0.0
    attitude_source: str | None = None
    wind_levels: tuple[WindLevel, ...] = ()
    wind_prior: tuple[np.ndarray, ...] = ()


@dataclass(frozen=True)
class JointProblem:
    """The joint smoother's problem on one flight, frozen (:func:`joint_problem`).

    Attributes
    ----------
    inputs : the smoother's inputs, with the end points (``inputs.end_points``)
    settings : the settings, every data-driven one resolved
    choices : the data-driven choices in the order made, each with its evidence
    tilt_evidence : what the GNSS fixes measured of the attitude's load-driven error
        (:func:`~flightrecon.methods.joint.problem.gnss_tilt_evidence`), or None
    attitude_note : the attitude source's note for the user, or None
    frame : what the output needs of the flight (None: a problem built from inputs alone)
    priors : the checks' table of the sensor errors' priors (``settings.prior_table``)
    flight : what the passes hold fixed, built once of ``inputs`` and ``settings`` (the state grid,
        the increments of the held inputs, the attitude step means, the measurement table's static
        part, the first pass's nominal:
        :func:`~flightrecon.methods.joint.linearisation.smoother_flight`; reused in part by
        :func:`adjusted`); None only once released (the method, after the calibrations)
    """

    inputs: JointInputs
    settings: JointSettings
    choices: tuple[SettingChoice, ...] = ()
    tilt_evidence: dict[str, Any] | None = None
    attitude_note: str | None = None
    frame: OutputFrame | None = None
    flight: SmootherFlight | None = None
    priors: dict[str, tuple[float, float]] | None = None


def held_attitude(t: np.ndarray, *angles_deg: np.ndarray) -> tuple[list[np.ndarray], list[str]]:
    """Roll, pitch, heading with each missing sample replaced by the nearest recorded one.

    The acceleration stays NaN there (the smoother then adds process noise instead of the measured
    acceleration); the rotation of the accelerometer biases and of the ground constraints needs an
    attitude and takes the nearest recorded one.  Returns the angles and a note for the summary when
    any was missing.  An angle never recorded is an error.
    """
    names = ("roll_deg", "pitch_deg", "heading_deg")
    out, notes = [], []
    for name, a in zip(names, angles_deg):
        ok = np.isfinite(a)
        if not ok.any():
            raise ValidationError(f"the joint smoother needs {name}: it has no finite sample",
                                  column=name)
        if ok.all():
            out.append(a)
            continue
        held = a.copy()
        held[~ok] = a[ok][nearest_index(t[ok], t[~ok])]
        out.append(held)
        notes.append(f"joint: {name} missing on {int((~ok).sum())} samples; the acceleration "
                     "there is replaced by process noise and the bias rotation holds the "
                     "nearest recorded attitude")
    return out, notes


def loads_in_ned(g: pd.DataFrame, t_in: np.ndarray,
                  lat_deg: float) -> tuple[np.ndarray, np.ndarray, list[str]]:
    """The (held) recorded attitude (Ni, 3) [deg] and the kinematic acceleration (NED) [m/s^2] of
    the loads on the grid ``g``, NaN where a load factor is saturated, with the notes for the
    summary."""
    def col(name):
        return g[name].to_numpy(dtype=float) if name in g.columns else np.full(len(g), np.nan)

    att, notes = held_attitude(t_in, col("roll_deg"), col("pitch_deg"), col("heading_deg"))
    Cnb = body_to_ned_matrix(*att)
    # gravity at the departure latitude (normal gravity changes by 5e-6 m/s^2 per km north)
    acc = kinematic_acceleration_ned(col("n_long_g"), col("n_lat_g"), col("n_norm_g"),
                                     col("roll_deg"), col("pitch_deg"), col("heading_deg"),
                                     lat_deg=lat_deg,
                                     h_m=np.nan_to_num(col("baro_alt_m")), C_nb=Cnb)
    sat = saturated_loads(g)   # at the recorder's range: a bound, not a reading (as missing)
    if sat.any():
        acc[sat] = np.nan
        notes.append(f"joint: load factors saturated on {int(sat.sum())} samples; treated as "
                     "missing (process noise instead of the acceleration)")
    return np.column_stack(att), acc, notes


def gnss_table(gn: pd.DataFrame, meta: FlightMeta) -> pd.DataFrame:
    """The GNSS fixes as the smoother reads them: ``t_s``, ``lat_deg``, ``lon_deg``, ellipsoidal
    ``h_m`` (NaN without a height), velocities and per-fix accuracies where recorded."""
    gnss = pd.DataFrame()
    if len(gn) and {"gnss_lat_deg", "gnss_lon_deg"} <= set(gn.columns):
        alt = (gn["gnss_alt_m"].to_numpy(float) if "gnss_alt_m" in gn.columns
               else np.full(len(gn), np.nan))
        if meta.gnss_alt_datum.lower() == "msl":
            alt = alt + meta.geoid_undulation_m
        gnss = pd.DataFrame({"t_s": gn["t_s"].to_numpy(float), "lat_deg": gn["gnss_lat_deg"],
                             "lon_deg": gn["gnss_lon_deg"], "h_m": alt})
        if {"gnss_vn_mps", "gnss_ve_mps"} <= set(gn.columns):
            gnss["vn_mps"] = gn["gnss_vn_mps"].to_numpy(float)
            gnss["ve_mps"] = gn["gnss_ve_mps"].to_numpy(float)
        # the receiver's per-fix accuracy (docs/ingest.md, "GNSS as receivers write it")
        for src, dst in (("gnss_h_sd_m", "h_sd_m"), ("gnss_v_sd_m", "v_sd_m"),
                         ("gnss_vel_sd_mps", "vel_sd_mps")):
            if src in gn.columns:
                gnss[dst] = gn[src].to_numpy(float)
    return gnss


def radar_table(rd: pd.DataFrame) -> pd.DataFrame:
    """The radar plots as the smoother reads them: ``t_s``, ``range_m``, ``azimuth_rad``
    (``elevation_rad`` where recorded); empty without range and azimuth."""
    radar = pd.DataFrame()
    if len(rd) and {"arms_range_m", "arms_azimuth_deg"} <= set(rd.columns):
        radar = pd.DataFrame({"t_s": rd["t_s"].to_numpy(float),
                              "range_m": rd["arms_range_m"].to_numpy(float),
                              "azimuth_rad": np.radians(rd["arms_azimuth_deg"].to_numpy(float))})
        if "arms_elevation_deg" in rd.columns:
            radar["elevation_rad"] = np.radians(rd["arms_elevation_deg"].to_numpy(float))
    return radar


def baro_field_reference_m(meta: FlightMeta) -> float:
    """What ``baro_alt_m`` reads on the ground at the departure field, by its datum
    (``meta.baro_datum``, docs/ingest.md): the reference of the smoother's ``baro_rel_m``.

    * ``"pressure"`` (1013.25 hPa): the field's pressure altitude under the departure QNH,
      :func:`flightrecon.geo.atmosphere.field_pressure_altitude_m` (its elevation where the
      QNH is not known, the offset state taking the difference, 8.3 m per hPa);
    * ``"qnh"``: an altimeter set to the field's QNH reads its elevation (MSL) on the ground,
      whatever the QNH: the elevation itself (converting it as if it were a pressure altitude
      would put the offset 8.3 m per hPa of QNH - 1013.25 off);
    * ``"qfe"``: an altimeter set to the field's pressure reads 0 on the ground.

    Above the field all three differ from the height above it by the same temperature scale (the
    hypsometric equation; to 0.3 % for a QNH 10 hPa from standard), the smoother's ``baro_scale``
    state.  ``meta.departure`` must be set.
    """
    dep = meta.departure
    if dep is None:
        raise MetadataError("the baro channel's field reference needs the departure airfield")
    if meta.baro_datum == "qnh":
        return float(dep.elev_m)
    if meta.baro_datum == "qfe":
        return 0.0
    return float(field_pressure_altitude_m(dep.elev_m, meta.qnh_departure_hpa))


def airfield_geometry(meta: FlightMeta) -> dict[str, Any]:
    """The airfields and the station as the smoother reads them: ``station``, ``departure``,
    ``arrival`` as (lat, lon, h_ellipsoidal), the runways' true directions ``runway_rad`` [rad] and
    their ``thresholds`` (lat, lon, h_ellipsoidal), ``None`` each where unknown; the known positions
    ``fixes`` (F, 5) (:attr:`JointInputs.fixes`) or None."""
    N_und = meta.geoid_undulation_m

    def pos(p):
        if p is None:
            return None
        return (p.lat_deg, p.lon_deg, float(msl_to_ellipsoid(p.elev_m, N_und)))

    def runway(p):
        return None if p is None or p.runway_true_deg is None else float(
            np.radians(p.runway_true_deg))

    def threshold(p):
        if p is None or p.threshold is None:
            return None
        return (float(p.threshold[0]), float(p.threshold[1]),
                float(msl_to_ellipsoid(p.elev_m, N_und)))

    fixes = None
    if meta.fixes:
        fixes = np.array([[f.t_s, f.lat_deg, f.lon_deg,
                           np.nan if f.alt_msl_m is None else f.alt_msl_m + N_und, f.sd_m]
                          for f in meta.fixes], dtype=float)
    return {"station": pos(meta.station), "departure": pos(meta.departure),
            "arrival": pos(meta.arrival),
            "runway_rad": (runway(meta.departure), runway(meta.arrival)),
            "thresholds": (threshold(meta.departure), threshold(meta.arrival)), "fixes": fixes}


def recorded_channels(g: pd.DataFrame, meta: FlightMeta, lat_deg: float) -> dict[str, Any]:
    """The grid's channels as the smoother reads them (:class:`JointInputs` fields ``t_in``,
    ``acc_ned``, ``attitude_deg``, ``tas``, ``heading_rad``, ``baro_rel_m``, ``field_h``,
    ``wind_ne``, ``doppler_gs``, ``drift_rad``, ``f_body_g``, ``wind_aloft``, ``notes``), gravity at
    ``lat_deg``."""
    def col(name):
        return g[name].to_numpy(dtype=float) if name in g.columns else np.full(len(g), np.nan)

    t_in = g["t_s"].to_numpy(float)
    att, acc, notes = loads_in_ned(g, t_in, lat_deg)
    dep = meta.departure
    h_pf, field_h = 0.0, 0.0
    if dep is not None:
        h_pf = baro_field_reference_m(meta)
        field_h = float(msl_to_ellipsoid(dep.elev_m, meta.geoid_undulation_m))
    wind = None
    if "wind_speed_mps" in g.columns and "wind_from_deg" in g.columns:
        wind = wind_toward_ne(col("wind_speed_mps"), col("wind_from_deg"))
    wa = wind_aloft_on_grid(g, meta)
    return {"t_in": t_in, "acc_ned": acc, "attitude_deg": att, "tas": col("tas_mps"),
            "heading_rad": np.radians(col("heading_deg")),
            "baro_rel_m": col("baro_alt_m") - h_pf, "field_h": field_h, "wind_ne": wind,
            "doppler_gs": col("doppler_gs_mps") if "doppler_gs_mps" in g.columns else None,
            "drift_rad": np.radians(col("drift_deg")) if "drift_deg" in g.columns else None,
            "f_body_g": np.c_[col("n_long_g"), col("n_lat_g"), -col("n_norm_g")],
            "wind_aloft": None if wa is None else np.c_[wa[0], wa[1]], "notes": tuple(notes)}


def joint_inputs(clean: CleanFlight, noise: JointNoise | None = None) -> JointInputs:
    """Assemble the smoother's inputs from a cleaned flight (SI, recorder time base), with the
    take-off roll and the end points (:func:`~flightrecon.methods.joint.inputs.end_points`, under
    ``noise``: the settings' ``JointNoise``, the defaults where not given)."""
    meta = clean.meta
    # the departure, or without one the frame origin from the first fix (cleaning/origin.py)
    p0 = meta.departure if meta.departure is not None else getattr(meta, "origin", None)
    if p0 is None:
        raise MetadataError("the joint smoother needs the departure position (--departure) or a "
                            "GNSS / radar fix: it anchors the output plane and the latitude of "
                            "normal gravity")
    ph = clean.phases
    la = meta.gnss_lever_arm_m
    inp = JointInputs(
        **recorded_channels(clean.grid, meta, p0.lat_deg), **airfield_geometry(meta),
        gnss=gnss_table(clean.gnss, meta), radar=radar_table(clean.radar),
        liftoff_t=float(ph.liftoff_t_s) if ph is not None else np.nan,
        touchdown_t=float(ph.touchdown_t_s) if ph is not None else np.nan,
        lever_arm=(float(la[0]), float(la[1]), float(la[2])),
        lineup_t=float(getattr(ph, "lineup_t_s", np.nan)) if ph is not None else np.nan,
        ends_airborne=bool(ph is not None and ph.ends_airborne))
    if "n_long_g" in meta.ingest.derived_channels:
        inp = without_floor_loads(inp)
    if not (ph is not None and ph.starts_airborne):
        roll = takeoff_roll(inp.t_in, inp.acc_ned, inp.heading_rad, inp.tas, inp.liftoff_t,
                            inp.wind_ne, not_before_t=inp.lineup_t)
        if not np.isfinite(roll.start_t) and ph is not None:
            roll = phases_roll(ph)
        inp = replace(inp, roll=roll)
    return replace(inp, end_points=end_points(inp, JointNoise() if noise is None else noise))


def choices_between(before: JointSettings, after: JointSettings,
                    why: str) -> tuple[SettingChoice, ...]:
    """The settings ``after`` changed from ``before``, each as a :class:`SettingChoice` for the
    reason ``why``: the noise fields, the priors added and any other field."""
    out = []
    for f in fields(before):
        a, b = getattr(before, f.name), getattr(after, f.name)
        if f.name == "noise":
            out += [SettingChoice(f"noise.{g.name}", getattr(b, g.name), why)
                    for g in fields(a) if getattr(a, g.name) != getattr(b, g.name)]
        elif f.name == "priors":
            out += [SettingChoice(f"priors.{p[0]}", (float(p[1]), float(p[2])), why)
                    for p in b if p not in a]
        elif a != b:
            out.append(SettingChoice(f.name, b, why))
    return tuple(out)


#: why each data-driven setting was chosen (the evidence it reads)
WHY = {
    "heading": "a heading propagated from the body rates: the grid's heading_sd_deg",
    "long": "n_long_g derived from airspeed and pitch at ingest: not a sensor's errors",
    "lat": "n_lat_g assumed (coordinated flight) at ingest: its missed side force",
    "sampling": "the loads' airborne sample-to-sample differences (a slow record)",
    "sat": "the recorded static air temperature's deviation from the ISA (airborne)",
    "tilt": "the declared attitude source, the GNSS fixes' measure of the tilt",
}


def resolved_settings(clean: CleanFlight, inp: JointInputs, settings: JointSettings
                      ) -> tuple[JointSettings, tuple[SettingChoice, ...], dict | None,
                                 str | None]:
    """The settings as the inputs call for them, with the choices made, the GNSS tilt evidence and
    the attitude source's note: the loads' sampling noise (:func:`sampled_loads_noise`), the SAT's
    prior of the pressure-altitude scale (:func:`temperature_baro_prior`), the attitude reference's
    tilt noise (:func:`~flightrecon.methods.joint.problem.attitude_source_noise`), in this order
    (each reads the settings the one before it chose)."""
    meta = clean.meta
    current = sampled_loads_noise(inp, settings)
    choices = choices_between(settings, current, WHY["sampling"])
    if meta.departure is not None and "sat_degc" in clean.grid.columns:
        h_p_field_m = field_pressure_altitude_m(meta.departure.elev_m, meta.qnh_departure_hpa)
        sat = temperature_baro_prior(inp, clean.grid["sat_degc"].to_numpy(float), h_p_field_m,
                                     current)
        choices += choices_between(current, sat, WHY["sat"])
        current = sat
    tilt_ev = (gnss_tilt_evidence(clean, inp, current)
               if tilt_noise_open(clean, inp, current) else None)
    tilted, attitude_note = attitude_source_noise(clean, inp, current, tilt_ev)
    choices += choices_between(current, tilted, attitude_note or WHY["tilt"])
    current = tilted
    return current, choices, tilt_ev, attitude_note


def output_frame(clean: CleanFlight, flight: SmootherFlight) -> OutputFrame:
    """What the output needs of ``clean`` and of its ``flight`` (:class:`OutputFrame`)."""
    meta = clean.meta
    return OutputFrame(t_s=clean.grid["t_s"].to_numpy(float), plane=output_plane(meta),
                       fixes=tuple(meta.fixes), geoid_undulation_m=meta.geoid_undulation_m,
                       attitude_source=meta.attitude_source, wind_levels=tuple(meta.wind_aloft),
                       wind_prior=flight.static.wind_prior)


def joint_problem(clean: CleanFlight, settings: JointSettings | None = None) -> JointProblem:
    """The joint smoother's problem on ``clean`` (:class:`JointProblem`): the settings the flight's
    channels call for (:mod:`~flightrecon.methods.joint.settings`: ``derived_heading_noise``,
    ``derived_long_priors``, ``derived_lat_noise``), the inputs with their end points
    (:func:`~flightrecon.methods.joint.inputs.joint_inputs`), then the settings the inputs call for
    (:func:`resolved_settings`); every choice with its evidence."""
    s = settings or JointSettings()
    choices: tuple[SettingChoice, ...] = ()
    for derive, why in ((derived_heading_noise, "heading"), (derived_long_priors, "long"),
                        (derived_lat_noise, "lat")):
        before, s = s, derive(clean, s)
        choices += choices_between(before, s, WHY[why])
    inp = joint_inputs(clean, s.noise)
    final, more, tilt_ev, note = resolved_settings(clean, inp, s)
    flight = smoother_flight(inp, final)
    return JointProblem(inputs=inp, settings=final, choices=choices + more, tilt_evidence=tilt_ev,
                        attitude_note=note, frame=output_frame(clean, flight), flight=flight,
                        priors=prior_table(final))


def problem_of(inp: JointInputs, settings: JointSettings | None = None) -> JointProblem:
    """The problem of inputs made without a cleaned flight (tests, studies): ``settings`` (the
    defaults where not given) as they are, no choices, no output frame."""
    s = JointSettings() if settings is None else settings
    return JointProblem(inputs=inp, settings=s, flight=smoother_flight(inp, s),
                        priors=prior_table(s))


def adjusted(problem: JointProblem, *, inputs: JointInputs | None = None,
             settings: JointSettings | None = None,
             choice: SettingChoice | None = None) -> JointProblem:
    """``problem`` with other ``inputs`` or ``settings`` (those not given unchanged) and ``choice``
    appended to its choices: a calibration's problem (docs/joint.md, "How the joint is built and
    solved", item 3), on the flight's parts already built.

    The inputs may differ in the GNSS fixes only and the settings in the gust sd and the wind walk
    only: none of the flight's parts depends on these but the process noise (recomputed) and, on the
    fixes, the nominal (built again), so the rest are the same arrays (the held-out smoothing of the
    gap calibration: 0.27 s and a second copy less on a 10-hour flight; the wind walk's rounds: the
    measurement table and the increments built once).  Any other difference is another problem
    (:func:`joint_problem`, :func:`problem_of`) and raises ``ValueError``."""
    inp = problem.inputs if inputs is None else inputs
    s = problem.settings if settings is None else settings
    fl = problem.flight

    def q_free(x: JointSettings) -> JointSettings:
        return replace(x, estimate_gust=False, noise=replace(x.noise, gust_mps=1.0,
                                                             wind_rw_mps_sqrt_s=1.0))

    if (fl is None or q_free(s) != q_free(fl.settings)
            or any(getattr(inp, f.name) is not getattr(fl.inp, f.name)
                   for f in fields(inp) if f.name != "gnss")):
        raise ValueError("an adjusted joint problem differs in the GNSS fixes, the gust sd and the "
                         "wind walk only (and needs its problem's flight); another is built by "
                         "joint_problem or problem_of")
    flight = replace(fl, inp=inp, settings=s, q=q_vector(s.noise), nominal=(
        fl.nominal if inp.gnss is fl.inp.gnss else nominal_trajectory(inp, fl.idx)))
    return replace(problem, inputs=inp, settings=s, flight=flight,
                   choices=(*problem.choices, *(() if choice is None else (choice,))))


def temperature_baro_prior(inp: JointInputs, sat_degc: np.ndarray, h_p_field_m: float,
                           settings: JointSettings) -> JointSettings:
    """The prior of the pressure-altitude scale ``c`` of the baro row ``h_p - h_p,f = (1 + c)(h -
    h_field) + b_h`` from the recorded static air temperature (docs/joint.md, "The pressure-altitude
    scale from the temperature", eq. 1-2): the mean ISA deviation ``dT`` of the airborne samples
    (:func:`~flightrecon.geo.pressure_height.isa_deviation_k`) gives each sample's height above the
    field ``H_k`` (:func:`flightrecon.geo.atmosphere.height_above_field_m`) and the least-squares
    ``1 + c = sum(dh_p,k H_k) / sum(H_k^2)``; its sd is that fit's change over ``sqrt(s^2 +
    sat_column_k^2)`` kelvin (``s`` the samples' spread of ``dT``).  Too few samples, or a
    ``baro_scale`` prior given in ``settings.priors`` (the user's, a fleet's): unchanged."""
    if any(p[0] == "baro_scale" for p in settings.priors):
        return settings
    h_p_all = inp.baro_rel_m + h_p_field_m
    deviation = isa_deviation_k(h_p_all, sat_degc, airborne_samples(inp))
    if deviation is None:
        return settings
    ok = (airborne_samples(inp) & np.isfinite(np.asarray(sat_degc, dtype=float))
          & np.isfinite(h_p_all))
    dh_p = inp.baro_rel_m[ok]
    h_p = h_p_all[ok]
    if not np.any(np.abs(dh_p) > 0):
        return settings

    def scale(dt_k: float) -> float:
        H = height_above_field_m(h_p, h_p_field_m, dt_k)
        return float(np.sum(dh_p * H) / np.sum(H * H)) - 1.0

    d_mean, spread = deviation
    sd_t = float(np.hypot(spread, settings.noise.sat_column_k))
    c0 = scale(d_mean)
    sd_c = 0.5 * abs(scale(d_mean + sd_t) - scale(d_mean - sd_t))
    if not (np.isfinite(c0) and np.isfinite(sd_c) and sd_c > 0):
        return settings
    return replace(settings, priors=(*settings.priors, ("baro_scale", c0, sd_c)))


#: fewest airborne sample-to-sample differences of the loads for :func:`sampled_loads_noise`
MIN_LOAD_DIFFERENCES = 60


def sampled_loads_noise(inp: JointInputs, settings: JointSettings) -> JointSettings:
    """The white-acceleration PSD per NED axis that the loads' own sampling implies (docs/joint.md,
    "1 Hz records: the loads' sampling, and the baro channel's datum"): the part of the acceleration
    that changes from one sample to the next, unresolved, makes each interval's velocity increment
    wrong by ``w_k dt``, a random walk of PSD ``q_s = s^2 dt``, ``s^2 = E[(a_{k+1} - a_k)^2] / 2``
    (over the airborne steps, on the NED acceleration the smoother is given).  It holds the sensor's
    own white noise, so it replaces the budget ``accel_noise_mps2_sqrt_hz`` where larger: the extra
    ``JointNoise.accel_sampling_mps2_sqrt_hz`` is sqrt(max(0, q_s - q_acc)) per axis (a record at
    recorder rate gets none).  Fewer than ``MIN_LOAD_DIFFERENCES`` differences, or an extra set by
    the user: unchanged."""
    nz = settings.noise
    if any(v > 0 for v in nz.accel_sampling_mps2_sqrt_hz):
        return settings
    t = inp.t_in
    air = airborne_samples(inp)
    a = inp.acc_ned
    ok = air[1:] & air[:-1] & np.isfinite(a[1:]).all(axis=1) & np.isfinite(a[:-1]).all(axis=1)
    if ok.sum() < MIN_LOAD_DIFFERENCES:
        return settings
    dt = np.diff(t)[ok]
    d = np.diff(a, axis=0)[ok]
    q_s = np.mean(d ** 2 * dt[:, None], axis=0) / 2.0   # s^2 dt per axis, dt-weighted
    extra = np.sqrt(np.maximum(q_s - nz.accel_noise_mps2_sqrt_hz ** 2, 0.0))
    if not np.all(np.isfinite(extra)) or not np.any(extra > 0):
        return settings
    return replace(settings, noise=replace(
        nz, accel_sampling_mps2_sqrt_hz=(float(extra[0]), float(extra[1]), float(extra[2]))))


#: the attitude reference's tilt noise for an attitude declared ``attitude_source = "ahrs"``
#: (methods/joint/tilt.py eq. 2: 1 m/s^2 per g of the erection driver, measured on the PH-LAB
#: AHRS; docs/realflights.md)
AHRS_TILT_MPS2_PER_G = 1.0

#: and the horizontal acceleration's share of its driver (tilt.py eq. 1b): 1, the aircraft's
#: whole acceleration (PH-LAB reference flight recorder only: 19.7 km RMS with the load's
#: departure alone, 3.8 km with it; docs/realflights.md)
AHRS_TILT_HORIZONTAL = 1.0

#: the remembered erection driver [g] (tilt.py eq. 1) above which an undeclared attitude source
#: is announced: below it the tilt noise would be a few tenths of m/s per minute
UNDECLARED_TILT_WARN_G = 0.1

#: a tilt gain measured by the GNSS below this [m/s^2 per g] is not used for an undeclared
#: source: JSBSim's attitude with its sensors' errors gives 0.04-0.18 on ten airwork, holding,
#: go-around, circuit, cross-country and jet flights, the PH-LAB AHRS 0.27 and 0.40
#: (docs/joint.md, "The attitude reference after sustained loads"); with 0.2 on JSBSim's
#: airwork (measured before the cubic fix velocities) a withheld 300 s gap went from 2 to 24 m
TILT_GAIN_MIN_MPS2_PER_G = 0.25


def gnss_tilt_evidence(clean: CleanFlight, inp: JointInputs,
                       settings: JointSettings) -> dict | None:
    """:func:`flightrecon.methods.joint.tilt.tilt_evidence` on the flight's GNSS fixes (those the
    smoother uses: withheld ones are not in ``inp.gnss``) between 30 s after the lift-off and 30 s
    before the touchdown (or the record's end); ``None`` without loads, fixes or a lift-off."""
    g = inp.gnss
    ph = clean.phases
    if (inp.f_body_g is None or g is None or len(g) < 10 or ph is None
            or not np.isfinite(ph.liftoff_t_s)):
        return None
    lat, lon = g["lat_deg"].to_numpy(float), g["lon_deg"].to_numpy(float)
    ok = np.isfinite(lat) & np.isfinite(lon)
    t_end = ph.touchdown_t_s if np.isfinite(ph.touchdown_t_s) else float(inp.t_in[-1])
    nz = settings.noise
    # on block means of about half a second (the windows are a minute long; a 10-hour, 16 Hz
    # record's regressors at full rate would be 150 MB)
    t = inp.t_in
    k = max(int(round(0.5 / float(np.median(np.diff(t))))), 1) if len(t) > 1 else 1
    nb = len(t) // k

    def blocks(x: np.ndarray) -> np.ndarray:  # NaN where a sample of the block is missing
        x = np.asarray(x, float)[:nb * k]
        return x.reshape((nb, k) + x.shape[1:]).mean(axis=1)

    tb, acc, fb = blocks(t), blocks(inp.acc_ned), blocks(inp.f_body_g)
    att = blocks(inp.attitude_deg[:, :2])
    psi = blocks(inp.heading_rad)
    C = body_to_ned_matrix(att[:, 0], att[:, 1], np.degrees(psi))
    f_ned_h = C[:, :2, :] * (fb * G0_MPS2)[:, None, :]
    return tilt_evidence(tb, acc, fb, psi, f_ned_h, g["t_s"].to_numpy(float)[ok], lat[ok], lon[ok],
                         ph.liftoff_t_s + 30.0, t_end - 30.0, tau_s=nz.ahrs_tilt_tau_s,
                         window_s=nz.ahrs_tilt_tau_s,
                         horizontal=nz.ahrs_tilt_horizontal or AHRS_TILT_HORIZONTAL)


def tilt_noise_open(clean: CleanFlight, inp: JointInputs, settings: JointSettings) -> bool:
    """Whether the flight's tilt noise is still to be chosen (:func:`attitude_source_noise`): not
    where the sidecar declares an inertial reference, the settings give the gain, or the log has no
    loads; only then is the GNSS's measurement (:func:`gnss_tilt_evidence`) of use."""
    return not (clean.meta.attitude_source == "inertial"
                or settings.noise.ahrs_tilt_mps2_per_g > 0.0 or inp.f_body_g is None)


def attitude_source_noise(clean: CleanFlight, inp: JointInputs, settings: JointSettings,
                          evidence: dict | None) -> tuple[JointSettings, str | None]:
    """The tilt noise from the flight's declared attitude source and its GNSS (docs/joint.md, "The
    attitude reference after sustained loads").

    Settings that give the tilt gain win.  ``"inertial"`` leaves the settings (no tilt). Otherwise,
    where the GNSS fixes measure the gain (:func:`gnss_tilt_evidence`: the loads integrated through
    the attitude against the fixes' velocity, the constant biases removed), that gain is used, at
    most :data:`AHRS_TILT_MPS2_PER_G`, with the horizontal share :data:`AHRS_TILT_HORIZONTAL`, and
    the returned note says so (undeclared: only from :data:`TILT_GAIN_MIN_MPS2_PER_G`; below it the
    attitude is taken as inertial without a note, the fixes having shown it holds); ``"ahrs"``
    without that evidence takes :data:`AHRS_TILT_MPS2_PER_G`.  Undeclared and unmeasured, the
    attitude is taken as inertial (off) and the note says so where the loads' remembered departure
    (tilt.py eq. 1) exceeds :data:`UNDECLARED_TILT_WARN_G` (a guess warns).  ``evidence``:
    :func:`gnss_tilt_evidence` measured (``None``: none)."""
    nz = settings.noise
    src = clean.meta.attitude_source
    if not tilt_noise_open(clean, inp, settings) or inp.f_body_g is None:  # (typed: no loads)
        return settings, None
    if evidence is not None:
        c = min(evidence["gain_mps2_per_g"], AHRS_TILT_MPS2_PER_G)
        if c < TILT_GAIN_MIN_MPS2_PER_G and src is None:
            return settings, None  # the fixes show no load-driven error worth the noise
        ev = evidence
        note = (f"joint: the GNSS measures the attitude's load-driven error: the loads "
                f"integrated through the recorded attitude leave the fixes by "
                f"{ev['gain_mps2_per_g']:.2f} m/s^2 per g of sustained load ({ev['busy_windows']} "
                f"of {ev['windows']} windows of {ev['window_s']:.0f} s under load, constant "
                f"biases removed); the tilt noise is set to {c:.2f} m/s^2 per g "
                f"(attitude source {src or 'not declared'}; docs/joint.md)")
        return replace(settings, noise=replace(
            nz, ahrs_tilt_mps2_per_g=c,
            ahrs_tilt_horizontal=nz.ahrs_tilt_horizontal or AHRS_TILT_HORIZONTAL)), note
    if src == "ahrs":
        return replace(settings, noise=replace(
            nz, ahrs_tilt_mps2_per_g=AHRS_TILT_MPS2_PER_G,
            ahrs_tilt_horizontal=nz.ahrs_tilt_horizontal or AHRS_TILT_HORIZONTAL)), None
    D = remembered(inp.t_in, erection_driver_g(inp.f_body_g, inp.acc_ned,
                                               nz.ahrs_tilt_horizontal), nz.ahrs_tilt_tau_s)
    i = int(np.argmax(D)) if len(D) else 0
    if not len(D) or D[i] <= UNDECLARED_TILT_WARN_G:
        return settings, None
    return settings, (f"joint: attitude source not declared, taken as inertial (no tilt noise); "
                      f"the loads depart from 1 g by {D[i]:.2f} g over a minute at "
                      f"t = {inp.t_in[i]:.0f} s, where an attitude and heading reference "
                      "erects wrongly: declare [flight] attitude_source = \"ahrs\" or "
                      "\"inertial\" in the sidecar (docs/joint.md)")
