"""Events of a reconstructed flight, the way an investigator lists them.

Lift-off and touchdown (from the cleaning's phase detection), the ground impact that ends an
accident record (detected by the cleaning from the loads: :mod:`flightrecon.cleaning.impact`,
with its time and peak loads) or the end of a record in the air, exceedances of a flight
envelope (load factor, attitude, airspeed), sensor outages (long gaps left unfilled by the
cleaning), gaps between GNSS fixes or radar plots, changes of the source of the default result,
the measurements used, and the spans where the joint smoother rejected a source.

Every event is a small :class:`Event` with the time in seconds from the flight's UTC epoch
(``t_s``) and, for a span, its end; :func:`events_table` turns them into JSON-ready rows with
the UTC time.  The detection reads the cleaned flight, the combined track and the per-method
status; it never changes them.

The envelope defaults (:class:`Envelope`) are generic and stated, not aircraft-specific:

* limit load factors +2.5 g / -1.0 g (transport category, CS/FAR 25.337 with flaps up);
* the airplane-upset attitude of the Airplane Upset Recovery Training Aid: pitch above 25 deg
  nose up or below 10 deg nose down, or bank beyond 45 deg;
* an airspeed limit only when given (``vmo_mps``: no type is assumed).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass
from datetime import UTC, datetime, timedelta
from typing import Any

import numpy as np
import pandas as pd

#: event kinds, in the order a reader scans them
KINDS = ("liftoff", "touchdown", "end_airborne", "impact", "exceedance", "outage", "gap",
         "source_change", "fixes", "rejected")


@dataclass(frozen=True)
class Envelope:
    """Limits whose exceedance is reported as an event (module docstring for the defaults).

    Attributes
    ----------
    n_max_g, n_min_g : normal load factor limits [g]
    pitch_up_deg, pitch_down_deg : pitch attitude limits, nose up / nose down (positive) [deg]
    bank_deg : bank angle limit [deg]
    vmo_mps : maximum operating true airspeed [m/s] (``None``: not checked)
    min_duration_s : shortest exceedance reported [s]
    """

    n_max_g: float = 2.5
    n_min_g: float = -1.0
    pitch_up_deg: float = 25.0
    pitch_down_deg: float = 10.0
    bank_deg: float = 45.0
    vmo_mps: float | None = None
    min_duration_s: float = 0.5


SEVERITIES: tuple[str, ...] = ("info", "caution", "alert")
"""The events' levels, least to most pressing: ``alert`` for what the aircraft did that an
investigator looks at first (an exceedance of the envelope, an impact, a record that ends in a
dive), ``caution`` for what limits the reconstruction there (an outage, a gap, a change of
source), ``info`` for the rest.  Not "warning": that word is the tool's own doubts about the
data or a method (the summary's ``warnings``, the console's ``warning:`` lines)."""


@dataclass(frozen=True)
class Event:
    """One event: ``t_s`` (and ``end_t_s`` for a span) in seconds from the UTC epoch.

    ``label`` is the short text drawn on the plots, ``detail`` the sentence of the table,
    ``severity`` one of :data:`SEVERITIES`; ``value`` the peak of an exceedance.
    """

    kind: str
    t_s: float
    label: str
    detail: str
    end_t_s: float | None = None
    severity: str = "info"
    channel: str | None = None
    value: float | None = None


def _spans(t: np.ndarray, mask: np.ndarray) -> list[tuple[int, int]]:
    """Index pairs ``(i0, i1)`` (inclusive) of the runs of True in ``mask``."""
    if not mask.any():
        return []
    m = np.concatenate(([False], mask, [False]))
    d = np.diff(m.astype(np.int8))
    starts = np.flatnonzero(d == 1)
    ends = np.flatnonzero(d == -1) - 1
    return list(zip(starts.tolist(), ends.tolist()))


def _col(df: pd.DataFrame, name: str) -> np.ndarray | None:
    if name in df.columns:
        v = df[name].to_numpy(dtype=float)
        if np.isfinite(v).any():
            return v
    return None


def phase_events(phases: Any, t0_s: float | None = None) -> list[Event]:
    """Lift-off and touchdown from :class:`~flightrecon.types.FlightPhases` (or its dict); a
    record that starts in the air gets a caution at its first sample ``t0_s``."""
    if phases is None:
        return []
    ph = phases if isinstance(phases, Mapping) else asdict(phases)
    out = []
    lo, td = ph.get("liftoff_t_s"), ph.get("touchdown_t_s")
    if lo is not None and np.isfinite(lo):
        out.append(Event("liftoff", float(lo), "lift-off", "lift-off (main wheels leave the "
                         "ground), detected by the cleaning from loads and air data"))
    elif ph.get("starts_airborne") and t0_s is not None:
        out.append(Event("liftoff", float(t0_s), "starts airborne",
                         "the record starts in the air: no lift-off in the record",
                         severity="caution"))
    if td is not None and np.isfinite(td):
        out.append(Event("touchdown", float(td), "touchdown",
                         "touchdown (sink rate arrested), detected by the cleaning"))
    return [e for e in out if np.isfinite(e.t_s)]


def _impact_entry(report: Sequence[Mapping[str, Any]]) -> Mapping[str, Any] | None:
    for r in report:
        if r.get("action") == "impact":
            return r
    return None


def end_of_record_events(grid: pd.DataFrame, phases: Any,
                         report: Sequence[Mapping[str, Any]] = (),
                         window_s: float = 10.0, sink_mps: float = 10.0,
                         load_g: float = 3.0) -> list[Event]:
    """The end of the record: the *impact* detected by the cleaning
    (:mod:`flightrecon.cleaning.impact`: ``phases.impact_t_s``, the peak loads from its report
    entry in ``report``), at its first sample; otherwise, for a record that ends in the air, an
    ``end_airborne`` event: a warning when, over its last ``window_s`` seconds, the descent is
    steeper than ``sink_mps`` or the normal load factor leaves 1 +- (``load_g``-1) g (an impact
    the loads do not show, or a record cut in an upset), a caution otherwise (recorder stopped,
    power lost, record cut).  The descent is taken from the recorded pressure altitude (a line
    fitted over the window), a measurement, not from an estimated track."""
    if phases is None:
        return []
    ph = phases if isinstance(phases, Mapping) else asdict(phases)
    t = grid["t_s"].to_numpy(float)
    t_end = float(t[-1])
    t_imp = ph.get("impact_t_s")
    if t_imp is not None and np.isfinite(t_imp):
        peak = float(ph.get("impact_peak_load_g", float("nan")))
        r = _impact_entry(report) or {}
        comps = ", ".join(f"{c} {r[f'peak_{c}']:+.2f} g" for c in ("n_long_g", "n_lat_g",
                                                                  "n_norm_g")
                          if isinstance(r.get(f"peak_{c}"), float))
        sat = r.get("saturated") or ""
        detail = (f"ground impact detected from the loads: peak |n| {peak:.2f} g"
                  + (f" ({comps})" if comps else "")
                  + (f", {sat} at the recorder's range (true peak at least that)" if sat else "")
                  + (f"; descent {r['sink_rate_mps']:.1f} m/s" if isinstance(
                      r.get("sink_rate_mps"), float) and np.isfinite(r["sink_rate_mps"]) else "")
                  + (f", airspeed {r['tas_mps']:.0f} m/s" if isinstance(
                      r.get("tas_mps"), float) and np.isfinite(r["tas_mps"]) else "")
                  + f"; the record ends {t_end - float(t_imp):.2f} s later")
        return [Event("impact", float(t_imp), f"impact {peak:.1f} g"
                      + (" (saturated)" if sat else ""), detail, end_t_s=t_end,
                      severity="alert", channel="n_norm_g", value=peak)]
    if not ph.get("ends_airborne"):
        return []
    last = t >= t_end - window_s
    reasons = []
    n = _col(grid, "n_norm_g")
    if n is not None and np.isfinite(n[last]).any():
        peak = float(np.nanmax(np.abs(n[last] - 1.0)))
        if peak + 1.0 >= load_g:
            reasons.append(f"normal load factor reaches {1 + peak:.1f} g")
    # the descent from the recorded pressure altitude (a measurement, not an estimate)
    hp = _col(grid, "baro_alt_m")
    if hp is not None:
        sel = last & np.isfinite(hp)
        if sel.sum() >= 2:
            tt, hh = t[sel], hp[sel]
            rate = float(np.polyfit(tt - tt[0], hh, 1)[0]) if tt[-1] > tt[0] else 0.0
            if rate <= -sink_mps:
                reasons.append(f"pressure altitude falling at {-rate:.0f} m/s")
    if reasons:
        return [Event("end_airborne", t_end, "record ends in an upset",
                      "record ends in the air with " + " and ".join(reasons)
                      + f" in its last {window_s:g} s; no impact detected in the loads "
                      "(no load spike at the end): a possible impact the recorder missed",
                      severity="alert")]
    return [Event("end_airborne", t_end, "record ends airborne",
                  "record ends in the air (no touchdown in the record)", severity="caution")]


def _merge_runs(t: np.ndarray, runs: list[tuple[int, int]], join_s: float
                ) -> list[tuple[int, int]]:
    out: list[tuple[int, int]] = []
    for i0, i1 in runs:
        if out and t[i0] - t[out[-1][1]] <= join_s:
            out[-1] = (out[-1][0], i1)
        else:
            out.append((i0, i1))
    return out


def exceedance_events(grid: pd.DataFrame, envelope: Envelope = Envelope()) -> list[Event]:
    """Spans where the recorded load factor, attitude or airspeed leaves the ``envelope``."""
    t = grid["t_s"].to_numpy(float)
    checks: list[tuple[str, str, np.ndarray, np.ndarray, str, str]] = []
    n = _col(grid, "n_norm_g")
    if n is not None:
        checks.append(("n_norm_g", "load factor", n, n > envelope.n_max_g, "g",
                       f"above the limit {envelope.n_max_g:+g} g"))
        checks.append(("n_norm_g", "load factor", n, n < envelope.n_min_g, "g",
                       f"below the limit {envelope.n_min_g:+g} g"))
    p = _col(grid, "pitch_deg")
    if p is not None:
        checks.append(("pitch_deg", "pitch", p, p > envelope.pitch_up_deg, "deg",
                       f"more than {envelope.pitch_up_deg:g} deg nose up (upset attitude)"))
        checks.append(("pitch_deg", "pitch", p, p < -envelope.pitch_down_deg, "deg",
                       f"more than {envelope.pitch_down_deg:g} deg nose down (upset attitude)"))
    r = _col(grid, "roll_deg")
    if r is not None:
        checks.append(("roll_deg", "bank", r, np.abs(r) > envelope.bank_deg, "deg",
                       f"beyond {envelope.bank_deg:g} deg (upset attitude)"))
    v = _col(grid, "tas_mps")
    if v is not None and envelope.vmo_mps is not None:
        checks.append(("tas_mps", "airspeed", v, v > envelope.vmo_mps, "m/s",
                       f"above VMO {envelope.vmo_mps:g} m/s"))
    out = []
    for channel, what, x, mask, unit, rule in checks:
        mask = mask & np.isfinite(x)
        for i0, i1 in _merge_runs(t, _spans(t, mask), 2.0):
            if t[i1] - t[i0] < envelope.min_duration_s and i1 > i0:
                continue
            if i1 == i0 and envelope.min_duration_s > 0:
                continue
            seg = x[i0:i1 + 1]
            k = int(np.nanargmax(np.abs(seg - (1.0 if channel == "n_norm_g" else 0.0))))
            peak = float(seg[k])
            out.append(Event("exceedance", float(t[i0]), f"{what} {peak:+.3g} {unit}",
                             f"{what} {rule}: peak {peak:+.4g} {unit} at t = {t[i0 + k]:.1f} s",
                             end_t_s=float(t[i1]), severity="alert", channel=channel,
                             value=peak))
    return out


def outage_events(grid: pd.DataFrame, report: Sequence[Mapping[str, Any]] = ()) -> list[Event]:
    """Sensor outages: spans of a recorder channel left unfilled by the cleaning
    (``<channel>_valid`` False), with the cleaning's reason when it gave one."""
    t = grid["t_s"].to_numpy(float)
    out = []
    for c in grid.columns:
        if not c.endswith("_valid"):
            continue
        ch = c[: -len("_valid")]
        valid = grid[c].to_numpy(bool)
        for i0, i1 in _spans(t, ~valid):
            dur = float(t[i1] - t[i0])
            out.append(Event("outage", float(t[i0]), f"{ch} outage",
                             f"{ch}: no valid data for {dur:.1f} s (gap longer than the "
                             "interpolation limit, left unfilled)", end_t_s=float(t[i1]),
                             severity="caution", channel=ch))
    return out


