"""Health of a method's track: non-finite positions, missing or non-positive sd, its own
verdicts, and the physical envelope (:mod:`flightrecon.envelope`)."""

from __future__ import annotations

from typing import Any

import numpy as np

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


def method_health(res: MethodResult, clean: CleanFlight | None = None) -> dict[str, Any]:
    """Health of a method's track, with the time spans of each problem.

    A method is unhealthy where its position turns non-finite inside its own coverage, where
    its standard deviation is missing or not positive where it gives a position (a covariance
    that lost positive definiteness), where it says so itself (``converged`` or ``healthy``
    false), or, given the cleaned flight, where its track is not physically possible
    (:func:`flightrecon.envelope.envelope_problems`: speeds, vertical speeds, accelerations
    beyond the envelope, a height far from the recorded pressure altitude).  Any problem makes
    it unhealthy: the default result then falls back to the healthy sources, and its
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
            holes = inside & ~fin & ~np.isnan(pos).all(axis=1)  # inf or half-missing
            if holes.any():
                out["problems"].append({"what": "non-finite position inside the coverage",
                                        "spans_s": _spans(t, holes)})
            for c in (f"{p}north_sd_m", f"{p}east_sd_m"):
                if c in tr.columns:
                    sd = tr[c].to_numpy(float)
                    bad = fin & ~(sd > 0)
                    if bad.any():
                        out["problems"].append({"what": f"{c} missing or not positive",
                                                "spans_s": _spans(t, bad)})
    s = res.summary
    if s.get("converged") is False:
        out["problems"].append({"what": "did not converge", "spans_s": []})
    if s.get("healthy") is False:
        out["problems"].append({"what": "reports itself unhealthy", "spans_s": []})
    if clean is not None:
        from flightrecon.envelope import envelope_problems

        for prob in envelope_problems(res, clean):
            out["problems"].append({"what": prob["what"], "check": prob["check"],
                                    "spans_s": prob["spans_s"]})
    out["healthy"] = not out["problems"]
    return out


def has_finite_track(res: MethodResult) -> bool:
    """Whether a method produced at least one finite horizontal position."""
    p = res.name + "_"
    tr = res.track
    if f"{p}north_m" not in tr.columns or not len(tr):
        return False
    return bool((np.isfinite(tr[f"{p}north_m"].to_numpy(float))
                 & np.isfinite(tr[f"{p}east_m"].to_numpy(float))).any())
