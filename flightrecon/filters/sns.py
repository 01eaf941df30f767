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
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numba as nb
import numpy as np

from flightrecon.constants import WGS84_A, WGS84_E2

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


@nb.njit(cache=True)
def radii(lat_rad: float, h_m: float) -> tuple[float, float]:
    """Meridian and prime-vertical radii of curvature plus height, ``(M + h, N + h)`` [m].

    WGS-84: ``M = a (1 - e^2) / (1 - e^2 sin^2 lat)^1.5``, ``N = a / sqrt(1 - e^2 sin^2 lat)``.
    """
    s = np.sin(lat_rad)
    w = 1.0 - _E2 * s * s
    n = _A / np.sqrt(w)
    m = n * (1.0 - _E2) / w
    return m + h_m, n + h_m


@nb.njit(cache=True)
def boxplus(lat: float, lon: float, dn: float, de: float, h: float) -> tuple[float, float]:
    """Move ``(lat, lon)`` [rad] by ``dn`` north and ``de`` east metres in the local-level frame.

    The radii are taken at the mid-latitude of the move (second-order accurate).
    """
    mh, nh = radii(lat, h)
    latm = lat + 0.5 * dn / mh
    mh, nh = radii(latm, h)
    return lat + dn / mh, lon + de / (nh * np.cos(latm))


@nb.njit(cache=True)
def boxminus(lat1: float, lon1: float, lat0: float, lon0: float, h: float) -> tuple[float, float]:
    """North/east metres from ``(lat0, lon0)`` to ``(lat1, lon1)`` [rad] (inverse of boxplus)."""
    latm = 0.5 * (lat1 + lat0)
    mh, nh = radii(latm, h)
    return (lat1 - lat0) * mh, (lon1 - lon0) * nh * np.cos(latm)


@nb.njit(cache=True)
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
    d = np.zeros(2)
    J = np.zeros((2, 3))
    Gs = np.zeros((2, 4))
    if model == MODEL_AIRSPEED:
        s = 1.0
        th = c[2]
    else:
        s = 1.0 + c[0]
        th = c[1] + c[2]
    ct = np.cos(th)
    st = np.sin(th)
    ra0 = ct * A[0] - st * A[1]
    ra1 = st * A[0] + ct * A[1]
    # derivative of R(theta) A with respect to theta
    dra0 = -ra1
    dra1 = ra0
    ru0 = ct * U[0] - st * U[1]
    ru1 = st * U[0] + ct * U[1]
    if model == MODEL_AIRSPEED:
        d[0] = ra0 + Wv[0] + c[0] * tau
        d[1] = ra1 + Wv[1] + c[1] * tau
        J[0, 0] = tau
        J[1, 1] = tau
        J[0, 2] = dra0
        J[1, 2] = dra1
        Gs[0, 0] = ru0 * sig[0]
        Gs[1, 0] = ru1 * sig[0]
        Gs[0, 1] = dra0 * sig[1]
        Gs[1, 1] = dra1 * sig[1]
        Gs[0, 2] = tau * sig[2]
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
    return d, J, Gs


@nb.njit(cache=True)
def _chol2(a: float, b: float, c: float) -> np.ndarray:
    """Lower Cholesky factor of the PSD 2x2 matrix [[a, b], [b, c]] (semi-definite allowed)."""
    L = np.zeros((2, 2))
    if a > 0.0:
        L[0, 0] = np.sqrt(a)
        L[1, 0] = b / L[0, 0]
        L[1, 1] = np.sqrt(max(c - b * b / a, 0.0))
    else:
        L[1, 1] = np.sqrt(max(c, 0.0))
    return L


@nb.njit(cache=True)
def segment_factor(model: int, c: np.ndarray, Q: np.ndarray, sig: np.ndarray) -> np.ndarray:
    """Factor L (2, 2) of the increment noise of whole recorder samples, ``L L^T = Cov``.

    ``Q`` (7,) holds sums over the samples of ``dt^2 u u^T`` (xx, xy, yy), ``dt^2 (Ja)(Ja)^T``
    (xx, xy, yy; ``Ja = [-a_e, a_n]``) and ``dt^2``.  With white errors per sample::

        Cov = s^2 R(theta) [sd_speed^2 Suu + sd_angle^2 Sjj] R(theta)^T + diag(sd_wn^2, sd_we^2) S

    (``sd_angle^2`` = heading, or drift + heading for the Doppler model).
    """
    if model == MODEL_AIRSPEED:
        s = 1.0
        th = c[2]
        va = sig[1] * sig[1]
        wn = sig[2] * sig[2] * Q[6]
        we = sig[3] * sig[3] * Q[6]
    else:
        s = 1.0 + c[0]
        th = c[1] + c[2]
        va = sig[1] * sig[1] + sig[2] * sig[2]
        wn = 0.0
        we = 0.0
    v0 = sig[0] * sig[0]
    m00 = v0 * Q[0] + va * Q[3]
    m01 = v0 * Q[1] + va * Q[4]
    m11 = v0 * Q[2] + va * Q[5]
    ct = np.cos(th)
    st = np.sin(th)
    # R M R^T
    r00 = ct * ct * m00 - 2 * ct * st * m01 + st * st * m11
    r01 = ct * st * (m00 - m11) + (ct * ct - st * st) * m01
    r11 = st * st * m00 + 2 * ct * st * m01 + ct * ct * m11
    return _chol2(s * s * r00 + wn, s * s * r01, s * s * r11 + we)


