"""State layout and measurement types of the joint post-flight smoother's compiled kernels.

The kernels: :mod:`~flightrecon.filters.joint.dynamics` (transition, process noise),
:mod:`~flightrecon.filters.joint.observation` (measurements) and
:mod:`~flightrecon.filters.joint.passes` (forward filter, backward smoother); the smoother that
drives them: :mod:`flightrecon.filters.joint`.

State (n = 24), SI units::

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

Propagation over one state step of length dt (inputs held between input samples)::

    p+ = p + C_en (v dt + dP_meas + J_p [dpsi, b_a])        dP_meas, dV_meas: increments of the
    v+ = v + dV_meas + J_v [dpsi, b_a]                       measured kinematic acceleration
    w+ = w + g dz + noise (random walk in time and in altitude)  over the step (exact for held
    g+ = g + noise (random walk in time)                     inputs; dz: the nominal's climb)
    b_a+ = exp(-dt/tau) b_a + noise

with J_v = [[a_E, -a_N, 0]^T dt, -g0 C_nb dt, -g0 C_nb diag(f) dt, -g0 dC/dphi f dt,
-g0 dC/dtheta f dt] and J_p = J_v dt / 2: the heading bias rotates the measured horizontal
acceleration, the accelerometer bias and scale errors add through the attitude (f: measured
specific force in body axes, in g), and the roll and pitch biases tilt it:
dC/dphi f = C_nb (e_x x f) and dC/dtheta f = C_nb (u x f), u = (0, cos phi, -sin phi)
(C_nb = R_z R_y R_x; R_x^T e_y = u), both as step means over the held inputs.  C_en (NED -> ECEF) is
evaluated on the nominal trajectory (Gauss-Newton linearisation, refreshed each iteration).

Measurements are scalars processed one at a time at their own step, with ``tau`` = their time
minus the step's time (the state is carried to the measurement time by the velocity):

* ``LINEAR``: z = H x + d (GNSS position / velocity components, end points, ground constraints)
* ``RANGE``, ``AZIMUTH``, ``ELEVATION``: radar slant range and angles from the station
* ``TAS``: (1 + s) |v - w| (three-dimensional air velocity, vertical wind neglected)
* ``HEADING``: atan2(v_E - w_E, v_N - w_N) + dpsi (innovation wrapped to (-pi, pi])
* ``BARO``: (1 + c) (h_nom + up . (p - p_nom) - v_D tau) + b_h
* ``DOPPLER``: (1 + k_W) |v_horizontal|
* ``TRACK``: heading + drift as recorded = atan2(v_E, v_N) + dpsi + dc (innovation wrapped)
"""

from __future__ import annotations

N_STATE = 24


IP, IV, IW, IBA, IPSI, IS, IBH, IC, IDW, IDC, IKS, IATT, IG = (0, 3, 6, 8, 11, 12, 13, 14, 15, 16,
                                                                17, 20, 22)


G0 = 9.80665


LINEAR, RANGE, AZIMUTH, ELEVATION, TAS, HEADING, BARO, DOPPLER, TRACK = 0, 1, 2, 3, 4, 5, 6, 7, 8


ANGLE_TYPES = (AZIMUTH, ELEVATION, HEADING, TRACK)
