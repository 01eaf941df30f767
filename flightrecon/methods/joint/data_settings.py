"""The joint smoother's settings as the data call for them: the priors of a heading from the
body rates and of a derived ``n_long_g``, the loads' noise of an assumed ``n_lat_g``, the
pressure-altitude scale from the SAT, the loads' sampling noise of a slow record, and the wind
walk re-estimated where the wind outran it."""

from __future__ import annotations

from dataclasses import replace
from typing import Any

import numpy as np

from flightrecon.geo.atmosphere import height_above_field_m
from flightrecon.geo.pressure_height import isa_deviation_k
from flightrecon.methods.joint import (
    JointInputs,
    JointRun,
    JointSettings,
    smooth_joint,
)
from flightrecon.methods.joint.diagnostics import (
    wind_walk_check,
)
from flightrecon.types import CleanFlight


def derived_heading_noise(clean: CleanFlight, settings: JointSettings) -> JointSettings:
    """A heading propagated from the body rates (``heading_sd_deg`` on the grid, cleaning's
    ``heading_from_rates``) has a slowly varying error (anchor offset, gyro-bias drift): the
    heading-bias state's prior is widened to its largest sd and its random walk to what lets
    the bias follow that sd's growth over the record (both never below the settings)."""
    g = clean.grid
    if "heading_sd_deg" not in g.columns:
        return settings
    sd = g["heading_sd_deg"].to_numpy(float)
    if not np.isfinite(sd).any():
        return settings
    nz = settings.noise
    span = max(float(g["t_s"].iloc[-1] - g["t_s"].iloc[0]), 1.0)
    prior = max(nz.heading_bias_deg, float(np.nanmax(sd)))
    rw = max(nz.heading_bias_rw_deg_sqrt_s, float(np.nanmax(sd)) / np.sqrt(span))
    return replace(settings, noise=replace(nz, heading_bias_deg=prior,
                                           heading_bias_rw_deg_sqrt_s=rw))


#: prior sd of the forward accelerometer's scale error and bias when ``n_long_g`` was not
#: recorded but derived from airspeed and pitch at ingest (flightrecon/ingest/derive.py): its
#: error is no sensor's, but the missed angle-of-attack and along-track wind terms (order
#: 0.01 g, a few per cent of the channel); the sensor budget (0.5 %, 0.003 g) is too tight
DERIVED_LONG_SCALE_SD = 0.1
DERIVED_LONG_BIAS_G = 0.01


def derived_long_priors(clean: CleanFlight, settings: JointSettings) -> JointSettings:
    """Wider priors of the forward accelerometer's scale and bias for a derived ``n_long_g``
    (ingest's ``derived_channels``); a prior the user gave for them is kept."""
    if "n_long_g" not in (clean.meta.extra.get("derived_channels") or {}):
        return settings
    given = {p[0] for p in settings.priors}
    extra = tuple(p for p in (("accel_scale_x", 0.0, DERIVED_LONG_SCALE_SD),
                              ("accel_bias_x_g", 0.0, DERIVED_LONG_BIAS_G)) if p[0] not in given)
    return replace(settings, priors=(*settings.priors, *extra))


#: white acceleration noise [m/s^2/sqrt(Hz)] for an ``n_lat_g`` taken as coordinated flight's
#: (0 g) at ingest (flightrecon/ingest/derive.py, ``derive_n_lat``): the side force it misses
#: is a Gauss-Markov acceleration of sd ``s`` 0.02-0.03 g (0.2-0.25 m/s^2; the JSBSim T-6's
#: air work: 0.026 g RMS, 60-s means to 0.017 g) and correlation time ``tau`` of tens of
#: seconds, whose white equivalent is ``sqrt(2 s^2 tau)`` = 0.9-1.5; the loads' noise is one
#: figure for the three axes.  Measured (docs/ingest.md, "Normal acceleration alone"): the
#: sensor budget's 0.05 left NEES of 3-22 where the side force persists, 1.0 brings them to 1.5
#: at most
DERIVED_LAT_ACCEL_NOISE = 1.0


def derived_lat_noise(clean: CleanFlight, settings: JointSettings) -> JointSettings:
    """The loads' white noise for an ``n_lat_g`` assumed at ingest (``derived_channels``):
    :data:`DERIVED_LAT_ACCEL_NOISE`, never below the settings'."""
    if "n_lat_g" not in (clean.meta.extra.get("derived_channels") or {}):
        return settings
    nz = settings.noise
    return replace(settings, noise=replace(nz, accel_noise_mps2_sqrt_hz=max(
        nz.accel_noise_mps2_sqrt_hz, DERIVED_LAT_ACCEL_NOISE)))


