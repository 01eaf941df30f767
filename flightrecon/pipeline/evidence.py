"""The default result chosen by the evidence the flight holds (docs/output.md, "How the default
result is chosen").

Each healthy track's reported sd is checked on the flight itself wherever the flight allows it
(:func:`track_checks`): the points a method did not use (held out: the GNSS stretches the joint
smoother withholds for its gap calibration, the known positions ``--fix`` a method does not
take) and the points it did use (the given end point, the fixes it takes; a miss there beyond
:data:`~flightrecon.pipeline.health.END_POINT_K` sd already makes it unhealthy).  The rule
(:func:`choose_order`):

1. a track whose miss of a held-out point exceeds :data:`HELD_OUT_K` of its sd is never the
   default (its sd is refuted on the flight);
2. tracks checked on the same held-out points are ordered by their miss there in metres (the
   error the flight measured, not the sd each claims);
3. the others keep the order of :data:`~flightrecon.pipeline.registry.DEFAULT_PRIORITY`
   (what each method uses: docs/output.md), where the flight holds no evidence between them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass
from typing import Any

import numpy as np

from flightrecon.types import CleanFlight, MethodResult

HELD_OUT_K = 4.0
"""A held-out point missed by more than this many combined sd (per axis) refutes the track's
sd: that track is never the default (the same 4 sd as the health rules' end points)."""

FIX_USE: dict[str, str] = {"joint": "all", "sns": "all", "sabziev": "end"}
"""Which known positions (``--fix``) each method takes as measurements: every one (the joint
smoother, SNS), only one at the record's end without an arrival (Sabziev's end point), none
(ARMS, azimuth): the others are held out from it (``flightrecon reconstruct --help``)."""


@dataclass(frozen=True)
class Check:
    """One point a track is checked on: ``what`` (words), whether it was ``held_out`` from the
    method, the miss [m] and the miss in combined sd ``z`` (largest per axis)."""

    what: str
    held_out: bool
    miss_m: float
    z: float


def _fix_checks(name: str, res: MethodResult, clean: CleanFlight) -> list[Check]:
    """The known positions (``--fix``) the track passes, held out where the method does not
    take them (:data:`FIX_USE`)."""
    from flightrecon.geo.frames import output_plane
    from flightrecon.track_evidence import END_FIX_S

    meta, tr, p = clean.meta, res.track, name + "_"
    if not meta.fixes or f"{p}north_m" not in tr.columns or not len(tr):
        return []
    plane = output_plane(meta)
    t = tr["t_s"].to_numpy(float)
    t_last = float(clean.grid["t_s"].iloc[-1])
    out = []
    for fx in meta.fixes:
        use = FIX_USE.get(name, "none")
        at_end = meta.arrival is None and t_last - END_FIX_S <= fx.t_s <= t_last
        held = use == "none" or (use == "end" and not at_end)
        alt = fx.alt_msl_m if fx.alt_msl_m is not None else 0.0
        ef, nf, _ = plane.forward(fx.lat_deg, fx.lon_deg, alt + meta.geoid_undulation_m)
        vals = []
        for c in ("north_m", "east_m", "north_sd_m", "east_sd_m"):
            col = tr[p + c].to_numpy(float) if p + c in tr.columns else np.zeros(len(t))
            ok = np.isfinite(col)
            vals.append(np.interp(fx.t_s, t[ok], col[ok], left=np.nan, right=np.nan)
                        if ok.sum() >= 2 else np.nan)
        n, e, sn, se = (float(v) for v in vals)
        if not (np.isfinite(n) and np.isfinite(e)):
            continue
        dn, de = n - float(nf), e - float(ef)
        z = max(abs(dn) / np.hypot(fx.sd_m, sn), abs(de) / np.hypot(fx.sd_m, se))
        out.append(Check(f"known position at t = {fx.t_s:.0f} s", held, float(np.hypot(dn, de)),
                         float(z)))
    return out


def _gap_checks(res: MethodResult) -> list[Check]:
    """The joint smoother's held-out GNSS stretches (its gap calibration,
    flightrecon/methods/joint/calibration.py): the RMS miss of each stretch's withheld
    fixes and the root of its largest mean NEES per axis with the calibrated sd."""
    gc = res.summary.get("gap_calibration") or {}
    rms = gc.get("heldout_rms_m") or []
    nees = np.asarray(gc.get("nees_after") or [], float).reshape(len(rms), -1) if rms else None
    out = []
    for k, (a, b) in enumerate(gc.get("stretches_s") or []):
        if k >= len(rms) or nees is None:
            break
        out.append(Check(f"GNSS withheld over {a:.0f}..{b:.0f} s", True, float(rms[k]),
                         float(np.sqrt(np.max(nees[k])))))
    return out


def track_checks(results: dict[str, MethodResult], healthy: dict[str, bool],
                 clean: CleanFlight) -> dict[str, list[Check]]:
    """Every healthy method's checks on the flight: the given end point (used), the known
    positions (held out or used, :data:`FIX_USE`) and, for the joint smoother, its held-out
    GNSS stretches."""
    from flightrecon.pipeline.health import end_point_miss, given_end_point

    end = given_end_point(clean)
    out: dict[str, list[Check]] = {}
    for name, res in results.items():
        if not healthy.get(name):
            continue
        checks: list[Check] = []
        if end is not None:
            got = end_point_miss(res, end)
            if got is not None:
                checks.append(Check(end.what, False, got[0], got[1]))
        checks += _fix_checks(name, res, clean)
        if name == "joint":
            checks += _gap_checks(res)
        out[name] = checks
    return out


def _held_out_rms(checks: Sequence[Check]) -> tuple[frozenset[str], float] | None:
    held = [c for c in checks if c.held_out]
    if not held:
        return None
    return (frozenset(c.what for c in held),
            float(np.sqrt(np.mean([c.miss_m ** 2 for c in held]))))


def choose_order(checks: dict[str, list[Check]], priority: Sequence[str]
                 ) -> tuple[list[str], dict[str, str]]:
    """The order in which healthy tracks feed the default, and why each has its place.

    Returns
    -------
    order, why
        ``order``: the healthy methods that may feed the default, first first (the default
        takes each sample from the first that covers it); ``why``: per healthy method, a
        sentence (excluded, ranked by a held-out miss, or in the priority for want of
        evidence).  When every healthy track is refuted the priority is kept and said so:
        no track is better supported than another.
    """
    healthy = [m for m in priority if m in checks]
    why: dict[str, str] = {}
    refuted = {}
    for m in healthy:
        bad = [c for c in checks[m] if c.held_out and c.z > HELD_OUT_K]
        if bad:
            worst = max(bad, key=lambda c: c.z)
            refuted[m] = (f"never the default: it misses {worst.what}, held out from it, by "
                          f"{worst.miss_m:.0f} m, {worst.z:.1f} sd (at most {HELD_OUT_K:g}): "
                          "its sd is refuted on this flight")
    eligible = [m for m in healthy if m not in refuted]
    if not eligible:
        for m in healthy:
            why[m] = refuted[m].replace("never the default", "refuted") + \
                "; every healthy track is, so the priority stands"
        return healthy, why
    why.update(refuted)
    held = {m: r for m in eligible if (r := _held_out_rms(checks[m])) is not None}
    order = list(eligible)
    groups: dict[frozenset[str], list[str]] = {}
    for m, (points, _) in held.items():
        groups.setdefault(points, []).append(m)
    for members in groups.values():
        if len(members) < 2:
            continue
        slots = sorted(order.index(m) for m in members)
        ranked = sorted(members, key=lambda m: (held[m][1], list(priority).index(m)))
        for s, m in zip(slots, ranked):
            order[s] = m
        for m in members:
            others = ", ".join(f"{o} {held[o][1]:.0f} m" for o in ranked if o != m)
            why[m] = (f"ranked by its RMS miss of the points held out from it "
                      f"({len(held[m][0])}; {held[m][1]:.0f} m against {others})")
    for m in eligible:
        if m not in why:
            ev = (f"its held-out points ({len(held[m][0])}) met within {HELD_OUT_K:g} sd, "
                  "no other track checked on the same points" if m in held
                  else "no point of this flight was held out from it")
            why[m] = f"in the priority {' > '.join(priority)}: {ev}"
    return order, why


def evidence_summary(checks: dict[str, list[Check]], order: Sequence[str],
                     why: dict[str, str]) -> dict[str, Any]:
    """The summary's ``result.evidence``: per healthy method its place in the order (1 first;
    ``None`` never the default), the sentence why, and its checks."""
    return {m: {"rank": order.index(m) + 1 if m in order else None, "why": why.get(m, ""),
                "checks": [asdict(c) for c in cs]} for m, cs in checks.items()}