def measurement_gap_events(times_s: np.ndarray, what: str, min_gap_s: float = 5.0
                           ) -> list[Event]:
    """Gaps between consecutive measurement times (GNSS fixes, radar plots) longer than
    ``min_gap_s`` and five times the median interval."""
    t = np.sort(np.asarray(times_s, float))
    t = t[np.isfinite(t)]
    if len(t) < 3:
        return []
    dt = np.diff(t)
    limit = max(min_gap_s, 5.0 * float(np.median(dt)))
    out = []
    for i in np.flatnonzero(dt > limit):
        out.append(Event("gap", float(t[i]), f"{what} gap {dt[i]:.0f} s",
                         f"no {what} from t = {t[i]:.1f} s to {t[i + 1]:.1f} s ({dt[i]:.1f} s)",
                         end_t_s=float(t[i + 1]), severity="caution", channel=what))
    return out


def source_change_events(track: pd.DataFrame, column: str = "source",
                         max_events: int = 50) -> list[Event]:
    """Samples where the method supplying the default result changes (``source`` column)."""
    if column not in track.columns or len(track) == 0:
        return []
    s = track[column].astype("string").fillna("none").to_numpy(dtype=object)
    t = track["t_s"].to_numpy(float)
    idx = np.flatnonzero(s[1:] != s[:-1]) + 1
    out = []
    what = "horizontal position" if column == "source" else "height"
    for i in idx[:max_events]:
        out.append(Event("source_change", float(t[i]), f"{what}: {s[i - 1]} -> {s[i]}",
                         f"the default result's {what} now comes from '{s[i]}' "
                         f"(was '{s[i - 1]}')", severity="caution", channel=column))
    if len(idx) > max_events:
        out.append(Event("source_change", float(t[idx[max_events]]),
                         f"{len(idx) - max_events} more source changes",
                         f"{len(idx) - max_events} further source changes not listed",
                         severity="caution", channel=column))
    return out