@nb.njit(cache=True)
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
    d, J, _ = increment(model, c, A, U, Wv, tau, sig)
    _, _, Gs = increment(model, c, star[0] * dt_star, star[1] * dt_star, star[2] * dt_star,
                         dt_star, sig)
    Lb = segment_factor(model, c, Qb, sig)
    La = segment_factor(model, c, Qa, sig)
    Phi = np.eye(N_STATE)
    B = np.zeros((N_STATE, N_EPS1))
    for i in range(2):
        for j in range(3):
            Phi[i, 2 + j] = J[i, j]
        for j in range(4):
            B[i, j] = Gs[i, j]
        for j in range(2):
            B[i, 4 + j] = Lb[i, j]
            B[i, 6 + j] = La[i, j]
    for j in range(3):
        B[2 + j, 8 + j] = np.sqrt(q[j] * tau)
    return d, Phi, B


@nb.njit(cache=True)
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
    dp, Jp, _ = increment(model, c, PA, PU, PW, tau, sig)
    _, _, Gp = increment(model, c, a * tau_in, u * tau_in, w * tau_in, tau_in, sig)
    Lb = segment_factor(model, c, Qb, sig)
    v, Jv, Gv = increment(model, c, a, u, w, 1.0, sig)
    h = np.zeros(4)
    H = np.zeros((4, N_STATE))
    G = np.zeros((4, N_EPS1))
    h[0] = dp[0]
    h[1] = dp[1]
    h[2] = v[0]
    h[3] = v[1]
    H[0, 0] = 1.0
    H[1, 1] = 1.0
    for i in range(2):
        for j in range(3):
            H[i, 2 + j] = Jp[i, j]
            H[2 + i, 2 + j] = Jv[i, j]
        for j in range(4):
            G[i, j] = Gp[i, j]
            G[2 + i, j] = Gv[i, j]
        for j in range(2):
            G[i, 4 + j] = Lb[i, j]
    return h, H, G


@nb.njit(cache=True)
def pinv_sym(S: np.ndarray, rcond: float):
    """Moore-Penrose pseudo-inverse of a symmetric matrix and its numerical rank.

    Eigen-decomposition ``S = V diag(l) V^T``; eigenvalues ``l <= rcond * max |l|`` are treated
    as zero.  Returns ``(S^+, rank)``.
    """
    Ss = 0.5 * (S + S.T)
    lam, V = np.linalg.eigh(Ss)
    lmax = np.max(np.abs(lam))
    inv = np.zeros(lam.shape[0])
    rank = 0
    for i in range(lam.shape[0]):
        if lam[i] > rcond * lmax and lam[i] > 0.0:
            inv[i] = 1.0 / lam[i]
            rank += 1
    return (V * inv) @ V.T, rank


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


