"""Joint post-flight smoother: one trajectory from every source, with honest uncertainty
(docs/joint.md).

The problem is built once from a cleaned flight (:mod:`~flightrecon.methods.joint.problem`: the
inputs, the end points, the settings the data call for, what the passes hold fixed; of hand-made
inputs: ``problem_of``), then solved (``smooth_joint(problem)``,
:mod:`~flightrecon.methods.joint.solve`: damped Gauss-Newton passes of a forward filter and an RTS
backward pass on the compiled model of :mod:`~flightrecon.methods.joint.model`, with robust
re-weighting, clock offsets estimated jointly with the track and, optionally, the noise factors);
its calibrations are adjusted problems solved again (:mod:`~flightrecon.methods.joint.calibration`);
the adapter is :func:`flightrecon.methods.joint.method.run_joint`.

Frame: position in ECEF, velocity in the local north-east-down frame of the (nominal) aircraft
position: valid on flights of any length; outputs converted to the departure tangent plane.
"""

from __future__ import annotations

from flightrecon.methods.joint.inputs import (
    TakeoffRoll,
    enu_to_ecef_matrix,
    refined_roll,
    takeoff_roll,
)
from flightrecon.methods.joint.linearisation import attitude_jacobian
from flightrecon.methods.joint.problem import JointProblem, joint_problem, problem_of
from flightrecon.methods.joint.settings import (
    POSITIVE_NOISE,
    PRIOR_STATES,
    JointNoise,
    JointSettings,
    prior_of,
)
from flightrecon.methods.joint.solve import JointRun, smooth_joint

__all__ = ["JointNoise", "POSITIVE_NOISE", "JointSettings", "PRIOR_STATES", "prior_of",
           "enu_to_ecef_matrix", "TakeoffRoll", "takeoff_roll", "refined_roll",
           "attitude_jacobian", "JointProblem", "joint_problem", "problem_of", "JointRun",
           "smooth_joint"]
