"""What both root searches of a Sabziev coefficient share: the memoised, counted evaluations of
``F(k) = s_N(k) - s_T`` (docs/sabziev.md; seed 001, equations (5)-(7)), the refinement of a
bracket by Newton steps kept inside it and the polish of a root, and the report
(:class:`RootReport`).  The searches themselves: :mod:`.newton` (the paper policy's safeguarded
Newton with its selection rules) and :mod:`.nearest` (the root nearest a target loop
frequency).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

Evaluator = Callable[[float], tuple[float, float, float]]
"""``k -> (F(k), dF/dk(k), misfit(k))``: end-point residual [m], its exact derivative and the
track's RMS distance from its reference (used by ``rule="baro"``; NaN when unused)."""


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
class CountedEvaluator:
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


def sign_of(x: float) -> float:
    return 1.0 if x >= 0 else -1.0


ROUNDING_ROOT_M = 1.0
"""A sign change of F between neighbouring floating-point k with |F| at most this on both sides
[m] is a root (F's rounding over a long flight reaches centimetres; the end point is known to
tens of metres); larger jumps there are not (a pole, a discontinuity)."""


def refine_bracket(f: CountedEvaluator, a: float, b: float, tol_m: float, max_iter: int,
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
        if sign_of(F) == sign_of(Fa):
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


def polish_root(f: CountedEvaluator, k: float, F: float, history: list, steps: int = 3
                ) -> tuple[float, float]:
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