@nb.njit(cache=True)
def _filter_kernel(model, form, x0, P0, t, hgt, A, U, W, fs, fe, flat, flon, fv, ftau,
                   fPA, fPU, fPW, fa, fu, fw, star, dt_star, Qb, Qa, ftau_in, sig, q, pos_sd,
                   vel_sd, rcond):
    N = t.shape[0]
    n = N_STATE
    xp = np.empty((N, n))
    xs = np.empty((N, n))
    Pp = np.empty((N, n, n))
    Ps = np.empty((N, n, n))
    cross = np.zeros((N, n, n))
    nis = np.full(N, np.nan)
    rank = np.zeros(N, dtype=np.int64)
    x = x0.copy()
    P = P0.copy()
    eye = np.eye(n)
    for k in range(N):
        xp[k] = x
        Pp[k] = P
        c = x[2:5].copy()
        # ---- fixes taken during step k: stacked observation
        m = 0
        for i in range(fs[k], fe[k]):
            m += 2
            for j in range(2):
                if not np.isnan(fv[i, j]):
                    m += 1
        have = m > 0
        Hs = np.zeros((m, n))
        Gs = np.zeros((m, N_EPS1))
        R = np.zeros((m, m))
        nu = np.zeros(m)
        Sp = np.zeros((m, m))
        K = np.zeros((n, m))
        if have:
            r = 0
            for i in range(fs[k], fe[k]):
                hh, Hi, Gi = observation_rows(model, c, fPA[i], fPU[i], fPW[i], ftau[i],
                                              fa[i], fu[i], fw[i], sig, ftau_in[i], Qb[k])
                dn, de = boxminus(flat[i], flon[i], x[0], x[1], hgt[k])
                for j in range(4):
                    if j >= 2 and np.isnan(fv[i, j - 2]):
                        continue
                    Hs[r] = Hi[j]
                    Gs[r] = Gi[j]
                    if j == 0:
                        nu[r] = dn - hh[0]
                        R[r, r] = pos_sd * pos_sd
                    elif j == 1:
                        nu[r] = de - hh[1]
                        R[r, r] = pos_sd * pos_sd
                    else:
                        nu[r] = fv[i, j - 2] - hh[j]
                        R[r, r] = vel_sd * vel_sd
                    r += 1
            Rt = R + Gs @ Gs.T
            PHt = P @ Hs.T
            S = Hs @ PHt + Rt
            Sp, rk = pinv_sym(S, rcond)
            K = PHt @ Sp
            dx = K @ nu
            IKH = eye - K @ Hs
            Pplus = IKH @ P @ IKH.T + K @ Rt @ K.T
            Pplus = 0.5 * (Pplus + Pplus.T)
            nis[k] = nu @ Sp @ nu
            rank[k] = rk
            lat, lon = boxplus(x[0], x[1], dx[0], dx[1], hgt[k])
            xplus = x.copy()
            xplus[0] = lat
            xplus[1] = lon
            for j in range(3):
                xplus[2 + j] = x[2 + j] + dx[2 + j]
        else:
            xplus = x.copy()
            Pplus = P.copy()
        xs[k] = xplus
        Ps[k] = Pplus
        if k == N - 1:
            break
        # ---- prediction to k+1 with the corrected readings of step k
        cp = xplus[2:5].copy()
        tau = t[k + 1] - t[k]
        d, Phi, B = step_matrices(model, cp, A[k], U[k], W[k], tau, sig, q, star[k],
                                  dt_star[k], Qb[k], Qa[k])
        dn = d[0]
        de = d[1]
        if have and form == FORM_CONSISTENT:
            BGS = B @ Gs.T @ Sp
            corr = BGS @ nu
            dn += corr[0]
            de += corr[1]
            Lg = Phi @ K + BGS
            PhiLH = Phi - Lg @ Hs
            BLG = B - Lg @ Gs
            Pn = PhiLH @ P @ PhiLH.T + BLG @ BLG.T + Lg @ R @ Lg.T
            cross[k] = Pplus @ Phi.T - K @ Gs @ B.T
        else:
            Pn = Phi @ Pplus @ Phi.T + B @ B.T
            cross[k] = Pplus @ Phi.T
        lat, lon = boxplus(xplus[0], xplus[1], dn, de, hgt[k])
        x = xplus.copy()
        x[0] = lat
        x[1] = lon
        P = 0.5 * (Pn + Pn.T)
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
        _c(inputs.Qa).reshape(-1, 7), _c(inputs.fix_tau_in), _c(noise.sensor_sd), _c(noise.rw_q), float(noise.pos_sd_m), float(noise.vel_sd_mps),
        float(noise.rcond))
    xp, xs, Pp, Ps, cross, nis, rank = out
    return SnsRun(xp, xs, Pp, Ps, cross, nis, rank, _c(inputs.h).copy(), int(model),
                  int(form))


@nb.njit(cache=True)
def _smoother_kernel(xp, xf, Pp, Pf, cross, hgt):
    N, n = xf.shape
    xs = xf.copy()
    Ps = Pf.copy()
    d = np.zeros(n)
    for k in range(N - 2, -1, -1):
        # C = cross_k Pp_{k+1}^{-1}, via a solve with the symmetric Pp
        C = np.linalg.solve(Pp[k + 1], cross[k].T).T
        dn, de = boxminus(xs[k + 1, 0], xs[k + 1, 1], xp[k + 1, 0], xp[k + 1, 1], hgt[k + 1])
        d[0] = dn
        d[1] = de
        for j in range(2, n):
            d[j] = xs[k + 1, j] - xp[k + 1, j]
        dx = C @ d
        lat, lon = boxplus(xf[k, 0], xf[k, 1], dx[0], dx[1], hgt[k])
        xs[k, 0] = lat
        xs[k, 1] = lon
        for j in range(2, n):
            xs[k, j] = xf[k, j] + dx[j]
        Pk = Pf[k] + C @ (Ps[k + 1] - Pp[k + 1]) @ C.T
        Ps[k] = 0.5 * (Pk + Pk.T)
    return xs, Ps


