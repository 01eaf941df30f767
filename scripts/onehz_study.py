"""1 Hz glass-cockpit exports: accuracy and honesty of the joint smoother (issue #36, items 4-5).

Measured on the shipped Garmin Perspective+ export (``sample_logs/g1000_sr22_LFQA_20220417.csv``)
against its own GPS fixes (SBAS, about 8-10 m), which are the reference:

* **recorder only** (every GNSS channel withheld, the departure and arrival stands taken from the
  first and last GPS fix as in ``tests/test_garmin_e2e.py``, MSL, with the geoid's 45.1 m
  there from the export's own AltGPS - AltMSL so that heights compare on one datum):
  horizontal and vertical RMS over the airborne fixes, against dead reckoning (TAS along the
  heading, no wind) with a linear end-point correction
  (:func:`flightrecon.methods.baselines.dead_reckoning`,
  ``corrected=True``); mean NEES per axis (north, east, up).
* **GNSS gaps**: the GPS used except in windows of 600, 300 and 120 s in the cruise (the GNSS
  columns masked in a copy of the flight; one run, the gaps separated by at least 240 s of GPS).
  Inside each gap the joint's error against the withheld fixes, against dead reckoning from the
  last fix before the gap with the wind of the minute before it (the mean of GPS velocity minus
  the TAS vector over those 60 s); mean NEES per axis inside the gaps.

NEES per axis is ``e_i^2 / (sd_i^2 + r_i^2)`` averaged over the fixes, where ``sd_i`` is the
joint's reported standard deviation and ``r_i`` the reference's own (5 m horizontal, 8 m
vertical per axis: the SBAS fixes' spread; it matters only where ``sd_i`` is a few metres).  A
consistent smoother gives 1 per axis; the bar (issue #36) is 5.

Writes ``docs/tables/onehz.json`` and ``docs/tables/onehz.md`` (``--tag`` appends a suffix, for
a before/after pair).  About 3 minutes on a 2-core machine once the kernels are compiled.

Usage: ``python scripts/onehz_study.py [--tag before]``
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd

from flightrecon.cleaning import clean_flight
from flightrecon.geo.frames import output_plane
from flightrecon.ingest import load_flight
from flightrecon.ingest.gnss_use import GnssUse
from flightrecon.methods.baselines import dead_reckoning
from flightrecon.methods.joint.method import run_joint
from flightrecon.types import CleanFlight, Flight

sys.path.insert(0, str(Path(__file__).resolve().parent))

from table_header import command_line, header  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
LOG = ROOT / "sample_logs" / "g1000_sr22_LFQA_20220417.csv"
OUT = ROOT / "docs" / "tables"
DEPARTURE = "49.2083817,4.1503086,89.3"
ARRIVAL = "49.9728737,2.6970961,109.3"
#: the geoid's height above the ellipsoid there: the export's AltGPS - AltMSL, 148 ft (the
#: stands' elevations above are MSL, the GPS heights ellipsoidal)
GEOID_M = 148 * 0.3048
GAPS_S = (600.0, 300.0, 120.0)
#: the reference's own sd per axis [m] (north, east, up): SBAS fixes
REF_SD = np.array([5.0, 5.0, 8.0])


def load(withhold: bool) -> Flight:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_flight(LOG, meta_overrides={"departure": DEPARTURE, "arrival": ARRIVAL,
                                                "geoid_undulation_m": GEOID_M},
                           gnss_use=GnssUse(withhold=withhold))


def gps_reference(flight: Flight, clean: CleanFlight, latency_s: float = 0.0) -> pd.DataFrame:
    """The export's GPS fixes in the output plane (t_s, n, e, u), airborne only, each at its
    time stamp plus the receiver's latency ``latency_s`` (the time the position was the
    aircraft's: the joint's GNSS clock offset estimated with all the fixes)."""
    g = flight.data.dropna(subset=["gnss_lat_deg", "gnss_lon_deg", "gnss_alt_m"])
    g = g[g.gnss_quality > 0]
    e, n, u = output_plane(clean.meta).forward(g.gnss_lat_deg.to_numpy(float),
                                               g.gnss_lon_deg.to_numpy(float),
                                               g.gnss_alt_m.to_numpy(float))
    ref = pd.DataFrame({"t_s": g.t_s.to_numpy(float) + latency_s, "n": n, "e": e, "u": u,
                        "vn": g.gnss_vn_mps.to_numpy(float), "ve": g.gnss_ve_mps.to_numpy(float)})
    ph = clean.phases
    return ref[(ref.t_s > ph.liftoff_t_s) & (ref.t_s < ph.touchdown_t_s)].reset_index(drop=True)


def joint_errors(track: pd.DataFrame, ref: pd.DataFrame) -> dict[str, np.ndarray]:
    """Joint error and sd per axis at the reference's times."""
    out = {}
    for ax, c in (("n", "north"), ("e", "east"), ("u", "up")):
        out[ax] = np.interp(ref.t_s, track.t_s, track[f"joint_{c}_m"]) - ref[ax].to_numpy()
        out["sd_" + ax] = np.interp(ref.t_s, track.t_s, track[f"joint_{c}_sd_m"])
    return out


