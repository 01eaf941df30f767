"""ADS/ARMS estimators: ground velocity from range/azimuth plots and the air-data error.

docs/arms.md; Vasyliev (2025), seed ``000_92b8f66acbd1b85b.txt``.

Frame: the station's east-north-up tangent plane, ``x`` east, ``y`` north, station at the origin.
Azimuth ``theta`` clockwise from north, ``theta = atan2(x, y)``; ``r`` is the *horizontal* range
(see :func:`horizontal_range`).  SI inside: metres, seconds, radians.

Three forms, each filtered forward on the estimation core's one forward loop
(:func:`flightrecon.estimation.filtering.forward_pass`) and (optionally) smoothed backward with
its RTS loop (:func:`flightrecon.estimation.kalman.rts_smooth_run`); each form's result is an
:class:`ArmsRun` (step times, the core's ``FilterRun`` and ``SmoothedRun``):

* stage 1 (:func:`track_ground_velocity`): constant-velocity (CV) tracker of
  ``X = [x, Vx, y, Vy]`` from the plots at their own times, linearised either as an EKF
  (paper eq. 12) or by converted measurements (paper eqs. 13-15);
* stage 2 (:func:`compensate`): the paper's compensation filter, state ``dV = [dVx, dVy]``
  (first-order Gauss-Markov per axis, paper eq. 4), measurement ``V* - W_hat`` at the plot times;
  :func:`run_cascade` chains the two as in the paper's Fig. 1;
* joint (:func:`run_joint_model`): one model ``[x, Vx, y, Vy, dVx, dVy]`` with range/azimuth and the
  air-data velocity ``V* = [Vx + dVx, Vy + dVy]`` as measurements, each at its own time: the
  consistent form (docs/arms.md, "Two cautions" of the joint form) and the product default.

Discretisations are exact for the step ``T`` taken from the data:
CV per axis ``F = [[1, T], [0, 1]]``, ``Q = q [[T^3/3, T^2/2], [T^2/2, T]]`` (q: acceleration
power spectral density, m^2/s^3); Gauss-Markov ``dV_i = e^{-a T} dV_{i-1} + w_i`` with
``var(w_i) = sigma^2 (1 - e^{-2 a T})`` (docs/arms.md: the seed's eq. 9 noise factor is
dimensionally inconsistent and is not used).

The nonlinear measurement update (EKF and converted forms) is the model
:class:`ArmsTrackModel`'s (compiled into the core's loop) with the Joseph-form covariance update;
the transition is linear, so the linear RTS smoother applies unchanged.
"""

from __future__ import annotations

from flightrecon.geo.radar import horizontal_range
from flightrecon.methods.arms.filter import (
    ArmsEstimate,
    ArmsRun,
    CascadeResult,
    compensate,
    estimate_of,
    run_cascade,
    run_joint_model,
    track_ground_velocity,
)
from flightrecon.methods.arms.inputs import (
    CONVERTED_AT,
    LINEARISATIONS,
    AirData,
    ArmsModel,
    RadarPlots,
    linearisation_code,
)
from flightrecon.methods.arms.measurement import (
    converted_covariance,
    converted_measurement,
    range_azimuth,
    range_azimuth_jacobian,
    wrap_angle,
)
from flightrecon.methods.arms.model import ArmsTrackModel, arms_track_model
from flightrecon.methods.arms.paper import PaperScenario, simulate_paper_scenario
from flightrecon.methods.arms.transition import (
    cv_process_noise,
    cv_transition,
    gm_process_noise,
    gm_transition,
    joint_process_noise,
    joint_transition,
)

__all__ = [
    "LINEARISATIONS", "CONVERTED_AT", "ArmsModel", "RadarPlots", "AirData", "horizontal_range",
    "range_azimuth", "range_azimuth_jacobian", "wrap_angle", "converted_measurement",
    "converted_covariance", "cv_transition", "cv_process_noise", "gm_transition",
    "gm_process_noise", "joint_transition", "joint_process_noise", "ArmsTrackModel",
    "arms_track_model",
    "linearisation_code", "ArmsEstimate", "ArmsRun", "CascadeResult", "track_ground_velocity",
    "compensate",
    "run_cascade", "run_joint_model", "estimate_of", "PaperScenario", "simulate_paper_scenario",
]