def measurement_events(clean: Any) -> list[Event]:
    """The GNSS fixes and radar plots used: first and last time and count."""
    out = []
    for df, what, one in ((clean.gnss, "GNSS fixes", "GNSS fix"),
                          (clean.radar, "radar plots", "radar plot")):
        if df is None or len(df) == 0 or "t_s" not in df.columns:
            continue
        t = df["t_s"].to_numpy(float)
        t = t[np.isfinite(t)]
        if len(t) == 0:
            continue
        out.append(Event("fixes", float(t[0]), f"{len(t)} {what}",
                         f"{len(t)} {what} from t = {t[0]:.1f} s to {t[-1]:.1f} s",
                         end_t_s=float(t[-1]), channel=what))
        out += measurement_gap_events(t, one)
    meta = getattr(clean, "meta", None)
    for f in getattr(meta, "fixes", ()) or ():
        # a known position (--fix): one event each, at its time
        alt = "" if f.alt_msl_m is None else f", {f.alt_msl_m:.0f} m MSL"
        out.append(Event("fixes", float(f.t_s), "known position",
                         f"known position (--fix) {f.lat_deg:.5f}, {f.lon_deg:.5f}{alt}, "
                         f"sd {f.sd_m:g} m", channel="fix"))
    return out


def rejection_events(status: Mapping[str, Any], max_spans: int = 3) -> list[Event]:
    """Spans where the joint smoother found a source inconsistent with the others and
    down-weighted it (``methods.joint.sources.<source>.flagged_spans_s``); more than
    ``max_spans`` spans of one source make one event covering them."""
    joint = status.get("joint") if isinstance(status, Mapping) else None
    sources = joint.get("sources") if isinstance(joint, Mapping) else None
    if not isinstance(sources, Mapping):
        return []
    out = []
    for src, st in sources.items():
        if not isinstance(st, Mapping):
            continue
        spans = [(float(a), float(b)) for a, b in (sp for sp in st.get("flagged_spans_s") or []
                                                   if len(sp) == 2)]
        if not spans:
            continue
        if len(spans) > max_spans:
            total = sum(b - a for a, b in spans)
            out.append(Event("rejected", spans[0][0], f"{src} down-weighted ({len(spans)}x)",
                             f"joint smoother: {src} inconsistent with the other sources and "
                             f"down-weighted in {len(spans)} spans, {total:.0f} s in all, "
                             f"between t = {spans[0][0]:.0f} and {spans[-1][1]:.0f} s",
                             end_t_s=spans[-1][1], severity="caution", channel=src))
            continue
        for a, b in spans:
            out.append(Event("rejected", a, f"{src} down-weighted",
                             f"joint smoother: {src} inconsistent with the other sources, "
                             "down-weighted", end_t_s=b, severity="caution", channel=src))
    return out