def summary(err: dict[str, np.ndarray], mask: np.ndarray) -> dict[str, float]:
    h = np.hypot(err["n"][mask], err["e"][mask])
    res = {"rms_h_m": float(np.sqrt(np.mean(h ** 2))), "max_h_m": float(np.max(h)),
           "rms_v_m": float(np.sqrt(np.mean(err["u"][mask] ** 2))),
           "mean_v_m": float(np.mean(err["u"][mask]))}
    for i, ax in enumerate("neu"):
        s2 = err["sd_" + ax][mask] ** 2 + REF_SD[i] ** 2
        res["nees_" + ax] = float(np.mean(err[ax][mask] ** 2 / s2))
        res["rms_sd_" + ax + "_m"] = float(np.sqrt(np.mean(err["sd_" + ax][mask] ** 2)))
    return res


def corrections(summary_: dict) -> dict[str, float]:
    c = summary_.get("corrections", {})
    return {k: float(v["value"]) for k, v in c.items()
            if k in ("baro_scale", "baro_offset_m", "heading_bias_deg", "tas_scale",
                     "pitch_bias_deg") and v.get("value") is not None}


def gps_latency_s() -> float:
    """The GPS fixes' latency [s]: the joint's GNSS clock offset with every fix used."""
    j = run_joint(clean_flight(load(False)))
    return float(j.summary["clock_offsets_s"]["gnss"]["value"])


def recorder_only(latency_s: float) -> dict:
    flight = load(True)
    clean = clean_flight(flight)
    ref = gps_reference(load(False), clean, latency_s)
    t0 = time.perf_counter()
    j = run_joint(clean)
    err = joint_errors(j.track, ref)
    res = {"joint": summary(err, np.ones(len(ref), bool)),
           "time_s": time.perf_counter() - t0, "corrections": corrections(j.summary)}
    res["dr_linear"] = dr_linear_errors(clean, ref)
    res["ratio_to_dr"] = res["joint"]["rms_h_m"] / res["dr_linear"]["rms_h_m"]
    return res


def dr_linear_errors(clean: CleanFlight, ref: pd.DataFrame) -> dict[str, float]:
    """RMS and largest horizontal error of dead reckoning with its linear end correction
    (:func:`flightrecon.methods.baselines.dead_reckoning`) against ``ref`` (``t_s``, ``n``,
    ``e``)."""
    dr = dead_reckoning(clean, corrected=True)
    ok = np.isfinite(dr.north_m.to_numpy(float))
    dn = np.interp(ref.t_s, dr.t_s[ok], dr.north_m[ok]) - ref.n
    de = np.interp(ref.t_s, dr.t_s[ok], dr.east_m[ok]) - ref.e
    h = np.hypot(dn, de)
    return {"rms_h_m": float(np.sqrt(np.mean(h ** 2))), "max_h_m": float(np.max(h))}


