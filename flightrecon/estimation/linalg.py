"""Small dense linear algebra for the compiled kernels: the one Cholesky factorisation and
solves built on it, a symmetric eigen-decomposition and pseudo-inverse, and products into
preallocated buffers.

Allocation-free, in plain loops (no BLAS call overhead at these sizes, 2 to 24 states), shared
by the SNS, joint-smoother and other kernels (docs/estimation.md, "Linear algebra").
"""

from __future__ import annotations

import numba as nb
import numpy as np


@nb.njit(cache=True, nogil=True)
def cholesky_factor(A, L, rel_tol):
    """Lower Cholesky factor of a symmetric positive-definite ``A`` into ``L`` (A = L L^T).

    Returns False (``L`` undefined) if a pivot is not positive, or, with ``rel_tol`` > 0, not
    above ``rel_tol`` times its diagonal entry of ``A`` (so that the caller can fall back to a
    general solve that reports singularity).
    """
    n = A.shape[0]
    for j in range(n):
        s = A[j, j]
        for m in range(j):
            s -= L[j, m] * L[j, m]
        if not s > 0.0 or (rel_tol > 0.0 and not s > rel_tol * abs(A[j, j])):
            return False
        dj = np.sqrt(s)
        L[j, j] = dj
        for i in range(j + 1, n):
            s = A[i, j]
            for m in range(j):
                s -= L[i, m] * L[j, m]
            L[i, j] = s / dj
    return True


@nb.njit(cache=True, nogil=True)
def cholesky_solve_columns(L, B, X):
    """X = (L L^T)^{-1} B: forward then back substitution, all columns of B at once (the row
    operations run along contiguous rows, so they vectorise)."""
    n = L.shape[0]
    nc = B.shape[1]
    for i in range(n):
        for c in range(nc):
            X[i, c] = B[i, c]
        for m in range(i):
            lim = L[i, m]
            for c in range(nc):
                X[i, c] -= lim * X[m, c]
        inv = 1.0 / L[i, i]
        for c in range(nc):
            X[i, c] *= inv
    for i in range(n - 1, -1, -1):
        for m in range(i + 1, n):
            lmi = L[m, i]
            for c in range(nc):
                X[i, c] -= lmi * X[m, c]
        inv = 1.0 / L[i, i]
        for c in range(nc):
            X[i, c] *= inv


@nb.njit(cache=True, nogil=True)
def cholesky_solve_vector(L, b, x):
    """x = (L L^T)^{-1} b for one right-hand side ``b`` (n,): :func:`cholesky_solve_columns`
    with one column, the same operations in the same order (so the same numbers to the bit),
    without the loop over the columns (3 times faster at 26 states: the mean-only RTS
    pass's solve)."""
    n = L.shape[0]
    for i in range(n):
        v = b[i]
        for m in range(i):
            v -= L[i, m] * x[m]
        x[i] = v * (1.0 / L[i, i])
    for i in range(n - 1, -1, -1):
        v = x[i]
        for m in range(i + 1, n):
            v -= L[m, i] * x[m]
        x[i] = v * (1.0 / L[i, i])


