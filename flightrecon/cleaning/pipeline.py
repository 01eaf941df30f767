"""``clean_flight``: from a validated :class:`~flightrecon.types.Flight` to a
:class:`~flightrecon.types.CleanFlight`.

Order: resolve time stamps -> unwrap angles -> despike input channels -> drop dead or stuck
channels (cleaning/dead.py: treated as absent) -> bring inputs onto the
uniform grid (short gaps bridged, long gaps flagged, anti-alias on downsampling; recorder
saturation flagged) -> measurement tables at their own (clock-offset) times -> phase detection
-> impact at the record's end.  ``docs/signals.md`` documents each
rule and its numbers.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from flightrecon.cleaning.arrival_end import arrival_not_end
from flightrecon.cleaning.attitude import heading_from_rates, heading_needed
from flightrecon.cleaning.dead import drop_dead_channels
from flightrecon.cleaning.despike import DespikeSettings
from flightrecon.cleaning.impact import with_impact
from flightrecon.cleaning.origin import with_origin
from flightrecon.cleaning.phases import PhaseSettings, detect_phases_with_report
from flightrecon.cleaning.rate_aided import rate_aided_attitude
from flightrecon.cleaning.rate_integrals import provisional_heading
from flightrecon.cleaning.report import report_entry
from flightrecon.cleaning.resample import resample_inputs, wrap_roll
from flightrecon.cleaning.saturation import detect_saturation, saturation_on_grid
from flightrecon.cleaning.steps import (
    Despike,
    ResolveTimestamps,
    UnwrapAngles,
    run_steps,
)
from flightrecon.cleaning.timebase import check_clock_offsets, measurement_table
from flightrecon.cleaning.trim import trim_flight
from flightrecon.errors import FlightReconError, ValidationError
from flightrecon.schema import GROUPS
from flightrecon.types import CleanFlight, Flight, FlightMeta, FlightPhases, IngestRecord

__all__ = ["CleaningSettings", "clean_flight"]


@dataclass(frozen=True)
class CleaningSettings:
    """Settings of :func:`clean_flight`.

    Attributes
    ----------
    max_gap_s : longest gap between samples of an input channel that is interpolated [s]
    despike : despiking parameters (``None`` switches despiking off)
    clock_offsets_s : seconds added to the sample times of a measurement group
        (``{"gnss": 0.0, "radar": 0.0}``)
    phases : phase-detector thresholds (``None`` skips phase detection)
    start, end : keep only ``start <= t_s <= end`` (seconds from the epoch, or UTC timestamps;
        :func:`flightrecon.cleaning.trim.trim_flight`); ``None``: the whole record
    """

    max_gap_s: float = 2.0
    despike: DespikeSettings | None = field(default_factory=DespikeSettings)
    clock_offsets_s: dict[str, float] = field(default_factory=lambda: {"gnss": 0.0, "radar": 0.0})
    phases: PhaseSettings | None = field(default_factory=PhaseSettings)
    start: float | str | None = None
    end: float | str | None = None


def _ingest_notes_entries(record: IngestRecord) -> list[dict]:
    """Cleaning-report entries for what ingest left out or made up: the log's columns mapped
    to no channel (``ignored_columns``) and the channels derived, not recorded
    (``derived_channel``, docs/ingest.md)."""
    out = []
    ignored = list(record.ignored_columns)
    if ignored:
        out.append(report_entry("*", "ignored_columns", "columns of the log mapped to no "
                                "channel (not in the schema, not in the mapping): not used",
                                count=len(ignored), columns=", ".join(ignored)))
    for ch, how in record.derived_channels.items():
        out.append(report_entry(ch, "derived_channel", f"not recorded: computed at ingest as "
                                f"{how}", count=0))
    use = record.gnss_use
    if use.get("options"):
        opts = use["options"]
        said = "; ".join(t for t in (
            "every GNSS channel withheld" if opts.get("withhold") else "",
            (f"at most one fix every {opts['interval_s']:g} s ({use.get('interval_dropped', 0)} "
             "fixes dropped)") if opts.get("interval_s") is not None else "",
            ", ".join(f"withheld {w['start_s']:g}..{w['end_s']:g} s ({w['fixes_withheld']} "
                      "fixes)" for w in use.get("withheld_windows", [])),
            ", ".join(f"receiver {k} {opts[k]:g} m" for k in ("h_sd_m", "v_sd_m")
                      if opts.get(k) is not None)) if t)
        out.append(report_entry("gnss", "gnss_use", f"the analyst's GNSS options: {said}",
                                count=int(use.get("fixes_read", 0)) - int(use.get("fixes_used",
                                                                                  0))))
    return out


def _repair_entry(r: dict) -> dict:
    """A cleaning-report entry for one validation repair (``flightrecon.ingest.validate.Repair``):
    ``range_clip`` / ``range_mask`` with the file, its source column and 1-based data rows."""
    action = "range_clip" if r["action"] == "clipped" else "range_mask"
    lo, hi = r["range"]
    why = (f"outside the physical range [{lo:g}, {hi:g}] (first {r['first_value']:g}); "
           + ("within the clip margin: clipped to the bound" if action == "range_clip" else
              "isolated (at most 1 % of the channel's samples): masked as missing samples"))
    if r.get("why"):
        action, why = "gnss_quality_mask", r["why"]
    e = report_entry(r["channel"], action, why, count=r["count"], t_s=r.get("t_s") or None,
                     file=r["file"], column=r["column"])
    e["file_rows"] = list(r["rows"])
    return e


def _checked_offsets(flight: Flight, settings: CleaningSettings) -> dict[str, float]:
    """Refuse a flight or settings that cannot be cleaned; the checked clock offsets [s]."""
    if not isinstance(flight, Flight):
        raise ValidationError("clean_flight expects a flightrecon.types.Flight")
    if not (np.isfinite(settings.max_gap_s) and settings.max_gap_s >= 0.0):
        raise ValidationError(f"max_gap_s must be a non-negative number, got {settings.max_gap_s}")
    offsets = check_clock_offsets(settings.clock_offsets_s)
    if not isinstance(flight.data, pd.DataFrame):
        raise ValidationError("flight.data must be a pandas DataFrame")
    return offsets


def _phases_and_end(grid: pd.DataFrame, meta: FlightMeta, settings: CleaningSettings,
                    report: list) -> tuple[FlightPhases | None, FlightMeta]:
    """The flight phases (``None`` when switched off or impossible, reported), an accident
    record's impact, and an arrival that is not the record's end (``report`` extended)."""
    if settings.phases is None:
        return None, meta
    phases: FlightPhases | None
    try:
        phases, rep = detect_phases_with_report(grid, settings.phases,
                                                lat_deg=_gravity_latitude(meta))
    except FlightReconError as exc:
        rep = [report_entry("phases", "not_detected", str(exc), count=0)]
        phases = None
    report.extend(rep)
    phases, rep = with_impact(grid, phases, meta)   # an accident record's end
    report.extend(rep)
    # an arrival given for a record cut in the air is not its end point (arrival_end.py)
    meta, rep = arrival_not_end(grid, phases, meta, settings.phases.airborne_speed_mps)
    report.extend(rep)
    return phases, meta


def clean_flight(flight: Flight, *, rate_hz: float | None = None,
                 settings: CleaningSettings = CleaningSettings()) -> CleanFlight:
    """Clean a flight and bring its input channels onto one grid.

    Parameters
    ----------
    flight : Flight
        Validated canonical log (not modified).
    rate_hz : float, optional
        Grid rate [Hz]; default: the fastest input channel's rate.
    settings : CleaningSettings

    Returns
    -------
    CleanFlight
        ``grid`` (``t_s``, each input channel and ``<channel>_valid``; angles unwrapped),
        ``gnss`` / ``radar`` (one row per fix / plot at its own time, ``t_s`` first), the report
        and the phases (docs/schema.md, "Two kinds of channel").  ``phases`` is ``None`` when
        phase detection is switched off or impossible on this data (no airspeed, no pressure
        altitude, no loads or attitude); the report then says why (``not_detected``).

    Raises
    ------
    ValidationError
        Bad settings, no input channel, non-finite time stamps, or a grid that would exceed
        50 million points.
    """
    offsets = _checked_offsets(flight, settings)
    untrimmed = flight.data
    flight, trim_rep = trim_flight(flight, settings.start, settings.end)
    # the part cut away still tells the gyro biases where the aircraft stood (attitude.py)
    trimmed = untrimmed if flight.data is not untrimmed else None
    data = flight.data
    if not isinstance(data, pd.DataFrame):
        raise ValidationError("flight.data must be a pandas DataFrame")
    steps: list = [ResolveTimestamps(), UnwrapAngles()]
    if settings.despike is not None:
        steps.append(Despike(settings.despike))
    try:
        work, report = run_steps(data, steps)
    except (TypeError, ValueError) as exc:  # non-numeric channel content
        raise ValidationError(f"cannot clean the log: {exc}") from exc
    derived = tuple(flight.meta.ingest.derived_channels)
    work, dead = drop_dead_channels(work, derived)   # a dead or stuck one is absent (dead.py)
    report.extend(dead)
    grid, rate, rep = resample_inputs(work, rate_hz, settings.max_gap_s)
    report.extend(rep)
    sat_masks, rep = detect_saturation(work)   # samples at the recorder's range (impact, dive)
    report.extend(rep)
    # repairs made at validation (values outside the physical range), first in the report
    ingest = [_repair_entry(r) for r in flight.meta.ingest.repairs]
    ingest += _ingest_notes_entries(flight.meta.ingest)
    report[:0] = ingest + trim_rep
    tables = _measurement_tables(work, offsets, report)
    meta, rep = with_origin(flight.meta, grid, tables["gnss"], tables["radar"])
    report.extend(rep)
    # roll, pitch and heading between their samples shaped by the body rates, where both exist
    grid, rep = rate_aided_attitude(grid, work, settings.max_gap_s)
    report.extend(rep)
    grid = saturation_on_grid(wrap_roll(grid), sat_masks)
    why = heading_needed(grid)
    why = next((e["why"].split(": treated")[0] for e in dead
                if e["channel"] == "heading_deg"), why) if why else why
    if why is not None:
        grid, rep = _heading_from_body_rates(grid, tables["gnss"], meta, settings, why,
                                             trimmed)
        report.extend(rep)
    phases, meta = _phases_and_end(grid, meta, settings, report)
    return CleanFlight(grid=grid, rate_hz=rate, gnss=tables["gnss"], radar=tables["radar"],
                       meta=meta, report=tuple(report), phases=phases)


def _measurement_tables(work: pd.DataFrame, offsets: dict[str, float], report: list
                        ) -> dict[str, pd.DataFrame]:
    """Each measurement group's table (one row per fix / plot at its own time), its clock
    offset added (reported)."""
    tables = {}
    for g in GROUPS:
        off = offsets.get(g, 0.0)
        tables[g] = measurement_table(work, g, off)
        if off != 0.0 and len(tables[g]):
            report.append(report_entry(g, "clock_offset", f"{off:+g} s added to the {g} times",
                                       count=len(tables[g]), offset_s=off))
    return tables


def _gravity_latitude(meta: FlightMeta) -> float:
    """Latitude for normal gravity in the phase detection: the departure airfield's, else the
    frame origin's, else 45 deg."""
    p0 = meta.departure if meta.departure is not None else meta.origin
    return p0.lat_deg if p0 is not None else 45.0


def _heading_from_body_rates(grid: pd.DataFrame, gnss: pd.DataFrame, meta: FlightMeta,
                             settings: CleaningSettings, why: str,
                             trimmed: pd.DataFrame | None = None
                             ) -> tuple[pd.DataFrame, list[dict]]:
    """Heading from the body rates: a provisional heading (from 0 deg) lets the phase detector
    find the take-off and landing rolls (its lift-off rule needs the vertical only), then the
    anchored heading replaces it (cleaning/attitude.py)."""
    g0 = grid.copy()
    g0["heading_deg"] = provisional_heading(grid)
    g0["heading_valid"] = True
    try:
        ph0 = detect_phases_with_report(g0, settings.phases or PhaseSettings(),
                                        lat_deg=_gravity_latitude(meta))[0]
    except FlightReconError:
        ph0 = None
    return heading_from_rates(grid, gnss, meta, ph0, why, trimmed)
