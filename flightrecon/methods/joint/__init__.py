"""Joint post-flight smoother: one trajectory from every source, with honest uncertainty.

The state, its propagation by the kinematic accelerations from load factors and attitude, and
the measurement models are in :mod:`flightrecon.methods.joint.layout` and the compiled kernels
beside it.  This package builds the problem once from a cleaned flight
(:mod:`~flightrecon.methods.joint.problem`: the inputs, the end points, the settings the data
call for), runs the forward filter
and the RTS backward pass, and iterates (Gauss-Newton about the smoothed trajectory) with

* the linearisation refreshed on the smoothed trajectory (nominal positions through pyproj);
* robust re-weighting: each measurement's smoothed residual, normalised by its own standard
  deviation sqrt(R - H P_s H^T), enters a Huber weight (threshold ``huber_c``), so a source that
  jumps (a GNSS offset of 500 m for a minute) is down-weighted rather than trusted;
* clock offsets of the GNSS positions, GNSS velocities and radar against the recorder
  estimated jointly with the track (constant columns of the forward filter: their Gauss-Newton
  step and covariance from its normal equations, ``updates.clock_step``).  An offset is the
  number of seconds to *add* to the source's time stamps, as ``flightrecon clean
  --radar-clock-offset`` takes it: a plot stamped t_m that belongs to true time t_m + c has
  residual hdot * c;
* optionally, a scale factor on each source's noise variance estimated from the flight
  (variance-component estimation from the normalised residuals);
* every pass damped on the MAP cost (:mod:`~flightrecon.methods.joint.cost`): a backtracking
  line search along the Gauss-Newton step, a Levenberg-Marquardt step where it fails, the
  result the lowest-cost iterate and the reason reported when the iterations did not settle
  (docs/joint.md, "Filter, smoother, iterations").

Frame: position in ECEF, velocity in the local north-east-down frame of the (nominal) aircraft
position: valid on flights of any length; outputs converted to the departure tangent plane.
"""

from __future__ import annotations

from flightrecon.methods.joint.diagnostics import source_report
from flightrecon.methods.joint.inputs import (
    EndPoint,
    JointInputs,
    TakeoffRoll,
    end_points,
    end_points_at,
    enu_to_ecef_matrix,
    refined_roll,
    takeoff_roll,
)
from flightrecon.methods.joint.layout import Measurements
from flightrecon.methods.joint.measurements import build_measurements, static_measurements
from flightrecon.methods.joint.noise import NOISE_GROUPS, innovation_loglik
from flightrecon.methods.joint.nominal import attitude_jacobian, relinearised_increments
from flightrecon.methods.joint.problem import (
    JointProblem,
    SettingChoice,
    joint_inputs,
    joint_problem,
)
from flightrecon.methods.joint.settings import (
    POSITIVE_NOISE,
    PRIOR_STATES,
    SOURCES,
    JointNoise,
    JointSettings,
    prior_of,
)
from flightrecon.methods.joint.smoother import smooth_joint
from flightrecon.methods.joint.state import JointRun

__all__ = [
    "SOURCES", "JointNoise", "POSITIVE_NOISE", "JointSettings", "PRIOR_STATES", "prior_of",
    "enu_to_ecef_matrix", "TakeoffRoll", "JointInputs", "joint_inputs", "takeoff_roll",
    "refined_roll", "EndPoint", "end_points", "end_points_at", "JointProblem", "SettingChoice",
    "joint_problem", "attitude_jacobian", "relinearised_increments", "Measurements",
    "static_measurements", "build_measurements", "NOISE_GROUPS", "innovation_loglik", "JointRun",
    "smooth_joint", "source_report",
]
