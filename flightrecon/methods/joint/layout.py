"""State layout and measurement types of the joint post-flight smoother's compiled kernels.

The kernels: :mod:`~flightrecon.methods.joint.model` (transition, process noise, measurement
functions, MAP cost); the passes and iterations that drive them:
:mod:`~flightrecon.methods.joint.solve`.

State (n = 26), SI units::

    0:3   p      position, ECEF [m]
    3:6   v      ground velocity, local north-east-down at the nominal position [m/s]
    6:8   w      horizontal wind velocity (where the air moves to), north, east [m/s]
    8:11  b_a    accelerometer bias, body axes, as load factor [g]   (measured - true)
    11    dpsi   heading bias [rad]                                    (measured - true)
    12    s      airspeed scale error: TAS_measured = (1 + s) TAS_true
    13    b_h    pressure-altitude offset [m]
    14    c      pressure-altitude scale: h_p - h_p,field = (1 + c)(h - h_field) + b_h
    15    k_W    Doppler ground-speed scale error: W_measured = (1 + k_W) |v_horizontal|
    16    dc     drift-angle bias [rad] (measured - true)
    17:20 s_a    accelerometer scale errors, body axes: f_measured = (1 + s_a) f_true + b_a
    20    dphi   roll bias [rad] (measured - true)
    21    dtheta pitch bias [rad] (measured - true)
    22:24 g      wind gradient with height, north, east [(m/s)/m]
    24:26 u      gust: the turbulence's effect on the air data, along and across the air
                 velocity [m/s] (first-order Gauss-Markov in distance flown: correlation
                 length L, sd sigma_u)

Propagation over one state step: :func:`~flightrecon.methods.joint.model.transition_into`.

Measurements are scalars processed one at a time at their own step, with ``tau`` = their time minus
the step's time (the state is carried to the measurement time by the velocity):

* ``LINEAR``: z = H x + d (GNSS position / velocity components, end points, ground constraints)
* ``RANGE``, ``AZIMUTH``, ``ELEVATION``: radar slant range and angles from the station
* ``TAS``: (1 + s) |v - w| + u_a (three-dimensional air velocity, vertical wind neglected;
  u_a the along-track gust)
* ``HEADING``: atan2(v_E - w_E, v_N - w_N) + dpsi + u_c / V (innovation wrapped to (-pi, pi];
  u_c the cross-track gust, V the recorded airspeed, carried in the measurement's ``d``)
* ``BARO``: (1 + c) (h_nom + up . (p - p_nom) - v_D tau) + b_h
* ``DOPPLER``: (1 + k_W) |v_horizontal|
* ``TRACK``: heading + drift as recorded = atan2(v_E, v_N) + dpsi + dc (innovation wrapped)
* ``NED_POS``: a position fix's component along the NED axis i = ``row`` at the step,
  z = c_i . p_fix, h = c_i . p + v_i tau (c_i: column i of C_en at the step): a ``LINEAR``
  measurement whose row is built in the kernel instead of stored (GNSS positions, ``--fix``)
* ``STATE``: one state component, index ``row``: h = x[row] + d (GNSS velocities)
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np

N_STATE = 26


IP, IV, IW, IBA, IPSI, IS, IBH, IC, IDW, IDC, IKS, IATT, IG, IGU = (0, 3, 6, 8, 11, 12, 13, 14, 15,
                                                                     16, 17, 20, 22, 24)


# the state's blocks as slices, named once (the indices above are their first elements)
S_POS = slice(IP, IP + 3)      # ECEF position [m]
S_VEL = slice(IV, IV + 3)      # NED velocity [m/s]
S_WIND = slice(IW, IW + 2)     # horizontal wind, north/east [m/s]
S_ACC_BIAS = slice(IBA, IBA + 3)
S_ACC_SCALE = slice(IKS, IKS + 3)
S_ATT_BIAS = slice(IATT, IATT + 2)
S_WIND_GRAD = slice(IG, IG + 2)
S_GUST = slice(IGU, IGU + 2)   # gust's effect on the air data, along / across [m/s]

G0 = 9.80665


LINEAR, RANGE, AZIMUTH, ELEVATION, TAS, HEADING, BARO, DOPPLER, TRACK = 0, 1, 2, 3, 4, 5, 6, 7, 8
NED_POS, STATE = 9, 10


ANGLE_TYPES = (AZIMUTH, ELEVATION, HEADING, TRACK)


# ---- named layouts across the compiled boundary (numba takes NamedTuples of arrays) ----

class Cost(NamedTuple):
    """The MAP cost of an iterate (the kernel :func:`~flightrecon.methods.joint.model.map_cost`,
    :func:`~flightrecon.methods.joint.linearisation.pass_cost`): its ``terms`` (``cost`` and its
    parts) and, per measurement, the residuals ``res`` and rates ``rate``."""

    terms: dict[str, Any]
    res: np.ndarray
    rate: np.ndarray


class Dynamics(NamedTuple):
    """The propagation model on the state grid (N steps)."""

    dt: np.ndarray        # (N,) step lengths [s] (dt[0] = 0)
    Cen: np.ndarray       # (N, 3, 3) NED -> ECEF at the nominal positions
    Cnb: np.ndarray       # (N, 3, 3) step-mean body -> NED
    Csf: np.ndarray       # (N, 3, 3) step-mean rotation of the specific force (bias terms)
    Jatt: np.ndarray      # (N, 3, 2) step-mean attitude Jacobian of the rotated force
    acc: np.ndarray       # (N, 3) step-mean measured kinematic acceleration [m/s^2]
    dP: np.ndarray        # (N, 3) exact position increments of the held accelerations
    dV: np.ndarray        # (N, 3) exact velocity increments
    dz: np.ndarray        # (N,) height change over each step (wind gradient)
    qv_extra: np.ndarray  # (N,) extra acceleration PSD where the loads are missing
    q: np.ndarray         # process-noise densities and the bias time constant (q_vector)
    ga: np.ndarray        # (N,) gust decay over each step, exp(-V_k dt_k / L) (ga[0] = 1)


class Scalars(NamedTuple):
    """The scalar measurements, sorted by state step (``start`` (N+1,) indexes each step's)."""

    start: np.ndarray     # (N+1,)
    mtype: np.ndarray     # (M,) measurement type (LINEAR, RANGE, ...)
    z: np.ndarray         # (M,) measured values
    r: np.ndarray         # (M,) variances (nominal in the forward pass, inflated backward)
    w: np.ndarray         # (M,) robust weights (the variance used is r / w)
    tau: np.ndarray       # (M,) measurement time minus its step's time [s]
    H: np.ndarray         # (K, n) rows of the LINEAR measurements
    row: np.ndarray       # (M,) LINEAR: their row in H; NED_POS: the axis; STATE: the state
                          # index; -1 for the others
    d: np.ndarray         # (M,) offsets of the LINEAR measurements; recorded TAS of HEADING


class Geometry(NamedTuple):
    """The linearisation point and the radar station."""

    pnom: np.ndarray      # (N, 3) nominal ECEF positions
    hnom: np.ndarray      # (N,) nominal ellipsoidal heights
    pst: np.ndarray       # (3,) station ECEF position
    Cst: np.ndarray       # (3, 3) station ENU -> ECEF


@dataclass(frozen=True)
class Measurements:
    """Scalar measurements sorted by state step (types: :mod:`~flightrecon.methods.joint.layout`).

    Only the ``LINEAR`` measurements have a row of H: ``H[hrow[j]]``; for ``NED_POS`` and ``STATE``
    ``hrow`` is the axis or the state index (their rows are built in the kernel), -1 for the others:
    the table stays small (a stored row is 26 numbers; GNSS positions and velocities at 1 Hz over 10
    hours are 175 000 of them).
    """

    step: np.ndarray
    source: np.ndarray      # index into SOURCES
    mtype: np.ndarray
    z: np.ndarray
    r: np.ndarray
    t: np.ndarray           # measurement time, recorder time base
    H: np.ndarray           # (M_linear, n)
    hrow: np.ndarray        # (M,) row of H, -1 where the measurement has none
    d: np.ndarray
    start: np.ndarray       # (N+1,)
    # (M,) the rate of change with the measurement's time of the prediction, where the
    # kernel's gradient does not give it (GNSS velocities: their own acceleration); 0
    # elsewhere (the clock offsets' Gauss-Newton column)
    rate: np.ndarray | None = None
