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
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from flightrecon.errors import ConvergenceError, ValidationError

__all__ = ["PARAMETRISATIONS", "RULES", "ManyEvaluator", "RootReport", "find_coefficient",
           "find_root_near"]

PARAMETRISATIONS = ("k", "alpha")

Evaluator = Callable[[float], tuple[float, float, float]]
"""``k -> (F(k), dF/dk(k), misfit(k))``: end-point residual [m], its exact derivative and the
track's RMS distance from its reference (used by ``rule="baro"``; NaN when unused)."""

STAGNATION = 8
"""Damped-Newton iterations without a new smallest |F| before the scan takes over."""

RULES = ("slowest", "baro")
"""Root-selection rules on the negative branch (module docstring, step 4)."""


@dataclass(frozen=True)
class RootReport:
    """What the root finder did for one axis.

    Attributes
    ----------
    converged : ``|F(root)| <= tol_m``
    root : the coefficient taken (NaN only when ``converged`` is False)
    residual_m : ``F(root)`` [m] (for a failure: the smallest ``|F|`` seen, signed)
    misfit_m : the track's RMS distance from its reference at the root (vertical: from the
        baro height) [m]; NaN if not computed
    rule : the selection rule applied
    iterations : Newton iterations (start phase plus refinement)
    evaluations : evaluations of ``F`` in total (scan included; values reused from the memo
        are not counted)
    branch : ``"negative"`` (stable / physical), ``"positive"`` (non-physical exponential
        weighting of lift-off data) or ``"none"``
    reason : one line on how the root was found or why none was
    history : ``(k, F)`` at every Newton iterate, in order (for plotting)
    brackets : sign-change intervals ``(k_a, k_b)`` found by the scan, both branches
    start : the start value used
    parametrisation : ``"k"`` or ``"alpha"``
    overflow : an iterate overflowed or exceeded ``kt_max`` and was pulled back
    """

    converged: bool
    root: float
    residual_m: float
    iterations: int
    evaluations: int
    branch: str
    reason: str
    history: tuple[tuple[float, float], ...] = ()
    brackets: tuple[tuple[float, float], ...] = ()
    start: float = float("nan")
    parametrisation: str = "k"
    overflow: bool = False
    misfit_m: float = float("nan")
    rule: str = "slowest"

    def as_dict(self) -> dict:
        """JSON-serialisable summary (history as lists ``[k, F]``)."""
        return {
            "converged": bool(self.converged), "k": _num(self.root),
            "residual_m": _num(self.residual_m), "iterations": int(self.iterations),
            "evaluations": int(self.evaluations), "branch": self.branch, "reason": self.reason,
            "start": _num(self.start), "parametrisation": self.parametrisation,
            "overflow": bool(self.overflow), "misfit_m": _num(self.misfit_m),
            "rule": self.rule,
            "history": [[_num(k), _num(f)] for k, f in self.history],
        }


def _num(x: float) -> float | None:
    x = float(x)
    return x if np.isfinite(x) else None


ManyEvaluator = Callable[[np.ndarray], tuple[np.ndarray, np.ndarray]]
"""``ks -> (F(ks), misfit(ks))`` for many ``k`` at once, without derivatives (the scan).  Must
return the same numbers as :data:`Evaluator` for each ``k`` (one pass over the data for all
of them is what makes the scan cheap: docs/sabziev.md, "Speed")."""


