"""Settings of the joint smoother: the sources, their noise (:class:`JointNoise`), the iteration
options (:class:`JointSettings`), the sensor-error priors (:data:`PRIOR_STATES`) and the settings a
cleaned flight's channels call for (a heading from the body rates, a derived ``n_long_g``, an
assumed ``n_lat_g``; those the smoother's inputs call for:
:mod:`~flightrecon.methods.joint.problem`)."""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np

from flightrecon.methods.joint import layout as jl
from flightrecon.types import CleanFlight

SOURCES = ("air", "baro", "gnss_pos", "gnss_vel", "radar", "endpoint", "ground", "runway",
           "doppler", "wind", "fix", "wind_aloft")


@dataclass(frozen=True)
class JointNoise:
    """Sensor error budget (one sigma unless stated) and process noise of the joint model.

    Defaults are a stated budget for a transport aircraft's recorder data; see docs/joint.md.
    """

    accel_noise_mps2_sqrt_hz: float = 0.05   # velocity random walk from load-factor noise
    accel_bias_g: float = 0.003              # accelerometer bias, Gauss-Markov sigma
    accel_bias_tau_s: float = 3600.0
    accel_scale: float = 0.005               # accelerometer scale errors, prior per axis
    ahrs_tilt_mps2_per_g: float = 0.0         # attitude reference's erection error after
    #                                          sustained loads: acceleration error per g of
    #                                          the load's departure from 1 g (tilt.py; 0: an
    #                                          inertial attitude, the default; 1.0 measured on
    #                                          the PH-LAB AHRS, docs/realflights.md)
    ahrs_tilt_tau_s: float = 60.0            # its erection time constant (memory of the load)
    ahrs_tilt_horizontal: float = 0.0        # share of the horizontal acceleration in the
    #                                          erection's driver (tilt.py eq. 1b; 0: the load's
    #                                          departure from 1 g alone; 1: the aircraft's
    #                                          whole acceleration, tan(roll) in a turn)
    accel_sampling_mps2_sqrt_hz: tuple[float, float, float] = (0.0, 0.0, 0.0)
    #                                          extra white acceleration per NED axis (added in
    #                                          PSD to accel_noise): the loads' sampling, set
    #                                          from the record (problem.sampled_loads_noise)
    wind_prior_mps: float = 15.0
    wind_rw_mps_sqrt_s: float = 0.05         # wind change with time
    wind_shear_mps_per_sqrt_m: float = 0.05  # wind change with altitude beyond the gradient:
    #                                          sd over 1 m of climb
    wind_gradient_per_km: float = 5.0        # prior of the wind's gradient with height [(m/s)/km]
    wind_gradient_rw_per_km_sqrt_s: float = 0.005  # its change with time
    gust_mps: float = 2.0                    # turbulence: sd of the gust's effect on the air
    #                                          data, along and across (the estimate's start)
    gust_length_m: float = 500.0             # its correlation length (the Dryden scale length
    #                                          above ~500 m): correlation time L / airspeed
    heading_bias_deg: float = 2.0
    attitude_bias_deg: float = 0.5           # roll and pitch biases (attitude reference), each
    heading_bias_rw_deg_sqrt_s: float = 1e-4
    tas_scale: float = 0.03
    baro_offset_m: float = 60.0
    baro_offset_rw_m_sqrt_s: float = 0.05
    baro_scale: float = 0.05                 # without a recorded SAT: a 15 K deviation from
    #                                          the ISA; with one, from it (problem.
    #                                          temperature_baro_prior)
    sat_column_k: float = 1.5                # the column's mean temperature against the
    #                                          recorded SAT, beyond the samples' spread: the
    #                                          probe and its ram-rise correction (1 K) and the
    #                                          unrecorded humidity (the virtual temperature is
    #                                          0.5-1.5 K above T in temperate air), in
    #                                          quadrature
    tas_mps: float = 1.5                     # airspeed noise (used at airdata_rate_hz)
    airspeed_lag_s: float = 0.0              # pitot-static lag (first order), from the data sheet
    heading_deg: float = 0.5
    baro_m: float = 8.0
    gnss_h_m: float = 5.0
    gnss_v_m: float = 10.0
    gnss_vel_mps: float = 0.3
    radar_range_m: float = 50.0
    radar_azimuth_deg: float = 0.25
    radar_elevation_deg: float = 0.3
    endpoint_h_m: float = 1500.0             # lift-off / touchdown point vs airfield reference
    endpoint_v_m: float = 30.0
    last_position_h_m: float = 100.0         # last known position of a record ending airborne
    #                                          or at impact (radar hand-off, wreckage)
    touchdown_m: float = 400.0               # touchdown distance past the runway threshold
    touchdown_sd_m: float = 150.0            # its dispersion
    screen_height_m: float = 15.24           # threshold crossing height (50 ft) above the
    #                                          touchdown: from it, the touchdown distance is the
    #                                          air distance flown to touchdown (inputs.float_
    #                                          touchdown); 0 keeps touchdown_m
    screen_along_sd_m: float = 150.0         # where the approach crosses the screen height,
    #                                          along the runway about the threshold
    float_wind_mps: float = 8.0              # runway wind component over that air distance
    roll_start_sd_m: float = 100.0           # start of the take-off roll vs the threshold
    lineup_heading_deg: float = 1.0          # the nose vs the runway, lined up at rest before
    #                                          the take-off roll (measurements.lineup_heading; with
    #                                          JointSettings.roll_velocity "nose")
    ground_mps: float = 0.5                  # zero vertical and cross-track velocity on ground
    runway_halfwidth_m: float = 25.0         # cross-track offset from the runway centreline
    ground_slip_deg: float = 0.0             # track vs runway on a roll (steering, tyre slip,
    #                                          crosswind): one error for the whole roll (0: off;
    #                                          measured on JSBSim, docs/jsbsim.md)
    doppler_gs_mps: float = 0.5              # Doppler ground-speed noise (used at airdata rate)
    drift_deg: float = 0.3                   # drift-angle noise
    doppler_scale: float = 0.02              # prior of the Doppler scale error
    drift_bias_deg: float = 1.0              # prior of the drift-angle bias
    wind_sensor_mps: float = 4.0             # recorded / forecast wind, per component
    init_pos_m: float = 3000.0
    init_vel_mps: float = 30.0

    def __post_init__(self) -> None:
        acs = self.accel_sampling_mps2_sqrt_hz
        if len(acs) != 3 or not all(np.isfinite(v) and v >= 0 for v in acs):
            raise ValueError("joint noise setting 'accel_sampling_mps2_sqrt_hz' must be three "
                             f"non-negative numbers (north, east, down), got {acs!r}")
        for name in ("ahrs_tilt_mps2_per_g", "ahrs_tilt_horizontal"):
            v = getattr(self, name)
            if not (np.isfinite(v) and v >= 0):
                raise ValueError(f"joint noise setting '{name}' must be a non-negative number, "
                                 f"got {v!r}")
        for name in POSITIVE_NOISE:
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v > 0):
                raise ValueError(f"joint noise setting '{name}' must be a positive number "
                                 f"(it is a measurement's standard deviation or a time "
                                 f"constant), got {v!r}")