def detect_events(clean: Any, track: pd.DataFrame | None = None,
                  status: Mapping[str, Any] | None = None,
                  envelope: Envelope = Envelope()) -> list[Event]:
    """Every event of a reconstruction, sorted by time.

    Parameters
    ----------
    clean : :class:`~flightrecon.types.CleanFlight`
    track : the combined result table (for source changes and the end-of-record descent)
    status : the per-method status of the summary (for the joint smoother's rejections)
    envelope : limits of the exceedance checks
    """
    grid = clean.grid
    ev = phase_events(clean.phases, float(grid["t_s"].iloc[0]) if len(grid) else None)
    if len(grid):
        ev += end_of_record_events(grid, clean.phases, clean.report)
        ev += exceedance_events(grid, envelope)
        ev += outage_events(grid, clean.report)
    ev += measurement_events(clean)
    if track is not None:
        ev += source_change_events(track, "source")
    if status:
        ev += rejection_events(status)
    return sorted(ev, key=lambda e: (e.t_s, KINDS.index(e.kind) if e.kind in KINDS else 99))


def utc_text(epoch_utc: str | None, t_s: float | None) -> str | None:
    """ISO-8601 UTC text (milliseconds) of ``t_s`` seconds after ``epoch_utc``, or ``None``."""
    if epoch_utc is None or t_s is None or not np.isfinite(t_s):
        return None
    t0 = parse_epoch(epoch_utc)
    if t0 is None:
        return None
    return (t0 + timedelta(seconds=float(t_s))).isoformat(timespec="milliseconds").replace(
        "+00:00", "Z")