def sns_smooth(run: SnsRun) -> SnsSmoothed:
    """Backward pass with the gain matching the filter's form (module docstring, "Smoother")."""
    xs, Ps = _smoother_kernel(_c(run.x_pred), _c(run.x), _c(run.P_pred), _c(run.P),
                              _c(run.cross), _c(run.h))
    return SnsSmoothed(xs, Ps)


@nb.njit(cache=True)
def _densify_kernel(model, xs, Ps, kidx, tq, tk, tk1, IA, IU, IW, IAk, IUk, IWk, IAk1, IUk1,
                    IWk1, hq, a, u, w, sig):
    M = tq.shape[0]
    lat = np.empty(M)
    lon = np.empty(M)
    Pn = np.empty((M, 2, 2))
    v = np.empty((M, 2))
    Pv = np.empty((M, 2, 2))
    nlast = xs.shape[0] - 1
    for j in range(M):
        k = kidx[j]
        c = xs[k, 2:5].copy()
        # forward from x_k over [t_k, t_j]
        d1, _, _ = increment(model, c, IA[j] - IAk[j], IU[j] - IUk[j], IW[j] - IWk[j],
                               tq[j] - tk[j], sig)
        la1, lo1 = boxplus(xs[k, 0], xs[k, 1], d1[0], d1[1], hq[j])
        if k < nlast and tk1[j] > tk[j]:
            wgt = (tq[j] - tk[j]) / (tk1[j] - tk[j])
            # backward from x_{k+1} over [t_j, t_{k+1}]
            d2, _, _ = increment(model, c, IAk1[j] - IA[j], IUk1[j] - IU[j], IWk1[j] - IW[j],
                                   tk1[j] - tq[j], sig)
            la2, lo2 = boxplus(xs[k + 1, 0], xs[k + 1, 1], -d2[0], -d2[1], hq[j])
            dn, de = boxminus(la2, lo2, la1, lo1, hq[j])
            la, lo = boxplus(la1, lo1, wgt * dn, wgt * de, hq[j])
            P2 = (1.0 - wgt) * Ps[k, 0:2, 0:2] + wgt * Ps[k + 1, 0:2, 0:2]
        else:
            la = la1
            lo = lo1
            P2 = Ps[k, 0:2, 0:2].copy()
        lat[j] = la
        lon[j] = lo
        Pn[j] = P2
        vv, Jv, Gv = increment(model, c, a[j], u[j], w[j], 1.0, sig)
        v[j] = vv
        Pc = Ps[k, 2:5, 2:5].copy()
        Pv[j] = Jv @ Pc @ Jv.T + Gv @ Gv.T
    return lat, lon, Pn, v, Pv


def densify(model: int, xs: np.ndarray, Ps: np.ndarray, kidx: np.ndarray, tq: np.ndarray,
            t_filter: np.ndarray, I_at_q: tuple[np.ndarray, np.ndarray, np.ndarray],
            I_at_filter: tuple[np.ndarray, np.ndarray, np.ndarray], hq: np.ndarray,
            readings: tuple[np.ndarray, np.ndarray, np.ndarray], sig: np.ndarray):
    """Smoothed position and velocity at every recorder-grid time from the filter-grid states.

    Between filter points ``t_k <= t < t_{k+1}`` the position is dead-reckoned exactly (held
    readings, corrections of step k) forward from ``x_k`` and backward from ``x_{k+1}`` and the
    two are blended linearly in time (they differ only by the smoothed process noise of the
    step); the position covariance is interpolated linearly.  The velocity is the corrected
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
    kidx = _c(kidx, np.int64)
    k1 = np.minimum(kidx + 1, len(t_filter) - 1)
    IA, IU, IW = (_c(x) for x in I_at_q)
    FA, FU, FW = (_c(x) for x in I_at_filter)
    a, u, w = (_c(x) for x in readings)
    return _densify_kernel(int(model), _c(xs), _c(Ps), kidx, _c(tq), _c(t_filter[kidx]),
                           _c(t_filter[k1]), IA, IU, IW, _c(FA[kidx]), _c(FU[kidx]),
                           _c(FW[kidx]), _c(FA[k1]), _c(FU[k1]), _c(FW[k1]), _c(hq), a, u, w,
                           _c(sig))
