"""Plausibility checks on a cleaned flight, before any estimation.

Each check returns findings (a small dict: ``check``, ``channel``, ``severity``, ``message``
and the affected time spans in ``t_s``); the pipeline puts them in the summary and turns them
into warnings.  Values that cannot be physical at all are already errors at ingest
(:mod:`flightrecon.ingest.validate`); these are the defects that leave a readable but suspect
record.  Thresholds are arguments with documented defaults (docs/signals.md, "Plausibility").

=====================  ========================================================================
check                  rule (defaults)
=====================  ========================================================================
frozen_channel         an input channel exactly constant for >= 120 s while airborne (a stuck
                       sensor or a recorder repeating its last word)
dead_channel           an input channel constant over the whole record, or over all of the
                       flight (stuck): dropped by the cleaning, treated as absent
                       (:mod:`flightrecon.cleaning.dead`)
out_of_envelope        |roll| > 70 deg, |pitch| > 35 deg, n_norm outside [-1, 3.5] g while
                       airborne (possible, but not in transport operations: look at it)
below_stall            true airspeed < 25 m/s for >= 5 s while airborne
time_jump              a step of the recorder's time stamps > 10 s (data missing in between)
endpoint_far           departure / arrival > 5 km from the first / last GNSS fix on the ground,
                       or the departure field's pressure altitude > 300 m from the recorded
                       pressure altitude before lift-off
=====================  ========================================================================
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pandas as pd
from pyproj import Geod

from flightrecon.geo.atmosphere import field_pressure_altitude_m
from flightrecon.types import CleanFlight

CONTINUOUS = ("n_long_g", "n_lat_g", "n_norm_g", "roll_deg", "pitch_deg", "heading_deg",
              "tas_mps", "baro_alt_m")


def time_spans(t: np.ndarray, mask: np.ndarray, min_len_s: float = 0.0) -> list[list[float]]:
    """Time spans [start, end] where ``mask`` holds for at least ``min_len_s``."""
    if not mask.any():
        return []
    m = np.concatenate([[False], mask, [False]]).astype(np.int8)
    d = np.diff(m)
    starts, ends = np.flatnonzero(d == 1), np.flatnonzero(d == -1) - 1
    out = []
    for a, b in zip(starts, ends):
        if t[b] - t[a] >= min_len_s:
            out.append([float(t[a]), float(t[b])])
    return out


def _finding(check: str, channel: str, message: str, spans=None) -> dict[str, Any]:
    return {"check": check, "channel": channel, "severity": "warning", "message": message,
            "spans_s": spans or []}


def _airborne(clean: CleanFlight) -> np.ndarray:
    t = clean.grid["t_s"].to_numpy(float)
    ph = clean.phases
    if ph is None:
        return np.ones(len(t), bool)
    lo = ph.liftoff_t_s if np.isfinite(ph.liftoff_t_s) else -np.inf
    td = ph.touchdown_t_s if np.isfinite(ph.touchdown_t_s) else np.inf
    return (t > lo) & (t < td)


def frozen_channels(clean: CleanFlight, min_s: float = 120.0) -> list[dict[str, Any]]:
    """Input channels exactly constant for ``min_s`` or more while airborne; dead channels."""
    g = clean.grid
    t = g["t_s"].to_numpy(float)
    air = _airborne(clean)
    out = [_finding("dead_channel", e["channel"], e["why"]) for e in clean.report
           if e.get("action") == "dead_channel"]
    for ch in CONTINUOUS:
        if ch not in g.columns:
            continue
        x = g[ch].to_numpy(float)
        ok = np.isfinite(x)
        if ok.sum() > 1 and np.nanmax(x) == np.nanmin(x):
            out.append(_finding("dead_channel", ch, f"{ch} never changes over the whole record "
                                f"(value {np.nanmin(x):g}): a dead or disconnected sensor"))
            continue
        same = np.zeros(len(x), bool)
        same[1:] = (np.diff(x) == 0.0) & ok[1:] & ok[:-1]
        spans = time_spans(t, same & air, min_s)
        if spans:
            out.append(_finding("frozen_channel", ch, f"{ch} exactly constant for "
                                f"{sum(b - a for a, b in spans):.0f} s while airborne: a stuck "
                                "sensor or a repeated recorder word", spans))
    return out


def envelope(clean: CleanFlight, max_roll_deg: float = 70.0, max_pitch_deg: float = 35.0,
             n_norm_range: tuple[float, float] = (-1.0, 3.5), min_tas_mps: float = 25.0,
             min_stall_s: float = 5.0) -> list[dict[str, Any]]:
    """Attitude and load factors outside the transport envelope; airspeed below stall."""
    g = clean.grid
    t = g["t_s"].to_numpy(float)
    air = _airborne(clean)
    out = []
    tests = []
    if "roll_deg" in g.columns:
        tests.append(("roll_deg", np.abs(g["roll_deg"].to_numpy(float)) > max_roll_deg,
                      f"|roll| above {max_roll_deg:g} deg"))
    if "pitch_deg" in g.columns:
        tests.append(("pitch_deg", np.abs(g["pitch_deg"].to_numpy(float)) > max_pitch_deg,
                      f"|pitch| above {max_pitch_deg:g} deg"))
    if "n_norm_g" in g.columns:
        n = g["n_norm_g"].to_numpy(float)
        tests.append(("n_norm_g", (n < n_norm_range[0]) | (n > n_norm_range[1]),
                      f"normal load factor outside [{n_norm_range[0]:g}, {n_norm_range[1]:g}] g"))
    for ch, bad, what in tests:
        spans = time_spans(t, bad & air, 0.0)
        if spans:
            out.append(_finding("out_of_envelope", ch, f"{what} while airborne", spans))
    if "tas_mps" in g.columns:
        slow = (g["tas_mps"].to_numpy(float) < min_tas_mps) & air
        spans = time_spans(t, slow, min_stall_s)
        if spans:
            out.append(_finding("below_stall", "tas_mps", f"true airspeed below {min_tas_mps:g} "
                                "m/s while airborne: airspeed channel suspect, or the lift-off / "
                                "touchdown detection is wrong", spans))
    return out


def time_jumps(clean: CleanFlight, max_step_s: float = 10.0) -> list[dict[str, Any]]:
    """Recorder time stamps that jump forward by more than ``max_step_s`` (input channels are
    invalid across it; the cleaning report says which)."""
    g = clean.grid
    t = g["t_s"].to_numpy(float)
    valid_cols = [c for c in g.columns if c.endswith("_valid")]
    if not valid_cols or len(t) < 2:
        return []
    any_valid = g[valid_cols].to_numpy(bool).any(axis=1)
    spans = time_spans(t, ~any_valid, max_step_s)
    if not spans:
        return []
    return [_finding("time_jump", "t_s", f"no input data for {len(spans)} span(s) longer than "
                     f"{max_step_s:g} s", spans)]


def endpoints(clean: CleanFlight, max_km: float = 5.0, max_alt_m: float = 300.0
              ) -> list[dict[str, Any]]:
    """Departure / arrival far from where the data say the flight began or ended."""
    meta = clean.meta
    out = []
    geod = Geod(ellps="WGS84")
    gn = clean.gnss
    if len(gn) and {"gnss_lat_deg", "gnss_lon_deg"} <= set(gn.columns):
        for which, pos, row in (("departure", meta.departure, gn.iloc[0]),
                                ("arrival", meta.arrival, gn.iloc[-1])):
            if pos is None:
                continue
            _, _, d = geod.inv(pos.lon_deg, pos.lat_deg, float(row["gnss_lon_deg"]),
                               float(row["gnss_lat_deg"]))
            if d > max_km * 1000.0:
                out.append(_finding("endpoint_far", which, f"the {which} airfield is "
                                    f"{d / 1000:.1f} km from the {'first' if which == 'departure' else 'last'}"
                                    " GNSS fix: wrong airfield, or the record is cut in the air",
                                    [[float(row["t_s"]), float(row["t_s"])]]))
    g = clean.grid
    ph = clean.phases
    if meta.departure is not None and "baro_alt_m" in g.columns and ph is not None \
            and np.isfinite(ph.liftoff_t_s) and not ph.starts_airborne:
        h_field = field_pressure_altitude_m(meta.departure.elev_m, meta.qnh_departure_hpa)
        before = g["t_s"].to_numpy(float) < ph.liftoff_t_s
        h = np.nanmedian(g["baro_alt_m"].to_numpy(float)[before]) if before.any() else np.nan
        if np.isfinite(h) and abs(h - h_field) > max_alt_m:
            out.append(_finding("endpoint_far", "baro_alt_m", f"pressure altitude on the ground "
                                f"before lift-off {h:.0f} m, but the departure airfield's is "
                                f"{h_field:.0f} m: wrong airfield elevation or QNH, or a baro "
                                "offset"))
    return out


def plausibility_checks(clean: CleanFlight) -> list[dict[str, Any]]:
    """Every check above, in order."""
    return (frozen_channels(clean) + envelope(clean) + time_jumps(clean) + endpoints(clean))


def findings_table(findings: list[dict[str, Any]]) -> pd.DataFrame:
    """Findings as a table (for notebooks)."""
    return pd.DataFrame(findings, columns=["check", "channel", "severity", "message", "spans_s"])
