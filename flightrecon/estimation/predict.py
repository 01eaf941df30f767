"""Prediction (compiled): ``x^- = F x``, ``P^- = F P F^T + Q``.

Two entry points of the same propagation ``F P F^T``:

* dense, :func:`predict_cov_into` (into caller-owned buffers) and :func:`predict` (allocating,
  with a dense ``Q``, symmetrised): the generic linear filter, ADS/ARMS, the azimuth channel and
  the SNS filter (which adds its process noise in factored form, ``B B^T``, and its
  correlated-noise terms; :func:`flightrecon.estimation.updates.correlated_noise_predict_into`);
* sparse, :func:`predict_sparse`: ``F`` row-compressed (:func:`sparse_rows`: row ``i`` has
  ``cnt[i]`` nonzeros ``vals[i, :cnt[i]]`` in the columns ``cols[i, :cnt[i]]``), so that the
  product costs O(n nnz) instead of O(n^3): the joint smoother's 26-state transition, which is the
  identity plus a few blocks (11 nonzeros at most per row).  The process noise is added by the
  caller, touching only its nonzero entries.

docs/estimation.md, "Prediction".
"""

from __future__ import annotations

import numba as nb
import numpy as np

from flightrecon.estimation.linalg import mm_into, mmt_into


@nb.njit(cache=True, nogil=True)
def predict_cov_into(P, F, out, T):
    """``out = F P F^T`` (not symmetrised: the caller adds its noise, then symmetrises).

    ``T`` (n, n) is scratch (``T = F P``); loop products
    (:func:`~flightrecon.estimation.linalg.mm_into`), no allocation.  ``F`` may be any (n, n)
    matrix, e.g. ``I - K H`` of a Joseph update.
    """
    mm_into(F, P, T)
    mmt_into(T, F, out)


@nb.njit(cache=True, nogil=True)
def add_noise_symmetrised_into(FPFt, Q, out):
    """``out = Q + F P F^T``, symmetrised as ``(out + out^T) / 2`` (the dense prediction's
    covariance from :func:`predict_cov_into`'s product; ``out`` may be the old ``P``, not
    ``FPFt``); no allocation."""
    n = out.shape[0]
    for i in range(n):
        for j in range(n):
            out[i, j] = Q[i, j] + FPFt[i, j]
    for i in range(n):
        for j in range(i + 1, n):
            v = 0.5 * (out[i, j] + out[j, i])
            out[i, j] = v
            out[j, i] = v


@nb.njit(cache=True, nogil=True)
def predict(x, P, F, Q):
    """Prediction ``x^- = F x``, ``P^- = F P F^T + Q``, symmetrised as ``(P^- + P^-T) / 2``."""
    x = F @ x
    Pn = np.empty_like(Q)
    FPFt = P.copy()
    T = P.copy()
    predict_cov_into(P, F, FPFt, T)
    add_noise_symmetrised_into(FPFt, Q, Pn)
    return x, Pn


@nb.njit(cache=True, nogil=True)
def predict_in_place(x, P, F, Q):
    """:func:`predict` into ``x`` and ``P`` (a model's ``predict_into`` on a dense linear
    transition: the linear model, the azimuth channel)."""
    xn, Pn = predict(x, P, F, Q)
    x[:] = xn
    P[:, :] = Pn


@nb.njit(cache=True, nogil=True)
def sparse_rows(F, cols, vals, cnt):
    """Row-compressed copy of ``F`` (n, n) into ``cols`` (n, n) int, ``vals`` (n, n), ``cnt``
    (n,) int: row i has ``cnt[i]`` nonzeros ``vals[i, :cnt[i]]`` in ``cols[i, :cnt[i]]``."""
    n = F.shape[0]
    for i in range(n):
        c = 0
        for m in range(n):
            if F[i, m] != 0.0:
                cols[i, c] = m
                vals[i, c] = F[i, m]
                c += 1
        cnt[i] = c


@nb.njit(cache=True, nogil=True)
def sparse_matvec(cols, vals, cnt, x, out):
    """``out = F x`` with the row-compressed ``F``."""
    for i in range(x.shape[0]):
        s = 0.0
        for c in range(cnt[i]):
            s += vals[i, c] * x[cols[i, c]]
        out[i] = s


@nb.njit(cache=True, nogil=True)
def sparse_rmatvec(cols, vals, cnt, y, out):
    """``out = F^T y`` with the row-compressed ``F``."""
    n = y.shape[0]
    for m in range(n):
        out[m] = 0.0
    for i in range(n):
        for c in range(cnt[i]):
            out[cols[i, c]] += vals[i, c] * y[i]


@nb.njit(cache=True, nogil=True)
def sparse_right_product(cols, vals, cnt, A, out):
    """``out = A F^T`` with the row-compressed ``F`` (``out[a, i] = sum_m A[a, m] F[i, m]``)."""
    n = A.shape[0]
    for i in range(cnt.shape[0]):
        for a in range(n):
            s = 0.0
            for c in range(cnt[i]):
                s += A[a, cols[i, c]] * vals[i, c]
            out[a, i] = s


@nb.njit(cache=True, nogil=True)
def sparse_left_product(cols, vals, cnt, A, out):
    """``out = F A`` with the row-compressed ``F`` (``out[i, b] = sum_m F[i, m] A[m, b]``).

    Row ``i`` of the product is accumulated from the rows of ``A`` that ``F``'s row ``i``
    picks (``out[i, :] += F[i, m] A[m, :]``): each element gets the same products in the
    same order as the sum over ``m`` (the same numbers to the bit), and the inner loop runs
    along contiguous rows, without a chain of dependent additions, so that it vectorises
    (four times the speed of the element-by-element sums at 26 states)."""
    nb_ = A.shape[1]
    for i in range(cnt.shape[0]):
        for b in range(nb_):
            out[i, b] = 0.0
        for c in range(cnt[i]):
            v = vals[i, c]
            m = cols[i, c]
            for b in range(nb_):
                out[i, b] += v * A[m, b]


@nb.njit(cache=True, nogil=True)
def predict_cov_sparse(P, cols, vals, cnt, B):
    """``P <- F P F^T`` in place with the row-compressed ``F``; ``B`` (n, n) scratch.

    ``B = P F^T`` (:func:`sparse_right_product`), then the upper triangle of ``F B``, mirrored:
    the result is exactly symmetric.
    """
    n = P.shape[0]
    sparse_right_product(cols, vals, cnt, P, B)
    for i in range(n):
        for j in range(i, n):
            s = 0.0
            for c in range(cnt[i]):
                s += vals[i, c] * B[cols[i, c], j]
            P[i, j] = s
    for i in range(n):
        for j in range(i):
            P[i, j] = P[j, i]


@nb.njit(cache=True, nogil=True)
def predict_sparse(x, P, cols, vals, cnt, xn, B):
    """Sparse prediction in place: ``x <- F x``, ``P <- F P F^T`` (row-compressed ``F``; the
    caller adds its control input and process noise).  ``xn`` (n,) and ``B`` (n, n) scratch."""
    sparse_matvec(cols, vals, cnt, x, xn)
    for i in range(x.shape[0]):
        x[i] = xn[i]
    predict_cov_sparse(P, cols, vals, cnt, B)
