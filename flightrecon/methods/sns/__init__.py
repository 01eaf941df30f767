"""Heading-airspeed / heading-Doppler dead reckoning fused with SNS fixes (docs/sns.md).

Seed 003 (Ukrainian paper on "non-invariant" processing): one nonlinear discrete filter estimates
the position *and* the corrections to the sensor readings, with SNS (GNSS) position and ground
velocity as observations.  This module holds the models, the forward filter (consistent
correlated-noise form and the seed's form) and the backward smoother.  The adapter that reads a
:class:`flightrecon.types.CleanFlight` is :mod:`flightrecon.methods.sns.method`.

Models
------
Both models share one structure.  Over an interval of length ``tau`` with the recorder readings
held (zero-order hold) between samples, the north/east increment is

    d = s * R(theta) A + Wv + dw * tau,        R(theta) = [[cos, -sin], [sin, cos]]

with the integrals of the held readings ``A = int a dt`` (``a`` the measured velocity vector),
``U = int u dt`` (``u`` its unit vector) and ``Wv = int w dt`` (``w`` the measured wind, toward):

* ``model=0`` heading-airspeed, state ``[n, e, corr_wind_n, corr_wind_e, corr_psi]``:
  ``a = TAS [cos psi~, sin psi~]``, ``w`` the wind reading (blowing toward), ``s = 1``,
  ``theta = corr_psi``, ``dw = (corr_wind_n, corr_wind_e)``.  docs/sns.md, "Models", eq. (1)
  with the wind
  correction in Cartesian form (observability note of section 4).
* ``model=1`` heading-Doppler, state ``[n, e, corr_W, corr_c, corr_psi]``:
  ``a = W~ [cos(psi~ + c~), sin(psi~ + c~)]``, ``w = 0``, ``s = 1 + corr_W``,
  ``theta = corr_c + corr_psi``, ``dw = 0``.  docs/sns.md, "Models", eq. (4).  Heading and drift
  enter only
  through their sum (the track angle), so they separate only through their priors; the sum is
  what the data determine.

Corrections are true minus measured (docs/schema.md, "Conventions"): the true heading is
``psi~ + corr_psi``; the true Doppler ground speed ``W~ (1 + corr_W)``.

Noise model
-----------
The recorder readings carry white errors, independent between recorder samples, with the sds
of :class:`SnsNoise` (``[eta_V, eta_psi, eta_wind_n, eta_wind_e]`` airspeed,
``[eta_W, eta_c, eta_psi, -]`` Doppler).  A filter step may span several recorder samples; its
``eps1`` (11 standard normal components) is split so that what the state and the observations
share is exact: ``[errors of the recorder sample held at the step's fixes (4), summed errors of
the step's samples before it (2, a Cholesky factor), after it (2), random walks of the three
corrections (3)]``.  The state moves from step k to k+1 with all of them (``B``); a fix in step k
sees the held sample's errors in its velocity (``G`` velocity rows) and the errors up to its time
in its position (``G`` position rows: the held sample over the time since it started, and the
samples before).  With one recorder sample per filter step this is the seed's structure: the
reading error held over the step, shared by the step and the observation.

Frame
-----
The position is carried as geodetic latitude/longitude and propagated in the moving local-level
frame: each north/east increment (metres) is turned into latitude/longitude increments with the
meridian and prime-vertical radii at the mid-latitude of the step (the height ``h`` comes with the
inputs).  The filter's position error state is north/east metres at the current position (the
reference re-centred every step), so the position block of ``Phi`` is the identity.  The neglected
terms are the dependence of the radii on a position error (relative 1e-7 per kilometre of error)
and the rotation of the local axes across one step (sub-millimetre); the test
``test_sns_models.py::test_local_level_propagation_10h`` bounds the total over a 10-hour flight.

Filter (docs/sns.md)
-----------------------------
Observation of the fixes in step k (stacked if several)::

    Y = h(X_k) + D eps2 + G eps1_k,     S = H P- H^T + D D^T + G G^T
    K = P- H^T S^+,  X+ = X- (+) K nu,  P+ = (I - K H) P- (I - K H)^T + K (D D^T + G G^T) K^T

with ``S^+`` the Moore-Penrose pseudo-inverse (eigen-decomposition, eigenvalues below
``rcond * max eigenvalue`` dropped).  Consistent prediction, with ``L = Phi K + B G^T S^+``::

    X_{k+1} = f(X+) + B G^T S^+ nu
    P_{k+1} = (Phi - L H) P- (Phi - L H)^T + (B - L G)(B - L G)^T + L D D^T L^T

which equals docs/sns.md's ``Phi P+ Phi^T + B B^T - B G^T S^+ G B^T - Phi P- H^T S^+ G B^T -
B G^T S^+ H P- Phi^T`` and is symmetric positive semi-definite by construction.  The seed's form
(``form=1``) ignores the correlation: ``X_{k+1} = f(X+)``, ``P_{k+1} = Phi P+ Phi^T + B B^T``.

Smoother
--------
Rauch-Tung-Striebel form with the cross-covariance ``Cov(x_k, x_{k+1} | Y_0..k)``::

    Cx_k = P+_k Phi^T - P-_k H^T S^+ G B^T            (consistent; P+_k Phi^T for the seed form)
    C_k  = Cx_k P_{k+1}^{-1}
    x^s_k = x+_k (+) C_k (x^s_{k+1} (-) x-_{k+1}),   P^s_k = P+_k + C_k (P^s_{k+1} - P-_{k+1}) C_k^T

(derivation in docs/sns.md: given x_{k+1}, later observations do not depend on x_k, so the
Gaussian conditioning argument of RTS goes through with the correct cross-covariance).

Implementation (speed, issue #13)
---------------------------------
The filter and the smoother are a model of the estimation core
(:class:`~flightrecon.methods.sns.filter.SnsModel` on the core's one forward loop and one
backward loop, :mod:`flightrecon.estimation.filtering`, :mod:`flightrecon.estimation.smoothing`):
the model's functions do the per-step work in preallocated buffers; the public model
functions (:func:`increment`, :func:`segment_factor`, :func:`step_matrices`,
:func:`observation_rows`) are thin allocating wrappers of the ``*_into`` forms that the model
calls directly (:func:`~flightrecon.methods.sns.model.step_matrices_into`,
:func:`~flightrecon.methods.sns.model.observation_rows_into`), small products are plain loops
(:func:`mm_into`, :func:`mmt_into`), the trigonometry of the corrections' rotation is
evaluated once per step (once per filter step in :func:`densify`, whose moves from the filter
states reuse the states' ``sin``/``cos`` of latitude).  ``S^+`` is the Cholesky inverse
whenever a trace bound proves full rank at ``rcond``
(:func:`~flightrecon.estimation.linalg.pinv_sym_into`), else a Jacobi eigen-decomposition; the
update, the correlated-noise prediction and the smoother's step are the estimation core's
(:mod:`flightrecon.estimation.updates`, :mod:`flightrecon.estimation.rts`: the smoother's gain
by a Cholesky solve with ``Pp``, or, counted, a general solve, which reports singularity, where
that fails).  The results equal the straightforward matrix expressions to round-off
(``tests/test_sns_speed_paths.py``).
"""

