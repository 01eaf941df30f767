"""Prediction, dense form (compiled): ``x^- = F x``, ``P^- = F P F^T + Q``, symmetrised.

The joint smoother's 24-state transition is sparse and predicts its covariance row-compressed
(``filters/joint/dynamics.py``, ``_predict_cov``); every dense filter predicts here
(docs/estimation.md, "Prediction").
"""

from __future__ import annotations

import numba as nb


@nb.njit(cache=True, nogil=True)
def predict(x, P, F, Q):
    """Prediction ``x^- = F x``, ``P^- = F P F^T + Q`` (symmetrised)."""
    x = F @ x
    P = F @ P @ F.T + Q
    return x, 0.5 * (P + P.T)