POSITIVE_NOISE = ("accel_bias_tau_s", "tas_mps", "heading_deg", "baro_m", "gnss_h_m", "gnss_v_m",
                  "gnss_vel_mps", "radar_range_m", "radar_azimuth_deg", "radar_elevation_deg",
                  "endpoint_h_m", "endpoint_v_m", "touchdown_sd_m", "roll_start_sd_m",
                  "lineup_heading_deg", "ground_mps", "runway_halfwidth_m", "doppler_gs_mps",
                  "drift_deg", "wind_sensor_mps", "last_position_h_m", "gust_mps", "gust_length_m",
                  "ahrs_tilt_tau_s", "sat_column_k", "screen_along_sd_m", "float_wind_mps")
"""JointNoise fields that must be positive (a zero would be a measurement without noise)."""


@dataclass(frozen=True)
class JointSettings:
    """Settings of the joint smoother."""

    noise: JointNoise = field(default_factory=JointNoise)
    state_rate_hz: float = 1.0
    airdata_rate_hz: float = 1.0
    baro_rate_hz: float = 1.0
    wind_rate_hz: float = 1.0 / 1800.0       # recorded wind: errors correlated over ~15 min
    wind_prior: tuple[float, float, float] = (3600.0, 1000.0, 0.25)  # winds-aloft (--wind)
    #   forecast error correlation time [s] and height [m], spacing of its pseudo-measurements
    #   in correlation lengths (docs/wind.md, "The prior in the joint smoother")
    ground_rate_hz: float = 1.0
    min_airspeed_mps: float = 30.0
    roll_velocity: str = "runway"            # the ground roll's velocity rows: along the
    #                                          runway's direction where known ("runway"), or
    #                                          along the true heading with a line-up row on the
    #                                          heading bias ("nose"; runway_measurements)
    crab_s: float = 10.0                     # no air-data heading this close to the runway
    heading_max_roll_deg: float = 45.0       # no air-data heading beyond these attitudes: the
    heading_max_pitch_deg: float = 30.0      # nose is then not along the air velocity (angle of
    #                                          attack times sin(roll), a spin's sideslip)
    heading_attack_offset: bool = True       # the heading measures the nose: take out the angle
    #                                          between it and the air velocity that the angle of
    #                                          attack makes in a bank (measurements.nose_offset)
    iterations: int = 50                     # cap on the Gauss-Newton passes
    converge_m: float = 2.0                  # nominal shift below which the linearisation holds
    converge_weight: float = 0.01            # largest weight change that counts as settled
    cost_tol: float = 1e-5                   # relative MAP-cost change that counts as settled
    line_search: bool = True                 # damp each Gauss-Newton step by backtracking on
    #                                          the MAP cost (False: full steps, cost reported)
    first_gate: bool = True                  # innovation gate in the first pass
    gate_damped: bool = False                # innovation gate also in the damped passes
    first_pass: str = "ekf"                  # "ekf": about the filter's own prediction;
    #                                          "nominal": damped from the nominal trajectory
    levenberg_marquardt: bool = True         # where the line search fails: LM steps
    lm_lambda0: float = 1.0                  # first LM damping (pseudo-measurement variance:
    #                                          the prior variance of each state / lambda)
    lm_lambda_max: float = 1e8               # largest damping tried before giving up
    line_search_halvings: int = 16           # step sizes tried: 1, 1/2, ..., 1/2^16
    huber_c: float = 3.0
    innovation_gate: float = 5.0
    reject_c: float = 8.0
    robust: bool = True
    estimate_gust: bool = True               # the gust sd re-estimated from each pass's track
    #                                          (solve.gust_round) and the iterations continued
    gust_rounds: int = 10                    # at most this many changes of it
    gust_tol: float = 0.1                    # stop when the estimate moves by less (relative)
    gust_bounds_mps: tuple[float, float] = (0.02, 8.0)  # estimates kept inside
    wind_rounds: int = 4                     # where the smoothed wind moves faster than its
    #                                          random walk allows (health.wind_walk_check):
    #                                          at most this many re-estimates of the walk (0: the
    #                                          track is then unhealthy)
    wind_rw_max_mps_sqrt_s: float = 1.0      # the re-estimated walk kept below this
    gap_stretches: int = 6                   # GNSS gaps: held-out stretches of the gaps'
    #                                          length that calibrate the in-gap position sd
    #                                          (calibration.py; 0: off)
    gap_min_s: float = 30.0                  # a GNSS gap: no horizontal fix for longer
    gap_guard_s: float = 60.0                # stretches this far from the gaps, the ends and
    #                                          each other
    gap_factor_bounds: tuple[float, float] = (1e-3, 1e3)  # the in-gap excess variance factor
    gap_stretch_p: float = 0.99              # no stretch-axis's mean NEES beyond this quantile
    #                                          of chi-square(1) after the calibration
    gap_pool_p: float = 0.16                 # the factor the held-out errors support at this
    #                                          one-sided level (chi-square(2 stretches) / dof)
    gap_heldout_passes: int = 3              # the held-out smoothing: at most this many
    #                                          Gauss-Newton passes from the converged run, fewer
    #                                          once one moved the track by <= 10 converge_m (0:
    #                                          the whole iteration again from the nominal)
    estimate_clock: bool = True
    long_load_derived: bool = False          # the forward load factor was derived from the
    #                                          airspeed at ingest (derived_long_priors): the
    #                                          GNSS positions' clock offset is then held
    #                                          (solve.clock_columns)
    estimate_noise: bool = False
    noise_iterations: int = 30               # cap on the EM iterations with estimate_noise
    noise_tol: float = 0.01                  # EM stops when no variance moves by more
    noise_factor_bounds: tuple[float, float] = (0.01, 100.0)  # EM variance factors kept inside
    priors: tuple[tuple[str, float, float], ...] = ()  # (error, mean, sd) replacing the
    #                                          default prior N(0, budget^2): PRIOR_STATES names

    def __post_init__(self) -> None:
        if len(self.wind_prior) != 3 or not all(np.isfinite(v) and v > 0 for v in self.wind_prior):
            raise ValueError(f"wind_prior must be three positive numbers (correlation time "
                             f"[s], height [m], spacing), got {self.wind_prior!r}")
        if self.roll_velocity not in ("runway", "nose"):
            raise ValueError(f"joint roll_velocity {self.roll_velocity!r}: 'runway' or 'nose'")
        if self.first_pass not in ("ekf", "nominal"):
            raise ValueError(f"joint first_pass {self.first_pass!r}: 'ekf' or 'nominal'")
        for name, mean, sd in self.priors:
            if name not in PRIOR_STATES:
                raise ValueError(f"joint prior '{name}': not a sensor-error state (choose from "
                                 f"{', '.join(PRIOR_STATES)})")
            if not (np.isfinite(mean) and np.isfinite(sd) and sd > 0):
                raise ValueError(f"joint prior '{name}': mean {mean!r}, sd {sd!r}: need finite "
                                 "numbers and sd > 0")


