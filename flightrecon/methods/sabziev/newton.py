"""Safeguarded Newton-Raphson for one Sabziev coefficient, with a root-selection rule and a report.

Solves ``F(k) = s_N(k) - s_T = 0`` (docs/sabziev.md; seed 001, equations (5)-(7)) where
``F`` and its exact derivative come from the discrete recursion of
:mod:`flightrecon.methods.sabziev`.  The paper iterates from ``k = 1``; over a flight of length
``T`` that weights lift-off data by ``e^T`` and overflows, so here (docs/sabziev.md,
"Root finding"):

1. **Scale.** ``k_ref = 1/T`` for the horizontal axes (k in 1/s) and ``(1/T)^2`` for the
   vertical axis (k2 in 1/s^2).  The default start is ``-3 k_ref``: time constant
   T/3 for the horizontal axes, ``w = sqrt(3)/T`` (loop period about 3.6 T) for the vertical.
2. **Damped Newton** from the start: each step may change ``|k|`` by at most a factor 10 and
   never crosses ``k = 0`` (the branches are searched separately); a non-finite ``F``
   (overflow) halves the step back towards the last good iterate, and ``k T`` above
   ``kt_max`` on the positive branch is pulled back (both recorded as ``overflow``).  The
   phase ends early when Newton heads below the scan range, is held at the branch limit three
   times running, or has not improved ``|F|`` for :data:`STAGNATION` iterations (``F``
   oscillates on the vertical negative branch).  A sign change between iterates is a bracket.
3. **Scan.** ``F`` is tabulated on a geometric grid of ``|k|`` (``points_per_decade``) from
   ``span[0] k_ref`` to ``k_max`` on each branch; sign changes are brackets.  With a batch
   evaluator (``fun_many``) the whole grid of a branch is computed in one call; the values
   are then taken in grid order exactly as point by point.  Values already computed are
   memoised (``F`` is deterministic), so a bracket end or a refined root is not recomputed.
4. **Selection rule** (negative branch first; it is the stable, physical one).
   ``rule="slowest"`` (horizontal axes): the root with the smallest ``|k|``.
   ``rule="baro"`` (vertical axis, default there): on the oscillatory branch ``F(k2)`` has a
   root about every ``pi/T`` in ``w = sqrt(-k2)`` and the slowest ones integrate the
   accelerometers almost open-loop (kilometres off on a one-hour flight with a 0.004 m/s^2
   bias); the root taken is the one whose track stays closest, in RMS over the flight, to the
   baro height it is tied to.  The three brackets with the smallest misfit at their ends (and
   the Newton root, if on this branch) are refined and compared.  If the negative branch has no
   root, the smallest ``|k|`` root on the positive branch is taken and reported
   ``branch="positive"``: an exponential weighting of the lift-off data, not physical.
   Brackets are refined by Newton steps kept inside the bracket (bisection when a step leaves
   it), :func:`scipy.optimize.brentq` as a last fallback.  Roots closer together than the scan
   grid can hide from the scan (every bracket found is a real root: ``F`` is continuous).
5. **No root.** When neither branch changes sign the result is ``converged=False`` with the
   reason and the smallest ``|F|`` seen; never a silent NaN.

The paper's own iteration on ``alpha = sqrt(k2)`` (plain Newton from ``alpha = 1``) is
available as ``parametrisation="alpha"`` to reproduce the paper; it covers ``k2 > 0`` only and
``F`` is even in ``alpha`` with ``F'(0) = 0``.

The counted evaluations, the bracket refinement, the polish and the report are :mod:`.roots`'
(shared with :mod:`.nearest`, the root nearest a target loop frequency).
"""

from __future__ import annotations

import numpy as np

from flightrecon.errors import ConvergenceError, ValidationError
from flightrecon.methods.sabziev.roots import (
    CountedEvaluator,
    Evaluator,
    ManyEvaluator,
    RootReport,
    polish_root,
    refine_bracket,
    sign_of,
)

__all__ = ["PARAMETRISATIONS", "RULES", "find_coefficient"]

PARAMETRISATIONS = ("k", "alpha")

STAGNATION = 8
"""Damped-Newton iterations without a new smallest |F| before the scan takes over."""

