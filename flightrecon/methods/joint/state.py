"""What the joint smoother's Gauss-Newton passes produce and carry from one to the next
(docs/joint.md, "Filter, smoother, iterations"): the outputs of one forward-backward pass, the
accepted iterate after the line search, and the state of the iterations."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.inputs import TakeoffRoll
from flightrecon.methods.joint.linearisation import PassModels
from flightrecon.methods.joint.passes import BackgroundCovariances


@dataclass
class PassResult:
    """Outputs of one forward filter and backward smoother pass."""

    xs: np.ndarray
    xf: np.ndarray
    res: np.ndarray
    rate: np.ndarray
    hph: np.ndarray | None
    infl: np.ndarray
    innov: np.ndarray
    innov_var: np.ndarray
    Pblk: np.ndarray | None
    var: np.ndarray | None
    n_fallback: int
    kern_args: tuple[Any, ...]
    scalars: jl.Scalars
    pending: BackgroundCovariances | None = None  # its covariance pass, still on its thread
    #                                               (Pblk and var None until joined)
    info: dict[str, Any] | None = None   # the pass's entry in the iterations
    # the clock columns and rates of its forward pass, and the offsets' outputs of it (normal
    # equations, filter columns after and before each step's updates: passes.forward)
    clock: tuple[tuple[np.ndarray, np.ndarray], tuple[np.ndarray, ...]] | None = None


@dataclass
class PassStep:
    """The accepted iterate of one pass (after the line search)."""

    X: np.ndarray
    alpha: float
    cost: dict[str, float]
    models: PassModels           # built about X with the pass's clock offsets and roll
    res: np.ndarray
    rate: np.ndarray
    evaluations: int
    ok: bool                  # False: no step lowered the cost (X is the pass's start)
    gn_shift_m: float         # largest position change of the full Gauss-Newton step
    gn_cost: float            # cost at the full Gauss-Newton step
    lm_lambda: float = 0.0    # > 0: a Levenberg-Marquardt step with this damping


@dataclass
class SmootherState:
    """What the passes carry from one to the next."""

    lat: np.ndarray                     # nominal of the next pass
    lon: np.ndarray
    h: np.ndarray
    vnom: np.ndarray                    # nominal velocity (runway constraints, take-off roll)
    clock: dict[str, float]
    clock_sd: dict[str, float]
    scale: np.ndarray                   # variance factor per noise group (EM)
    psi_hat: np.ndarray | None = None   # heading bias of the iterate (rotation's linearisation)
    ba_hat: np.ndarray | None = None    # accelerometer biases of the iterate (take-off roll)
    X: np.ndarray | None = None         # the current iterate (None before the first pass)
    models: PassModels | None = None       # built about X (reused when nothing else changed)
    # cost, residuals, rates of X under ``models`` and ``cost_scale``: the next pass's start
    cost: tuple[dict[str, float], np.ndarray, np.ndarray] | None = None
    cost_scale: np.ndarray | None = None
    weights: np.ndarray | None = None
    bufs: tuple[np.ndarray, ...] | None = None
    lm_bufs: tuple[np.ndarray, ...] | None = None
    running: PassResult | None = None   # a pass whose covariance thread reads ``bufs``
    lm_lambda: float = 0.0              # the last accepted Levenberg-Marquardt damping / 10
    converged: bool = False
    reason: str = ""
    refit: bool = False                 # the models' noise changed (gust sd): a new cost
    gust_rounds: list[dict[str, Any]] = field(default_factory=list)   # gust sd estimates
    rolls_seen: list[TakeoffRoll] = field(default_factory=list)  # rolls of the passes so far,
    #                                     the last pass's last (a roll once left is not taken)