def gap_windows(ref: pd.DataFrame) -> list[tuple[float, float]]:
    """Gaps of GAPS_S in the middle of the airborne fixes, 240 s of GPS between them."""
    t = ref.t_s.to_numpy()
    total = sum(GAPS_S) + 240.0 * (len(GAPS_S) - 1)
    start = 0.5 * (t[0] + t[-1]) - 0.5 * total
    out = []
    for L in GAPS_S:
        out.append((start, start + L))
        start += L + 240.0
    return out


def with_gaps(flight: Flight, gaps: list[tuple[float, float]]) -> Flight:
    d = flight.data.copy()
    cols = [c for c in d.columns if c.startswith("gnss_")]
    for a, b in gaps:
        m = (d.t_s >= a) & (d.t_s <= b)
        d.loc[m, cols] = np.nan
    return replace(flight, data=d)


def dr_in_gap(clean: CleanFlight, ref: pd.DataFrame, a: float, b: float,
              fixes: pd.DataFrame | None = None) -> np.ndarray:
    """Dead reckoning through a gap from the last fix before it, with the wind of the minute
    before it (mean of GPS velocity minus TAS vector); horizontal error against ``ref`` (the
    truth: columns ``t_s``, ``n``, ``e``, and ``vn``, ``ve`` where ``fixes`` is not given) at
    its samples inside the gap.  ``fixes``: the GNSS fixes the wind and the start come from
    (default ``ref``, when the truth is the GPS itself)."""
    fixes = ref if fixes is None else fixes
    g = clean.grid
    t = g.t_s.to_numpy(float)
    psi = np.radians(g.heading_deg.to_numpy(float))
    tas = g.tas_mps.to_numpy(float)
    va = np.c_[tas * np.cos(psi), tas * np.sin(psi)]
    before = fixes[(fixes.t_s >= a - 60.0) & (fixes.t_s < a)]
    air = np.c_[np.interp(before.t_s, t, va[:, 0]), np.interp(before.t_s, t, va[:, 1])]
    w = np.nanmean(np.c_[before.vn, before.ve] - air, axis=0)
    last = fixes[fixes.t_s < a].iloc[-1]
    k = (t >= last.t_s) & (t <= b + 1.0)
    tk = t[k]
    v = va[k] + w
    pos = np.c_[last.n + np.r_[0.0, np.cumsum(0.5 * (v[1:, 0] + v[:-1, 0]) * np.diff(tk))],
                last.e + np.r_[0.0, np.cumsum(0.5 * (v[1:, 1] + v[:-1, 1]) * np.diff(tk))]]
    inside = ref[(ref.t_s >= a) & (ref.t_s <= b)]
    dn = np.interp(inside.t_s, tk, pos[:, 0]) - inside.n
    de = np.interp(inside.t_s, tk, pos[:, 1]) - inside.e
    return np.hypot(dn, de).to_numpy()


def gnss_gaps(latency_s: float) -> dict:
    full = load(False)
    clean_full = clean_flight(full)
    ref = gps_reference(full, clean_full, latency_s)
    gaps = gap_windows(ref)
    clean = clean_flight(with_gaps(full, gaps))
    t0 = time.perf_counter()
    j = run_joint(clean)
    err = joint_errors(j.track, ref)
    res: dict = {"time_s": time.perf_counter() - t0, "gaps": []}
    for (a, b), L in zip(gaps, GAPS_S):
        m = ((ref.t_s >= a) & (ref.t_s <= b)).to_numpy()
        s = summary(err, m)
        h_dr = dr_in_gap(clean_full, ref, a, b)
        s["dr_wind_rms_h_m"] = float(np.sqrt(np.mean(h_dr ** 2)))
        s["ratio_to_dr"] = s["rms_h_m"] / s["dr_wind_rms_h_m"]
        res["gaps"].append({"length_s": L, "t0_s": a, "t1_s": b, **s})
    out_of_gaps = np.ones(len(ref), bool)
    for a, b in gaps:
        out_of_gaps &= ~((ref.t_s >= a) & (ref.t_s <= b)).to_numpy()
    res["with_gps"] = summary(err, out_of_gaps)
    res["corrections"] = corrections(j.summary)
    return res


