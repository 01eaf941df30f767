"""The exponential-integrator functions phi_j(z) and their vertical-axis analogues psi_j(q),
with derivatives, as series near zero and closed forms elsewhere (compiled)."""

from __future__ import annotations

import numba as nb
import numpy as np

HOLDS = ("linear", "zero")
"""Input holds between samples: first-order (default) or zero-order."""


_SERIES_LIMIT = 1.0
"""Below this |argument| the phi/psi functions are summed as series (30 terms: 1/33! ~ 1e-37)."""


_SERIES_TERMS = 30


# --------------------------------------------------------------------------------------------
# phi_j(z) and psi_j(q) with their derivatives
# --------------------------------------------------------------------------------------------
@nb.njit(cache=True, nogil=True)
def phi_functions(z: float) -> tuple[np.ndarray, np.ndarray]:
    """Exponential-integrator functions ``phi_j(z) = sum_m z^m/(m+j)!``, j = 0..3, and derivatives.

    ``phi_0 = e^z``, ``phi_1 = expm1(z)/z``, ``phi_{j+1} = (phi_j - 1/j!)/z``;
    ``phi_j'(z) = sum_m m z^(m-1)/(m+j)!`` = ``(phi_{j-1} - j phi_j)/z`` (j >= 1), ``phi_0' = e^z``.
    Series for ``|z| < 1`` (no cancellation near the removable singularity ``k = 0``).

    Returns
    -------
    phi, dphi : arrays of shape (4,)
    """
    phi = np.zeros(4)
    dphi = np.zeros(4)
    if abs(z) < _SERIES_LIMIT:
        for j in range(4):
            term = 1.0
            for i in range(1, j + 1):
                term /= i  # 1/j!
            s = 0.0
            ds = 0.0
            zp = 1.0  # z^m
            zpm1 = 0.0  # m z^(m-1)
            for m in range(_SERIES_TERMS):
                s += zp * term
                ds += zpm1 * term
                zpm1 = (m + 1) * zp
                zp *= z
                term /= m + j + 1
            phi[j] = s
            dphi[j] = ds
    else:
        e = np.exp(z)
        phi[0] = e
        phi[1] = np.expm1(z) / z
        phi[2] = (phi[1] - 1.0) / z
        phi[3] = (phi[2] - 0.5) / z
        dphi[0] = e
        for j in range(1, 4):
            dphi[j] = (phi[j - 1] - j * phi[j]) / z
    return phi, dphi


@nb.njit(cache=True, nogil=True)
def psi_functions(q: float) -> tuple[np.ndarray, np.ndarray]:
    """Even kernels ``psi_j(q) = sum_m q^m/(2m+j)!``, j = 0..3, and their derivatives in ``q``.

    ``psi_0 = cosh(sqrt q)`` (``cos(sqrt(-q))`` for q < 0), ``psi_1 = sinh(sqrt q)/sqrt q``
    (``sin(w)/w``), ``psi_{j+2} = (psi_j - 1/j!)/q``; ``psi_0' = psi_1/2`` and
    ``psi_j' = (psi_{j-1} - j psi_j)/(2q)`` for j >= 1.  Series for ``|q| < 1``.

    Returns
    -------
    psi, dpsi : arrays of shape (4,)
    """
    psi = np.zeros(4)
    dpsi = np.zeros(4)
    if abs(q) < _SERIES_LIMIT:
        for j in range(4):
            term = 1.0
            for i in range(1, j + 1):
                term /= i  # 1/j!
            s = 0.0
            ds = 0.0
            qp = 1.0
            qpm1 = 0.0
            for m in range(_SERIES_TERMS):
                s += qp * term
                ds += qpm1 * term
                qpm1 = (m + 1) * qp
                qp *= q
                term /= (2 * m + j + 1) * (2 * m + j + 2)
            psi[j] = s
            dpsi[j] = ds
    else:
        if q > 0.0:
            r = np.sqrt(q)
            psi[0] = np.cosh(r)
            psi[1] = np.sinh(r) / r
        else:
            r = np.sqrt(-q)
            psi[0] = np.cos(r)
            psi[1] = np.sin(r) / r
        psi[2] = (psi[0] - 1.0) / q
        psi[3] = (psi[1] - 1.0) / q
        dpsi[0] = 0.5 * psi[1]
        for j in range(1, 4):
            dpsi[j] = (psi[j - 1] - j * psi[j]) / (2.0 * q)
    return psi, dpsi
