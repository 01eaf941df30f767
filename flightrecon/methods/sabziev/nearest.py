"""The root of the vertical Sabziev ``F(k2)``, ``k2 = -w^2``, nearest a target loop frequency
(docs/sabziev.md, "Root finding", the ``nearest`` rule): ``F`` tabulated outwards from the
target on both sides until it changes sign, the bracket nearest the target refined."""

from __future__ import annotations

import numpy as np

from flightrecon.errors import ValidationError
from flightrecon.methods.sabziev.roots import (
    CountedEvaluator,
    Evaluator,
    ManyEvaluator,
    RootReport,
    polish_root,
    refine_bracket,
    sign_of,
)


def _sign_changes(up: list[tuple[float, float, float]], down: list[tuple[float, float, float]]
                  ) -> list[tuple[float, float]]:
    """The brackets ``(w_a, w_b)`` between neighbouring scan points of finite ``F`` of opposite
    signs: along the upward and the downward scans, then across ``w_target`` between their
    first points."""
    found = []
    for seq in (up, down):
        for (w1, F1, _), (w2, F2, _) in zip(seq[:-1], seq[1:]):
            if np.isfinite(F1) and np.isfinite(F2) and sign_of(F1) != sign_of(F2):
                found.append((min(w1, w2), max(w1, w2)))
    if up and down and np.isfinite(up[0][1]) and np.isfinite(down[0][1]) \
            and sign_of(up[0][1]) != sign_of(down[0][1]):
        found.append((down[0][0], up[0][0]))
    return found


def find_root_near(fun: Evaluator, *, w_target: float, w_step: float, w_lo: float,
                   w_hi: float, tol_m: float = 1e-3, max_iter: int = 60, chunk: int = 64,
                   max_points: int = 1024, fun_many: ManyEvaluator | None = None,
                   axis: str = "") -> RootReport:
    """The root of the vertical ``F(k2)``, ``k2 = -w^2``, nearest a target loop frequency.

    On the stable (oscillatory) branch ``F`` has a root about every ``pi/T`` in ``w``
    (docs/sabziev.md, "Signs and branches"); the root taken is the one nearest ``w_target``
    (docs/sabziev.md, "Root finding", the ``nearest`` rule).  ``F`` is tabulated outwards
    from ``w_target`` on both sides in steps of ``w_step`` (a quarter of the root spacing:
    each oscillation of ``F`` is sampled at least four times), ``chunk`` points per side at a
    time (one batched pass over the data for both sides), until a sign change is found or
    ``max_points`` points per side or the limits ``[w_lo, w_hi]`` are reached.  Of the sign
    changes of one round the one whose bracket is nearest ``w_target`` is refined by Newton
    steps kept inside the bracket (:func:`refine_bracket`).

    Parameters
    ----------
    fun : ``k2 -> (F, dF/dk2, misfit)`` (:data:`Evaluator`)
    w_target : loop frequency [rad/s] the root should be nearest
    w_step : scan step in ``w`` [rad/s]
    w_lo, w_hi : the scan's limits in ``w`` [rad/s]
    tol_m : convergence: ``|F| <= tol_m`` [m]
    max_iter : Newton iterations of the refinement
    chunk : scan points per side and round
    max_points : scan points per side in all
    fun_many : batch evaluator ``ks -> (F, misfit)`` (:data:`ManyEvaluator`)
    axis : axis name for messages

    Returns
    -------
    RootReport
        ``rule = "nearest"``; ``converged`` False (with the smallest ``|F|`` seen and the scan
        range in ``reason``) when no sign change was found.
    """
    if not (0 < w_lo <= w_target <= w_hi and w_step > 0 and tol_m > 0):
        raise ValidationError("need 0 < w_lo <= w_target <= w_hi and positive w_step, tol_m")
    f = CountedEvaluator(fun, fun_many)
    history: list = []
    up: list[tuple[float, float, float]] = []    # (w, F, misfit) from w_target upwards
    down: list[tuple[float, float, float]] = []  # from w_target downwards
    j = 0
    brackets: list[tuple[float, float]] = []
    while j < max_points:
        ws_up = w_target + w_step * np.arange(j, j + chunk)
        ws_up = ws_up[ws_up <= w_hi]
        ws_dn = w_target - w_step * np.arange(max(j, 1), j + chunk)
        ws_dn = ws_dn[ws_dn >= w_lo]
        if len(ws_up) == 0 and len(ws_dn) == 0:
            break
        ws = np.concatenate([ws_up, ws_dn])
        vals = list(f.scan(-ws * ws))
        for w, (_k, F, m) in zip(ws.tolist(), vals):
            (up if w >= w_target else down).append((w, F, m))
        found = _sign_changes(up, down)
        if found:
            brackets = found
            break
        j += chunk
    bk = [(-b * b, -a * a) for a, b in brackets]
    if not brackets:
        kb, Fb = f.best
        reason = (f"no sign change of F within {len(up) + len(down)} points from w = "
                  f"{min([w for w, _, _ in down] + [w_target]):.4g} to "
                  f"{max([w for w, _, _ in up] + [w_target]):.4g} rad/s; smallest |F| = "
                  f"{abs(Fb):.3g} m at k2 = {kb:.6g}")
        return RootReport(False, float("nan"), Fb, 0, f.n, "none", reason, tuple(history),
                          (), -w_target**2, "k", False, float("nan"), "nearest")
    a, b = min(brackets, key=lambda br: abs(0.5 * (br[0] + br[1]) - w_target))
    k_a, k_b = -b * b, -a * a
    r, F, it, how, resolved = refine_bracket(f, k_a, k_b, tol_m, max_iter, history)
    if resolved:
        r, F = polish_root(f, r, F, history)
    mis = f(r)[2]
    reason = (f"rule 'nearest': the root nearest w = {w_target:.4g} rad/s (w = "
              f"{np.sqrt(max(-r, 0.0)):.4g}) of {len(brackets)} bracketed; {how}")
    return RootReport(bool(resolved), float(r) if resolved else float("nan"), float(F), it,
                      f.n, "negative" if resolved else "none", reason, tuple(history),
                      tuple(bk), -w_target**2, "k", False, float(mis), "nearest")
