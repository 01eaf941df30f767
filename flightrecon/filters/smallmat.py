"""Small dense linear algebra for the compiled filter and smoother kernels.

Allocation-free, in plain loops (no BLAS call overhead at these sizes, 5 to 24 states), shared
by the SNS and joint-smoother kernels.
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