@nb.njit(cache=True, nogil=True)
def chol2_into(a: float, b: float, c: float, L: np.ndarray) -> None:
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
    chol2_into(a, b, c, L)
    return L


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
def pinv_sym_into(S: np.ndarray, rcond: float, Sp: np.ndarray, A: np.ndarray,
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
def solve_sym_eig_into(S: np.ndarray, B: np.ndarray, rcond: float, X: np.ndarray) -> int:
    """``X = S^+ B`` for a symmetric ``S`` (m, m) that need not be positive definite; ``B``,
    ``X`` (m, k).  Returns the numerical rank.

    The general-solve fallback where a Cholesky factorisation failed (an indefinite or nearly
    singular predicted covariance): ``S = V diag(l) V^T`` by :func:`_jacobi_eigh` and
    ``X = V diag(1/l) V^T B`` over the eigenvalues with ``|l| > rcond max |l|`` (negative ones
    kept, so that a regular indefinite ``S`` gets its inverse, to round-off the LU solve's
    answer; the others treated as zero: the minimum-norm solution instead of an error).  In
    place of ``np.linalg.solve`` inside the kernels: the same answer on a regular matrix without
    compiling numba's LAPACK bindings into every kernel that has the fallback (seconds of a first
    run's compilation, docs/performance.md).  Raises ``LinAlgError`` when ``S`` is not finite.
    """
    m = S.shape[0]
    k = B.shape[1]
    A = np.empty((m, m))
    V = np.empty((m, m))
    for i in range(m):
        for j in range(m):
            if not np.isfinite(S[i, j]):
                raise np.linalg.LinAlgError("matrix is not finite")
            A[i, j] = 0.5 * (S[i, j] + S[j, i])
    # views of any layout ('A'), as the SNS filter's sliced buffers reach it through
    # pinv_sym_into: one compiled specialisation of the eigen-decomposition instead of two
    # (0.4 s of a cold start; the same arithmetic)
    _jacobi_eigh(A[:, :], V[:, :])
    lmax = 0.0
    for i in range(m):
        lmax = max(lmax, abs(A[i, i]))
    W = np.zeros((m, k))   # diag(1/l) V^T B
    rank = 0
    for e in range(m):
        lam = A[e, e]
        if abs(lam) > rcond * lmax and lam != 0.0:
            rank += 1
            for c in range(k):
                v = 0.0
                for i in range(m):
                    v += V[i, e] * B[i, c]
                W[e, c] = v / lam
    for i in range(m):
        for c in range(k):
            v = 0.0
            for e in range(m):
                v += V[i, e] * W[e, c]
            X[i, c] = v
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
    rank = pinv_sym_into(S, rcond, Sp, np.empty((m, m)), np.empty((m, m)))
    return Sp, rank


@nb.njit(cache=True, nogil=True, inline="always")
def mm_into(A, B, out):
    """``out = A @ B`` for small matrices (plain loops: no allocation, no BLAS call overhead).

    Row-update order (``out[i, :] += A[i, l] B[l, :]``): the inner loop carries no dependency
    chain, which matters more than anything else at these sizes.  Inlined at numba's IR level
    (as :func:`mmt_into` and :func:`mdmt_acc_into`): otherwise compiled once per array layout
    it is called with (four in the SNS's prediction) on a cold cache (docs/performance.md,
    "The first run").
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


@nb.njit(cache=True, nogil=True, inline="always")
def mmt_into(A, B, out):
    """``out = A @ B.T`` for small matrices (row-update order, as :func:`mm_into`)."""
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


@nb.njit(cache=True, nogil=True, inline="always")
def mdmt_acc_into(A, dg, B, out):
    """``out += A @ diag(dg) @ B.T`` for small matrices (row-update order, as :func:`mm_into`)."""
    n, kk = A.shape
    m = B.shape[0]
    for i in range(n):
        for l in range(kk):
            a = A[i, l] * dg[l]
            if a != 0.0:
                for j in range(m):
                    out[i, j] += a * B[j, l]


@nb.njit(cache=True, nogil=True)
def sym_into(M, out):
    """``out = (M + M^T) / 2``."""
    n = M.shape[0]
    for i in range(n):
        for j in range(i, n):
            v = 0.5 * (M[i, j] + M[j, i])
            out[i, j] = v
            out[j, i] = v


def packed_size(n: int) -> int:
    """Length of the packed lower triangle of a symmetric (n, n) matrix: n (n + 1) / 2."""
    return n * (n + 1) // 2


@nb.njit(cache=True, nogil=True)
def pack_sym(P, out):
    """The lower triangle of the symmetric ``P`` (n, n), row by row, into ``out``
    (n (n + 1) / 2,): stored covariances in half the memory (docs/estimation.md)."""
    n = P.shape[0]
    m = 0
    for i in range(n):
        for j in range(i + 1):
            out[m] = P[i, j]
            m += 1


@nb.njit(cache=True, nogil=True)
def unpack_sym(p, out):
    """The symmetric (n, n) matrix whose lower triangle :func:`pack_sym` stored in ``p``, into
    ``out`` (both triangles)."""
    n = out.shape[0]
    m = 0
    for i in range(n):
        for j in range(i + 1):
            out[i, j] = p[m]
            out[j, i] = p[m]
            m += 1