RULES = ("slowest", "baro")
"""Root-selection rules on the negative branch (module docstring, step 4)."""


def _damped_newton(f: CountedEvaluator, k0: float, k_max_pos: float, k_max_neg: float, tol_m: float,
                   max_iter: int, history: list,
                   k_floor: float = 0.0) -> tuple[float | None, tuple | None, int, bool]:
    """Step 2 of the module docstring. Returns (root or None, bracket or None, iters, overflow).

    The phase ends early (the scan takes over) when Newton keeps pushing ``|k|`` below
    ``k_floor`` (the root lies on the other branch or at k = 0), when it is held at the branch
    limit three times running (F flat towards the limit), or when ``|F|`` has not improved for
    ``STAGNATION`` iterations (F oscillating: the vertical negative branch).
    """
    k = k0
    overflow = False
    s = sign_of(k0)
    lim = k_max_pos if s > 0 else k_max_neg
    if abs(k) > lim:
        overflow = s > 0
        k = s * lim
    F, dF, _ = f(k)
    it = 0
    k_good, F_good = None, None
    clamps = 0
    best, since_best = np.inf, 0
    while it < max_iter:
        if not (np.isfinite(F) and np.isfinite(dF)):
            overflow = True
            k = 0.5 * k if k_good is None else 0.5 * (k + k_good)
            if abs(k) < 1e-300:
                break
            F, dF, _ = f(k)
            it += 1
            continue
        history.append((k, F))
        if abs(F) <= tol_m:
            return k, None, it, overflow
        if abs(F) < best:
            best, since_best = abs(F), 0
        else:
            since_best += 1
            if since_best >= STAGNATION:
                break
        if k_good is not None and sign_of(F) != sign_of(F_good):
            return None, (min(k, k_good), max(k, k_good)), it, overflow
        k_good, F_good = k, F
        if dF == 0.0:
            break
        k_new = k - F / dF
        if k_new * s <= 0.0 or abs(k_new) < abs(k) / 10.0:
            k_new = k / 10.0
            if abs(k_new) < k_floor:
                break
        elif abs(k_new) > 10.0 * abs(k):
            k_new = 10.0 * k
        if abs(k_new) > lim:
            clamps += 1
            if clamps >= 3:
                break
            if s > 0:
                overflow = True
            k_new = s * 0.5 * (abs(k) + lim)
        else:
            clamps = 0
        k = k_new
        F, dF, _ = f(k)
        it += 1
    return None, None, it, overflow


def _scan(f: CountedEvaluator, sign: float, k_lo: float, k_hi: float,
          points_per_decade: int) -> list[tuple[float, float, float]]:
    """Sign changes of F on a geometric grid of |k| in [k_lo, k_hi] on one branch.

    Returns ``(k_a, k_b, misfit)`` per bracket, ``misfit`` the mean of the end misfits.
    """
    if k_hi <= k_lo:
        return []
    n = max(2, int(np.ceil(np.log10(k_hi / k_lo) * points_per_decade)) + 1)
    ks = sign * np.geomspace(k_lo, k_hi, n)
    out = []
    prev = None
    for k, F, m in f.scan(ks):
        if not np.isfinite(F):
            break  # beyond here the branch overflows
        if prev is not None and sign_of(F) != sign_of(prev[1]):
            out.append((min(prev[0], k), max(prev[0], k), 0.5 * (m + prev[2])))
        prev = (k, F, m)
    return out