@dataclass
class _Counter:
    """Evaluations of ``F`` with a memo: ``F`` is a deterministic function of ``k``, so a value
    already computed (a scan point that became a bracket end, the last Newton iterate of a
    refinement) is not recomputed.  ``n`` counts the evaluations actually made."""

    fun: Evaluator
    many: ManyEvaluator | None = None
    n: int = 0
    best: tuple[float, float] = (float("nan"), float("inf"))
    memo: dict = field(default_factory=dict)

    def _seen(self, k: float, F: float) -> None:
        if np.isfinite(F) and abs(F) < abs(self.best[1]):
            self.best = (k, F)

    def __call__(self, k: float) -> tuple[float, float, float]:
        k = float(k)
        hit = self.memo.get(k)
        if hit is not None and not np.isnan(hit[1]):
            return hit
        self.n += 1
        with np.errstate(over="ignore", invalid="ignore"):
            F, dF, m = self.fun(k)
        F, dF, m = float(F), float(dF), float(m)
        self._seen(k, F)
        self.memo[k] = (F, dF, m)
        return F, dF, m

    def value(self, k: float) -> float:
        """``F(k)`` alone (from the memo when the scan or Newton already has it)."""
        hit = self.memo.get(float(k))
        return hit[0] if hit is not None else self(k)[0]

    def scan(self, ks: np.ndarray):
        """Yield ``(k, F, misfit)`` along a grid of ``k``, each accounted for (count, best,
        memo) as it is taken: the caller may stop early (overflow) and the report is the same
        as for point-by-point evaluation.  With ``many`` the whole grid is computed in one
        batch first (values past an early stop are then computed but not used)."""
        ks = np.asarray(ks, dtype=np.float64)
        if self.many is None:
            for k in ks.tolist():
                F, _, m = self(k)
                yield k, F, m
            return
        with np.errstate(over="ignore", invalid="ignore"):
            Fs, ms = self.many(ks)
        for k, F, m in zip(ks.tolist(), np.asarray(Fs, dtype=np.float64).tolist(),
                           np.asarray(ms, dtype=np.float64).tolist()):
            self.consume(k, F, m)
            yield k, F, m

    def consume(self, k: float, F: float, m: float) -> None:
        """Account for one scan value (count, best |F|, memo)."""
        k, F, m = float(k), float(F), float(m)
        self.n += 1
        self._seen(k, F)
        if k not in self.memo:
            self.memo[k] = (F, float("nan"), m)


def _sign(x: float) -> float:
    return 1.0 if x >= 0 else -1.0