def airborne_samples(inp: JointInputs) -> np.ndarray:
    """Input samples from lift-off to touchdown (the whole record where either is unknown)."""
    t = inp.t_in
    air = np.ones(len(t), bool)
    if np.isfinite(inp.liftoff_t):
        air &= t >= inp.liftoff_t
    if np.isfinite(inp.touchdown_t):
        air &= t <= inp.touchdown_t
    return air


def temperature_baro_prior(inp: JointInputs, sat_degc: np.ndarray, h_p_field_m: float,
                           settings: JointSettings) -> JointSettings:
    """The prior of the pressure-altitude scale ``c`` from the recorded static air temperature.

    The smoother's baro row is ``h_p - h_p,f = (1 + c)(h - h_field) + b_h``.  In air warmer
    than the ISA by ``dT`` the height above the field exceeds the pressure-altitude difference
    by ``dT / T`` (:func:`flightrecon.geo.atmosphere.height_above_field_m`, eq. 1-2): ``c``
    is the temperature's, not an unknown of 5 % (a 15 K deviation) to be found from the
    accelerations.  With the deviation ``dT_k = SAT_k - T_ISA(h_p,k)`` of the airborne samples
    (lift-off to touchdown; ``h_p,k = baro_rel_k + h_p,f``), their mean ``dT`` gives each
    sample's height above the field ``H_k`` (eq. 2) and ``c`` is the least-squares fit of
    ``h_p,k - h_p,f = (1 + c) H_k``::

        1 + c = sum(dh_p,k H_k) / sum(H_k^2)

    Its sd is that fit's change per kelvin times ``sqrt(s^2 + sat_column_k^2)``: ``s`` the
    spread of the samples' ``dT`` (the column is not one deviation everywhere),
    ``JointNoise.sat_column_k`` what the recorded SAT does not tell of the column (probe,
    humidity).  Fewer than :data:`flightrecon.geo.pressure_height.MIN_SAT_SAMPLES` samples
    (:func:`~flightrecon.geo.pressure_height.isa_deviation_k`), or a ``baro_scale`` prior given in
    ``settings.priors`` (the user's, a fleet's): unchanged.
    """
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
    """The white-acceleration PSD per NED axis that the loads' own sampling implies.

    The smoother integrates the recorded acceleration a_k over each input interval dt as
    a_k dt.  Of a record sampled slower than the aircraft's accelerations vary (a 1 Hz
    glass-cockpit export: turbulence, control inputs, an attitude and a load factor not taken
    at the same instant) the part that changes from one sample to the next is not resolved:
    if it is w_k, uncorrelated from sample to sample with variance s^2, the velocity
    increment over each interval is wrong by w_k dt, a velocity random walk of PSD

        q_s = s^2 dt,    s^2 = E[(a_{k+1} - a_k)^2] / 2

    (the difference of two independent samples has twice their variance; the slow part of the
    acceleration adds little to it at the record's rate and makes q_s an upper bound).  It
    also holds the sensor's own white noise, so q_s replaces the budget
    ``accel_noise_mps2_sqrt_hz`` where it is larger: the extra PSD per axis is
    max(0, q_s - q_acc) (``JointNoise.accel_sampling_mps2_sqrt_hz``, its square root).
    Measured over the airborne steps (lift-off to touchdown, or the whole record), on the
    NED acceleration the smoother is given; a record of recorder rate (8 Hz and more) gives
    q_s below the budget and is left as it is.  Fewer than ``MIN_LOAD_DIFFERENCES``
    differences, or an extra set by the user: unchanged.
    """
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


def inertial_wind_share(inp: JointInputs, settings: JointSettings) -> float:
    """The PSD ``r`` of the loads' velocity random walk where a record sampled slower than
    its accelerations (:func:`sampled_loads_noise` set) has the loads as the wind's only
    witness, else 0 [m^2/s^3].

    Without GNSS, radar, known fixes, a recorded wind, Doppler or a winds-aloft prior, the
    smoother learns the wind's change only as the ground velocity's change from the loads
    less the air velocity's; the loads' error integrates to a velocity random walk of PSD
    ``r = accel_noise_mps2_sqrt_hz^2 + (s_n^2 + s_e^2) / 2`` with ``s`` the horizontal
    ``accel_sampling_mps2_sqrt_hz``.  The smoothed wind change is then the share
    ``kappa = Q / (Q + r L)`` of the observed one (``Q`` the wind model's variance over L;
    :func:`~flightrecon.methods.joint.diagnostics.wind_walk_check`): of a 1 Hz export
    ``r`` is about 0.08 m^2/s^3 (JSBSim's fleet; 0.011 the shipped G1000 export) and over
    ten minutes of the default walk (``Q`` = 1.5 m^2/s^2) ``kappa`` is 0.03 (0.19), where a
    wind that turns moves the smoothed wind by little.  A recorder-rate log (no sampling
    term; ``r`` the budget 0.0025, ``kappa`` 1/2) or any other source of the wind: 0 (the
    check's bound, ``kappa = 1``, within a factor 2 there)."""
    nz = settings.noise
    s = nz.accel_sampling_mps2_sqrt_hz
    if (not (s[0] > 0 or s[1] > 0) or len(inp.gnss) or len(inp.radar)
            or (inp.fixes is not None and len(inp.fixes)) or inp.wind_ne is not None
            or inp.doppler_gs is not None or inp.wind_aloft is not None):
        return 0.0
    return float(nz.accel_noise_mps2_sqrt_hz ** 2 + 0.5 * (s[0] ** 2 + s[1] ** 2))