def find_coefficient(fun: Evaluator, *, k_ref: float, k_max_pos: float, k_max_neg: float,
                     k0: float | None = None, tol_m: float = 1e-3, max_iter: int = 60,
                     span_lo: float = 1e-2, points_per_decade: int = 12,
                     parametrisation: str = "k", rule: str = "slowest", n_refine: int = 3,
                     strict: bool = False, axis: str = "",
                     fun_many: ManyEvaluator | None = None,
                     branches: tuple[str, ...] = ("negative", "positive")) -> RootReport:
    """Find one Sabziev coefficient by the safeguarded Newton iteration and selection rule.

    Parameters
    ----------
    fun : ``k -> (F, dF/dk, misfit)`` (:data:`Evaluator`)
    k_ref : natural scale of ``|k|`` (``1/T`` or ``1/T^2``)
    k_max_pos : largest ``k`` allowed on the positive branch (overflow guard, from ``kt_max``)
    k_max_neg : largest ``|k|`` scanned on the negative branch
    k0 : start value (default ``-3 k_ref``); with ``parametrisation="alpha"`` the start
        ``alpha`` (default 1, the paper's)
    tol_m : convergence: ``|F| <= tol_m`` [m]
    max_iter : Newton iterations per phase
    span_lo : the scan starts at ``span_lo * k_ref``
    points_per_decade : density of the scan grid
    parametrisation : ``"k"`` (default) or ``"alpha"`` (paper: ``k = alpha^2``, plain Newton)
    rule : ``"slowest"`` or ``"baro"`` (module docstring, step 4)
    n_refine : with ``rule="baro"``, how many brackets (best misfit first) are refined
    strict : raise :class:`~flightrecon.errors.ConvergenceError` instead of returning a
        non-converged report
    axis : axis name for messages
    fun_many : optional ``ks -> (F, misfit)`` for many ``k`` at once (:data:`ManyEvaluator`),
        used by the scan; it must agree with ``fun`` (the Sabziev one is bit-identical).
        Without it the scan calls ``fun`` point by point: same result, slower.
    branches : the branches searched, in order: ``("negative", "positive")`` (the paper's
        search, both) or ``("negative",)`` (the stable range only: every exponential of the
        recursion is then at most 1, docs/sabziev.md "Finite exponentials")

    Returns
    -------
    RootReport
    """
    if parametrisation not in PARAMETRISATIONS:
        raise ValidationError(f"parametrisation must be one of {PARAMETRISATIONS}, "
                              f"got {parametrisation!r}")
    if rule not in RULES:
        raise ValidationError(f"rule must be one of {RULES}, got {rule!r}")
    if not (k_ref > 0 and k_max_pos > 0 and k_max_neg > 0 and tol_m > 0):
        raise ValidationError("k_ref, k_max_pos, k_max_neg and tol_m must be positive")
    f = CountedEvaluator(fun, fun_many)
    if parametrisation == "alpha":
        rep = _alpha_newton(f, 1.0 if k0 is None else float(k0), k_max_pos, tol_m, max_iter)
    else:
        if not branches or any(b not in ("negative", "positive") for b in branches):
            raise ValidationError(f"branches must name 'negative' and/or 'positive', got "
                                  f"{branches!r}")
        rep = _k_search(f, k_ref, k_max_pos, k_max_neg, k0, tol_m, max_iter, span_lo,
                        points_per_decade, rule, n_refine, branches)
    if strict and not rep.converged:
        raise ConvergenceError(f"Sabziev {axis} axis: {rep.reason}")
    return rep


