"""Smooth command profiles: a constant joined by quintic smooth steps, with exact derivative
and integral.

A profile is ``v(t) = v0 + sum_i delta_i * S((t - start_i) / duration_i)`` with the quintic
smooth step ``S(u) = 6u^5 - 15u^4 + 10u^3`` on ``[0, 1]`` (0 before, 1 after).  ``S`` is C2
(value, slope and curvature continuous), so a speed profile built from it gives a continuous
acceleration and jerk.  Value, derivative and the integral from ``t = 0`` are closed forms
(docs/simulator.md, "Command profiles"); the per-point work is a compiled loop over the
(few) transitions.
"""

from __future__ import annotations

from dataclasses import dataclass

import numba
import numpy as np

from flightrecon.errors import ValidationError

__all__ = ["SmoothProfile", "smoothstep"]


def smoothstep(u):
    """Quintic smooth step S(u) = 6u^5 - 15u^4 + 10u^3, clipped to [0, 1] outside."""
    u = np.clip(np.asarray(u, float), 0.0, 1.0)
    return u**3 * (10.0 + u * (-15.0 + 6.0 * u))


@numba.njit(cache=True)
def _evaluate(t, v0, start, dur, delta, out_v, out_d, out_i):
    """Value, derivative and integral from 0 of the profile at every ``t`` (compiled)."""
    n = t.shape[0]
    k = start.shape[0]
    for j in range(n):
        tj = t[j]
        v = v0
        d = 0.0
        integ = v0 * tj
        for i in range(k):
            s = start[i]
            if tj <= s:
                continue
            di = dur[i]
            u = (tj - s) / di
            if u >= 1.0:
                v += delta[i]
                integ += delta[i] * (0.5 * di + (tj - s - di))
            else:
                u2 = u * u
                u3 = u2 * u
                v += delta[i] * u3 * (10.0 + u * (-15.0 + 6.0 * u))
                d += delta[i] * 30.0 * u2 * (1.0 - u) * (1.0 - u) / di
                integ += delta[i] * di * u2 * u2 * (2.5 + u * (-3.0 + u))
        out_v[j] = v
        out_d[j] = d
        out_i[j] = integ


@dataclass(frozen=True, eq=False)
class SmoothProfile:
    """A scalar command ``v(t)``: ``initial`` plus smooth steps.

    Attributes
    ----------
    initial : value before the first transition
    start_s, duration_s, delta : per transition, start time [s] (>= 0), duration [s] (> 0)
        and the change of value it makes
    """

    initial: float
    start_s: np.ndarray
    duration_s: np.ndarray
    delta: np.ndarray

    @classmethod
    def build(cls, initial: float, steps: list[tuple[float, float, float]]) -> SmoothProfile:
        """Profile from ``[(start_s, duration_s, delta), ...]``.

        Raises
        ------
        ValidationError
            On a negative start or a non-positive duration.
        """
        arr = np.asarray(steps, float).reshape(-1, 3)
        if np.any(arr[:, 0] < 0) or np.any(arr[:, 1] <= 0) or not np.all(np.isfinite(arr)):
            raise ValidationError("profile transitions need start >= 0, duration > 0, finite")
        return cls(float(initial), np.ascontiguousarray(arr[:, 0]),
                   np.ascontiguousarray(arr[:, 1]), np.ascontiguousarray(arr[:, 2]))

    def evaluate(self, t) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Return ``(value, derivative, integral from 0)`` at times ``t`` [s] (any shape)."""
        ta = np.ascontiguousarray(np.asarray(t, float).ravel())
        v = np.empty_like(ta)
        d = np.empty_like(ta)
        i = np.empty_like(ta)
        _evaluate(ta, self.initial, self.start_s, self.duration_s, self.delta, v, d, i)
        shape = np.shape(t)
        return v.reshape(shape), d.reshape(shape), i.reshape(shape)

    def value(self, t) -> np.ndarray:
        """Profile value at ``t``."""
        return self.evaluate(t)[0]

    def final(self) -> float:
        """Value after the last transition."""
        return float(self.initial + self.delta.sum())