#: sensor-error states that take a prior (names as in the summary's ``corrections``):
#: name -> (state index, factor from the reported unit to the state's, JointNoise field of the
#: default prior sd in the reported unit).  The accelerometer biases are first-order
#: Gauss-Markov: a prior mean decays towards zero with their time constant.
PRIOR_STATES: dict[str, tuple[int, float, str]] = {
    "heading_bias_deg": (jl.IPSI, float(np.radians(1.0)), "heading_bias_deg"),
    "tas_scale": (jl.IS, 1.0, "tas_scale"),
    "baro_offset_m": (jl.IBH, 1.0, "baro_offset_m"),
    "baro_scale": (jl.IC, 1.0, "baro_scale"),
    "accel_bias_x_g": (jl.IBA, 1.0, "accel_bias_g"),
    "accel_bias_y_g": (jl.IBA + 1, 1.0, "accel_bias_g"),
    "accel_bias_z_g": (jl.IBA + 2, 1.0, "accel_bias_g"),
    "doppler_scale": (jl.IDW, 1.0, "doppler_scale"),
    "accel_scale_x": (jl.IKS, 1.0, "accel_scale"),
    "accel_scale_y": (jl.IKS + 1, 1.0, "accel_scale"),
    "accel_scale_z": (jl.IKS + 2, 1.0, "accel_scale"),
    "drift_bias_deg": (jl.IDC, float(np.radians(1.0)), "drift_bias_deg"),
    "roll_bias_deg": (jl.IATT, float(np.radians(1.0)), "attitude_bias_deg"),
    "pitch_bias_deg": (jl.IATT + 1, float(np.radians(1.0)), "attitude_bias_deg"),
    "wind_gradient_n_per_km": (jl.IG, 1e-3, "wind_gradient_per_km"),
    "wind_gradient_e_per_km": (jl.IG + 1, 1e-3, "wind_gradient_per_km"),
}


