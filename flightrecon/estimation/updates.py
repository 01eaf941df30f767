"""Measurement updates (compiled): the Joseph form, the scalar short form, and the prediction
that follows an update whose measurement noise is correlated with the next step's process noise.

* :func:`gain_into`: ``S = H P H^T + R``, ``K = P H^T S^+`` with ``S^+`` the inverse from a
  Cholesky factor when ``S`` is provably regular, else the pseudo-inverse (Jacobi
  eigen-decomposition; :func:`~flightrecon.estimation.linalg.pinv_sym_into`), and its rank;
* :func:`joseph_cov_into`: ``P^+ = (I - K H) P (I - K H)^T + K R K^T`` (symmetric, positive
  semi-definite for any gain); :func:`joseph_update` composes the two for a regular ``S``;
* :func:`scalar_update_short`: for one scalar measurement with row ``h``, ``PH = P h^T`` and
  ``S = h P h^T + r``, the optimal gain is ``K = PH / S``; the Joseph form expands, at that gain,
  to the *short form* ``P - PH PH^T / S`` (equal in exact arithmetic, different in rounding). It
  costs O(n^2) and, written as below, keeps ``P`` bitwise symmetric; it does not guard against the
  loss of positive definiteness that the Joseph form protects against when the gain is not
  optimal;
* :func:`correlated_noise_predict_into`: the update and the next prediction fused when the
  measurement noise ``G w + D v`` shares the white sequence ``w`` with the process noise
  ``B w`` of the next step (Simon 2006, section 7.1): gain ``L = F K + B G^T S^+``.

docs/estimation.md, "Updates".
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flightrecon.estimation.linalg import mdmt_acc_into, mm_into, mmt_into, pinv_sym_into, sym_into
from flightrecon.estimation.manifold import EUCLIDEAN, state_plus_into
from flightrecon.estimation.predict import predict_cov_into


@nb.njit(cache=True, nogil=True)
def scalar_update_short(x, P, PH, nu, S):
    """In place: ``x += PH nu / S``, ``P -= PH PH^T / S`` (short form, optimal gain).

    Parameters
    ----------
    x : (n,) state, updated in place
    P : (n, n) covariance, updated in place (stays exactly symmetric if it was)
    PH : (n,) ``P h^T`` of the measurement row ``h`` (computed before the call)
    nu : innovation ``z - h(x)``
    S : innovation variance ``h P h^T + r`` (> 0)
    """
    n = x.shape[0]
    inv_s = 1.0 / S
    for a in range(n):
        pa = PH[a]
        for b in range(n):
            P[a, b] -= (pa * PH[b]) * inv_s
        x[a] += pa * inv_s * nu


@nb.njit(cache=True, nogil=True)
def gain_into(P, H, R, rcond, PHt, S, Sp, K, A, V):
    """Gain of a measurement update into caller-owned buffers; returns the rank of ``S``.

    ``PHt = P H^T`` (n, m), ``S = H P H^T + R`` (m, m), ``Sp = S^+`` (m, m), ``K = PHt Sp``
    (n, m); ``A``, ``V`` (m, m) scratch.  ``S^+`` is the inverse when a Cholesky factorisation
    proves that no eigenvalue of ``S`` is below ``rcond`` times the largest, else the
    pseudo-inverse with that tolerance (docs/estimation.md, "Linear algebra").
    """
    mmt_into(P, H, PHt)
    mm_into(H, PHt, S)
    m = S.shape[0]
    for i in range(m):
        for j in range(m):
            S[i, j] += R[i, j]
    rk = pinv_sym_into(S, rcond, Sp, A, V)
    mm_into(PHt, Sp, K)
    return rk


@nb.njit(cache=True, nogil=True)
def joseph_cov_into(P, K, H, R, out, IKH, T, TK, Pn):
    """``out = (I - K H) P (I - K H)^T + K R K^T``, symmetrised (Joseph form).

    ``IKH``, ``T``, ``Pn`` (n, n) and ``TK`` (n, m) scratch.
    """
    n = P.shape[0]
    mm_into(K, H, IKH)
    for i in range(n):
        for j in range(n):
            IKH[i, j] = (1.0 if i == j else 0.0) - IKH[i, j]
    predict_cov_into(P, IKH, Pn, T)
    mm_into(K, R, TK)
    mmt_into(TK, K, out)
    for i in range(n):
        for j in range(n):
            out[i, j] += Pn[i, j]
    sym_into(out, out)


@nb.njit(cache=True, nogil=True)
def state_correction_into(geom, x, K, nu, h, dx, out):
    """``out = x (+) K nu`` in the geometry ``geom`` (:mod:`~flightrecon.estimation.manifold`);
    ``dx`` (n,) scratch; ``h`` the height [m] for a latitude/longitude state.  ``out`` may be
    ``x``."""
    n = x.shape[0]
    m = nu.shape[0]
    for i in range(n):
        s = 0.0
        for j in range(m):
            s += K[i, j] * nu[j]
        dx[i] = s
    state_plus_into(geom, x, dx, h, out)


@nb.njit(cache=True, nogil=True)
def normalised_innovation(Sp, nu, Spnu):
    """NIS ``nu^T S^+ nu``; ``Spnu`` (m,) receives ``S^+ nu``."""
    m = nu.shape[0]
    nis = 0.0
    for i in range(m):
        s = 0.0
        for j in range(m):
            s += Sp[i, j] * nu[j]
        Spnu[i] = s
        nis += nu[i] * s
    return nis


@nb.njit(cache=True, nogil=True)
def joseph_update(x, P, nu, H, R):
    """Measurement update with innovation ``nu`` (m,), ``H`` (m, n), ``R`` (m, m), allocating.

    :func:`gain_into` (``S`` must be positive definite: raises ``LinAlgError`` otherwise) and
    :func:`joseph_cov_into`.  Returns the updated ``x``, ``P``, the innovation covariance ``S``
    and the normalised innovation squared ``nu^T S^-1 nu``.
    """
    n = x.shape[0]
    m = nu.shape[0]
    PHt = np.empty((n, m))
    S = np.empty((m, m))
    Sp = np.empty((m, m))
    K = np.empty((n, m))
    rk = gain_into(P, H, R, 0.0, PHt, S, Sp, K, np.empty((m, m)), np.empty((m, m)))
    if rk < m:
        raise np.linalg.LinAlgError("innovation covariance is not positive definite")
    Pu = np.empty((n, n))
    joseph_cov_into(P, K, H, R, Pu, np.empty((n, n)), np.empty((n, n)), np.empty((n, m)),
                    np.empty((n, n)))
    xu = np.empty(n)
    state_correction_into(EUCLIDEAN, x, K, nu, 0.0, np.empty(n), xu)
    nis = normalised_innovation(Sp, nu, np.empty(m))
    return xu, Pu, S, nis


@nb.njit(cache=True, nogil=True)
def correlated_noise_predict_into(P, F, B, K, H, G, Sp, Rd, Pn, cross, BGS, work):
    """Update at step k and prediction to k+1 with correlated noise, covariances only.

    Model: ``x_{k+1} = f(x_k) + B w_k``, ``z_k = h(x_k) + G w_k + D v_k`` with ``w_k``, ``v_k``
    independent unit white noise (``D D^T = diag(Rd)``), so the measurement noise at k is
    correlated with the process noise of the step k -> k+1.  Given the predicted ``P`` (= P_k^-)
    and ``K = P H^T S^+`` with ``S = H P H^T + G G^T + D D^T``:

    * ``L = F K + B G^T S^+`` (the one-step predictor's gain; Simon 2006, section 7.1);
    * ``P_{k+1}^- = (F - L H) P (F - L H)^T + (B - L G)(B - L G)^T + L D D^T L^T`` into ``Pn``
      (not symmetrised);
    * the smoother's cross-covariance ``Cov(x_k, x_{k+1} | Y_k) = P^+ F^T - K G B^T``: ``cross``
      holds ``P^+ F^T`` on entry, the ``- K G B^T`` term is added;
    * ``BGS = B G^T S^+`` (n, m): the state's correction is ``BGS nu`` on top of the filtered
      mean's prediction (the caller applies it in its geometry).

    ``work``: scratch ``(L, BG, A, T, BmLG, ones_w, minus_m)``, ``L``, ``BG`` (n, m), ``A``,
    ``T`` (n, n), ``BmLG`` (n, nw), ``ones_w`` (nw,) ones, ``minus_m`` (m,) minus ones.
    """
    L, BG, A, T, BmLG, ones_w, minus_m = work
    n = P.shape[0]
    m = K.shape[1]
    nw = B.shape[1]
    mmt_into(B, G, BG)  # B G^T
    mm_into(BG, Sp, BGS)  # B G^T S^+
    mm_into(F, K, L)  # L = F K + B G^T S^+
    for i in range(n):
        for j in range(m):
            L[i, j] += BGS[i, j]
    mm_into(L, H, A)  # F - L H
    for i in range(n):
        for j in range(n):
            A[i, j] = F[i, j] - A[i, j]
    predict_cov_into(P, A, Pn, T)
    mm_into(L, G, BmLG)  # B - L G
    for i in range(n):
        for j in range(nw):
            BmLG[i, j] = B[i, j] - BmLG[i, j]
    mdmt_acc_into(BmLG, ones_w, BmLG, Pn)  # + (B - L G)(B - L G)^T
    mdmt_acc_into(L, Rd, L, Pn)  # + L D D^T L^T
    mdmt_acc_into(K, minus_m, BG, cross)  # cross -= K G B^T