def _k_search(f: CountedEvaluator, k_ref, k_max_pos, k_max_neg, k0, tol_m, max_iter, span_lo, ppd,
              rule, n_refine, branches=("negative", "positive")):
    start = -3.0 * k_ref if k0 is None else float(k0)
    if start == 0.0 or not np.isfinite(start):
        raise ValidationError("the start value of k must be finite and non-zero")
    if "positive" not in branches and start > 0:
        raise ValidationError("the start value of k must be negative when only the negative "
                              "branch is searched")
    history: list = []
    k_lo = span_lo * k_ref
    root_n, bracket_n, it, overflow = _damped_newton(f, start, k_max_pos, k_max_neg, tol_m,
                                                     max_iter, history, 1e-2 * k_lo)
    all_brackets: list = []
    candidates: list = []  # (root, F, misfit, how, resolved)
    for sign, k_hi in ((-1.0, k_max_neg), (1.0, k_max_pos)):
        if ("negative" if sign < 0 else "positive") not in branches:
            continue
        found = _scan(f, sign, k_lo, k_hi, ppd)
        all_brackets.extend((a, b) for a, b, _ in found)
        if bracket_n is not None and sign_of(bracket_n[0]) == sign:
            found.append((bracket_n[0], bracket_n[1], f(bracket_n[0])[2]))
        use_rule = rule if sign < 0 else "slowest"
        if use_rule == "slowest":
            found.sort(key=lambda br: min(abs(br[0]), abs(br[1])))
            pick = found[:1]
        else:
            found.sort(key=lambda br: br[2] if np.isfinite(br[2]) else np.inf)
            pick = found[:n_refine]
        for a, b, _ in pick:
            r, F, it2, how, resolved = refine_bracket(f, a, b, tol_m, max_iter, history)
            it += it2
            candidates.append((r, F, f(r)[2], f"scan bracket refined ({how})", resolved))
        if root_n is not None and sign_of(root_n) == sign and not any(
                abs(c[0] - root_n) <= 1e-9 * abs(root_n) for c in candidates):
            Fn, _, mn = f(root_n)
            candidates.append((root_n, Fn, mn, "damped Newton from the start value",
                               bool(abs(Fn) <= tol_m)))
        good = [c for c in candidates if c[4]]
        if good:
            if use_rule == "slowest":
                best = min(good, key=lambda c: abs(c[0]))
            else:
                best = min(good, key=lambda c: c[2] if np.isfinite(c[2]) else np.inf)
            root, F, mis, how, _ = best
            root, F = polish_root(f, root, F, history)
            branch = "negative" if root < 0 else "positive"
            how = (f"rule '{use_rule}' among {len(good)} root(s) on the {branch} branch; {how}")
            return RootReport(True, float(root), float(F), it, f.n, branch, how, tuple(history),
                              tuple(all_brackets), start, "k", overflow, float(mis), use_rule)
    kb, Fb = f.best
    if candidates:
        worst = min(candidates, key=lambda c: abs(c[1]))
        reason = (f"no root resolved to tol {tol_m:g} m: the best bracketed candidate k = "
                  f"{worst[0]:.6g} leaves |F| = {abs(worst[1]):.3g} m ({worst[3]})")
    else:
        where = (f"either branch (|k| from {k_lo:.3g} to {k_max_neg:.3g} negative, to "
                 f"{k_max_pos:.3g} positive)" if "positive" in branches else
                 f"the negative branch (|k| from {k_lo:.3g} to {k_max_neg:.3g})")
        reason = (f"no root: F does not change sign on {where} and Newton did not "
                  f"converge; smallest |F| = {abs(Fb):.3g} m at k = {kb:.6g}")
    return RootReport(False, float("nan"), Fb, it, f.n, "none", reason, tuple(history),
                      tuple(all_brackets), start, "k", overflow, float("nan"), rule)


def _alpha_newton(f: CountedEvaluator, alpha0: float, k_max_pos: float, tol_m: float,
                  max_iter: int):
    """The paper's iteration: plain Newton on alpha = sqrt(k2), dF/dalpha = 2 alpha dF/dk."""
    alpha = alpha0
    history: list = []
    F = float("nan")
    for it in range(max_iter + 1):
        k = alpha * alpha
        F, dFk, mis = f(k)
        if k > k_max_pos or not (np.isfinite(F) and np.isfinite(dFk)):
            return RootReport(False, float("nan"), F, it, f.n, "none",
                              f"alpha iteration overflowed at alpha = {alpha:.6g} (alpha T is "
                              f"{alpha / np.sqrt(k_max_pos):.3g} times the guard kt_max): the "
                              "paper's start alpha = 1 weights lift-off data by e^(alpha T)",
                              tuple(history), (), alpha0, "alpha", True)
        history.append((k, F))
        if abs(F) <= tol_m:
            k, F = polish_root(f, k, F, history)
            mis = f(k)[2]
            return RootReport(True, float(k), F, it, f.n, "positive" if k > 0 else "negative",
                              "plain Newton on alpha (paper)", tuple(history), (), alpha0,
                              "alpha", False, float(mis), "alpha")
        dFa = 2.0 * alpha * dFk
        if dFa == 0.0:
            break
        alpha = alpha - F / dFa
    return RootReport(False, float("nan"), F, max_iter, f.n, "none",
                      f"alpha iteration did not converge in {max_iter} iterations "
                      f"(|F| = {abs(F):.3g} m)", tuple(history), (), alpha0, "alpha", False)
