"""Health of a method's track: non-finite positions, missing or non-positive sd, its own
verdicts with their reasons, the physical envelope, the plausibility of its estimated states
and its agreement with the evidence (:mod:`flightrecon.envelope`,
:mod:`flightrecon.track_evidence`)."""

from __future__ import annotations

from dataclasses import dataclass
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
        if not any(pr["check"] in ("arrival", "end_point") for pr in out["problems"]):
            out["problems"] += end_point_problems(res, clean)
    out["healthy"] = not out["problems"]
    return out


END_POINT_K = 4.0
"""A given end point is met when the track's end is within this many sd of it per axis (the
end point's own sd combined with the track's, the track's taken at most as wide as the end
point's: a track that used the end point knows its end at least that well)."""


@dataclass(frozen=True)
class EndPoint:
    """The end point the user gave, in the output plane: when (``t_s``), where (``north_m``,
    ``east_m``; one or more references, the airfield's reference point and its runway
    threshold), how well (``sd_m`` per horizontal axis) and what it is in words."""

    t_s: float
    north_m: tuple[float, ...]
    east_m: tuple[float, ...]
    sd_m: float
    what: str


def given_end_point(clean: CleanFlight) -> EndPoint | None:
    """The track's given end point: the arrival at touchdown for a record that ends on the
    ground, or at the last sample for a record that ends fast and keeps it (short final, a
    fast roll-out, a hand-off: flightrecon/cleaning/arrival_end.py), both with the sd
    :data:`~flightrecon.methods.baselines.ARRIVAL_POINT_SD_M` (the airfield's reference point
    standing for where the aircraft is: a record cut on short final below the 150 m that keeps
    the arrival is within a few km of it, so the joint smoother's 100 m of a hand-off point
    would refuse a good track), else a known position (``--fix``) within
    :data:`flightrecon.track_evidence.END_FIX_S` of the record's end (its own sd); ``None``
    without one, or after a ground impact."""
    from flightrecon.geo.frames import output_plane
    from flightrecon.methods.baselines import ARRIVAL_POINT_SD_M
    from flightrecon.track_evidence import END_FIX_S

    meta, ph, g = clean.meta, clean.phases, clean.grid
    if ph is None or not len(g) or np.isfinite(getattr(ph, "impact_t_s", float("nan"))):
        return None
    try:
        plane = output_plane(meta)
    except Exception:   # no frame: nothing to hold the track against
        return None
    t_last = float(g["t_s"].iloc[-1])
    arr = meta.arrival
    refs: list[tuple[float, float, float]] = []
    if arr is not None:
        h = arr.elev_m + meta.geoid_undulation_m
        refs.append((arr.lat_deg, arr.lon_deg, h))
        if ph.ends_airborne:
            t_end, sd, what = t_last, ARRIVAL_POINT_SD_M, \
                "the arrival given (the aircraft's position at the last sample)"
        elif np.isfinite(ph.touchdown_t_s):
            t_end, sd, what = float(ph.touchdown_t_s), ARRIVAL_POINT_SD_M, \
                "the arrival given (touchdown about the airfield's reference point)"
            if arr.threshold_lat_deg is not None and arr.threshold_lon_deg is not None:
                refs.append((arr.threshold_lat_deg, arr.threshold_lon_deg, h))
        else:
            return None
    else:
        ends = [f for f in meta.fixes if t_last - END_FIX_S <= f.t_s <= t_last]
        if not ends:
            return None
        fx = ends[-1]
        alt = fx.alt_msl_m if fx.alt_msl_m is not None else 0.0
        refs.append((fx.lat_deg, fx.lon_deg, alt + meta.geoid_undulation_m))
        t_end, sd, what = float(fx.t_s), float(fx.sd_m), \
            f"the known position at the record's end (t = {fx.t_s:.0f} s)"
    ne = [plane.forward(lat, lon, h) for lat, lon, h in refs]
    return EndPoint(t_end, tuple(float(n) for _, n, _ in ne),
                    tuple(float(e) for e, _, _ in ne), float(sd), what)


def end_point_miss(res: MethodResult, end: EndPoint) -> tuple[float, float] | None:
    """The track's miss of the given end point: the distance [m] and its largest per-axis
    ratio to the combined sd (:data:`END_POINT_K`), at the end's time or the track's last
    finite sample before it, the nearest of the end's references; ``None`` without a track
    there."""
    tr, p = res.track, res.name + "_"
    if f"{p}north_m" not in tr.columns or not len(tr):
        return None
    t = tr["t_s"].to_numpy(float)
    n, e = tr[f"{p}north_m"].to_numpy(float), tr[f"{p}east_m"].to_numpy(float)
    fin = np.flatnonzero(np.isfinite(n) & np.isfinite(e) & (t <= end.t_s + 1e-6))
    if not len(fin) or end.t_s - t[fin[-1]] > 60.0:
        return None
    i = int(fin[-1])
    sds = []
    for c in (f"{p}north_sd_m", f"{p}east_sd_m"):
        v = float(tr[c].to_numpy(float)[i]) if c in tr.columns else 0.0
        sds.append(min(v, end.sd_m) if np.isfinite(v) else end.sd_m)
    best = (np.inf, np.inf)
    for nr, er in zip(end.north_m, end.east_m):
        dn, de = n[i] - nr, e[i] - er
        z = max(abs(dn) / np.hypot(end.sd_m, sds[0]), abs(de) / np.hypot(end.sd_m, sds[1]))
        if z < best[1]:
            best = (float(np.hypot(dn, de)), float(z))
    return best


def end_point_problems(res: MethodResult, clean: CleanFlight) -> list[dict[str, Any]]:
    """A track that does not meet the end point the user gave (:func:`given_end_point`)
    within :data:`END_POINT_K` sd per axis: unhealthy, with the miss in km and in sd.  The
    track's own sd counts only up to the end point's: a track that ends with an sd wider than
    the end point's did not honour it, and a wide sd does not excuse the miss (an A320 export
    whose track ended 12.6 km from the arrival with its own east sd of 11.6 km, exit 0)."""
    end = given_end_point(clean)
    if end is None:
        return []
    got = end_point_miss(res, end)
    if got is None or got[1] <= END_POINT_K:
        return []
    d, z = got
    return [{"what": f"the track ends {d / 1000:.2f} km from {end.what}: {z:.1f} sd of the end "
                     f"point (sd {end.sd_m:.0f} m per axis, at most {END_POINT_K:g}): the end "
                     "point was given and the track does not honour it",
             "check": "end_point", "spans_s": [[end.t_s, end.t_s]], "worst": z,
             "limit": END_POINT_K}]


def _convergence(s: dict[str, Any], out: dict[str, Any]) -> None:
    """The convergence check, in place on ``out``: a method that says it did not converge is
    unhealthy, unless it stopped short with a bounded remaining movement (the joint smoother's
    flightrecon/methods/joint/health.py, ``settling``: within 0.1 sd, or its sd widened by
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