#: how long after lift-off and before touchdown the rolls still witness the wind where the
#: loads are its only other witness: a derived ``n_long_g``'s bias prior (0.01 g) alone
#: integrates to 6 m/s in a minute, beyond the wind walk's 0.4 m/s (0.05 m/s/sqrt(s))
ROLL_WITNESS_S = 60.0
#: false-alarm probability of the wind-walk check where the loads are the wind's only
#: witness: the share kappa leaves out the other witnesses (the end points, the estimated
#: load biases), so its chi-square overstates a change and the check asks for stronger
#: evidence than the bound's 1 %
LOADS_WITNESS_P_FALSE = 1e-4


def wind_walk_rounds(inp: JointInputs, settings: JointSettings, run: JointRun
                      ) -> tuple[JointRun, JointSettings, list[dict[str, Any]]]:
    """Where the smoothed wind moved faster than its random walk allows
    (:func:`~flightrecon.methods.joint.diagnostics.wind_walk_check`, with the loads' PSD
    ``r`` of :func:`inertial_wind_share`), the walk re-estimated from the flight and the
    smoother run again, at most ``settings.wind_rounds`` times.

    The check's worst window (length L, the model's variance ``Q`` of which ``Q_h`` from
    the height flown through, the loads' ``r L``) has ``z^2 = |dw|^2 / (kappa Q)`` with
    ``kappa = Q / (Q + r L)``: the observed change ``|do|^2 = |dw|^2 / kappa^2`` is
    ``z^2 (Q + r L)``.  With ``r = 0`` (another witness of the wind) the walk is scaled so
    that this window would be a typical one, its chi-square at the mean 2 of chi-square(2):
    ``q' = q z^2 / 2`` (the smoothed change of a walk shrinks towards zero by the data's
    weight, so an estimate can be low and the rounds climb).  Where the loads are the only
    witness (``r > 0``) the worst window's change is mostly the loads' error, and the walk is
    the smallest that the check accepts, ``|do|^2 = limit (Q' + r L)``:

        q' L = z^2 (Q + r L) / limit - r L - Q_h

    Never below ``q``, kept below ``wind_rw_max_mps_sqrt_s``, until the smoothed wind is
    within the walk (docs/joint.md, "Wind and turbulence": JSBSim's holding, 22 m/s turning
    100 deg in 30 minutes).  Returns the last run, its settings and the rounds (the walk each
    started from, the check's chi-square and limit, the loads' PSD)."""
    rounds: list[dict[str, Any]] = []
    r = inertial_wind_share(inp, settings)
    within = None
    if r > 0:   # windows clear of the rolls (a record without both: the check as it is)
        if not (np.isfinite(inp.liftoff_t) and np.isfinite(inp.touchdown_t)):
            r = 0.0
        else:
            within = (inp.liftoff_t + ROLL_WITNESS_S, inp.touchdown_t - ROLL_WITNESS_S)
    for _ in range(max(0, settings.wind_rounds)):
        nz = settings.noise
        c = wind_walk_check(run, nz.wind_rw_mps_sqrt_s, nz.wind_shear_mps_per_sqrt_m,
                            loads_psd_m2ps3=r, within_s=within,
                            p_false=LOADS_WITNESS_P_FALSE if r > 0 else 0.01)
        if c is None or nz.wind_rw_mps_sqrt_s >= settings.wind_rw_max_mps_sqrt_s:
            break
        rounds.append({"wind_rw_mps_sqrt_s": nz.wind_rw_mps_sqrt_s, "z2": c["z2"],
                       "limit": c["limit"], "loads_psd_m2ps3": r})
        L = c["t1_s"] - c["t0_s"]
        q = nz.wind_rw_mps_sqrt_s ** 2
        q_h = c["walk_var_m2ps2"] - q * L
        if r > 0:
            q_new = (c["z2"] * (c["walk_var_m2ps2"] + c["loads_var_m2ps2"]) / c["limit"]
                     - c["loads_var_m2ps2"] - q_h) / L
        else:
            q_new = q * 0.5 * c["z2"]
        q_new = max(q_new, q)
        settings = replace(settings, noise=replace(nz, wind_rw_mps_sqrt_s=min(
            float(np.sqrt(q_new)), settings.wind_rw_max_mps_sqrt_s)))
        run = smooth_joint(inp, settings)
    return run, settings, rounds
