"""Health of a method's track: non-finite positions, missing or non-positive sd, its own
verdicts with their reasons, the physical envelope, the plausibility of its estimated states
and its agreement with the evidence (:mod:`flightrecon.envelope`,
:mod:`flightrecon.track_evidence`)."""

from __future__ import annotations

from typing import Any

import numpy as np

from flightrecon.pipeline.status import stopped_short
from flightrecon.types import CleanFlight, MethodResult


def _spans(t: np.ndarray, bad: np.ndarray, gap_s: float = 5.0) -> list[list[float]]:
    """Time spans [start, end] of the samples where ``bad`` holds (joined across gaps < gap_s)."""
    tb = t[bad]
    if len(tb) == 0:
        return []
    brk = np.flatnonzero(np.diff(tb) > gap_s)
    starts = np.r_[tb[0], tb[brk + 1]]
    ends = np.r_[tb[brk], tb[-1]]
    return [[float(a), float(b)] for a, b in zip(starts, ends)]


def self_verdict_reason(summary: dict[str, Any]) -> str:
    """Why a method calls itself unhealthy, from its own summary: its ``unhealthy_reason``
    when it gives one, else its consistency verdict (a gross mean NIS, no measurement used)
    and its warnings that name the verdict; never an empty reason."""
    if summary.get("unhealthy_reason"):
        return str(summary["unhealthy_reason"])
    why: list[str] = []
    cons = summary.get("consistency") or {}
    if cons.get("gross"):
        why.append(f"its mean NIS per degree of freedom is {float(cons['mean']):.1f} (expected "
                   "1, at most 5): its noise model does not fit the flight")
    elif cons and cons.get("count", 1) == 0:
        why.append("no measurement reached its filter (nothing to check its noise against)")
    why += [str(w) for w in summary.get("warnings", []) or [] if "(unhealthy)" in str(w)]
    # a method's own list of problems (Sabziev's health_problems: text or {"what": ...})
    for p in summary.get("health_problems", []) or []:
        text = p.get("what") if isinstance(p, dict) else p
        if text and str(text) not in why:
            why.append(str(text))
    if not why:
        why.append("it reports itself unhealthy and gives no reason")
    return "; ".join(why)


def method_health(res: MethodResult, clean: CleanFlight | None = None) -> dict[str, Any]:
    """Health of a method's track, with the time spans of each problem.

    A method is unhealthy where its position is non-finite anywhere inside its own coverage
    (infinite, half missing or missing between finite samples), where its standard deviation
    is missing or not positive where it gives a position (a covariance that lost positive
    definiteness), where it says so itself (``converged`` or ``healthy`` false, with the reason
    it gives: :func:`self_verdict_reason`), or, given the cleaned flight, where its track is not
    physically possible (:func:`flightrecon.envelope.envelope_problems`: speeds, vertical
    speeds, accelerations beyond the envelope, a height far from the recorded pressure
    altitude) or its states are implausible and its track disagrees with the evidence
    (:func:`flightrecon.track_evidence.evidence_problems`: wind, ground against air speed, heading
    bias, the arrival, known positions, dead reckoning between two known ends).  Any problem
    makes it unhealthy: the default result then falls back to the healthy sources, and its
    coefficients are not stored."""
    tr = res.track
    p = res.name + "_"
    t = tr["t_s"].to_numpy(float)
    out: dict[str, Any] = {"problems": []}
    if f"{p}north_m" in tr.columns and len(tr):
        pos = tr[[f"{p}north_m", f"{p}east_m"]].to_numpy(float)
        fin = np.isfinite(pos).all(axis=1)
        if fin.any():
            i0, i1 = np.flatnonzero(fin)[[0, -1]]
            inside = np.zeros(len(t), bool)
            inside[i0:i1 + 1] = True
            holes = inside & ~fin
            if holes.any():
                out["problems"].append({"what": "non-finite position inside the coverage",
                                        "check": "finite", "spans_s": _spans(t, holes)})
            for c in (f"{p}north_sd_m", f"{p}east_sd_m"):
                if c in tr.columns:
                    sd = tr[c].to_numpy(float)
                    bad = fin & ~(sd > 0)
                    if bad.any():
                        out["problems"].append({"what": f"{c} missing or not positive",
                                                "check": "finite", "spans_s": _spans(t, bad)})
        elif (~np.isnan(pos)).any():
            out["problems"].append({"what": "no finite position (only infinite values)",
                                    "check": "finite", "spans_s": []})
    s = res.summary
    _convergence(s, out)
    if s.get("healthy") is False:
        out["problems"].append({"what": self_verdict_reason(s), "check": "self",
                                "spans_s": []})
    if clean is not None:
        from flightrecon.envelope import envelope_problems
        from flightrecon.track_evidence import evidence_problems

        for prob in envelope_problems(res, clean) + evidence_problems(res, clean):
            out["problems"].append({"what": prob["what"], "check": prob["check"],
                                    "spans_s": prob["spans_s"]})
    out["healthy"] = not out["problems"]
    return out


def _convergence(s: dict[str, Any], out: dict[str, Any]) -> None:
    """The convergence check, in place on ``out``: a method that says it did not converge is
    unhealthy, unless it stopped short with a bounded remaining movement (the joint smoother's
    ``settling``, flightrecon/methods/joint/settling.py: within 0.1 sd, or its sd widened by
    it), which ``out["stopped_short"]`` then says."""
    if s.get("converged") is not False:
        return
    short = stopped_short(s)
    if short is not None:
        out["stopped_short"] = short
        return
    settle = s.get("settling") or {}
    why = s.get("stop_reason") or ""
    if settle.get("sentence"):
        why = f"{why}; {settle['sentence']}" if why else str(settle["sentence"])
    out["problems"].append({"what": "did not converge" + (f" ({why})" if why else ""),
                            "check": "converged", "spans_s": []})


def has_finite_track(res: MethodResult) -> bool:
    """Whether a method produced at least one finite horizontal position."""
    p = res.name + "_"
    tr = res.track
    if f"{p}north_m" not in tr.columns or not len(tr):
        return False
    return bool((np.isfinite(tr[f"{p}north_m"].to_numpy(float))
                 & np.isfinite(tr[f"{p}east_m"].to_numpy(float))).any())
