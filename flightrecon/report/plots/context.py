"""The figures' common ground: the :class:`ReportContext` they draw from, the method names
and colours, units, and the time axis with the numbered events (conventions:
:mod:`flightrecon.report.plots`)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, field
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.dates as mdates
import numpy as np
import pandas as pd

from flightrecon.events import Event, events_from_summary, parse_epoch

PREFIXES = ("sabziev", "arms", "azimuth", "sns")
METHOD_NAMES = {"joint": "joint smoother", "sabziev": "Sabziev fusion", "arms": "ADS/ARMS",
                "azimuth": "azimuth channel", "sns": "SNS smoother"}
COLOURS = {"default": "k", "sabziev": "tab:blue", "arms": "tab:orange", "azimuth": "tab:green",
           "sns": "tab:red", "truth": "tab:gray"}
FT = 0.3048
KT = 1852.0 / 3600.0
FPM = FT / 60.0
G0 = 9.80665


@dataclass
class ReportContext:
    """Everything the figures draw from.

    Attributes
    ----------
    track : result table (``reconstruct``'s output)
    summary : summary document (may be empty for a bare CSV result)
    truth : truth table of a simulated flight (``t_s`` first), or ``None``
    grid : the recorder's channels (``t_s``, ``roll_deg``, ``n_norm_g``, ``baro_alt_m`` ...),
        or ``None`` when the log was not available
    gnss : GNSS fixes (``t_s``, ``lat_deg``, ``lon_deg``), or ``None``
    radar : radar plots (``t_s``, ``arms_range_m``, ``arms_azimuth_deg``,
        ``arms_elevation_deg``), drawn on the map from the station, or ``None``
    sensor_truth : the simulated aircraft's sensor errors (``<stem>.sensors.json``), or ``None``
    """

    track: pd.DataFrame
    summary: Mapping[str, Any]
    truth: pd.DataFrame | None = None
    grid: pd.DataFrame | None = None
    gnss: pd.DataFrame | None = None
    sensor_truth: Mapping[str, Any] | None = None
    radar: pd.DataFrame | None = None
    events: list[Event] = field(default_factory=list)

    #: result rows drawn at most (a 10-hour 16 Hz flight has 576 000; the figures do not get
    #: better beyond this, only slower); the recorder channels are drawn in full, so a load
    #: spike stays visible
    max_track_rows: int = 60_000

    def __post_init__(self) -> None:
        if len(self.track) > self.max_track_rows:
            step = int(np.ceil(len(self.track) / self.max_track_rows))
            keep = np.zeros(len(self.track), bool)
            keep[::step] = True
            keep[-1] = True
            self.track = self.track.loc[keep].reset_index(drop=True)
        if self.gnss is not None and "gnss_lat_deg" in self.gnss.columns:
            self.gnss = self.gnss.rename(columns={"gnss_lat_deg": "lat_deg",
                                                  "gnss_lon_deg": "lon_deg"})
        if not self.events:
            self.events = events_from_summary(self.summary)
        self.epoch = parse_epoch((self.summary.get("flight") or {}).get("epoch_utc"))

    @property
    def flight(self) -> Mapping[str, Any]:
        return self.summary.get("flight") or {}

    @property
    def geoid_m(self) -> float | None:
        v = self.flight.get("geoid_undulation_m")
        return float(v) if isinstance(v, (int, float)) else None

    def time(self, t_s: Any) -> np.ndarray:
        """Plot abscissa: UTC datetimes, or seconds when the epoch is unknown."""
        t = np.asarray(t_s, float)
        if self.epoch is None:
            return t
        base = np.datetime64(self.epoch.replace(tzinfo=None), "ms")
        return base + (t * 1000.0).round().astype("timedelta64[ms]")

    def time_label(self) -> str:
        if self.epoch is None:
            return "time from the record start [s] (UTC epoch unknown)"
        return f"UTC ({self.epoch:%Y-%m-%d})"


def column_values(df: pd.DataFrame | None, name: str) -> np.ndarray | None:
    if df is not None and name in df.columns:
        v = pd.to_numeric(df[name], errors="coerce").to_numpy(dtype=float)
        if np.isfinite(v).any():
            return v
    return None


def _time_axis(ax, ctx: ReportContext) -> None:
    if ctx.epoch is not None:
        loc = mdates.AutoDateLocator(minticks=4, maxticks=10)
        ax.xaxis.set_major_locator(loc)
        ax.xaxis.set_major_formatter(mdates.DateFormatter("%H:%M" if _span_s(ctx) > 1800
                                                          else "%H:%M:%S"))
    ax.grid(alpha=0.3)


def _span_s(ctx: ReportContext) -> float:
    t = ctx.track["t_s"].to_numpy(float) if len(ctx.track) else np.zeros(1)
    return float(np.nanmax(t) - np.nanmin(t)) if len(t) else 0.0


_POINT_KINDS = ("liftoff", "touchdown", "impact", "end_airborne", "source_change")
_SPAN_STYLE = {"exceedance": ("tab:red", 0.18), "outage": ("0.5", 0.22),
               "gap": ("tab:purple", 0.12),
               "rejected": ("tab:orange", 0.18)}


def event_numbers(ctx: ReportContext) -> list[tuple[int, Event]]:
    """``(number, event)`` as numbered in the report's events table (from 1)."""
    return list(enumerate(ctx.events, start=1))


def mark_events(ax, ctx: ReportContext, label: bool = True) -> None:
    """Events on a time axis: point events as numbered vertical lines, spans shaded."""
    for num, e in event_numbers(ctx):
        if e.kind in _SPAN_STYLE and e.end_t_s is not None:
            c, a = _SPAN_STYLE[e.kind]
            t0, t1 = ctx.time([e.t_s, max(e.end_t_s, e.t_s)])
            if e.kind == "rejected":  # a strip along the bottom: the source, not the flight
                ax.axvspan(t0, t1, ymin=0, ymax=0.035, color=c, alpha=0.6, lw=0)
            else:
                ax.axvspan(t0, t1, color=c, alpha=a, lw=0)
            if label:
                ax.text(t0, 0.02, str(num), transform=ax.get_xaxis_transform(), fontsize=6,
                        color=c if c != "0.5" else "0.3", va="bottom")
        elif e.kind in _POINT_KINDS:
            t0 = ctx.time([e.t_s])[0]
            style = {"liftoff": "tab:green", "touchdown": "tab:blue", "impact": "tab:red",
                     "end_airborne": "tab:red", "source_change": "tab:brown"}[e.kind]
            ax.axvline(t0, color=style, lw=0.8, ls="--" if e.kind == "source_change" else "-",
                       alpha=0.8)
            if label:
                ax.text(t0, 0.98, f" {num}", transform=ax.get_xaxis_transform(), fontsize=7,
                        color=style, va="top", ha="left",
                        bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none",
                              "alpha": 0.7})


def _events_note(ctx: ReportContext) -> str:
    return ("events (numbers: events table): lines green lift-off, blue touchdown, red impact, "
            "brown source change; shading red exceedance, grey sensor outage, purple "
            "measurement gap;\norange strip at the bottom: a source down-weighted by the joint "
            "smoother") if ctx.events else ""


def finish_time_figure(fig, axes, ctx: ReportContext, title: str) -> None:
    for ax in axes:
        _time_axis(ax, ctx)
        mark_events(ax, ctx, label=ax is axes[0])
    axes[-1].set_xlabel(ctx.time_label())
    fig.suptitle(title, fontsize=11)
    note = _events_note(ctx)
    if note:
        fig.text(0.01, 0.004, note, fontsize=6.5, color="0.35", va="bottom")
    fig.tight_layout(rect=(0, 0.035 * 4.5 / fig.get_figheight(), 1, 1))


def twin_units(ax, factor: float, label: str) -> None:
    sec = ax.secondary_yaxis("right", functions=(lambda x: x / factor, lambda x: x * factor))
    sec.set_ylabel(label)

