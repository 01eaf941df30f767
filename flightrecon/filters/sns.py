"""Heading-airspeed / heading-Doppler dead reckoning fused with SNS fixes (METHODS.md section 4).

Seed 003 (Ukrainian paper on "non-invariant" processing): one nonlinear discrete filter estimates
the position *and* the corrections to the sensor readings, with SNS (GNSS) position and ground
velocity as observations.  This module holds the models, the forward filter (consistent
correlated-noise form and the seed's form) and the backward smoother.  The adapter that reads a
:class:`flightrecon.types.CleanFlight` is :mod:`flightrecon.filters.sns_method`.

Models
------
Both models share one structure.  Over an interval of length ``tau`` with the recorder readings
held (zero-order hold) between samples, the north/east increment is

    d = s * R(theta) A + Wv + dw * tau,        R(theta) = [[cos, -sin], [sin, cos]]

with the integrals of the held readings ``A = int a dt`` (``a`` the measured velocity vector),
``U = int u dt`` (``u`` its unit vector) and ``Wv = int w dt`` (``w`` the measured wind, toward):

* ``model=0`` heading-airspeed, state ``[n, e, corr_wind_n, corr_wind_e, corr_psi]``:
  ``a = TAS [cos psi~, sin psi~]``, ``w`` the wind reading (blowing toward), ``s = 1``,
  ``theta = corr_psi``, ``dw = (corr_wind_n, corr_wind_e)``.  METHODS.md eq. (1) with the wind
  correction in Cartesian form (observability note of section 4).
* ``model=1`` heading-Doppler, state ``[n, e, corr_W, corr_c, corr_psi]``:
  ``a = W~ [cos(psi~ + c~), sin(psi~ + c~)]``, ``w = 0``, ``s = 1 + corr_W``,
  ``theta = corr_c + corr_psi``, ``dw = 0``.  METHODS.md eq. (4).  Heading and drift enter only
  through their sum (the track angle), so they separate only through their priors; the sum is
  what the data determine.

Corrections are true minus measured (METHODS.md "Common ground"): the true heading is
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

Filter (METHODS.md section 4)
-----------------------------
Observation of the fixes in step k (stacked if several)::

    Y = h(X_k) + D eps2 + G eps1_k,     S = H P- H^T + D D^T + G G^T
    K = P- H^T S^+,  X+ = X- (+) K nu,  P+ = (I - K H) P- (I - K H)^T + K (D D^T + G G^T) K^T

with ``S^+`` the Moore-Penrose pseudo-inverse (eigen-decomposition, eigenvalues below
``rcond * max eigenvalue`` dropped).  Consistent prediction, with ``L = Phi K + B G^T S^+``::

    X_{k+1} = f(X+) + B G^T S^+ nu
    P_{k+1} = (Phi - L H) P- (Phi - L H)^T + (B - L G)(B - L G)^T + L D D^T L^T

which equals METHODS.md's ``Phi P+ Phi^T + B B^T - B G^T S^+ G B^T - Phi P- H^T S^+ G B^T -
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
The kernels do all per-step and per-sample work in preallocated buffers: the public model
functions (:func:`increment`, :func:`segment_factor`, :func:`step_matrices`,
:func:`observation_rows`) are thin allocating wrappers of ``_*_into`` cores that the kernels
call directly, small products are plain loops (:func:`_mm`, :func:`_mmt`), the trigonometry of
the corrections' rotation is evaluated once per step (once per filter step in :func:`densify`,
whose moves from the filter states reuse the states' ``sin``/``cos`` of latitude,
:func:`_boxplus_pre`).  ``S^+`` is the Cholesky inverse whenever a trace bound proves full rank
at ``rcond`` (:func:`_inv_spd_into`), else a Jacobi eigen-decomposition; the smoother's gain uses
a Cholesky solve with ``Pp`` (a general solve, which reports singularity, if that fails).  The
results equal the straightforward matrix expressions to round-off
(``tests/test_sns_speed_paths.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numba as nb
import numpy as np

from flightrecon.constants import WGS84_A, WGS84_E2
from flightrecon.filters.smallmat import cholesky_factor

MODEL_AIRSPEED = 0
MODEL_DOPPLER = 1
FORM_CONSISTENT = 0
FORM_SEED = 1
N_STATE = 5
N_EPS1 = 11

STATE_NAMES = {
    MODEL_AIRSPEED: ("north_m", "east_m", "corr_wind_n_mps", "corr_wind_e_mps", "corr_psi_rad"),
    MODEL_DOPPLER: ("north_m", "east_m", "corr_W_scale", "corr_c_rad", "corr_psi_rad"),
}

_A = WGS84_A
_E2 = WGS84_E2


@nb.njit(cache=True, nogil=True)
def radii(lat_rad: float, h_m: float) -> tuple[float, float]:
    """Meridian and prime-vertical radii of curvature plus height, ``(M + h, N + h)`` [m].

    WGS-84: ``M = a (1 - e^2) / (1 - e^2 sin^2 lat)^1.5``, ``N = a / sqrt(1 - e^2 sin^2 lat)``.
    """
    s = np.sin(lat_rad)
    w = 1.0 - _E2 * s * s
    n = _A / np.sqrt(w)
    m = n * (1.0 - _E2) / w
    return m + h_m, n + h_m


@nb.njit(cache=True, nogil=True)
def boxplus(lat: float, lon: float, dn: float, de: float, h: float) -> tuple[float, float]:
    """Move ``(lat, lon)`` [rad] by ``dn`` north and ``de`` east metres in the local-level frame.

    The radii are taken at the mid-latitude of the move (second-order accurate).
    """
    mh, nh = radii(lat, h)
    latm = lat + 0.5 * dn / mh
    mh, nh = radii(latm, h)
    return lat + dn / mh, lon + de / (nh * np.cos(latm))


@nb.njit(cache=True, nogil=True)
def boxminus(lat1: float, lon1: float, lat0: float, lon0: float, h: float) -> tuple[float, float]:
    """North/east metres from ``(lat0, lon0)`` to ``(lat1, lon1)`` [rad] (inverse of boxplus)."""
    latm = 0.5 * (lat1 + lat0)
    mh, nh = radii(latm, h)
    return (lat1 - lat0) * mh, (lon1 - lon0) * nh * np.cos(latm)


@nb.njit(cache=True, nogil=True)
def _increment_into(model: int, c: np.ndarray, A0: float, A1: float, U0: float, U1: float,
                    W0: float, W1: float, tau: float, sig: np.ndarray, d: np.ndarray,
                    J: np.ndarray, Gs: np.ndarray) -> None:
    """:func:`increment` writing into caller-owned ``d`` (2,), ``J`` (2, 3), ``Gs`` (2, 4).

    The allocation-free core used by the filter kernel (every entry of the outputs is written).
    """
    s, th = _scale_angle(model, c)
    _increment_cs_into(model, s, np.cos(th), np.sin(th), c, A0, A1, U0, U1, W0, W1, tau, sig,
                       d, J, Gs)


@nb.njit(cache=True, nogil=True)
def _increment_cs_into(model: int, s: float, ct: float, st: float, c: np.ndarray, A0: float,
                       A1: float, U0: float, U1: float, W0: float, W1: float, tau: float,
                       sig: np.ndarray, d: np.ndarray, J: np.ndarray, Gs: np.ndarray) -> None:
    """:func:`_increment_into` given the scale ``s`` and ``cos``/``sin`` of the rotation angle
    (``s = 1, theta = c[2]`` airspeed; ``s = 1 + c[0], theta = c[1] + c[2]`` Doppler)."""
    ra0 = ct * A0 - st * A1
    ra1 = st * A0 + ct * A1
    # derivative of R(theta) A with respect to theta
    dra0 = -ra1
    dra1 = ra0
    ru0 = ct * U0 - st * U1
    ru1 = st * U0 + ct * U1
    if model == MODEL_AIRSPEED:
        d[0] = ra0 + W0 + c[0] * tau
        d[1] = ra1 + W1 + c[1] * tau
        J[0, 0] = tau
        J[0, 1] = 0.0
        J[1, 0] = 0.0
        J[1, 1] = tau
        J[0, 2] = dra0
        J[1, 2] = dra1
        Gs[0, 0] = ru0 * sig[0]
        Gs[1, 0] = ru1 * sig[0]
        Gs[0, 1] = dra0 * sig[1]
        Gs[1, 1] = dra1 * sig[1]
        Gs[0, 2] = tau * sig[2]
        Gs[1, 2] = 0.0
        Gs[0, 3] = 0.0
        Gs[1, 3] = tau * sig[3]
    else:
        d[0] = s * ra0
        d[1] = s * ra1
        J[0, 0] = ra0
        J[1, 0] = ra1
        J[0, 1] = s * dra0
        J[1, 1] = s * dra1
        J[0, 2] = s * dra0
        J[1, 2] = s * dra1
        Gs[0, 0] = s * ru0 * sig[0]
        Gs[1, 0] = s * ru1 * sig[0]
        Gs[0, 1] = s * dra0 * sig[1]
        Gs[1, 1] = s * dra1 * sig[1]
        Gs[0, 2] = s * dra0 * sig[2]
        Gs[1, 2] = s * dra1 * sig[2]
        Gs[0, 3] = 0.0
        Gs[1, 3] = 0.0


@nb.njit(cache=True, nogil=True)
def increment(model: int, c: np.ndarray, A: np.ndarray, U: np.ndarray, Wv: np.ndarray,
              tau: float, sig: np.ndarray):
    """Dead-reckoning increment over an interval, its Jacobian and its noise matrix.

    Parameters
    ----------
    model : ``MODEL_AIRSPEED`` (0) or ``MODEL_DOPPLER`` (1)
    c : (3,) corrections (see module docstring)
    A, U, Wv : (2,) integrals over the interval of the measured velocity vector, of its unit
        vector and of the measured wind vector (north, east) [m, s, m]
    tau : interval length [s]
    sig : (4,) sensor noise standard deviations per recorder sample (module docstring)

    Returns
    -------
    d : (2,) increment north/east [m] (METHODS.md eq. (1) / (4), exact for held readings)
    J : (2, 3) ``dd/dc``
    Gs : (2, 4) ``dd/d eta`` times the noise standard deviations

    With ``A = a``, ``U = u``, ``Wv = w`` and ``tau = 1`` the same function gives the corrected
    velocity at an instant, its Jacobian and the velocity rows of ``G``.
    """
    d = np.empty(2)
    J = np.empty((2, 3))
    Gs = np.empty((2, 4))
    _increment_into(model, c, A[0], A[1], U[0], U[1], Wv[0], Wv[1], tau, sig, d, J, Gs)
    return d, J, Gs


@nb.njit(cache=True, nogil=True)
def _chol2_into(a: float, b: float, c: float, L: np.ndarray) -> None:
    """Lower Cholesky factor of the PSD 2x2 [[a, b], [b, c]] into ``L`` (semi-definite allowed)."""
    L[0, 1] = 0.0
    if a > 0.0:
        L[0, 0] = np.sqrt(a)
        L[1, 0] = b / L[0, 0]
        L[1, 1] = np.sqrt(max(c - b * b / a, 0.0))
    else:
        L[0, 0] = 0.0
        L[1, 0] = 0.0
        L[1, 1] = np.sqrt(max(c, 0.0))


@nb.njit(cache=True, nogil=True)
def _chol2(a: float, b: float, c: float) -> np.ndarray:
    """Lower Cholesky factor of the PSD 2x2 matrix [[a, b], [b, c]] (semi-definite allowed)."""
    L = np.empty((2, 2))
    _chol2_into(a, b, c, L)
    return L


@nb.njit(cache=True, nogil=True)
def _segment_factor_into(model: int, c: np.ndarray, Q: np.ndarray, sig: np.ndarray,
                         L: np.ndarray) -> None:
    """:func:`segment_factor` writing into a caller-owned (2, 2) ``L``."""
    s, th = _scale_angle(model, c)
    _segment_factor_cs_into(model, s, np.cos(th), np.sin(th), Q, sig, L)


@nb.njit(cache=True, nogil=True)
def _scale_angle(model: int, c: np.ndarray) -> tuple[float, float]:
    """Scale ``s`` and rotation angle ``theta`` of the corrected reading (module docstring)."""
    if model == MODEL_AIRSPEED:
        return 1.0, c[2]
    return 1.0 + c[0], c[1] + c[2]


@nb.njit(cache=True, nogil=True)
def _segment_factor_cs_into(model: int, s: float, ct: float, st: float, Q: np.ndarray,
                            sig: np.ndarray, L: np.ndarray) -> None:
    """:func:`_segment_factor_into` given ``s`` and ``cos``/``sin`` of ``theta``."""
    if model == MODEL_AIRSPEED:
        va = sig[1] * sig[1]
        wn = sig[2] * sig[2] * Q[6]
        we = sig[3] * sig[3] * Q[6]
    else:
        va = sig[1] * sig[1] + sig[2] * sig[2]
        wn = 0.0
        we = 0.0
    v0 = sig[0] * sig[0]
    m00 = v0 * Q[0] + va * Q[3]
    m01 = v0 * Q[1] + va * Q[4]
    m11 = v0 * Q[2] + va * Q[5]
    # R M R^T
    r00 = ct * ct * m00 - 2 * ct * st * m01 + st * st * m11
    r01 = ct * st * (m00 - m11) + (ct * ct - st * st) * m01
    r11 = st * st * m00 + 2 * ct * st * m01 + ct * ct * m11
    _chol2_into(s * s * r00 + wn, s * s * r01, s * s * r11 + we, L)


@nb.njit(cache=True, nogil=True)
def segment_factor(model: int, c: np.ndarray, Q: np.ndarray, sig: np.ndarray) -> np.ndarray:
    """Factor L (2, 2) of the increment noise of whole recorder samples, ``L L^T = Cov``.

    ``Q`` (7,) holds sums over the samples of ``dt^2 u u^T`` (xx, xy, yy), ``dt^2 (Ja)(Ja)^T``
    (xx, xy, yy; ``Ja = [-a_e, a_n]``) and ``dt^2``.  With white errors per sample::

        Cov = s^2 R(theta) [sd_speed^2 Suu + sd_angle^2 Sjj] R(theta)^T + diag(sd_wn^2, sd_we^2) S

    (``sd_angle^2`` = heading, or drift + heading for the Doppler model).
    """
    L = np.empty((2, 2))
    _segment_factor_into(model, c, Q, sig, L)
    return L


@nb.njit(cache=True, nogil=True)
def _step_matrices_into(model: int, c: np.ndarray, A: np.ndarray, U: np.ndarray,
                        Wv: np.ndarray, tau: float, sig: np.ndarray, q: np.ndarray,
                        star: np.ndarray, dt_star: float, Qb: np.ndarray, Qa: np.ndarray,
                        d: np.ndarray, Phi: np.ndarray, B: np.ndarray, J: np.ndarray,
                        Gs: np.ndarray, d2: np.ndarray, L: np.ndarray) -> None:
    """:func:`step_matrices` writing ``d`` (2,), ``Phi`` (5, 5), ``B`` (5, 11) in place.

    ``J`` (2, 3), ``Gs`` (2, 4), ``d2`` (2,), ``L`` (2, 2) are scratch buffers.
    """
    for i in range(N_STATE):
        for j in range(N_STATE):
            Phi[i, j] = 1.0 if i == j else 0.0
        for j in range(N_EPS1):
            B[i, j] = 0.0
    s, th = _scale_angle(model, c)
    ct = np.cos(th)
    st = np.sin(th)
    _increment_cs_into(model, s, ct, st, c, A[0], A[1], U[0], U[1], Wv[0], Wv[1], tau, sig, d,
                       J, Gs)
    for i in range(2):
        for j in range(3):
            Phi[i, 2 + j] = J[i, j]
    _increment_cs_into(model, s, ct, st, c, star[0, 0] * dt_star, star[0, 1] * dt_star,
                       star[1, 0] * dt_star, star[1, 1] * dt_star, star[2, 0] * dt_star,
                       star[2, 1] * dt_star, dt_star, sig, d2, J, Gs)
    for i in range(2):
        for j in range(4):
            B[i, j] = Gs[i, j]
    _segment_factor_cs_into(model, s, ct, st, Qb, sig, L)
    for i in range(2):
        for j in range(2):
            B[i, 4 + j] = L[i, j]
    _segment_factor_cs_into(model, s, ct, st, Qa, sig, L)
    for i in range(2):
        for j in range(2):
            B[i, 6 + j] = L[i, j]
    for j in range(3):
        B[2 + j, 8 + j] = np.sqrt(q[j] * tau)


@nb.njit(cache=True, nogil=True)
def step_matrices(model: int, c: np.ndarray, A: np.ndarray, U: np.ndarray, Wv: np.ndarray,
                  tau: float, sig: np.ndarray, q: np.ndarray, star: np.ndarray, dt_star: float,
                  Qb: np.ndarray, Qa: np.ndarray):
    """Increment, ``Phi = df/dX`` (5, 5) and ``B`` (5, 11) of one filter step.

    ``eps1`` columns: the 4 errors of the recorder sample held at the step's fixes (``star``
    (3, 2): its ``a, u, w``; held for ``dt_star`` within the step; zero without a fix), the
    factors of the summed errors of the samples before (``Qb``) and after (``Qa``) it (see
    :func:`segment_factor`), and the random walks of the corrections: ``q`` (3,) intensities
    [unit^2/s], noise ``sqrt(q tau)``.  Position block of ``Phi`` is the identity in the
    re-centred local-level frame (module docstring, "Frame").
    """
    d = np.empty(2)
    Phi = np.empty((N_STATE, N_STATE))
    B = np.empty((N_STATE, N_EPS1))
    _step_matrices_into(model, c, A, U, Wv, tau, sig, q, star, dt_star, Qb, Qa, d, Phi, B,
                        np.empty((2, 3)), np.empty((2, 4)), np.empty(2), np.empty((2, 2)))
    return d, Phi, B


@nb.njit(cache=True, nogil=True)
def _observation_rows_into(model: int, c: np.ndarray, PA: np.ndarray, PU: np.ndarray,
                           PW: np.ndarray, tau: float, a: np.ndarray, u: np.ndarray,
                           w: np.ndarray, sig: np.ndarray, tau_in: float, Qb: np.ndarray,
                           h: np.ndarray, H: np.ndarray, G: np.ndarray, d: np.ndarray,
                           J: np.ndarray, Gs: np.ndarray, L: np.ndarray) -> None:
    """:func:`observation_rows` writing ``h`` (4,), ``H`` (4, 5), ``G`` (4, 11) in place.

    ``d`` (2,), ``J`` (2, 3), ``Gs`` (2, 4), ``L`` (2, 2) are scratch buffers.
    """
    for i in range(4):
        for j in range(N_STATE):
            H[i, j] = 0.0
        for j in range(N_EPS1):
            G[i, j] = 0.0
    H[0, 0] = 1.0
    H[1, 1] = 1.0
    s, th = _scale_angle(model, c)
    ct = np.cos(th)
    st = np.sin(th)
    _increment_cs_into(model, s, ct, st, c, PA[0], PA[1], PU[0], PU[1], PW[0], PW[1], tau, sig,
                       d, J, Gs)
    h[0] = d[0]
    h[1] = d[1]
    for i in range(2):
        for j in range(3):
            H[i, 2 + j] = J[i, j]
    _increment_cs_into(model, s, ct, st, c, a[0] * tau_in, a[1] * tau_in, u[0] * tau_in,
                       u[1] * tau_in, w[0] * tau_in, w[1] * tau_in, tau_in, sig, d, J, Gs)
    for i in range(2):
        for j in range(4):
            G[i, j] = Gs[i, j]
    _segment_factor_cs_into(model, s, ct, st, Qb, sig, L)
    for i in range(2):
        for j in range(2):
            G[i, 4 + j] = L[i, j]
    _increment_cs_into(model, s, ct, st, c, a[0], a[1], u[0], u[1], w[0], w[1], 1.0, sig, d, J,
                       Gs)
    h[2] = d[0]
    h[3] = d[1]
    for i in range(2):
        for j in range(3):
            H[2 + i, 2 + j] = J[i, j]
        for j in range(4):
            G[2 + i, j] = Gs[i, j]


@nb.njit(cache=True, nogil=True)
def observation_rows(model: int, c: np.ndarray, PA: np.ndarray, PU: np.ndarray, PW: np.ndarray,
                     tau: float, a: np.ndarray, u: np.ndarray, w: np.ndarray, sig: np.ndarray,
                     tau_in: float, Qb: np.ndarray):
    """``h``, ``H = dh/dX`` (4, 5) and ``G`` (4, 11) of one SNS fix taken ``tau`` after the step.

    ``h = [partial increment north, east, corrected velocity north, east]`` relative to the
    position at the start of the step; ``PA, PU, PW`` are the integrals up to the fix time and
    ``a, u, w`` the readings of the recorder sample held at the fix time, held for ``tau_in``
    before it.  ``G``: velocity rows carry that sample's errors; position rows its errors over
    ``tau_in`` and the summed errors of the step's earlier samples (``Qb``), shared with ``B``.
    """
    h = np.empty(4)
    H = np.empty((4, N_STATE))
    G = np.empty((4, N_EPS1))
    _observation_rows_into(model, c, PA, PU, PW, tau, a, u, w, sig, tau_in, Qb, h, H, G,
                           np.empty(2), np.empty((2, 3)), np.empty((2, 4)), np.empty((2, 2)))
    return h, H, G


@nb.njit(cache=True, nogil=True)
def _jacobi_eigh(A: np.ndarray, V: np.ndarray) -> None:
    """Eigen-decomposition of a symmetric matrix by cyclic Jacobi rotations, in place.

    On return the diagonal of ``A`` holds the eigenvalues and the columns of ``V`` the
    eigenvectors (``A_in = V diag V^T``).  Each rotation zeroes one off-diagonal pair
    (``t = tan phi`` the small root of ``t^2 + 2 theta t - 1 = 0``,
    ``theta = (a_qq - a_pp) / (2 a_pq)``); sweeps stop when the off-diagonal Frobenius norm is
    below 1e-17 of the whole norm (backward-stable: eigenvalues to round-off of ``||A||``), at
    most 60 sweeps.  For the small (4..8) innovation covariances of the filter this is several
    times cheaper than a LAPACK call with its workspace allocations.
    """
    m = A.shape[0]
    for i in range(m):
        for j in range(m):
            V[i, j] = 1.0 if i == j else 0.0
    for _sweep in range(60):
        off = 0.0
        tot = 0.0
        for i in range(m):
            tot += A[i, i] * A[i, i]
            for j in range(i + 1, m):
                off += A[i, j] * A[i, j]
        tot += 2.0 * off
        if off <= 1e-34 * tot:
            return
        for p in range(m - 1):
            for q in range(p + 1, m):
                apq = A[p, q]
                if apq == 0.0:
                    continue
                theta = (A[q, q] - A[p, p]) / (2.0 * apq)
                if abs(theta) > 1e150:
                    t = 0.5 / theta
                else:
                    t = 1.0 / (abs(theta) + np.sqrt(theta * theta + 1.0))
                    if theta < 0.0:
                        t = -t
                cs = 1.0 / np.sqrt(t * t + 1.0)
                sn = t * cs
                for r in range(m):  # columns: A J
                    arp = A[r, p]
                    arq = A[r, q]
                    A[r, p] = cs * arp - sn * arq
                    A[r, q] = sn * arp + cs * arq
                for r in range(m):  # rows: J^T (A J)
                    apr = A[p, r]
                    aqr = A[q, r]
                    A[p, r] = cs * apr - sn * aqr
                    A[q, r] = sn * apr + cs * aqr
                A[p, q] = 0.0
                A[q, p] = 0.0
                for r in range(m):
                    vrp = V[r, p]
                    vrq = V[r, q]
                    V[r, p] = cs * vrp - sn * vrq
                    V[r, q] = sn * vrp + cs * vrq


@nb.njit(cache=True, nogil=True)
def _inv_spd_into(S: np.ndarray, rcond: float, Sp: np.ndarray, L: np.ndarray) -> bool:
    """``Sp = S^{-1}`` by Cholesky when that provably equals the pseudo-inverse of :func:`pinv_sym`.

    With ``S = L L^T`` and ``X = S^{-1}`` (from the triangular factor), every eigenvalue of ``S``
    lies in ``[1 / trace(X), trace(S)]``; if ``1 / trace(X) > rcond * trace(S)`` no eigenvalue
    falls below ``rcond * max eigenvalue``, the rank is full and ``S^+ = S^{-1}``.  Returns False
    (``Sp`` undefined) when the factorisation fails or that test does not pass (the caller then
    uses the eigen-decomposition).  ``L`` is scratch of ``S``'s shape.
    """
    m = S.shape[0]
    tr = 0.0
    for j in range(m):
        tr += S[j, j]
        acc = S[j, j]
        for k in range(j):
            acc -= L[j, k] * L[j, k]
        if not acc > 0.0:
            return False
        L[j, j] = np.sqrt(acc)
        for i in range(j + 1, m):
            acc = 0.5 * (S[i, j] + S[j, i])
            for k in range(j):
                acc -= L[i, k] * L[j, k]
            L[i, j] = acc / L[j, j]
    # W = L^{-1} (lower triangular) into the upper part of Sp's transpose workspace: use Sp
    for j in range(m):
        for i in range(m):
            Sp[i, j] = 0.0
        Sp[j, j] = 1.0 / L[j, j]
        for i in range(j + 1, m):
            acc = 0.0
            for k in range(j, i):
                acc -= L[i, k] * Sp[k, j]
            Sp[i, j] = acc / L[i, i]
    # X = W^T W (symmetric); W is stored in the lower triangle of Sp, so build X into L
    trx = 0.0
    for i in range(m):
        for j in range(i, m):
            acc = 0.0
            for k in range(j, m):
                acc += Sp[k, i] * Sp[k, j]
            L[i, j] = acc
        trx += L[i, i]
    if not 1.0 / trx > rcond * tr:
        return False
    for i in range(m):
        for j in range(i, m):
            Sp[i, j] = L[i, j]
            Sp[j, i] = L[i, j]
    return True


@nb.njit(cache=True, nogil=True)
def _pinv_sym_into(S: np.ndarray, rcond: float, Sp: np.ndarray, A: np.ndarray,
                   V: np.ndarray) -> int:
    """:func:`pinv_sym` writing ``S^+`` into ``Sp``; ``A``, ``V`` scratch of ``S``'s shape.

    Well-conditioned ``S`` (the usual innovation covariance) takes the Cholesky inverse
    (:func:`_inv_spd_into`, full rank proven); otherwise the Jacobi eigen-decomposition.
    """
    m = S.shape[0]
    for i in range(m):
        for j in range(m):
            if not np.isfinite(S[i, j]):
                raise np.linalg.LinAlgError("innovation covariance is not finite")
    if _inv_spd_into(S, rcond, Sp, A):
        return m
    for i in range(m):
        for j in range(m):
            A[i, j] = 0.5 * (S[i, j] + S[j, i])
    _jacobi_eigh(A, V)
    lmax = 0.0
    for i in range(m):
        lmax = max(lmax, abs(A[i, i]))
    for i in range(m):
        for j in range(m):
            Sp[i, j] = 0.0
    rank = 0
    for e in range(m):
        lam = A[e, e]
        if lam > rcond * lmax and lam > 0.0:
            rank += 1
            inv = 1.0 / lam
            for i in range(m):
                vi = V[i, e] * inv
                for j in range(m):
                    Sp[i, j] += vi * V[j, e]
    return rank


@nb.njit(cache=True, nogil=True)
def pinv_sym(S: np.ndarray, rcond: float):
    """Moore-Penrose pseudo-inverse of a symmetric matrix and its numerical rank.

    Eigen-decomposition ``S = V diag(l) V^T`` (cyclic Jacobi, :func:`_jacobi_eigh`);
    eigenvalues ``l <= rcond * max |l|`` are treated as zero.  Returns ``(S^+, rank)``.  When a
    Cholesky factorisation proves that no eigenvalue is below the threshold the result is the
    inverse computed from that factor (same matrix, to round-off; :func:`_inv_spd_into`).
    """
    m = S.shape[0]
    Sp = np.empty((m, m))
    rank = _pinv_sym_into(S, rcond, Sp, np.empty((m, m)), np.empty((m, m)))
    return Sp, rank


@dataclass(frozen=True)
class StepInputs:
    """Everything the filter needs per filter step, precomputed from the recorder grid.

    Filter grid of ``N`` points ``t`` (s); step k runs from ``t[k]`` to ``t[k+1]``.

    Attributes
    ----------
    t : (N,) filter times [s]
    h : (N,) height used for the radii [m]
    A, U, W : (N, 2) integrals of the held readings over step k (row ``N-1`` zero)
    fix_start, fix_end : (N,) int: the fixes taken during step k are ``fix_start[k]:fix_end[k]``
        (the last point takes the fixes at its own time)
    fix_lat, fix_lon : (F,) centre-of-mass fix position [rad]
    fix_v : (F, 2) centre-of-mass ground velocity north/east [m/s] (NaN where absent)
    fix_tau : (F,) time of the fix after the start of its step [s]
    fix_PA, fix_PU, fix_PW : (F, 2) integrals from the start of the step to the fix
    fix_a, fix_u, fix_w : (F, 2) readings of the recorder sample held at the fix time
    star : (N, 3, 2) ``a, u, w`` of the recorder sample held at the fixes of step k (all fixes of
        a step fall in one recorder sample); ``dt_star`` (N,) how long it is held in the step
    Qb, Qa : (N, 7) noise sums (:func:`segment_factor`) of the step's recorder samples before and
        after that sample (steps without fixes: all samples in ``Qb``)
    fix_tau_in : (F,) time from the start of the fix's recorder sample to the fix [s]

    fix_pos_sd, fix_vel_sd : (F,) per-fix sd of the position / velocity components (the
        receiver's accuracy figures); ``None`` or NaN: ``SnsNoise.pos_sd_m`` / ``vel_sd_mps``
    ``star``, ``dt_star``, ``Qb``, ``Qa``, ``fix_tau_in`` may be left ``None`` when every filter
    step is one recorder sample (then ``star = A / tau`` etc., as :func:`fill_single_sample`).
    """

    t: np.ndarray
    h: np.ndarray
    A: np.ndarray
    U: np.ndarray
    W: np.ndarray
    fix_start: np.ndarray
    fix_end: np.ndarray
    fix_lat: np.ndarray
    fix_lon: np.ndarray
    fix_v: np.ndarray
    fix_tau: np.ndarray
    fix_PA: np.ndarray
    fix_PU: np.ndarray
    fix_PW: np.ndarray
    fix_a: np.ndarray
    fix_u: np.ndarray
    fix_w: np.ndarray
    star: np.ndarray | None = None
    dt_star: np.ndarray | None = None
    Qb: np.ndarray | None = None
    Qa: np.ndarray | None = None
    fix_tau_in: np.ndarray | None = None
    fix_pos_sd: np.ndarray | None = None
    fix_vel_sd: np.ndarray | None = None


def _per_fix_sd(v: np.ndarray | None, default: float, n: int) -> np.ndarray:
    """(n,) per-fix standard deviations: ``v`` where finite and positive, else ``default``."""
    if v is None:
        return np.full(n, float(default))
    v = np.asarray(v, float).reshape(-1)
    return np.ascontiguousarray(np.where(np.isfinite(v) & (v > 0), v, float(default)))


def fill_single_sample(inp: StepInputs) -> StepInputs:
    """Complete the per-sample noise fields for filter steps of one recorder sample each."""
    if inp.star is not None:
        return inp
    t = np.asarray(inp.t, float)
    tau = np.zeros(len(t))
    tau[:-1] = np.diff(t)
    inv = np.divide(1.0, tau, out=np.zeros_like(tau), where=tau > 0)[:, None]
    star = np.stack([np.asarray(inp.A) * inv, np.asarray(inp.U) * inv,
                     np.asarray(inp.W) * inv], axis=1)
    z = np.zeros((len(t), 7))
    return replace(inp, star=star, dt_star=tau, Qb=z, Qa=z.copy(),
                   fix_tau_in=np.asarray(inp.fix_tau, float).copy())


@dataclass(frozen=True)
class SnsNoise:
    """Noise and prior settings of the SNS filter (SI; angles in radians).

    Attributes
    ----------
    sensor_sd : (4,) sensor noise per recorder sample (white): airspeed model ``[TAS m/s, heading rad,
        wind north m/s, wind east m/s]``; Doppler model ``[ground speed m/s, drift rad,
        heading rad, unused]``
    rw_q : (3,) random-walk intensities of the corrections [unit^2/s]
    pos_sd_m, vel_sd_mps : SNS position / velocity noise per component (``D``)
    prior_sd : (3,) prior standard deviations of the corrections
    rcond : relative eigenvalue tolerance of the pseudo-inverse of ``S``
    """

    sensor_sd: tuple[float, float, float, float]
    rw_q: tuple[float, float, float]
    pos_sd_m: float
    vel_sd_mps: float
    prior_sd: tuple[float, float, float]
    rcond: float = 1e-10


def default_noise(model: int) -> SnsNoise:
    """Default noise settings, typical of a transport aircraft's recorder and a GNSS receiver.

    Airspeed: TAS 0.5 m/s, heading 0.2 deg, wind reading 1 m/s white per recorder sample; heading bias prior
    2 deg, wind-correction prior 10 m/s.  Doppler: ground speed 0.5 m/s, drift 0.2 deg, heading
    0.2 deg; scale prior 0.03, drift and heading bias priors 1 and 2 deg.  Random walks let the
    corrections drift by about 0.1 deg/h, 1 m/s per hour and 0.1 %/h.  GNSS 3 m, 0.1 m/s.
    """
    d = np.deg2rad
    hour = 3600.0
    if model == MODEL_AIRSPEED:
        return SnsNoise((0.5, float(d(0.2)), 1.0, 1.0),
                        (1.0 / hour, 1.0 / hour, float(d(0.1)) ** 2 / hour),
                        3.0, 0.1, (10.0, 10.0, float(d(2.0))))
    if model == MODEL_DOPPLER:
        return SnsNoise((0.5, float(d(0.2)), float(d(0.2)), 0.0),
                        (1e-6 / hour, float(d(0.1)) ** 2 / hour, float(d(0.1)) ** 2 / hour),
                        3.0, 0.1, (0.03, float(d(1.0)), float(d(2.0))))
    raise ValueError(f"unknown model {model}")


@dataclass(frozen=True)
class SnsRun:
    """A forward run of the SNS filter (time-major; position in lat/lon radians).

    Attributes
    ----------
    x_pred, x : (N, 5) predicted / filtered states ``[lat_rad, lon_rad, c1, c2, c3]``
    P_pred, P : (N, 5, 5) covariances in the local-level frame (north/east metres first)
    cross : (N, 5, 5) ``Cov(x_k, x_{k+1} | Y_0..k)`` (smoother numerator; row ``N-1`` zero)
    nis : (N,) normalised innovation squared (NaN without fixes), ``rank`` its degrees of freedom
    h : (N,) heights used for the radii
    model, form : as passed
    """

    x_pred: np.ndarray
    x: np.ndarray
    P_pred: np.ndarray
    P: np.ndarray
    cross: np.ndarray
    nis: np.ndarray
    rank: np.ndarray
    h: np.ndarray
    model: int
    form: int


@dataclass(frozen=True)
class SnsSmoothed:
    """Smoothed states ``x`` (N, 5) (lat/lon radians first) and covariances ``P`` (N, 5, 5)."""

    x: np.ndarray
    P: np.ndarray


@nb.njit(cache=True, nogil=True)
def _mm(A, B, out):
    """``out = A @ B`` for small matrices (plain loops: no allocation, no BLAS call overhead).

    Row-update order (``out[i, :] += A[i, l] B[l, :]``): the inner loop carries no dependency
    chain, which matters more than anything else at these sizes.
    """
    n, kk = A.shape
    m = B.shape[1]
    for i in range(n):
        for j in range(m):
            out[i, j] = 0.0
        for l in range(kk):
            a = A[i, l]
            if a != 0.0:
                for j in range(m):
                    out[i, j] += a * B[l, j]


@nb.njit(cache=True, nogil=True)
def _mmt(A, B, out):
    """``out = A @ B.T`` for small matrices (row-update order, as :func:`_mm`)."""
    n, kk = A.shape
    m = B.shape[0]
    for i in range(n):
        for j in range(m):
            out[i, j] = 0.0
        for l in range(kk):
            a = A[i, l]
            if a != 0.0:
                for j in range(m):
                    out[i, j] += a * B[j, l]


@nb.njit(cache=True, nogil=True)
def _mdmt_acc(A, dg, B, out):
    """``out += A @ diag(dg) @ B.T`` for small matrices (row-update order, as :func:`_mm`)."""
    n, kk = A.shape
    m = B.shape[0]
    for i in range(n):
        for l in range(kk):
            a = A[i, l] * dg[l]
            if a != 0.0:
                for j in range(m):
                    out[i, j] += a * B[j, l]


@nb.njit(cache=True, nogil=True)
def _sym_into(M, out):
    """``out = (M + M^T) / 2``."""
    n = M.shape[0]
    for i in range(n):
        for j in range(i, n):
            v = 0.5 * (M[i, j] + M[j, i])
            out[i, j] = v
            out[j, i] = v


@nb.njit(cache=True, nogil=True)
def _filter_kernel(model, form, x0, P0, t, hgt, A, U, W, fs, fe, flat, flon, fv, ftau,
                   fPA, fPU, fPW, fa, fu, fw, star, dt_star, Qb, Qa, ftau_in, sig, q, pos_sd,
                   vel_sd, rcond):
    # pos_sd, vel_sd: (F,) per-fix standard deviations of the SNS position / velocity (D)
    # All small-matrix algebra runs in preallocated buffers with loop products (_mm, _mmt):
    # the same operations as the matrix expressions in the module docstring, without the
    # per-step heap allocations and BLAS calls that dominated the run time.
    N = t.shape[0]
    n = N_STATE
    ne = N_EPS1
    xp = np.empty((N, n))
    xs = np.empty((N, n))
    Pp = np.empty((N, n, n))
    Ps = np.empty((N, n, n))
    cross = np.zeros((N, n, n))
    nis = np.full(N, np.nan)
    rank = np.zeros(N, dtype=np.int64)
    mmax = 1
    for k in range(N):
        m = 0
        for i in range(fs[k], fe[k]):
            m += 2
            for j in range(2):
                if not np.isnan(fv[i, j]):
                    m += 1
        mmax = max(mmax, m)
    # buffers
    Hb = np.zeros((mmax, n))
    Gb = np.zeros((mmax, ne))
    Rd = np.zeros(mmax)
    nub = np.zeros(mmax)
    Rtb = np.zeros((mmax, mmax))
    Sb = np.zeros((mmax, mmax))
    Spb = np.zeros((mmax, mmax))
    Ab = np.zeros((mmax, mmax))
    Vb = np.zeros((mmax, mmax))
    PHtb = np.zeros((n, mmax))
    Kb = np.zeros((n, mmax))
    T5m = np.zeros((n, mmax))
    BGb = np.zeros((n, mmax))
    BGSb = np.zeros((n, mmax))
    Lgb = np.zeros((n, mmax))
    Spnu = np.zeros(mmax)
    hh = np.zeros(4)
    Hi = np.zeros((4, n))
    Gi = np.zeros((4, ne))
    d = np.zeros(2)
    d2 = np.zeros(2)
    Jw = np.zeros((2, 3))
    Gw = np.zeros((2, 4))
    Lw = np.zeros((2, 2))
    Phi = np.zeros((n, n))
    B = np.zeros((n, ne))
    KH = np.zeros((n, n))
    T55 = np.zeros((n, n))
    Pn = np.zeros((n, n))
    Pplus = np.zeros((n, n))
    T5e = np.zeros((n, ne))
    ones_e = np.ones(ne)
    minus_m = -np.ones(mmax)
    x = x0.copy()
    P = P0.copy()
    xplus = np.zeros(n)
    c = np.zeros(3)
    for k in range(N):
        xp[k] = x
        Pp[k] = P
        for j in range(3):
            c[j] = x[2 + j]
        # ---- fixes taken during step k: stacked observation
        m = 0
        for i in range(fs[k], fe[k]):
            m += 2
            for j in range(2):
                if not np.isnan(fv[i, j]):
                    m += 1
        have = m > 0
        Hs = Hb[:m]
        Gs = Gb[:m]
        nu = nub[:m]
        K = Kb[:, :m]
        Rt = Rtb[:m, :m]
        S = Sb[:m, :m]
        Sp = Spb[:m, :m]
        PHt = PHtb[:, :m]
        if have:
            r = 0
            for i in range(fs[k], fe[k]):
                _observation_rows_into(model, c, fPA[i], fPU[i], fPW[i], ftau[i], fa[i], fu[i],
                                       fw[i], sig, ftau_in[i], Qb[k], hh, Hi, Gi, d, Jw, Gw, Lw)
                dn, de = boxminus(flat[i], flon[i], x[0], x[1], hgt[k])
                for j in range(4):
                    if j >= 2 and np.isnan(fv[i, j - 2]):
                        continue
                    for l in range(n):
                        Hs[r, l] = Hi[j, l]
                    for l in range(ne):
                        Gs[r, l] = Gi[j, l]
                    if j == 0:
                        nu[r] = dn - hh[0]
                        Rd[r] = pos_sd[i] * pos_sd[i]
                    elif j == 1:
                        nu[r] = de - hh[1]
                        Rd[r] = pos_sd[i] * pos_sd[i]
                    else:
                        nu[r] = fv[i, j - 2] - hh[j]
                        Rd[r] = vel_sd[i] * vel_sd[i]
                    r += 1
            _mmt(Gs, Gs, Rt)  # Rt = D D^T + G G^T
            for r in range(m):
                Rt[r, r] += Rd[r]
            _mmt(P, Hs, PHt)  # P- H^T
            _mm(Hs, PHt, S)
            for i in range(m):
                for j in range(m):
                    S[i, j] += Rt[i, j]
            rk = _pinv_sym_into(S, rcond, Sp, Ab[:m, :m], Vb[:m, :m])
            _mm(PHt, Sp, K)  # K = P- H^T S^+
            # Joseph form: (I - K H) P- (I - K H)^T + K Rt K^T
            _mm(K, Hs, KH)
            for i in range(n):
                for j in range(n):
                    KH[i, j] = (1.0 if i == j else 0.0) - KH[i, j]
            _mm(KH, P, T55)
            _mmt(T55, KH, Pn)
            T = T5m[:, :m]
            _mm(K, Rt, T)
            _mmt(T, K, Pplus)
            for i in range(n):
                for j in range(n):
                    Pplus[i, j] += Pn[i, j]
            _sym_into(Pplus, Pplus)
            nis_k = 0.0
            for i in range(m):
                s = 0.0
                for j in range(m):
                    s += Sp[i, j] * nu[j]
                Spnu[i] = s
                nis_k += nu[i] * s
            nis[k] = nis_k
            rank[k] = rk
            dx0 = 0.0
            dx1 = 0.0
            for j in range(m):
                dx0 += K[0, j] * nu[j]
                dx1 += K[1, j] * nu[j]
            lat, lon = boxplus(x[0], x[1], dx0, dx1, hgt[k])
            xplus[0] = lat
            xplus[1] = lon
            for i in range(2, n):
                s = 0.0
                for j in range(m):
                    s += K[i, j] * nu[j]
                xplus[i] = x[i] + s
        else:
            for i in range(n):
                xplus[i] = x[i]
                for j in range(n):
                    Pplus[i, j] = P[i, j]
        xs[k] = xplus
        Ps[k] = Pplus
        if k == N - 1:
            break
        # ---- prediction to k+1 with the corrected readings of step k
        for j in range(3):
            c[j] = xplus[2 + j]
        tau = t[k + 1] - t[k]
        _step_matrices_into(model, c, A[k], U[k], W[k], tau, sig, q, star[k], dt_star[k],
                            Qb[k], Qa[k], d, Phi, B, Jw, Gw, d2, Lw)
        dn = d[0]
        de = d[1]
        ck = cross[k]
        if have and form == FORM_CONSISTENT:
            BG = BGb[:, :m]
            BGS = BGSb[:, :m]
            Lg = Lgb[:, :m]
            _mmt(B, Gs, BG)  # B G^T
            _mm(BG, Sp, BGS)  # B G^T S^+
            for j in range(m):  # state correction B G^T S^+ nu (position rows only: the
                dn += BGS[0, j] * nu[j]  # random-walk columns of B have no G counterpart)
                de += BGS[1, j] * nu[j]
            _mm(Phi, K, Lg)  # L = Phi K + B G^T S^+
            for i in range(n):
                for j in range(m):
                    Lg[i, j] += BGS[i, j]
            _mm(Lg, Hs, KH)  # Phi - L H
            for i in range(n):
                for j in range(n):
                    KH[i, j] = Phi[i, j] - KH[i, j]
            _mm(KH, P, T55)
            _mmt(T55, KH, Pn)
            _mm(Lg, Gs, T5e)  # B - L G
            for i in range(n):
                for j in range(ne):
                    T5e[i, j] = B[i, j] - T5e[i, j]
            _mdmt_acc(T5e, ones_e, T5e, Pn)  # + (B - L G)(B - L G)^T
            _mdmt_acc(Lg, Rd, Lg, Pn)  # + L D D^T L^T
            # smoother numerator P+ Phi^T - K G B^T
            _mmt(Pplus, Phi, ck)
            _mdmt_acc(K, minus_m, BG, ck)
        else:
            _mm(Phi, Pplus, T55)
            _mmt(T55, Phi, Pn)
            _mdmt_acc(B, ones_e, B, Pn)
            _mmt(Pplus, Phi, ck)
        lat, lon = boxplus(xplus[0], xplus[1], dn, de, hgt[k])
        x[0] = lat
        x[1] = lon
        for i in range(2, n):
            x[i] = xplus[i]
        _sym_into(Pn, P)
    return xp, xs, Pp, Ps, cross, nis, rank


def _c(a, dtype=np.float64) -> np.ndarray:
    return np.ascontiguousarray(np.asarray(a, dtype=dtype))


def sns_filter(inputs: StepInputs, x0: np.ndarray, P0: np.ndarray, noise: SnsNoise, *,
               model: int, form: int = FORM_CONSISTENT) -> SnsRun:
    """Run the nonlinear SNS filter forward (module docstring; METHODS.md section 4).

    Parameters
    ----------
    inputs : :class:`StepInputs`
    x0 : (5,) initial state ``[lat_rad, lon_rad, c1, c2, c3]`` at ``inputs.t[0]``
    P0 : (5, 5) its covariance (north/east metres, correction units)
    noise : :class:`SnsNoise`
    model : ``MODEL_AIRSPEED`` or ``MODEL_DOPPLER``
    form : ``FORM_CONSISTENT`` (correlated-noise terms) or ``FORM_SEED`` (seed 003 as printed)
    """
    if model not in (MODEL_AIRSPEED, MODEL_DOPPLER):
        raise ValueError(f"unknown model {model}")
    if form not in (FORM_CONSISTENT, FORM_SEED):
        raise ValueError(f"unknown form {form}")
    t = _c(inputs.t)
    if t.ndim != 1 or t.size < 2 or not np.all(np.diff(t) > 0):
        raise ValueError("filter times must be strictly increasing, at least two")
    P0 = _c(P0)
    if P0.shape != (N_STATE, N_STATE):
        raise ValueError(f"P0 must be (5, 5), got {P0.shape}")
    inputs = fill_single_sample(inputs)
    out = _filter_kernel(
        int(model), int(form), _c(x0), P0, t, _c(inputs.h), _c(inputs.A), _c(inputs.U),
        _c(inputs.W), _c(inputs.fix_start, np.int64), _c(inputs.fix_end, np.int64),
        _c(inputs.fix_lat), _c(inputs.fix_lon), _c(inputs.fix_v).reshape(-1, 2),
        _c(inputs.fix_tau), _c(inputs.fix_PA).reshape(-1, 2), _c(inputs.fix_PU).reshape(-1, 2),
        _c(inputs.fix_PW).reshape(-1, 2), _c(inputs.fix_a).reshape(-1, 2),
        _c(inputs.fix_u).reshape(-1, 2), _c(inputs.fix_w).reshape(-1, 2),
        _c(inputs.star).reshape(-1, 3, 2), _c(inputs.dt_star), _c(inputs.Qb).reshape(-1, 7),
        _c(inputs.Qa).reshape(-1, 7), _c(inputs.fix_tau_in), _c(noise.sensor_sd),
        _c(noise.rw_q), _per_fix_sd(inputs.fix_pos_sd, noise.pos_sd_m, len(inputs.fix_lat)),
        _per_fix_sd(inputs.fix_vel_sd, noise.vel_sd_mps, len(inputs.fix_lat)),
        float(noise.rcond))
    xp, xs, Pp, Ps, cross, nis, rank = out
    return SnsRun(xp, xs, Pp, Ps, cross, nis, rank, _c(inputs.h).copy(), int(model),
                  int(form))


@nb.njit(cache=True, nogil=True)
def _chol_solve_rows(P, Cr, L, out) -> bool:
    """``out = Cr P^{-1}`` for a symmetric positive-definite ``P`` (n, n) by Cholesky.

    ``L`` is an (n, n) scratch.  Returns False (``out`` undefined) if a pivot is not clearly
    positive (``<= 1e-14`` of its diagonal entry), so the caller can fall back to a general solve
    that reports singularity.
    """
    n = P.shape[0]
    if not cholesky_factor(P, L, 1e-14):
        return False
    for r in range(Cr.shape[0]):  # P z = Cr[r]^T (P symmetric), out[r] = z^T
        for i in range(n):  # L y = b
            s = Cr[r, i]
            for l in range(i):
                s -= L[i, l] * out[r, l]
            out[r, i] = s / L[i, i]
        for i in range(n - 1, -1, -1):  # L^T z = y
            s = out[r, i]
            for l in range(i + 1, n):
                s -= L[l, i] * out[r, l]
            out[r, i] = s / L[i, i]
    return True


@nb.njit(cache=True, nogil=True)
def _smoother_kernel(xp, xf, Pp, Pf, cross, hgt):
    N, n = xf.shape
    xs = xf.copy()
    Ps = Pf.copy()
    d = np.zeros(n)
    dx = np.zeros(n)
    C = np.zeros((n, n))
    Lw = np.zeros((n, n))
    Dd = np.zeros((n, n))
    T = np.zeros((n, n))
    Pk = np.zeros((n, n))
    for k in range(N - 2, -1, -1):
        # C = cross_k Pp_{k+1}^{-1}: Cholesky solve with the symmetric Pp; a general solve
        # (which raises LinAlgError if Pp is singular) when it is not positive definite
        if not _chol_solve_rows(Pp[k + 1], cross[k], Lw, C):
            C[:, :] = np.linalg.solve(Pp[k + 1], cross[k].T).T
        dn, de = boxminus(xs[k + 1, 0], xs[k + 1, 1], xp[k + 1, 0], xp[k + 1, 1], hgt[k + 1])
        d[0] = dn
        d[1] = de
        for j in range(2, n):
            d[j] = xs[k + 1, j] - xp[k + 1, j]
        for i in range(n):
            s = 0.0
            for j in range(n):
                s += C[i, j] * d[j]
            dx[i] = s
        lat, lon = boxplus(xf[k, 0], xf[k, 1], dx[0], dx[1], hgt[k])
        xs[k, 0] = lat
        xs[k, 1] = lon
        for j in range(2, n):
            xs[k, j] = xf[k, j] + dx[j]
        for i in range(n):
            for j in range(n):
                Dd[i, j] = Ps[k + 1, i, j] - Pp[k + 1, i, j]
        _mm(C, Dd, T)
        _mmt(T, C, Pk)
        for i in range(n):
            for j in range(n):
                Pk[i, j] += Pf[k, i, j]
        _sym_into(Pk, Ps[k])
    return xs, Ps


def sns_smooth(run: SnsRun) -> SnsSmoothed:
    """Backward pass with the gain matching the filter's form (module docstring, "Smoother")."""
    xs, Ps = _smoother_kernel(_c(run.x_pred), _c(run.x), _c(run.P_pred), _c(run.P),
                              _c(run.cross), _c(run.h))
    return SnsSmoothed(xs, Ps)


@nb.njit(cache=True, nogil=True)
def _inc_pos(model, s, ct, st, c0, c1, A0, A1, W0, W1, tau):
    """North/east increment ``s R(theta) A + Wv + dw tau`` of :func:`increment` (scalars)."""
    ra0 = ct * A0 - st * A1
    ra1 = st * A0 + ct * A1
    if model == MODEL_AIRSPEED:
        return ra0 + W0 + c0 * tau, ra1 + W1 + c1 * tau
    return s * ra0, s * ra1


@nb.njit(cache=True, nogil=True)
def _boxplus_pre(lat: float, lon: float, slat: float, clat: float, mr: float, nr: float,
                 dn: float, de: float, h: float) -> tuple[float, float]:
    """:func:`boxplus` from a point whose ``sin``/``cos`` of latitude and height-free radii
    ``mr, nr`` (``radii(lat, 0)``) are known.

    The mid-latitude ``lat + dl`` (``dl = dn / (2 (M + h))``) enters through the angle-addition
    formulas with ``sin dl = dl - dl^3/6`` and ``cos dl = 1 - dl^2/2 + dl^4/24``, whose
    truncation (``dl^5/120``, ``dl^6/720``) is below 1e-17 for ``|dl| <= 1e-3`` rad (6 km);
    larger moves take :func:`boxplus` itself.  Same result to round-off, without the three
    trigonometric calls per move.
    """
    mh = mr + h
    dl = 0.5 * dn / mh
    if abs(dl) > 1e-3:
        return boxplus(lat, lon, dn, de, h)
    d2 = dl * dl
    sd = dl * (1.0 - d2 / 6.0)
    cd = 1.0 - 0.5 * d2 + d2 * d2 / 24.0
    sm = slat * cd + clat * sd
    cm = clat * cd - slat * sd
    w = 1.0 - _E2 * sm * sm
    n = _A / np.sqrt(w)
    m = n * (1.0 - _E2) / w
    return lat + dn / (m + h), lon + de / ((n + h) * cm)


@nb.njit(cache=True, nogil=True)
def _densify_kernel(model, xs, Ps, kidx, tq, tf, IA, IU, IW, FA, FU, FW, hq, a, u, w, sig):
    # Scalar form of the per-sample work (no allocation): the increments of :func:`increment`
    # (only ``d`` is needed for the positions; the velocity uses ``d``, ``J`` and ``Gs`` at
    # ``tau = 1``), blended as described in :func:`densify`.
    M = tq.shape[0]
    lat = np.empty(M)
    lon = np.empty(M)
    Pn = np.empty((M, 2, 2))
    v = np.empty((M, 2))
    Pv = np.empty((M, 2, 2))
    nlast = xs.shape[0] - 1
    J = np.zeros((2, 3))
    Gs = np.zeros((2, 4))
    d = np.zeros(2)
    c = np.zeros(3)
    JP = np.zeros((2, 3))
    kprev = -1
    s = 1.0
    ct = 1.0
    st = 0.0
    # sin/cos of latitude and height-free radii of the states x_k and x_{k+1} (_boxplus_pre)
    s0 = c0 = m0 = n0 = s1 = c1 = m1 = n1 = 0.0
    for j in range(M):
        k = kidx[j]
        k1 = min(k + 1, nlast)
        if k != kprev:
            for i in range(3):
                c[i] = xs[k, 2 + i]
            s, th = _scale_angle(model, c)
            ct = np.cos(th)
            st = np.sin(th)
            kprev = k
            s0 = np.sin(xs[k, 0])
            c0 = np.cos(xs[k, 0])
            m0, n0 = radii(xs[k, 0], 0.0)
            s1 = np.sin(xs[k1, 0])
            c1 = np.cos(xs[k1, 0])
            m1, n1 = radii(xs[k1, 0], 0.0)
        tk = tf[k]
        tk1 = tf[k1]
        # forward from x_k over [t_k, t_j]
        d10, d11 = _inc_pos(model, s, ct, st, c[0], c[1], IA[j, 0] - FA[k, 0],
                            IA[j, 1] - FA[k, 1], IW[j, 0] - FW[k, 0], IW[j, 1] - FW[k, 1],
                            tq[j] - tk)
        la1, lo1 = _boxplus_pre(xs[k, 0], xs[k, 1], s0, c0, m0, n0, d10, d11, hq[j])
        if k < nlast and tk1 > tk:
            wgt = (tq[j] - tk) / (tk1 - tk)
            # backward from x_{k+1} over [t_j, t_{k+1}]
            d20, d21 = _inc_pos(model, s, ct, st, c[0], c[1], FA[k1, 0] - IA[j, 0],
                                FA[k1, 1] - IA[j, 1], FW[k1, 0] - IW[j, 0],
                                FW[k1, 1] - IW[j, 1], tk1 - tq[j])
            la2, lo2 = _boxplus_pre(xs[k1, 0], xs[k1, 1], s1, c1, m1, n1, -d20, -d21, hq[j])
            # linear blend in latitude/longitude: the two dead-reckoned positions differ by
            # the step's smoothed process noise (millimetres to centimetres), over which the
            # radii change by 1e-9 relative, so this equals the blend of the north/east
            # difference (la1 (+) wgt (la2 (-) la1)) to far below a micrometre
            la = la1 + wgt * (la2 - la1)
            lo = lo1 + wgt * (lo2 - lo1)
            for r in range(2):
                for q in range(2):
                    Pn[j, r, q] = (1.0 - wgt) * Ps[k, r, q] + wgt * Ps[k1, r, q]
        else:
            la = la1
            lo = lo1
            for r in range(2):
                for q in range(2):
                    Pn[j, r, q] = Ps[k, r, q]
        lat[j] = la
        lon[j] = lo
        _increment_cs_into(model, s, ct, st, c, a[j, 0], a[j, 1], u[j, 0], u[j, 1], w[j, 0],
                           w[j, 1], 1.0, sig, d, J, Gs)
        v[j, 0] = d[0]
        v[j, 1] = d[1]
        # Pv = J P_c J^T + Gs Gs^T
        for r in range(2):
            for q in range(3):
                acc = 0.0
                for l in range(3):
                    acc += J[r, l] * Ps[k, 2 + l, 2 + q]
                JP[r, q] = acc
        for r in range(2):
            for q in range(2):
                acc = 0.0
                for l in range(3):
                    acc += JP[r, l] * J[q, l]
                for l in range(4):
                    acc += Gs[r, l] * Gs[q, l]
                Pv[j, r, q] = acc
    return lat, lon, Pn, v, Pv


def densify(model: int, xs: np.ndarray, Ps: np.ndarray, kidx: np.ndarray, tq: np.ndarray,
            t_filter: np.ndarray, I_at_q: tuple[np.ndarray, np.ndarray, np.ndarray],
            I_at_filter: tuple[np.ndarray, np.ndarray, np.ndarray], hq: np.ndarray,
            readings: tuple[np.ndarray, np.ndarray, np.ndarray], sig: np.ndarray):
    """Smoothed position and velocity at every recorder-grid time from the filter-grid states.

    Between filter points ``t_k <= t < t_{k+1}`` the position is dead-reckoned exactly (held
    readings, corrections of step k) forward from ``x_k`` and backward from ``x_{k+1}`` and the
    two are blended linearly in time, in latitude/longitude (they differ only by the smoothed
    process noise of the step, millimetres, over which this equals a blend of the north/east
    difference to 1e-9 relative); the position covariance is interpolated linearly.  The velocity is the corrected
    reading, with covariance ``Jv P_c Jv^T + Gv Gv^T`` (corrections' covariance plus the
    reading's own noise).

    Parameters
    ----------
    xs, Ps : smoothed (or filtered) states and covariances on the filter grid
    kidx : (M,) filter step of each query time
    tq : (M,) query times [s]; ``t_filter`` the filter times
    I_at_q, I_at_filter : cumulative integrals ``(IA, IU, IW)`` of the held readings at the query
        times (each (M, 2)) and at the filter times (each (N, 2))
    hq : (M,) heights [m]; ``readings`` ``(a, u, w)`` held at the query times, each (M, 2)

    Returns
    -------
    lat, lon [rad] (M,), P_ne (M, 2, 2), v_ne (M, 2) [m/s], P_v (M, 2, 2)
    """
    IA, IU, IW = (_c(x) for x in I_at_q)
    FA, FU, FW = (_c(x) for x in I_at_filter)
    a, u, w = (_c(x) for x in readings)
    return _densify_kernel(int(model), _c(xs), _c(Ps), _c(kidx, np.int64), _c(tq),
                           _c(t_filter), IA, IU, IW, FA, FU, FW, _c(hq), a, u, w, _c(sig))


@nb.njit(cache=True, nogil=True)
def _integrate_kernel(t, a, u, w):
    M = t.shape[0]
    IA = np.empty((M, 2))
    IU = np.empty((M, 2))
    IW = np.empty((M, 2))
    CQ = np.empty((M + 1, 7))
    for i in range(2):
        IA[0, i] = 0.0
        IU[0, i] = 0.0
        IW[0, i] = 0.0
    for i in range(7):
        CQ[0, i] = 0.0
    for j in range(M):
        dt = t[j + 1] - t[j] if j < M - 1 else 0.0
        if j < M - 1:
            for i in range(2):
                IA[j + 1, i] = IA[j, i] + a[j, i] * dt
                IU[j + 1, i] = IU[j, i] + u[j, i] * dt
                IW[j + 1, i] = IW[j, i] + w[j, i] * dt
        dt2 = dt * dt
        ja0 = -a[j, 1]
        ja1 = a[j, 0]
        CQ[j + 1, 0] = CQ[j, 0] + dt2 * (u[j, 0] * u[j, 0])
        CQ[j + 1, 1] = CQ[j, 1] + dt2 * (u[j, 0] * u[j, 1])
        CQ[j + 1, 2] = CQ[j, 2] + dt2 * (u[j, 1] * u[j, 1])
        CQ[j + 1, 3] = CQ[j, 3] + dt2 * (ja0 * ja0)
        CQ[j + 1, 4] = CQ[j, 4] + dt2 * (ja0 * ja1)
        CQ[j + 1, 5] = CQ[j, 5] + dt2 * (ja1 * ja1)
        CQ[j + 1, 6] = CQ[j, 6] + dt2
    return IA, IU, IW, CQ


def integrate_readings(t: np.ndarray, a: np.ndarray, u: np.ndarray, w: np.ndarray):
    """Cumulative integrals of the held readings and the cumulative per-sample noise sums.

    Parameters
    ----------
    t : (M,) recorder times [s], strictly increasing
    a, u, w : (M, 2) measured velocity vector, its unit vector, measured wind (toward), each
        held from its sample to the next (left zero-order hold)

    Returns
    -------
    IA, IU, IW : (M, 2) integrals from ``t[0]`` to ``t[j]`` of the held series
    CQ : (M + 1, 7) ``CQ[j]`` = sum over samples ``i < j`` of ``dt_i^2 [u u^T (xx, xy, yy),
        (Ja)(Ja)^T (xx, xy, yy), 1]`` with ``Ja = [-a_e, a_n]`` and ``dt_i = t[i+1] - t[i]``
        (0 for the last sample): the sums :func:`segment_factor` takes, for any run of samples
        as a difference of two rows.

    One sequential pass (the same additions, in the same order, as ``np.cumsum``).
    """
    return _integrate_kernel(_c(t), _c(a), _c(u), _c(w))
