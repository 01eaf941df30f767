"""Ground impact at the end of a record (docs/signals.md, "Impact").

An accident record ends at the impact: the recorder loses power or its data within a fraction
of a second of the first contact.  The impact is told apart from a landing (even a firm one)
by what the record does at its very end::

    within the last ``end_window_s`` (3 s) of the record, a jolt: the load vector
    n = (n_long, n_lat, n_norm) changes by at least ``jump_g`` (1.5 g) from one sample to the
    next with |n| at least ``peak_g`` (2.5 g) on one of the two, or a load factor reads at the
    recorder's range (:mod:`flightrecon.cleaning.saturation`; a clipped impact can even lower
    |n|: the change of the vector, not its magnitude, is the test);
    and the aircraft came down onto it:
      * the pressure altitude fell at ``sink_mps`` (5 m/s) or more over the ``pre_s`` (3 s)
        before the jolt (a straight line fitted to the recorded pressure altitude), or the
        airspeed at the jolt was still at least ``airborne_mps`` (20 m/s) (the record ends
        within ``end_window_s`` of it: no roll-out; a landing's record runs on while the
        aircraft decelerates on the runway);
    and, where the departure and arrival (the wreckage) elevations are known, the pressure
    height above the end point at the jolt (pressure altitude minus the one at the start of
    the record on the departure field, less the elevation difference) is below
    ``max_height_m`` (300 m: a load spike at altitude is an in-flight break-up or a recorder
    fault, not an impact with the ground).

A crash sequence (a tumble or bounces along the ground before the record stops) is followed
back from that jolt: an earlier jolt (or saturated load) within ``chain_height_m`` (30 m) of
the final pressure altitude and at most ``chain_gap_s`` (10 s: a bounce to 40 m and back
takes about 6 s) before the last one found is part of it, within ``max_sequence_s`` (60 s)
of the record's last jolt, and the impact is the sequence's first.  A touchdown the phase detection placed inside
or after the sequence (the gear touching in the tumble) is no landing: it is removed
(:func:`with_impact`, reported).

A firm landing has |n| of 1.5-2.5 g at a sink rate of 1-3.5 m/s and a record that continues
through the roll-out: its touchdown is not in the record's last seconds.  The impact time is
the first jolting (or saturated) sample of the last ``end_window_s``; the peak loads are the
extremes of each load factor from there to the end of the record (a saturated component's
true peak is at least the reading: reported as such), ``pre_load_g`` the median |n| over the
``pre_s`` before it.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from flightrecon.cleaning.report import report_entry
from flightrecon.cleaning.saturation import LOAD_FACTORS
from flightrecon.types import FlightMeta, FlightPhases

__all__ = ["Impact", "ImpactSettings", "detect_impact", "with_impact"]


@dataclass(frozen=True)
class ImpactSettings:
    """Thresholds of the impact rule (module docstring)."""

    end_window_s: float = 3.0
    pre_s: float = 3.0
    jump_g: float = 1.5
    peak_g: float = 2.5
    sink_mps: float = 5.0
    airborne_mps: float = 20.0
    max_height_m: float = 300.0
    chain_gap_s: float = 10.0
    max_sequence_s: float = 60.0
    chain_height_m: float = 30.0


@dataclass(frozen=True)
class Impact:
    """A detected impact.

    Attributes
    ----------
    t_s : time of the first impact sample [s]
    peak_load_g : largest |n| from ``t_s`` to the end of the record [g]
    peak_n_long_g, peak_n_lat_g, peak_n_norm_g : each load factor's extreme there (signed) [g]
    saturated : load factors whose reading there reached the recorder's range (their true
        peak is at least the reading)
    pre_load_g : median |n| before the impact [g]
    sink_rate_mps : descent rate of the pressure altitude before the impact [m/s] (NaN: none)
    tas_mps : airspeed at the impact [m/s] (NaN: not recorded)
    height_above_end_m : pressure height above the end point at the impact [m] (NaN: unknown)
    record_end_t_s : the record's last sample [s]
    """

    t_s: float
    peak_load_g: float
    peak_n_long_g: float
    peak_n_lat_g: float
    peak_n_norm_g: float
    saturated: tuple[str, ...]
    pre_load_g: float
    sink_rate_mps: float
    tas_mps: float
    height_above_end_m: float
    record_end_t_s: float


def _col(grid: pd.DataFrame, name: str) -> np.ndarray | None:
    if name not in grid.columns:
        return None
    v = grid[name].to_numpy(float)
    return v if np.isfinite(v).any() else None


def _sink_rate(t: np.ndarray, hp: np.ndarray | None, t0: float, t1: float) -> float:
    """Descent rate [m/s] (positive down) of a line fitted to the pressure altitude on
    [t0, t1]; NaN with fewer than two samples."""
    if hp is None:
        return float("nan")
    sel = (t >= t0) & (t <= t1) & np.isfinite(hp)
    if sel.sum() < 2 or np.ptp(t[sel]) <= 0.0:
        return float("nan")
    return -float(np.polyfit(t[sel] - t[sel][0], hp[sel], 1)[0])


def _height_above_end(grid: pd.DataFrame, meta: FlightMeta | None, phases: FlightPhases | None,
                      hp_imp: float) -> float:
    """Pressure height above the arrival point (the wreckage) at the impact [m]: the pressure
    altitude there minus the one on the departure field (the first 10 s of a record that starts
    on the ground), less the elevation difference; NaN where either is unknown."""
    if (meta is None or meta.departure is None or meta.arrival is None or phases is None
            or phases.starts_airborne or not np.isfinite(hp_imp)):
        return float("nan")
    t = grid["t_s"].to_numpy(float)
    hp = grid["baro_alt_m"].to_numpy(float)
    first = (t <= t[0] + 10.0) & np.isfinite(hp)
    if not first.any():
        return float("nan")
    return float(hp_imp - np.median(hp[first])
                 - (meta.arrival.elev_m - meta.departure.elev_m))


def detect_impact(grid: pd.DataFrame, phases: FlightPhases | None = None,
                  meta: FlightMeta | None = None,
                  settings: ImpactSettings = ImpactSettings()
                  ) -> tuple[Impact | None, list[dict]]:
    """The impact at the end of the record, if there is one (module docstring).

    Parameters
    ----------
    grid : the cleaned grid (load factors, pressure altitude, airspeed; ``<channel>_saturated``
        where :func:`flightrecon.cleaning.saturation.saturation_on_grid` found any)
    phases : the detected phases (for the start on the departure field)
    meta : the flight's metadata (departure and arrival elevations)

    Returns
    -------
    (Impact or None, report entries): one ``impact`` entry with the numbers when detected, one
    ``no_impact`` entry saying which rule failed when the record ends with a load spike that is
    not an impact.
    """
    cols = [_col(grid, c) for c in LOAD_FACTORS]
    if any(c is None for c in cols) or len(grid) < 3:
        return None, []
    t = grid["t_s"].to_numpy(float)
    nl, nt, nn = (np.asarray(c) for c in cols)
    mag = np.sqrt(nl ** 2 + nt ** 2 + nn ** 2)
    s = settings
    t_end = float(t[-1])
    fin = np.isfinite(mag)
    hp = _col(grid, "baro_alt_m")
    k0 = _first_jolt(grid, t, (nl, nt, nn), mag, hp, s)
    if k0 is None:
        return None, []
    t_imp = float(t[k0])
    pre_sel = (t >= t_imp - s.pre_s - 0.25) & (t < t_imp - 0.25) & fin
    pre = float(np.median(mag[pre_sel])) if pre_sel.any() else float("nan")
    sink = _sink_rate(t, hp, t_imp - s.pre_s, t_imp - 0.25)
    tas_c = _col(grid, "tas_mps")
    tas = float(tas_c[k0]) if tas_c is not None and np.isfinite(tas_c[k0]) else float("nan")
    hp_imp = float("nan")
    if hp is not None:
        okh = np.flatnonzero(np.isfinite(hp[: k0 + 1]))
        hp_imp = float(hp[okh[-1]]) if len(okh) else float("nan")
    h_end = _height_above_end(grid, meta, phases, hp_imp)
    came_down = bool((np.isfinite(sink) and sink >= s.sink_mps)
                     or (np.isfinite(tas) and tas >= s.airborne_mps))
    low = not (np.isfinite(h_end) and h_end > s.max_height_m)
    peak_end = float(np.nanmax(mag[k0:]))
    if not (came_down and low):
        why = ("the load spike at the end of the record is not an impact: "
               + ("no descent onto it (pressure altitude falling at "
                  f"{sink:.1f} m/s < {s.sink_mps:g} m/s, airspeed {tas:.0f} m/s)"
                  if not came_down else
                  f"{h_end:.0f} m above the end point (> {s.max_height_m:g} m)"))
        return None, [report_entry("phases", "no_impact", why, count=1, t_s=[t_imp],
                                   peak_load_g=peak_end, pre_load_g=pre,
                                   sink_rate_mps=sink, tas_mps=tas, height_above_end_m=h_end)]
    peaks, satd = _peaks(grid, slice(k0, len(t)), (nl, nt, nn))
    peak_all = float(np.nanmax(mag[k0:]))
    imp = Impact(t_s=t_imp, peak_load_g=peak_all, peak_n_long_g=peaks[0], peak_n_lat_g=peaks[1],
                 peak_n_norm_g=peaks[2], saturated=tuple(satd), pre_load_g=pre,
                 sink_rate_mps=sink, tas_mps=tas, height_above_end_m=h_end,
                 record_end_t_s=t_end)
    return imp, [_impact_entry(imp)]


def _first_jolt(grid: pd.DataFrame, t: np.ndarray, loads: tuple[np.ndarray, ...],
                mag: np.ndarray, hp: np.ndarray | None, s: ImpactSettings) -> int | None:
    """Index of the impact's first sample (module docstring), ``None`` without a candidate:
    the first jolt (or saturated load) in the record's last ``end_window_s``, then back along
    the crash sequence to the earliest chain of jolts near the same pressure altitude."""
    nl, nt, nn = loads
    sat = np.zeros(len(t), bool)
    for c in LOAD_FACTORS:
        if f"{c}_saturated" in grid.columns:
            sat |= grid[f"{c}_saturated"].to_numpy(bool)
    fin = np.isfinite(mag)
    # the change of the load vector from the previous sample [g]
    dev = np.full(len(t), np.nan)
    dev[1:] = np.sqrt((nl[1:] - nl[:-1]) ** 2 + (nt[1:] - nt[:-1]) ** 2
                      + (nn[1:] - nn[:-1]) ** 2)
    big = np.maximum(mag, np.r_[np.nan, mag[:-1]])
    jolt = (dev >= s.jump_g) & (big >= s.peak_g)
    last = (t >= float(t[-1]) - s.end_window_s) & fin
    cand = np.flatnonzero(last & (jolt | sat))
    if not len(cand):
        return None
    k0 = int(cand[0])
    if hp is not None:   # back along a crash sequence: earlier jolts near the same height
        okh = np.isfinite(hp)
        hpf = np.interp(t, t[okh], hp[okh])
        h_last = hpf[int(cand[-1])]
        near = (jolt | sat) & fin & (np.abs(hpf - h_last) <= s.chain_height_m) \
            & (t >= t[int(cand[-1])] - s.max_sequence_s)
        seq = np.append(np.flatnonzero(near[:k0]), k0)
        brk = np.flatnonzero(np.diff(t[seq]) > s.chain_gap_s)
        k0 = int(seq[brk[-1] + 1] if len(brk) else seq[0])
    return k0


def _peaks(grid: pd.DataFrame, win: slice,
           loads: tuple[np.ndarray, ...]) -> tuple[list[float], list[str]]:
    """Per load factor the reading farthest from its level-flight value (1 g normal, 0 g the
    others) over ``win`` [g], and the load factors saturated there."""
    peaks = []
    satd = []
    for c, x in zip(LOAD_FACTORS, loads):
        seg = x[win]
        ref = 1.0 if c == "n_norm_g" else 0.0
        jj = int(np.nanargmax(np.abs(seg - ref)))
        peaks.append(float(seg[jj]))
        if f"{c}_saturated" in grid.columns and grid[f"{c}_saturated"].to_numpy(bool)[win].any():
            satd.append(c)
    return peaks, satd


def _impact_entry(imp: Impact) -> dict:
    """The cleaning report's ``impact`` entry for ``imp``."""
    sat_txt = (f"; saturated: {', '.join(imp.saturated)} (true peak at least the reading)"
               if imp.saturated else "")
    h_end = imp.height_above_end_m
    why = (f"ground impact: load jolt to |n| {imp.peak_load_g:.2f} g against "
           f"{imp.pre_load_g:.2f} g before{sat_txt}; descent {imp.sink_rate_mps:.1f} m/s, "
           f"airspeed {imp.tas_mps:.0f} m/s"
           + (f", {h_end:.0f} m above the end point" if np.isfinite(h_end) else "")
           + f"; record ends {imp.record_end_t_s - imp.t_s:.2f} s later")
    return report_entry("phases", "impact", why, count=1, t_s=[imp.t_s],
                        peak_n_long_g=imp.peak_n_long_g, peak_n_lat_g=imp.peak_n_lat_g,
                        peak_n_norm_g=imp.peak_n_norm_g, saturated=",".join(imp.saturated),
                        record_end_t_s=imp.record_end_t_s, peak_load_g=imp.peak_load_g,
                        pre_load_g=imp.pre_load_g, sink_rate_mps=imp.sink_rate_mps,
                        tas_mps=imp.tas_mps, height_above_end_m=h_end)


def with_impact(grid: pd.DataFrame, phases: FlightPhases | None, meta: FlightMeta | None,
                settings: ImpactSettings = ImpactSettings()
                ) -> tuple[FlightPhases | None, list[dict]]:
    """``phases`` with the impact's time and peak load (``impact_t_s``,
    ``impact_peak_load_g``) from :func:`detect_impact`, and its report entries."""
    imp, rep = detect_impact(grid, phases, meta, settings)
    if imp is None or phases is None:
        return phases, rep
    td = phases.touchdown_t_s
    if np.isfinite(td) and td >= imp.t_s:
        rep.append(report_entry("phases", "touchdown_removed", f"the touchdown at {td:.2f} s "
                                f"lies in the crash sequence that starts at {imp.t_s:.2f} s: "
                                "a contact of the impact, not a landing", count=1, t_s=[td]))
        td = float("nan")
    return replace(phases, impact_t_s=imp.t_s, impact_peak_load_g=imp.peak_load_g,
                   touchdown_t_s=td), rep
