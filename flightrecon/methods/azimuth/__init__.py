"""Azimuth channel of an approach radar: Singer model and load-factor-aided model (docs/azimuth.md).

State ``x = [eps, omega, a]``: azimuth [rad, clockwise from true north at the station], azimuth
rate [rad/s] and azimuth angular acceleration [rad/s^2].  Two process models:

* **Singer** (Singer 1970; seed 002 equations (1)-(3) are its Euler form): ``a`` is a first-order
  Markov process, ``a' = -alpha_m a + w``, ``E[w w] = 2 alpha_m sigma_m^2``.  Exact transition
  :func:`singer_transition` and process noise :func:`singer_process_noise`.
* **Aided** (seed 002 equations (5)-(7)): ``a`` is a random walk driven by white noise on ``a'``
  of spectral density ``q``; exact discretisation :func:`random_walk_matrices`.

Observations (docs/azimuth.md):

* radar azimuth ``eps_meas = eps + v``, innovation wrapped to (-pi, pi] (seed eq. (4)/(8));
* the *transverse acceleration* from the downlinked load factors and attitude (replacing the
  seed's garbled eq. (9); derivation in ``docs/azimuth.md``)::

      z = a_E cos(eps) - a_N sin(eps) = 2 r_dot omega + r a

  with horizontal range ``r`` and its rate from a range tracker (:func:`track_range`).  ``z`` is
  evaluated at the current azimuth estimate and linearised there (an extended-Kalman update of an
  implicit measurement): ``H = [-dz/deps, 2 r_dot, r]``, ``dz/deps = -(a_E sin eps + a_N cos eps)``.
  Its noise ``R_z`` is propagated to first order from the sensor errors
  (:func:`horizontal_acceleration_covariance`) and from the range tracker's covariance.

The angular process noises are set from physical ones: ``sigma_m = sigma_m_mps2 / r`` and
``q = q_jerk / r^2`` with the tracked range ``r`` at each step.

Every filter here runs forward on the estimation core's one forward loop
(:func:`azimuth_filter`: the model :class:`AzimuthModel` in
:func:`flightrecon.estimation.filtering.forward_pass`) and is smoothed backward by the linear
Rauch-Tung-Striebel pass :func:`flightrecon.estimation.kalman.rts_smooth`; the result, an
:class:`AzimuthRun`, holds the core's ``FilterRun`` and ``SmoothedRun``.
"""

from __future__ import annotations

from flightrecon.estimation.discretise import (
    random_walk_matrices,
    singer_process_noise,
    singer_transition,
)
from flightrecon.methods.azimuth.filter import AzimuthRun, azimuth_filter
from flightrecon.methods.azimuth.model import AzimuthModel, azimuth_model
from flightrecon.methods.azimuth.observation import (
    horizontal_acceleration,
    horizontal_acceleration_covariance,
    horizontal_acceleration_jacobian,
    transverse_acceleration,
    wrap_pi,
)
from flightrecon.methods.azimuth.range_track import RangeTrack, track_range

__all__ = [
    "singer_transition", "singer_process_noise", "random_walk_matrices",
    "horizontal_acceleration", "horizontal_acceleration_jacobian",
    "horizontal_acceleration_covariance", "transverse_acceleration", "wrap_pi", "RangeTrack",
    "track_range", "AzimuthModel", "azimuth_model", "AzimuthRun", "azimuth_filter",
]