def markdown(r: dict) -> str:
    ro = r["recorder_only"]
    j = ro["joint"]
    lines = ["# 1 Hz glass-cockpit export: recorder only and GNSS gaps",
             "", f"`{LOG.relative_to(ROOT)}`, against its own GPS (`scripts/onehz_study.py`; "
             f"fixes taken {r['gps_latency_s']:.3f} s after their stamps: the joint's GNSS clock "
             "offset with every fix).", "",
             "## Recorder only (GPS withheld, both stands from the GPS)", "",
             "| | horizontal RMS (max) [m] | vertical RMS (mean) [m] | NEES n / e / u |",
             "|---|---|---|---|",
             f"| joint | {j['rms_h_m']:.0f} ({j['max_h_m']:.0f}) | {j['rms_v_m']:.1f} "
             f"({j['mean_v_m']:+.1f}) | {j['nees_n']:.2f} / {j['nees_e']:.2f} / "
             f"{j['nees_u']:.2f} |",
             f"| dead reckoning, linear end correction | {ro['dr_linear']['rms_h_m']:.0f} "
             f"({ro['dr_linear']['max_h_m']:.0f}) | | |", "",
             f"joint / dead reckoning: **{ro['ratio_to_dr']:.2f}**; joint's sensor corrections: "
             + ", ".join(f"{k} {v:+.4g}" for k, v in ro["corrections"].items()), "",
             "## GNSS gaps (GPS used outside them)", "",
             "| gap [s] | joint RMS (max) [m] | dead reckoning, wind of the minute before [m] | "
             "ratio | vertical RMS [m] | NEES n / e / u |", "|---|---|---|---|---|---|"]
    for g in r["gaps"]["gaps"]:
        lines.append(f"| {g['length_s']:.0f} | {g['rms_h_m']:.0f} ({g['max_h_m']:.0f}) | "
                     f"{g['dr_wind_rms_h_m']:.0f} | {g['ratio_to_dr']:.2f} | {g['rms_v_m']:.1f} | "
                     f"{g['nees_n']:.2f} / {g['nees_e']:.2f} / {g['nees_u']:.2f} |")
    w = r["gaps"]["with_gps"]
    lines += ["", f"Outside the gaps: {w['rms_h_m']:.1f} m RMS horizontal, {w['rms_v_m']:.1f} m "
              f"vertical, NEES {w['nees_n']:.2f} / {w['nees_e']:.2f} / {w['nees_u']:.2f} "
              f"(reference sd {REF_SD[0]:.0f} m horizontal, {REF_SD[2]:.0f} m vertical per axis "
              "added to the joint's).", ""]
    return "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--tag", default="", help="suffix of the output files (onehz_<tag>.json)")
    ap.add_argument("--only", choices=("recorder", "gaps"), default=None)
    args = ap.parse_args()
    lat = gps_latency_s()
    r: dict = {"gps_latency_s": lat}
    if args.only in (None, "recorder"):
        r["recorder_only"] = recorder_only(lat)
        print(json.dumps(r["recorder_only"], indent=1))
    if args.only in (None, "gaps"):
        r["gaps"] = gnss_gaps(lat)
        print(json.dumps(r["gaps"], indent=1))
    name = "onehz" + (f"_{args.tag}" if args.tag else "")
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / f"{name}.json").write_text(json.dumps({"command": command_line(), **r}, indent=1)
                                         + "\n")
    if len(r) == 3:
        (OUT / f"{name}.md").write_text(header() + markdown(r))


if __name__ == "__main__":
    main()
