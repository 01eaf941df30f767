"""The forward filter: one loop over the time steps, for every method.

For each step k = 0 .. N-1 (docs/estimation.md, "One forward loop")::

    x_k^- = f_k(x_{k-1}^+),   P_k^- = F_k P_{k-1}^+ F_k^T + Q_k     (k >= 1; model.predict_into)
    keep x_k^-, P_k^-                                               (model.keep_predicted)
    x_k^+, P_k^+ = the updates with step k's measurements           (model.update_into)
    keep x_k^+, P_k^+                                               (model.keep_filtered)

The model (:mod:`flightrecon.estimation.model`) supplies the four functions: its transition and
noise, its measurement rows with the core's update variant it needs (block Joseph, sequential
scalar with a robust gate and a linearisation point, the correlated-noise form), and where its
results go.  numba compiles this loop once per model class, with the model's functions inside.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numba as nb
import numpy as np

from flightrecon.estimation.model import (
    keep_filtered,
    keep_predicted,
    predict_into,
    update_into,
    workspace,
)

__all__ = ["FilterRun", "forward_pass", "keep_dense_into"]


@nb.njit(cache=True, nogil=True)
def keep_dense_into(x_buf, P_buf, k, x, P):
    """``x_buf[k] = x``, ``P_buf[k] = P`` for a model that keeps dense states (N, n) and
    covariances (N, n, n): element loops, which allocate nothing, so that a model's
    ``keep_predicted`` / ``keep_filtered`` built on it may be registered ``refcounted=False``
    (:func:`flightrecon.estimation.model.implements`)."""
    n = x.shape[0]
    for i in range(n):
        x_buf[k, i] = x[i]
        for j in range(n):
            P_buf[k, i, j] = P[i, j]


@nb.njit(cache=True, nogil=True)
def forward_pass(model, x0, P0, N):
    """Run the forward filter of ``model`` over ``N`` steps from ``x0`` (n,), ``P0`` (n, n) at
    step 0 (the prior of step 0, before its measurements).

    Returns the model's workspace after the last step (the model's outputs are in its own
    buffers).
    """
    x = x0.copy()
    P = P0.copy()
    ws = workspace(model)
    for k in range(N):
        if k > 0:
            predict_into(model, k, x, P, ws)
        keep_predicted(model, k, x, P)
        update_into(model, k, x, P, ws)
        keep_filtered(model, k, x, P)
    return ws


@dataclass(frozen=True)
class FilterRun:
    """A forward run of any method: time first, state ``x``, covariance ``P``.

    ``x``/``P`` the filtered estimates (N, n) / (N, n, n), ``x_pred``/``P_pred`` the one-step
    predictions (``x_pred[0] = x0``); ``diagnostics`` the method's per-step or per-measurement
    records (innovations ``nu``, their covariances ``S``, normalised innovations ``nis``, ...),
    by name, read as ``run.diagnostics["nis"]`` (which names a method records is in its
    filter's docstring); ``model`` what the backward pass needs of the method (its model, or
    None).
    """

    x: np.ndarray
    P: np.ndarray
    x_pred: np.ndarray
    P_pred: np.ndarray
    diagnostics: dict[str, np.ndarray] = field(default_factory=dict)
    model: Any = None

