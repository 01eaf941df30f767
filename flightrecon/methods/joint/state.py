"""What the joint smoother's Gauss-Newton passes hold, produce and carry from one to the next
(docs/joint.md, "Filter, smoother, iterations"): what the iterations hold fixed
(:class:`SmootherFlight`), the models built about one linearisation point
(:class:`PassModels`), the outputs of one forward-backward pass, the accepted iterate after
the line search, the state of the iterations, and the run they end in (:class:`JointRun`).
Types only: the functions that fill them are in ``linearisation``, ``passes`` and
``smoother``, and every module above reads them from here."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from flightrecon.methods.joint import layout as jl
from flightrecon.methods.joint.inputs import EndPoint, JointInputs, TakeoffRoll
from flightrecon.methods.joint.layout import Measurements
from flightrecon.methods.joint.passes import BackgroundCovariances
from flightrecon.methods.joint.settings import JointSettings


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


@dataclass
class SmootherFlight:
    """What the iterations hold fixed: the state grid, the held-input increments, the
    attitude step means, the process noise, the station and the prior of x_0."""

    inp: JointInputs
    settings: JointSettings
    idx: np.ndarray           # input samples that are state steps
    T: np.ndarray
    dt: np.ndarray
    acc: np.ndarray
    dV: np.ndarray
    dP: np.ndarray
    Cnb: np.ndarray
    Csf: np.ndarray
    Jatt: np.ndarray
    qv_extra: np.ndarray
    q: np.ndarray
    ga: np.ndarray            # gust decay over each step (turbulence.gust_decay)
    static: Any
    pst: np.ndarray
    Cst: np.ndarray
    x0: np.ndarray | None = None
    P0: np.ndarray | None = None
    P0inv: np.ndarray | None = None


@dataclass
class PassModels:
    """The dynamics, measurements and geometry built about one linearisation point."""

    lat: np.ndarray
    lon: np.ndarray
    h: np.ndarray
    pnom: np.ndarray
    Cen: np.ndarray
    meas: Measurements
    dyn: jl.Dynamics
    geo: jl.Geometry
    roll: TakeoffRoll
    clock: dict[str, float]
    groups: np.ndarray


@dataclass(frozen=True)
class JointRun:
    """Result of :func:`smooth_joint` on the state grid."""

    t: np.ndarray
    x: np.ndarray            # smoothed states (N, n)
    P_pv: np.ndarray         # smoothed position-velocity covariance block (ECEF p, NED v)
    var: np.ndarray          # smoothed state variances (N, n)
    xf: np.ndarray           # filtered states
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    h_m: np.ndarray          # ellipsoidal height
    Cen: np.ndarray
    meas: Measurements
    weights: np.ndarray
    resid_norm: np.ndarray
    innov: np.ndarray
    innov_var: np.ndarray
    clock_offsets_s: dict[str, tuple[float, float]]  # (value, sd): seconds added to the stamps
    noise_scale: dict[str, float]
    iterations: list[dict[str, Any]]
    end_points: tuple[EndPoint, ...]   # as used in the last pass (end_points_at)
    roll: TakeoffRoll                  # the take-off roll of the last pass (refined_roll)
    noise_check: dict[str, Any] | None = None   # estimate_noise: the likelihood check
    cholesky_fallbacks: int = 0  # last pass's steps whose Cholesky failed (general solve)
    # convergence: the test of docs/joint.md ("Filter, smoother, iterations"), and why not
    converged: bool = False
    stop_reason: str = ""
    gust: dict[str, Any] | None = None   # gust sd of the last pass, its estimates (turbulence)
    prior: tuple[np.ndarray, np.ndarray] | None = None   # (x0, P0): the prior of step 0 used
    # the iteration-independent parts it was smoothed with (for a warm start on the same
    # flight: :func:`smooth_joint_from`); None once the run leaves the method
    flight: SmootherFlight | None = None
    # the last pass's position change per state [m] when the passes stopped unconverged
    # (settling.settling); None when they converged
    last_shift_m: np.ndarray | None = None