def parse_epoch(epoch_utc: str | None) -> datetime | None:
    """The epoch as an aware UTC :class:`datetime` (``None`` if missing or unreadable)."""
    if not epoch_utc:
        return None
    try:
        d = datetime.fromisoformat(str(epoch_utc).replace("Z", "+00:00"))
    except ValueError:
        return None
    if d.tzinfo is None:
        d = d.replace(tzinfo=UTC)
    return d.astimezone(UTC)


def events_table(events: Sequence[Event], epoch_utc: str | None) -> list[dict[str, Any]]:
    """JSON-ready rows: every field of :class:`Event` plus ``utc`` and ``end_utc``."""
    rows = []
    for e in events:
        d = asdict(e)
        d["utc"] = utc_text(epoch_utc, e.t_s)
        d["end_utc"] = utc_text(epoch_utc, e.end_t_s)
        rows.append(d)
    return rows


def events_from_summary(summary: Mapping[str, Any]) -> list[Event]:
    """The events listed in a summary (``summary['events']``), as :class:`Event` objects."""
    out = []
    names = set(Event.__dataclass_fields__)
    for row in summary.get("events") or []:
        if isinstance(row, Mapping) and "kind" in row and "t_s" in row:
            out.append(Event(**{k: v for k, v in row.items() if k in names}))
    return out
