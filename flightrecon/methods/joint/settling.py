"""How far the joint smoother's track still was from its fixed point when its passes stopped
short of the convergence test (docs/joint.md, "Filter, smoother, iterations"; docs/output.md,
"Method health"), and the track's standard deviations widened by it.

The damped Gauss-Newton passes, with the clock offsets, the take-off roll and the weights
updated between them, converge linearly once the line search takes full steps: each pass moves
the track by about ``rho`` times what the one before moved it.  Where they reach the cap on the
passes still contracting (``0 < rho < 1``), the passes still to come would move each state by
at most the geometric tail of its last change ``d_k``, ``d_k rho / (1 - rho)``, with ``rho``
the slowest contraction of the last :data:`CONTRACTION_PASSES` passes.  That bound is compared
with the state's own smallest position sd: within :data:`SETTLE_SD_FRACTION` of it the track is
as good as converged and is left as it is; beyond it the bound is added in quadrature to the
track's position sd, so that the track still covers the fixed point it was converging to.
Without contraction (the passes' changes not shrinking, or a failed line search), or while the
last pass still moved a state by more than its own sd (:data:`LINEAR_REGION_SD`), nothing bounds
what the passes would still do: the track stays unconverged.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from flightrecon.methods.joint.state import JointRun

SETTLE_SD_FRACTION = 0.1
"""A remaining movement of at most this fraction of a state's smallest position sd is left out
of the sd: an error of 0.1 sd added in quadrature grows the sd by 0.5 % (``sqrt(1 + 0.1^2)``)
and the expected NEES by 1 %, below what a flight's NEES can resolve (its 95 % band on a
thousand independent samples is about +-9 %)."""

LINEAR_REGION_SD = 1.0
"""The geometric tail bounds the passes to come only once they move each state by at most this
many of its own position sd: inside that region the Gauss-Newton model linearised at the track
holds and the passes converge at the rate seen; a pass that still moves the track by more than
its sd (a real recorder-only flight stopped moving it by 8.5 km a pass, 314 sd, where the real
SR22T export with its GPS stopped at 0.4 sd) is far from its fixed point: unbounded."""

CONTRACTION_PASSES = 5
"""The contraction ``rho`` is the largest ratio of successive passes' largest position changes
over the last this many passes (the slowest of them: a bound, not an average)."""


def settling(run: JointRun) -> dict[str, Any] | None:
    """The remaining movement of a run that stopped unconverged, or ``None`` when it converged
    (or did not keep its last change).

    Returns
    -------
    dict or None
        ``verdict``: ``settled`` (the bound within :data:`SETTLE_SD_FRACTION` of every state's
        smallest sd), ``widened`` (beyond it: the sd is to be widened by the bound) or
        ``unbounded`` (the passes did not contract, or the last moved a state by more than
        :data:`LINEAR_REGION_SD` of its sd); ``passes``, ``last_change_m`` (the last
        pass's largest change), ``contraction`` (``rho``), ``remaining_m`` (the largest bound),
        ``remaining_over_sd`` (the largest bound over the state's smallest sd),
        ``tolerance_over_sd`` and, not for the summary, ``remaining_k_m`` (the bound per state).
    """
    if run.converged or run.last_shift_m is None:
        return None
    shifts = np.array([float(it.get("max_position_change_m", np.nan))
                       for it in run.iterations[-(CONTRACTION_PASSES + 1):]])
    out: dict[str, Any] = {"passes": len(run.iterations),
                           "last_change_m": float(shifts[-1]),
                           "tolerance_over_sd": SETTLE_SD_FRACTION}
    ratios = shifts[1:] / shifts[:-1] if len(shifts) > 1 else np.array([np.nan])
    rho = float(np.max(ratios)) if len(ratios) and np.isfinite(ratios).all() else np.nan
    out["contraction"] = rho if np.isfinite(rho) else None
    if not (0.0 < rho < 1.0):
        out["verdict"] = "unbounded"
        return out
    last = np.asarray(run.last_shift_m, float)
    sd = np.sqrt(np.maximum(np.linalg.eigvalsh(run.P_pv[:, 0:3, 0:3])[:, 0], 1e-12))
    last_over = float(np.max(last / sd))
    out["last_change_over_sd"] = last_over
    if last_over > LINEAR_REGION_SD:
        # still far from its fixed point: the contraction seen is no rate to extrapolate
        out["verdict"] = "unbounded"
        return out
    remaining = last * rho / (1.0 - rho)
    over = float(np.max(remaining / sd))
    out.update(verdict="settled" if over <= SETTLE_SD_FRACTION else "widened",
               remaining_m=float(np.max(remaining)), remaining_over_sd=over,
               remaining_k_m=remaining)
    return out


def widened_track_sd(track: Any, t_state: np.ndarray, remaining_k_m: np.ndarray,
                     prefix: str = "joint_") -> None:
    """Add the remaining movement (per state, interpolated to the track's times) in quadrature
    to the track's north, east and up sd, in place: its direction is unknown, so each axis
    takes the whole of it."""
    t = track["t_s"].to_numpy(float)
    b = np.interp(t, t_state, remaining_k_m)
    for axis in ("north", "east", "up"):
        c = f"{prefix}{axis}_sd_m"
        track[c] = np.hypot(track[c].to_numpy(float), b)


def settling_sentence(s: dict[str, Any]) -> str:
    """The verdict in words, for the method's stop reason and the console."""
    head = (f"stopped at {s['passes']} passes, the last moving the track by "
            f"{s['last_change_m']:.2g} m")
    if s["verdict"] == "unbounded":
        if (s.get("last_change_over_sd") or 0.0) > LINEAR_REGION_SD:
            return head + f", {s['last_change_over_sd']:.2g} of its sd: still far from where " \
                          "its passes converge, nothing bounds what more passes would do"
        return head + ", its passes' changes not shrinking: nothing bounds what more passes " \
                      "would do"
    tail = (f"; contracting by {s['contraction']:.3f} a pass, more passes would move it by at "
            f"most {s['remaining_m']:.2g} m, {s['remaining_over_sd']:.2g} of its sd")
    if s["verdict"] == "settled":
        return head + tail + f" (at most {s['tolerance_over_sd']:g}: as good as converged)"
    return head + tail + ": its position sd is widened by that movement"
