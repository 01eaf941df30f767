"""Each method's status word in the summary and on the console, from its health and its own
summary (README, "Each method's status word"; docs/output.md, "Method health").

| status | meaning |
|---|---|
| ``ok`` | it ran, met its own convergence test, and its track is physically possible |
| ``fallback`` | healthy, but it ran its documented fallback (the Sabziev fusion with no root
  of the end-point condition on an axis: a fixed coefficient and a linear end correction);
  the reason gives the axes and the corrections removed |
| ``stopped`` | healthy, but it stopped short of its convergence test (the joint smoother at
  its cap of passes) while its passes still contracted; the reason gives how far more passes
  would move it and whether its sd was widened by that |
| ``doubtful`` | healthy, but a channel it leans on has a unit the door doubts, or one used
  against a certain contradiction the mapping confirmed (:mod:`.unit_doubts`); set by the
  pipeline, the reason gives the channel and the figure |
| ``unhealthy`` | it ran but failed a health check (the reason follows) |
| ``failed`` / ``skipped`` | set by the pipeline: an error, or not run |

A method whose status is in :data:`FEEDS_DEFAULT` may feed the default result; the others
never do.  The summary's ``healthy`` of a method that ran is the pipeline's verdict (its own,
its envelope's and the evidence's), so that it never contradicts ``status``; where its chi-square
verdict says ``consistent: false`` the ``consistency`` entry carries a ``note`` saying why that
does or does not make it unhealthy.
"""

from __future__ import annotations

from typing import Any

from flightrecon.estimation.consistency import GROSS_FACTOR
from flightrecon.pipeline.unit_doubts import DOUBTFUL
from flightrecon.types import MethodResult

FEEDS_DEFAULT: tuple[str, ...] = ("ok", "fallback", "stopped", DOUBTFUL)
"""The statuses of a healthy method: its track may feed the default result."""

STOPPED_VERDICTS: tuple[str, ...] = ("settled", "widened")
"""The joint smoother's ``settling`` verdicts of a run that stopped short with a bounded
remaining movement (flightrecon/methods/joint/health.py, ``settling``)."""

#: the Sabziev fusion's axes (its order north, up, east)
_SABZIEV_AXES = {"x": "north", "y": "up", "z": "east"}


def stopped_short(summary: dict[str, Any]) -> str | None:
    """The sentence of a method that stopped short of its convergence test with a bounded
    remaining movement (its summary's ``settling``), else ``None``."""
    s = summary.get("settling")
    if isinstance(s, dict) and s.get("verdict") in STOPPED_VERDICTS:
        return str(s.get("sentence") or s["verdict"])
    return None


def fallback_note(summary: dict[str, Any]) -> str | None:
    """The Sabziev fusion's fallback in figures: the axes without a root of the end-point
    condition and the linear end correction removed on each (docs/sabziev.md, "The stable
    policy"); ``None`` when every axis has its root."""
    axes = summary.get("fallback_axes") or []
    if not axes:
        return None
    parts = []
    for a in axes:
        corr = ((summary.get("axes") or {}).get(a) or {}).get("end_correction_m")
        k = ((summary.get("axes") or {}).get(a) or {}).get("k_used")
        what = [f"k = {k:.3g}"] if k is not None else []
        what += [f"end correction {corr / 1000.0:+.2f} km"] if corr is not None else []
        parts.append(f"{_SABZIEV_AXES.get(a, a)} ({a}" + "".join(f", {w}" for w in what) + ")")
    return (f"no root of the end-point condition on {len(axes)} of 3 axes: a fixed "
            "coefficient and the end miss removed linearly in time instead ("
            + "; ".join(parts) + ")")


def consistency_note(summary: dict[str, Any], healthy: bool) -> str | None:
    """Why a method whose chi-square verdict is ``consistent: false`` is or is not healthy
    (docs/estimation.md, "Consistency"); ``None`` when it is consistent or has no verdict."""
    c = summary.get("consistency")
    if not isinstance(c, dict) or c.get("consistent") is not False:
        return None
    if not c.get("count"):
        return ("no measurement reached its filter: no evidence either way about its noise "
                "model (consistent: false means untested here)")
    mean, band = float(c["mean"]), c.get("band") or [float("nan"), float("nan")]
    where = (f"mean NIS per degree of freedom {mean:.3g} outside the 95 % band "
             f"[{band[0]:.3g}, {band[1]:.3g}] of a noise model that fits the flight exactly")
    if c.get("gross"):
        return where + f", above {GROSS_FACTOR:g}: its noise model does not fit the flight " \
                       "(unhealthy)"
    side = ("below it: the noise it assumes is larger than its residuals show, its sd errs on "
            "the cautious side" if mean < band[0] else
            f"above it: its noise model is tighter than its residuals show (by up to "
            f"{mean ** 0.5:.2g} x in sd)")
    verdict = (f"only a mean above {GROSS_FACTOR:g} makes a method unhealthy" if healthy
               else "it is unhealthy for the reason given")
    return f"{where}, {side}; {verdict}"


def method_status(res: MethodResult, health: dict[str, Any]) -> dict[str, Any]:
    """The summary entry of a method that ran: its own summary, ``status`` (the word),
    ``reason`` (why, in figures, for every word but ``ok``), ``healthy`` (the pipeline's
    verdict) and ``health`` (:func:`flightrecon.pipeline.health.method_health`)."""
    s: dict[str, Any] = {**res.summary, "health": health, "healthy": bool(health["healthy"])}
    if "healthy" in res.summary and res.summary["healthy"] != s["healthy"]:
        s["own_verdict_healthy"] = res.summary["healthy"]
    note = consistency_note(res.summary, s["healthy"])
    if note:
        s["consistency"] = {**res.summary["consistency"], "note": note}
    if not health["healthy"]:
        s["status"] = "unhealthy"
        s["reason"] = "; ".join(pr["what"] for pr in health["problems"])
        return s
    stopped, fallback = stopped_short(res.summary), fallback_note(res.summary)
    s["status"] = "stopped" if stopped else "fallback" if fallback else "ok"
    reason = "; ".join(x for x in (stopped, fallback) if x)
    if reason:
        s["reason"] = reason
    return s