def _damped_newton(f: _Counter, k0: float, k_max_pos: float, k_max_neg: float, tol_m: float,
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
    s = _sign(k0)
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
        if k_good is not None and _sign(F) != _sign(F_good):
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


ROUNDING_ROOT_M = 1.0
"""A sign change of F between neighbouring floating-point k with |F| at most this on both sides
[m] is a root (F's rounding over a long flight reaches centimetres; the end point is known to
tens of metres); larger jumps there are not (a pole, a discontinuity)."""


def _refine(f: _Counter, a: float, b: float, tol_m: float, max_iter: int,
            history: list) -> tuple[float, float, int, str, bool]:
    """Newton kept inside the bracket [a, b] (bisection otherwise), brentq as the fallback.
    Returns (k, F, iterations, how, resolved): ``resolved`` when ``|F| <= tol_m`` or the
    bracket shrank to neighbouring floats with ``|F| <= ROUNDING_ROOT_M`` on both sides."""
    Fa = f.value(a)
    k = 0.5 * (a + b)
    it = 0
    while it < max_iter:
        F, dF, _ = f(k)
        history.append((k, F))
        it += 1
        if abs(F) <= tol_m:
            return k, F, it, "Newton in bracket", True
        if _sign(F) == _sign(Fa):
            a, Fa = k, F
        else:
            b = k
        if abs(b - a) <= 4e-16 * max(abs(a), abs(b)):
            if max(abs(Fa), abs(F)) <= ROUNDING_ROOT_M:
                # F changes sign between neighbouring floats and is small on both sides: the
                # root to machine precision; what is left of |F| is F's own rounding
                return k, F, it, (f"bracket collapsed at floating-point resolution: |F| = "
                                  f"{abs(F):.3g} m, {abs(Fa):.3g} m on the other side"), True
            return k, F, it, ("bracket collapsed before |F| <= tol: F not resolvable in "
                              "floating point"), False
        k_new = k - F / dF if dF != 0.0 and np.isfinite(dF) else np.nan
        if not (min(a, b) < k_new < max(a, b)):
            k_new = 0.5 * (a + b)
        k = k_new
    from scipy.optimize import brentq

    root = brentq(lambda x: f(x)[0], min(a, b), max(a, b), xtol=1e-300, rtol=4e-16,
                  maxiter=200)
    F = f(root)[0]
    history.append((root, F))
    return root, F, it, "brentq fallback", bool(abs(F) <= tol_m)


def _polish(f: _Counter, k: float, F: float, history: list, steps: int = 3) -> tuple[float, float]:
    """A few plain Newton steps after ``|F| <= tol``, each kept only if it reduces ``|F|``:
    the tolerance is a test on metres, the polish makes ``k`` itself accurate (fleet means
    average it)."""
    for _ in range(steps):
        _, dF, _ = f(k)
        if dF == 0.0 or not np.isfinite(dF):
            break
        k_new = k - F / dF
        if k_new * k <= 0.0:
            break
        F_new = f(k_new)[0]
        if not (np.isfinite(F_new) and abs(F_new) < abs(F)):
            break
        k, F = k_new, F_new
        history.append((k, F))
        if F == 0.0:
            break
    return k, F


def _scan(f: _Counter, sign: float, k_lo: float, k_hi: float,
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
        if prev is not None and _sign(F) != _sign(prev[1]):
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
    f = _Counter(fun, fun_many)
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


def _k_search(f: _Counter, k_ref, k_max_pos, k_max_neg, k0, tol_m, max_iter, span_lo, ppd,
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
        if bracket_n is not None and _sign(bracket_n[0]) == sign:
            found.append((bracket_n[0], bracket_n[1], f(bracket_n[0])[2]))
        use_rule = rule if sign < 0 else "slowest"
        if use_rule == "slowest":
            found.sort(key=lambda br: min(abs(br[0]), abs(br[1])))
            pick = found[:1]
        else:
            found.sort(key=lambda br: br[2] if np.isfinite(br[2]) else np.inf)
            pick = found[:n_refine]
        for a, b, _ in pick:
            r, F, it2, how, resolved = _refine(f, a, b, tol_m, max_iter, history)
            it += it2
            candidates.append((r, F, f(r)[2], f"scan bracket refined ({how})", resolved))
        if root_n is not None and _sign(root_n) == sign and not any(
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
            root, F = _polish(f, root, F, history)
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


def _alpha_newton(f: _Counter, alpha0: float, k_max_pos: float, tol_m: float, max_iter: int):
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
            k, F = _polish(f, k, F, history)
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


def _sign_changes(up: list[tuple[float, float, float]], down: list[tuple[float, float, float]]
                  ) -> list[tuple[float, float]]:
    """The brackets ``(w_a, w_b)`` between neighbouring scan points of finite ``F`` of opposite
    signs: along the upward and the downward scans, then across ``w_target`` between their
    first points."""
    found = []
    for seq in (up, down):
        for (w1, F1, _), (w2, F2, _) in zip(seq[:-1], seq[1:]):
            if np.isfinite(F1) and np.isfinite(F2) and _sign(F1) != _sign(F2):
                found.append((min(w1, w2), max(w1, w2)))
    if up and down and np.isfinite(up[0][1]) and np.isfinite(down[0][1]) \
            and _sign(up[0][1]) != _sign(down[0][1]):
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
    steps kept inside the bracket (:func:`_refine`).

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
    f = _Counter(fun, fun_many)
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
    r, F, it, how, resolved = _refine(f, k_a, k_b, tol_m, max_iter, history)
    if resolved:
        r, F = _polish(f, r, F, history)
    mis = f(r)[2]
    reason = (f"rule 'nearest': the root nearest w = {w_target:.4g} rad/s (w = "
              f"{np.sqrt(max(-r, 0.0)):.4g}) of {len(brackets)} bracketed; {how}")
    return RootReport(bool(resolved), float(r) if resolved else float("nan"), float(F), it,
                      f.n, "negative" if resolved else "none", reason, tuple(history),
                      tuple(bk), -w_target**2, "k", False, float(mis), "nearest")