def prior_table(settings: JointSettings) -> dict[str, tuple[float, float]]:
    """(mean, sd) of the prior of every sensor-error state of :data:`PRIOR_STATES`, in its reported
    unit: the one given in ``settings.priors``, else N(0, the noise budget's sd); the table the
    run's checks receive (docs/joint.md, "Outputs": the summary's ``corrections``)."""
    given = {n: (float(mean), float(sd)) for n, mean, sd in settings.priors}
    return {name: given.get(name, (0.0, float(getattr(settings.noise, budget))))
            for name, (_i, _unit, budget) in PRIOR_STATES.items()}


def prior_of(name: str, settings: JointSettings) -> tuple[float, float]:
    """(mean, sd) of the prior of the sensor-error state ``name`` (:func:`prior_table`)."""
    return prior_table(settings)[name]


def derived_heading_noise(clean: CleanFlight, settings: JointSettings) -> JointSettings:
    """A heading propagated from the body rates (``heading_sd_deg`` on the grid, cleaning's
    ``heading_from_rates``) has a slowly varying error (anchor offset, gyro-bias drift): the
    heading-bias state's prior is widened to its largest sd and its random walk to what lets the
    bias follow that sd's growth over the record (both never below the settings)."""
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
    (ingest's ``derived_channels``), and ``long_load_derived`` set; a prior the user gave for them
    is kept."""
    if "n_long_g" not in clean.meta.ingest.derived_channels:
        return settings
    given = {p[0] for p in settings.priors}
    extra = tuple(p for p in (("accel_scale_x", 0.0, DERIVED_LONG_SCALE_SD),
                              ("accel_bias_x_g", 0.0, DERIVED_LONG_BIAS_G)) if p[0] not in given)
    return replace(settings, priors=(*settings.priors, *extra), long_load_derived=True)


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
    if "n_lat_g" not in clean.meta.ingest.derived_channels:
        return settings
    nz = settings.noise
    return replace(settings, noise=replace(nz, accel_noise_mps2_sqrt_hz=max(
        nz.accel_noise_mps2_sqrt_hz, DERIVED_LAT_ACCEL_NOISE)))