from __future__ import annotations

from flightrecon.estimation.filtering import FilterRun
from flightrecon.estimation.linalg import pinv_sym
from flightrecon.estimation.manifold import boxminus, boxplus, radii
from flightrecon.estimation.smoothing import SmoothedRun
from flightrecon.methods.sns.filter import SnsModel, rts_smooth_cross, sns_filter, sns_smooth
from flightrecon.methods.sns.model import (
    FORM_CONSISTENT,
    FORM_SEED,
    MODEL_AIRSPEED,
    MODEL_DOPPLER,
    N_EPS1,
    N_STATE,
    STATE_NAMES,
    SnsNoise,
    StepInputs,
    default_noise,
    fill_single_sample,
    increment,
    observation_rows,
    segment_factor,
    step_matrices,
)
from flightrecon.methods.sns.output import densify, integrate_readings

__all__ = [
    "pinv_sym", "MODEL_AIRSPEED", "MODEL_DOPPLER", "FORM_CONSISTENT", "FORM_SEED", "N_STATE",
    "N_EPS1", "STATE_NAMES", "radii", "boxplus", "boxminus", "increment", "segment_factor",
    "step_matrices", "observation_rows", "StepInputs", "fill_single_sample", "SnsNoise",
    "default_noise", "FilterRun", "SmoothedRun", "SnsModel", "sns_filter", "sns_smooth",
    "rts_smooth_cross", "densify",
    "integrate_readings",
]
