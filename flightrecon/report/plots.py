"""Figures of a reconstruction (matplotlib, Agg backend), drawn for an investigator.

Every figure takes a :class:`ReportContext` (the result table, the summary, and optionally the
recorder's channels, the truth of a simulated flight and its sensor truth) and returns a
:class:`matplotlib.figure.Figure`, or ``None`` when the data hold nothing to show.

Conventions: time axes in UTC (seconds from the record start when the epoch is unknown);
altitudes above mean sea level (ellipsoidal height minus the flight's geoid undulation) and
pressure altitude (standard atmosphere, 1013.25 hPa) in metres with feet on the right axis;
wind as the direction it blows *from* (true, degrees) and its speed in m/s and knots; bands are
2 sigma; numbered markers are the rows of the events table.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.dates as mdates
import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse

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

#: readable names and display units of the estimated sensor corrections:
#: key -> (name, unit, factor from the stored value, key path in the sensor truth file)
CORRECTIONS: dict[str, tuple[str, str, float, tuple[Any, ...] | None]] = {
    "heading_bias_deg": ("Heading bias (measured - true)", "deg", 1.0,
                         ("aircraft", "heading_bias_deg")),
    "tas_scale": ("Airspeed scale error", "%", 100.0, ("aircraft", "airspeed_scale")),
    "baro_offset_m": ("Pressure-altitude offset at the field", "m", 1.0, None),
    "baro_scale": ("Pressure-altitude scale error", "%", 100.0, None),
    "accel_bias_x_g": ("Accelerometer bias, forward", "mg", 1000.0,
                       ("aircraft", "accel_bias_g", 0)),
    "accel_bias_y_g": ("Accelerometer bias, right", "mg", 1000.0, ("aircraft", "accel_bias_g", 1)),
    "accel_bias_z_g": ("Accelerometer bias, down", "mg", 1000.0, ("aircraft", "accel_bias_g", 2)),
    "accel_scale_x": ("Accelerometer scale error, forward", "%", 100.0,
                      ("aircraft", "accel_scale", 0)),
    "accel_scale_y": ("Accelerometer scale error, right", "%", 100.0,
                      ("aircraft", "accel_scale", 1)),
    "accel_scale_z": ("Accelerometer scale error, down", "%", 100.0,
                      ("aircraft", "accel_scale", 2)),
    "doppler_scale": ("Doppler ground-speed scale error", "%", 100.0,
                      ("aircraft", "doppler_scale")),
    "drift_bias_deg": ("Doppler drift-angle bias", "deg", 1.0, ("aircraft", "drift_bias_deg")),
    "roll_bias_deg": ("Roll bias (measured - true)", "deg", 1.0, ("aircraft", "roll_bias_deg")),
    "pitch_bias_deg": ("Pitch bias (measured - true)", "deg", 1.0,
                       ("aircraft", "pitch_bias_deg")),
    "wind_gradient_n_per_km": ("Wind gradient with height, north", "(m/s)/km", 1.0, None),
    "wind_gradient_e_per_km": ("Wind gradient with height, east", "(m/s)/km", 1.0, None),
    "heading_corr_deg": ("Heading correction", "deg", 1.0, None),
    "wind_corr_n_mps": ("Wind correction, north", "m/s", 1.0, None),
    "wind_corr_e_mps": ("Wind correction, east", "m/s", 1.0, None),
    "doppler_scale_corr": ("Doppler ground-speed scale correction", "%", 100.0, None),
    "drift_corr_deg": ("Drift-angle correction", "deg", 1.0, None),
    "track_corr_deg": ("Track-angle correction", "deg", 1.0, None),
}
_UNIT_SUFFIX = (("_deg", "deg"), ("_mps", "m/s"), ("_m", "m"), ("_g", "g"), ("_s", "s"))


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


def _col(df: pd.DataFrame | None, name: str) -> np.ndarray | None:
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


def _finish_time_figure(fig, axes, ctx: ReportContext, title: str) -> None:
    for ax in axes:
        _time_axis(ax, ctx)
        mark_events(ax, ctx, label=ax is axes[0])
    axes[-1].set_xlabel(ctx.time_label())
    fig.suptitle(title, fontsize=11)
    note = _events_note(ctx)
    if note:
        fig.text(0.01, 0.004, note, fontsize=6.5, color="0.35", va="bottom")
    fig.tight_layout(rect=(0, 0.035 * 4.5 / fig.get_figheight(), 1, 1))


# ----------------------------------------------------------------------------------- map ----

def _nice_length_km(width_km: float) -> float:
    target = width_km / 5.0
    if target <= 0:
        return 1.0
    p = 10 ** math.floor(math.log10(target))
    for m in (1, 2, 5, 10):
        if m * p >= target * 0.7:
            return m * p
    return 10 * p


def _method_latlon(ctx: ReportContext, prefix: str) -> tuple[np.ndarray, np.ndarray] | None:
    n, e = _col(ctx.track, f"{prefix}_north_m"), _col(ctx.track, f"{prefix}_east_m")
    dep = ctx.flight.get("departure")
    if n is None or e is None or not isinstance(dep, Mapping):
        return None
    from flightrecon.geo.frames import TangentPlane

    h0 = float(dep.get("elev_m") or 0.0) + float(ctx.geoid_m or 0.0)
    plane = TangentPlane(float(dep["lat_deg"]), float(dep["lon_deg"]), h0)
    ok = np.isfinite(n) & np.isfinite(e)
    lat = np.full(len(n), np.nan)
    lon = np.full(len(n), np.nan)
    if ok.any():
        la, lo, _ = plane.inverse(e[ok], n[ok], np.zeros(ok.sum()))
        lat[ok], lon[ok] = la, lo
    return lat, lon


def _radar_latlon(ctx: ReportContext) -> tuple[np.ndarray, np.ndarray] | None:
    """Positions of the radar plots: slant range, azimuth (clockwise from true north) and
    elevation from the station (docs/schema.md), through the station's tangent plane; the
    elevation taken as 0 where not measured."""
    rd, st = ctx.radar, ctx.flight.get("station")
    if rd is None or len(rd) == 0 or not isinstance(st, Mapping) or st.get("lat_deg") is None:
        return None
    r, az = _col(rd, "arms_range_m"), _col(rd, "arms_azimuth_deg")
    if r is None or az is None:
        return None
    el = _col(rd, "arms_elevation_deg")
    el = np.zeros(len(r)) if el is None else np.nan_to_num(el)
    from flightrecon.geo.frames import TangentPlane

    hr = r * np.cos(np.radians(el))
    ok = np.isfinite(hr) & np.isfinite(az)
    h0 = float(st.get("elev_m") or 0.0) + float(ctx.geoid_m or 0.0)
    plane = TangentPlane(float(st["lat_deg"]), float(st["lon_deg"]), h0)
    a = np.radians(az[ok])
    lat, lon, _ = plane.inverse(hr[ok] * np.sin(a), hr[ok] * np.cos(a),
                                r[ok] * np.sin(np.radians(el[ok])))
    return np.asarray(lat), np.asarray(lon)


def _fmt_lat(v: float, _pos: Any = None) -> str:
    return f"{abs(v):.2f}°{'N' if v >= 0 else 'S'}"


def _fmt_lon(v: float, _pos: Any = None) -> str:
    return f"{abs(v):.2f}°{'E' if v >= 0 else 'W'}"


def ground_track(ctx: ReportContext) -> Figure | None:
    """Map: lat/lon grid, scale bar, north arrow, airfields, runways, radar station, GNSS fixes,
    start/end, numbered events, every method, the default result coloured by its horizontal
    2-sigma and its 2-sigma ellipses (to scale)."""
    lat, lon = _col(ctx.track, "lat_deg"), _col(ctx.track, "lon_deg")
    if lat is None or lon is None:
        return None
    fig, ax = plt.subplots(figsize=(9, 8.2))
    lat0 = float(np.nanmean(lat))
    coslat = math.cos(math.radians(lat0))
    if ctx.truth is not None and {"lat_deg", "lon_deg"} <= set(ctx.truth.columns):
        ax.plot(ctx.truth["lon_deg"], ctx.truth["lat_deg"], color=COLOURS["truth"], lw=4,
                alpha=0.35, label="truth", zorder=1)
    if ctx.gnss is not None and {"lat_deg", "lon_deg"} <= set(ctx.gnss.columns) and len(ctx.gnss):
        g = ctx.gnss.iloc[:: max(1, len(ctx.gnss) // 1500)]
        ax.plot(g["lon_deg"], g["lat_deg"], ".", ms=2, color="tab:cyan", alpha=0.6,
                label=f"GNSS fixes ({len(ctx.gnss)})", zorder=2)
    rll = _radar_latlon(ctx)
    if rll is not None and len(rll[0]):
        step = max(1, len(rll[0]) // 1500)
        ax.plot(rll[1][::step], rll[0][::step], "+", ms=3, color="tab:purple", alpha=0.5,
                label=f"radar plots ({len(rll[0])}, from the station)", zorder=2)
    for p in PREFIXES:
        ll = _method_latlon(ctx, p)
        if ll is not None:
            ax.plot(ll[1], ll[0], color=COLOURS[p], lw=0.9, alpha=0.8,
                    label=METHOD_NAMES[p], zorder=3)
    sn, se = _col(ctx.track, "north_sd_m"), _col(ctx.track, "east_sd_m")
    ok = np.isfinite(lat) & np.isfinite(lon)
    if sn is not None and se is not None:
        s2 = 2 * np.hypot(sn, se)
        pts = np.column_stack([lon, lat])[:, None, :]
        segs = np.concatenate([pts[:-1], pts[1:]], axis=1)
        good = ok[:-1] & ok[1:] & np.isfinite(s2[:-1])
        vals = s2[:-1][good]
        if len(vals):
            norm = matplotlib.colors.LogNorm(vmin=max(np.nanmin(vals), 0.1),
                                             vmax=max(np.nanmax(vals), np.nanmin(vals) * 1.01,
                                                      0.2))
            lc = LineCollection(segs[good], cmap="plasma", norm=norm, lw=2.2, zorder=4)
            lc.set_array(vals)
            ax.add_collection(lc)
            cb = fig.colorbar(lc, ax=ax, shrink=0.6, pad=0.02)
            cb.set_label("default result: horizontal 2-sigma radius [m]")
            ax.plot([], [], color="darkorange", lw=2.2, label="default result (colour: 2 sigma)")
        idx = np.flatnonzero(ok & np.isfinite(sn) & np.isfinite(se))
        for i in idx[:: max(1, len(idx) // 25)]:
            ax.add_patch(Ellipse((lon[i], lat[i]), 4 * se[i] / (111320.0 * coslat),
                                 4 * sn[i] / 110540.0, fill=False, color="k", lw=0.7, zorder=5))
        ax.plot([], [], "o", mfc="none", color="k", ms=6,
                label="2-sigma ellipses (to scale; a dot where smaller than the line)")
    else:
        ax.plot(lon, lat, color="k", lw=1.5, label="default result", zorder=4)
    first, last = np.flatnonzero(ok)[[0, -1]]
    ax.plot(lon[first], lat[first], "o", color="tab:green", ms=8, zorder=6, label="start of record")
    ax.plot(lon[last], lat[last], "s", color="tab:red", ms=8, zorder=6, label="end of record")
    # airfields, runways and the radar station from the metadata
    dep, arr = ctx.flight.get("departure"), ctx.flight.get("arrival")
    same = (isinstance(dep, Mapping) and isinstance(arr, Mapping)
            and dep.get("lat_deg") == arr.get("lat_deg")
            and dep.get("lon_deg") == arr.get("lon_deg"))
    for key, mark, lab in (("departure", "^", "departure" + (" and arrival" if same else "")),
                           ("arrival", "v", "arrival")):
        pos = ctx.flight.get(key)
        if not isinstance(pos, Mapping) or pos.get("lat_deg") is None:
            continue
        if same and key == "arrival":
            continue
        ax.plot(pos["lon_deg"], pos["lat_deg"], mark, ms=11, mfc="white", mec="navy", mew=1.8,
                zorder=7, label=f"{lab} airfield ({pos.get('elev_m', 0):.0f} m MSL)")
        ax.annotate(lab, (pos["lon_deg"], pos["lat_deg"]), xytext=(8, -12),
                    textcoords="offset points", fontsize=8, color="navy")
        rwy, tla, tlo = pos.get("runway_true_deg"), pos.get("threshold_lat_deg"), \
            pos.get("threshold_lon_deg")
        if rwy is not None and tla is not None and tlo is not None:
            length_m = 2500.0
            a = math.radians(float(rwy))
            dla = length_m * math.cos(a) / 110540.0
            dlo = length_m * math.sin(a) / (111320.0 * coslat)
            ax.plot([tlo, tlo + dlo], [tla, tla + dla], color="navy", lw=4, alpha=0.7,
                    solid_capstyle="butt", zorder=6)
            label = f"RWY {(round(float(rwy)) - 1) % 360 + 1:03d}°"
            ax.annotate(label, (tlo, tla), xytext=(-40, 6),
                        textcoords="offset points", fontsize=7, color="navy")
    ax.plot([], [], color="navy", lw=4, alpha=0.7,
            label="runway: threshold, true direction (drawn 2.5 km)")
    st = ctx.flight.get("station")
    if isinstance(st, Mapping) and st.get("lat_deg") is not None:
        ax.plot(st["lon_deg"], st["lat_deg"], "D", ms=9, color="tab:purple", zorder=7,
                label="radar station")
        ax.annotate("radar", (st["lon_deg"], st["lat_deg"]), xytext=(8, 4),
                    textcoords="offset points", fontsize=8, color="tab:purple")
    # numbered events along the track
    t = ctx.track["t_s"].to_numpy(float)
    for num, e in event_numbers(ctx):
        if e.kind not in ("liftoff", "touchdown", "impact", "end_airborne", "exceedance",
                          "outage", "gap", "source_change", "rejected"):
            continue
        if not np.isfinite(e.t_s) or ok.sum() < 2:
            continue
        la = float(np.interp(e.t_s, t[ok], lat[ok]))
        lo = float(np.interp(e.t_s, t[ok], lon[ok]))
        colour = {"liftoff": "tab:green", "touchdown": "tab:blue"}.get(e.kind, "tab:red")
        ax.plot(lo, la, "o", ms=5, color=colour, zorder=8)
        ax.annotate(str(num), (lo, la), xytext=(4, 4), textcoords="offset points", fontsize=7,
                    color=colour, zorder=8,
                    bbox={"boxstyle": "round,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.7})
    ax.margins(0.08)
    ax.set_aspect(1.0 / coslat, adjustable="datalim")
    ax.xaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(_fmt_lon))
    ax.yaxis.set_major_formatter(matplotlib.ticker.FuncFormatter(_fmt_lat))
    ax.grid(alpha=0.4, lw=0.6)
    ax.set_xlabel("longitude (WGS-84)")
    ax.set_ylabel("latitude (WGS-84)")
    ax.autoscale_view()
    fig.canvas.draw()
    x0, x1 = ax.get_xlim()
    y0, y1 = ax.get_ylim()
    width_km = (x1 - x0) * 111.32 * coslat
    bar_km = _nice_length_km(width_km)
    bar_deg = bar_km / (111.32 * coslat)
    bx, by = x0 + 0.05 * (x1 - x0), y0 + 0.05 * (y1 - y0)
    ax.plot([bx, bx + bar_deg], [by, by], color="k", lw=3, solid_capstyle="butt", zorder=9)
    ax.plot([bx, bx + bar_deg / 2], [by, by], color="white", lw=1.2, solid_capstyle="butt",
            zorder=10)
    ax.text(bx + bar_deg / 2, by + 0.015 * (y1 - y0), f"{bar_km:g} km", ha="center",
            va="bottom", fontsize=8, zorder=9)
    ax.annotate("N", xy=(0.95, 0.95), xytext=(0.95, 0.84), xycoords="axes fraction",
                ha="center", va="center", fontsize=12, fontweight="bold",
                arrowprops={"arrowstyle": "-|>", "color": "k", "lw": 1.5})
    ax.legend(loc="upper center", bbox_to_anchor=(0.5, -0.07), ncol=3, fontsize=7,
              framealpha=0.9)
    ax.set_title("Ground track (WGS-84; north up; numbered markers: events table)", fontsize=11)
    fig.tight_layout()
    return fig


# ------------------------------------------------------------------------- time series ----

def _twin_units(ax, factor: float, label: str) -> None:
    sec = ax.secondary_yaxis("right", functions=(lambda x: x / factor, lambda x: x * factor))
    sec.set_ylabel(label)


def altitude_profile(ctx: ReportContext) -> Figure | None:
    """Altitude above MSL of the default result with its 2-sigma band, pressure altitude from
    the recorder, airfield elevations; metres left, feet right."""
    alt = _col(ctx.track, "alt_m")
    if alt is None:
        return None
    n_geoid = ctx.geoid_m
    fig, ax = plt.subplots(figsize=(10, 4.6))
    x = ctx.time(ctx.track["t_s"])
    if ctx.truth is not None and "alt_msl_m" in ctx.truth.columns:
        ax.plot(ctx.time(ctx.truth["t_s"]), ctx.truth["alt_msl_m"], color=COLOURS["truth"], lw=4,
                alpha=0.35, label="truth, MSL")
    if n_geoid is not None:
        msl = alt - n_geoid
        sd = _col(ctx.track, "up_sd_m")
        if sd is not None:
            ax.fill_between(x, msl - 2 * sd, msl + 2 * sd, color="k", alpha=0.15, lw=0,
                            label="2 sigma")
        ax.plot(x, msl, "k", lw=1.2, label="reconstructed altitude, MSL")
        ylab = "altitude [m]"
    else:
        ax.plot(x, alt, "k", lw=1.2, label="reconstructed WGS-84 ellipsoidal height "
                "(geoid undulation unknown: not MSL)")
        ylab = "height [m]"
    hp = _col(ctx.grid, "baro_alt_m")
    if hp is not None:
        g = ctx.grid
        datum = (ctx.flight.get("baro_datum") or "pressure")
        lab = ("pressure altitude (1013.25 hPa), recorded" if datum == "pressure"
               else f"baro altitude ({datum}), recorded")
        ax.plot(ctx.time(g["t_s"]), hp, color="tab:purple", lw=0.9, label=lab)
    if ctx.truth is not None and "pressure_alt_m" in ctx.truth.columns:
        ax.plot(ctx.time(ctx.truth["t_s"]), ctx.truth["pressure_alt_m"], ":", color="tab:purple",
                lw=1, label="pressure altitude, truth")
    for key, xpos, ha in (("departure", 0.005, "left"), ("arrival", 0.995, "right")):
        pos = ctx.flight.get(key)
        if isinstance(pos, Mapping) and pos.get("elev_m") is not None:
            ax.axhline(float(pos["elev_m"]), color="navy", lw=0.7, ls=":")
            ax.text(xpos, float(pos["elev_m"]), f"{key} elevation {float(pos['elev_m']):.0f} m",
                    color="navy", fontsize=7, ha=ha, va="bottom",
                    transform=ax.get_yaxis_transform())
    ax.set_ylabel(ylab)
    _twin_units(ax, FT, "altitude [ft]")
    ax.legend(fontsize=7, loc="best")
    _finish_time_figure(fig, [ax], ctx, "Altitude above mean sea level and pressure altitude "
                        "(band: 2 sigma)")
    return fig


def speeds(ctx: ReportContext) -> Figure | None:
    """Ground speed and true airspeed (m/s, kt), vertical speed (m/s, ft/min), 2-sigma bands."""
    vn, ve = _col(ctx.track, "vn_mps"), _col(ctx.track, "ve_mps")
    if vn is None or ve is None:
        return None
    x = ctx.time(ctx.track["t_s"])
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    if ctx.truth is not None and "gs_mps" in ctx.truth.columns:
        a1.plot(ctx.time(ctx.truth["t_s"]), ctx.truth["gs_mps"], color=COLOURS["truth"], lw=4,
                alpha=0.35, label="ground speed, truth")
    gs = np.hypot(vn, ve)
    sdn, sde = _col(ctx.track, "vn_sd_mps"), _col(ctx.track, "ve_sd_mps")
    if sdn is not None and sde is not None:
        with np.errstate(invalid="ignore", divide="ignore"):
            sd = np.sqrt((vn * sdn) ** 2 + (ve * sde) ** 2) / np.where(gs > 0.1, gs, np.nan)
        sd = np.where(np.isfinite(sd), sd, np.hypot(sdn, sde))
        a1.fill_between(x, gs - 2 * sd, gs + 2 * sd, color="k", alpha=0.15, lw=0)
    a1.plot(x, gs, "k", lw=1.1, label="ground speed (reconstructed)")
    tas = _col(ctx.grid, "tas_mps")
    if tas is not None:
        a1.plot(ctx.time(ctx.grid["t_s"]), tas, color="tab:orange", lw=0.9,
                label="true airspeed (recorded)")
    a1.set_ylabel("speed [m/s]")
    _twin_units(a1, KT, "speed [kt]")
    a1.legend(fontsize=7, loc="upper right")
    vu = _col(ctx.track, "vu_mps")
    if vu is not None:
        if ctx.truth is not None and "vu_mps" in ctx.truth.columns:
            a2.plot(ctx.time(ctx.truth["t_s"]), ctx.truth["vu_mps"], color=COLOURS["truth"], lw=4,
                    alpha=0.35, label="truth")
        sdu = _col(ctx.track, "vu_sd_mps")
        if sdu is not None:
            a2.fill_between(x, vu - 2 * sdu, vu + 2 * sdu, color="k", alpha=0.15, lw=0)
        a2.plot(x, vu, "k", lw=1.0, label="vertical speed (reconstructed, up positive)")
        a2.legend(fontsize=7, loc="upper right")
    a2.axhline(0, color="k", lw=0.5)
    a2.set_ylabel("vertical speed [m/s]")
    _twin_units(a2, FPM, "vertical speed [ft/min]")
    _finish_time_figure(fig, [a1, a2], ctx, "Speeds (bands: 2 sigma)")
    return fig


def attitude(ctx: ReportContext) -> Figure | None:
    """Recorded roll, pitch and heading (truth overlaid), with the reconstructed track angle."""
    cols = [c for c in ("roll_deg", "pitch_deg", "heading_deg") if _col(ctx.grid, c) is not None]
    if not cols:
        return None
    fig, axes = plt.subplots(len(cols), 1, figsize=(10, 2.2 * len(cols) + 1), sharex=True,
                             squeeze=False)
    axes = list(axes[:, 0])
    g = ctx.grid
    names = {"roll_deg": "roll [deg] (right wing down +)", "pitch_deg": "pitch [deg] (nose up +)",
             "heading_deg": "heading [deg true]"}
    for ax, c in zip(axes, cols):
        v = _col(g, c)
        if c == "heading_deg":
            v = np.mod(v, 360.0)
        if ctx.truth is not None and c in ctx.truth.columns:
            tv = ctx.truth[c].to_numpy(float)
            ax.plot(ctx.time(ctx.truth["t_s"]), np.mod(tv, 360) if c == "heading_deg" else tv,
                    ".", ms=1, color=COLOURS["truth"], alpha=0.5, label="truth")
        ax.plot(ctx.time(g["t_s"]), v, "." if c == "heading_deg" else "-", ms=1, lw=0.8,
                color="tab:blue", label="recorded")
        if c == "heading_deg":
            vn, ve = _col(ctx.track, "vn_mps"), _col(ctx.track, "ve_mps")
            if vn is not None and ve is not None:
                trk = np.mod(np.degrees(np.arctan2(ve, vn)), 360.0)
                trk[np.hypot(vn, ve) < 5] = np.nan
                ax.plot(ctx.time(ctx.track["t_s"]), trk, ".", ms=1, color="k",
                        label="track angle (reconstructed)")
            ax.set_ylim(0, 360)
            ax.set_yticks([0, 90, 180, 270, 360])
        ax.set_ylabel(names[c], fontsize=8)
        ax.legend(fontsize=7, loc="upper right", markerscale=6)
    _finish_time_figure(fig, axes, ctx, "Attitude (recorded; shaded red: exceedances)")
    return fig


def load_factors(ctx: ReportContext) -> Figure | None:
    """Recorded body load factors with the envelope limits of the events."""
    cols = [c for c in ("n_long_g", "n_lat_g", "n_norm_g") if _col(ctx.grid, c) is not None]
    if not cols:
        return None
    from flightrecon.events import Envelope

    env = Envelope()
    fig, axes = plt.subplots(len(cols), 1, figsize=(10, 2.0 * len(cols) + 1), sharex=True,
                             squeeze=False)
    axes = list(axes[:, 0])
    names = {"n_long_g": "longitudinal [g]\n(forward +)", "n_lat_g": "lateral [g]\n(right +)",
             "n_norm_g": "normal [g]\n(1 in level flight)"}
    for ax, c in zip(axes, cols):
        if ctx.truth is not None and c in ctx.truth.columns:
            ax.plot(ctx.time(ctx.truth["t_s"]), ctx.truth[c], color=COLOURS["truth"], lw=3,
                    alpha=0.35, label="truth")
        ax.plot(ctx.time(ctx.grid["t_s"]), _col(ctx.grid, c), lw=0.6, color="tab:blue",
                label="recorded")
        if c == "n_norm_g":
            for lim in (env.n_max_g, env.n_min_g):
                ax.axhline(lim, color="tab:red", lw=0.8, ls="--")
            ax.text(0.005, env.n_max_g, f"limit {env.n_max_g:+g} g", color="tab:red", fontsize=7,
                    transform=ax.get_yaxis_transform(), va="bottom")
            v = _col(ctx.grid, c)
            lo, hi = np.nanpercentile(v, [0.05, 99.95])
            ax.set_ylim(min(lo - 0.2, env.n_min_g - 0.2), max(hi + 0.2, env.n_max_g + 0.2))
        ax.set_ylabel(names[c], fontsize=8)
        ax.legend(fontsize=7, loc="upper right")
    _finish_time_figure(fig, axes, ctx, "Load factors (recorded, body axes; dashed: limit load "
                        "factors)")
    return fig


def _wind_from_speed(wn: np.ndarray, we: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Direction the wind blows from [deg true, 0..360) and its speed, from the velocity of
    the air (north, east: where it moves to)."""
    return np.mod(np.degrees(np.arctan2(-we, -wn)), 360.0), np.hypot(wn, we)


def wind(ctx: ReportContext) -> Figure | None:
    """Wind of the joint smoother as direction-from and speed (m/s and kt), 2-sigma bands; the
    recorded wind channel and the truth overlaid; grey where the aircraft is on the ground."""
    wn, we = _col(ctx.track, "wind_n_mps"), _col(ctx.track, "wind_e_mps")
    if wn is None or we is None:
        return None
    x = ctx.time(ctx.track["t_s"])
    dirn, spd = _wind_from_speed(wn, we)
    sdn, sde = _col(ctx.track, "wind_n_sd_mps"), _col(ctx.track, "wind_e_sd_mps")
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    if ctx.truth is not None and {"wind_n_mps", "wind_e_mps"} <= set(ctx.truth.columns):
        td, ts = _wind_from_speed(ctx.truth["wind_n_mps"].to_numpy(float),
                                  ctx.truth["wind_e_mps"].to_numpy(float))
        xt = ctx.time(ctx.truth["t_s"])
        a1.plot(xt, td, ".", ms=3, color=COLOURS["truth"], alpha=0.4, label="truth")
        a2.plot(xt, ts, color=COLOURS["truth"], lw=4, alpha=0.35, label="truth")
    if ctx.grid is not None and {"wind_speed_mps", "wind_from_deg"} <= set(ctx.grid.columns):
        xg = ctx.time(ctx.grid["t_s"])
        a1.plot(xg, np.mod(ctx.grid["wind_from_deg"].to_numpy(float), 360), ".", ms=1,
                color="tab:orange", label="recorded wind channel")
        a2.plot(xg, ctx.grid["wind_speed_mps"], color="tab:orange", lw=0.8,
                label="recorded wind channel")
    if sdn is not None and sde is not None:
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.where(spd > 0.1, spd, np.nan)
            sd_spd = np.sqrt((wn * sdn) ** 2 + (we * sde) ** 2) / s
            sd_dir = np.degrees(np.sqrt((we * sdn) ** 2 + (wn * sde) ** 2) / s ** 2)
        sd_spd = np.where(np.isfinite(sd_spd), sd_spd, np.hypot(sdn, sde))
        a2.fill_between(x, np.maximum(spd - 2 * sd_spd, 0), spd + 2 * sd_spd, color="k",
                        alpha=0.15, lw=0, label="2 sigma")
        sd_dir = np.minimum(sd_dir, 90.0)
        a1.fill_between(x, dirn - 2 * sd_dir, dirn + 2 * sd_dir, color="k", alpha=0.12, lw=0,
                        label="2 sigma")
    a1.plot(x, dirn, ".", ms=1.2, color="k", label="joint smoother")
    a2.plot(x, spd, "k", lw=1.1, label="joint smoother")
    a1.set_ylim(0, 360)
    a1.set_yticks([0, 90, 180, 270, 360])
    a1.set_ylabel("wind from [deg true]")
    a2.set_ylabel("wind speed [m/s]")
    _twin_units(a2, KT, "wind speed [kt]")
    a2.set_ylim(bottom=0)
    ph = ctx.summary.get("phases") or {}
    t = ctx.track["t_s"].to_numpy(float)
    for ax in (a1, a2):
        lo, td = ph.get("liftoff_t_s"), ph.get("touchdown_t_s")
        if lo is not None and np.isfinite(lo) and t[0] < lo:
            ax.axvspan(*ctx.time([t[0], lo]), color="0.85", lw=0, zorder=0)
        if td is not None and np.isfinite(td) and td < t[-1]:
            ax.axvspan(*ctx.time([td, t[-1]]), color="0.85", lw=0, zorder=0)
        ax.legend(fontsize=7, loc="upper right", markerscale=6)
    _finish_time_figure(fig, [a1, a2], ctx, "Wind: direction it blows from and speed (light "
                        "grey: on the ground, wind unobservable)")
    return fig


def method_differences(ctx: ReportContext) -> Figure | None:
    """Each method's horizontal position minus the reference (truth if given, else default)."""
    track, truth = ctx.track, ctx.truth
    ref_name = "truth" if truth is not None else "default result"
    if truth is not None and {"north_m", "east_m"} <= set(truth.columns):
        ref = pd.DataFrame({"t_s": track["t_s"]}).merge(truth[["t_s", "north_m", "east_m"]],
                                                        on="t_s", how="left")
        rn, re_ = ref["north_m"].to_numpy(), ref["east_m"].to_numpy()
    else:
        truth = None
        ref_name = "default result"
        rn, re_ = _col(track, "north_m"), _col(track, "east_m")
    if rn is None or re_ is None:
        return None
    x = ctx.time(track["t_s"])
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    drawn = False
    if truth is not None:
        dn, de = _col(track, "north_m"), _col(track, "east_m")
        if dn is not None and de is not None:
            drawn = True
            axes[0].plot(x, dn - rn, "k", lw=1, label="default result")
            axes[1].plot(x, de - re_, "k", lw=1, label="default result")
            for ax, c in ((axes[0], "north_sd_m"), (axes[1], "east_sd_m")):
                sd = _col(track, c)
                if sd is not None:
                    ax.fill_between(x, -2 * sd, 2 * sd, color="k", alpha=0.12, lw=0)
    diffs = {}
    for p in PREFIXES:
        pn, pe = _col(track, f"{p}_north_m"), _col(track, f"{p}_east_m")
        if pn is not None and pe is not None:
            diffs[p] = (pn - rn, pe - re_)
    # the scale: the well-determined methods (a method kilometres off would flatten the rest
    # to a line); one whose error leaves it is drawn clipped and named "off scale"
    sizes = {p: float(np.nanpercentile(np.abs(np.r_[d[0], d[1]]), 95))
             for p, d in diffs.items() if np.isfinite(np.r_[d[0], d[1]]).any()}
    dn_, de_ = _col(track, "north_m"), _col(track, "east_m")
    if truth is not None and dn_ is not None and de_ is not None:
        sizes["default"] = float(np.nanpercentile(np.abs(np.r_[dn_ - rn, de_ - re_]), 95))
    small = sorted(v for v in sizes.values() if np.isfinite(v))
    limit = None
    if len(small) >= 2 and small[-1] > 5 * small[0]:
        limit = max(4.0 * small[0], 20.0)
        for v in small:
            if v <= 3 * limit / 4.0:
                limit = max(limit, 1.3 * v)
    for p, (en, ee) in diffs.items():
        drawn = True
        worst = float(np.nanmax(np.abs(np.r_[en, ee]))) if np.isfinite(np.r_[en, ee]).any() \
            else 0.0
        lab = METHOD_NAMES[p]
        if limit is not None and worst > limit:
            lab += f" (off scale: up to {worst / 1000:.1f} km)" if worst >= 1000 else \
                f" (off scale: up to {worst:.0f} m)"
        axes[0].plot(x, en, color=COLOURS[p], lw=1, label=lab)
        axes[1].plot(x, ee, color=COLOURS[p], lw=1, label=lab)
        for ax, c in ((axes[0], f"{p}_north_sd_m"), (axes[1], f"{p}_east_sd_m")):
            sd = _col(track, c)
            if sd is not None:
                ax.fill_between(x, -2 * sd, 2 * sd, color=COLOURS[p], alpha=0.12, lw=0)
    if not drawn:
        plt.close(fig)
        return None
    if limit is not None:
        for ax in axes:
            ax.set_ylim(-limit, limit)
    axes[0].set_ylabel(f"north - {ref_name} [m]")
    axes[1].set_ylabel(f"east - {ref_name} [m]")
    axes[0].legend(fontsize=7, loc="upper right")
    _finish_time_figure(fig, list(axes), ctx, f"Methods against the {ref_name} (bands: each "
                        "method's own 2 sigma)")
    return fig


def air_data_error(ctx: ReportContext) -> Figure | None:
    """Estimated air-data error of ADS/ARMS (air-data velocity minus ground velocity)."""
    vn, ve = _col(ctx.track, "arms_dvn_mps"), _col(ctx.track, "arms_dve_mps")
    if vn is None or ve is None:
        return None
    x = ctx.time(ctx.track["t_s"])
    fig, ax = plt.subplots(figsize=(10, 4))
    for v, sdc, name, c in ((vn, "arms_dvn_sd_mps", "north", "tab:blue"),
                            (ve, "arms_dve_sd_mps", "east", "tab:orange")):
        ax.plot(x, v, color=c, lw=1, label=f"air-data error, {name}")
        sd = _col(ctx.track, sdc)
        if sd is not None:
            ax.fill_between(x, v - 2 * sd, v + 2 * sd, color=c, alpha=0.15, lw=0)
    if ctx.truth is not None and {"wind_n_mps", "wind_e_mps"} <= set(ctx.truth.columns):
        xt = ctx.time(ctx.truth["t_s"])
        ax.plot(xt, -ctx.truth["wind_n_mps"], ":", color="tab:blue", label="-wind north (truth)")
        ax.plot(xt, -ctx.truth["wind_e_mps"], ":", color="tab:orange", label="-wind east (truth)")
    ax.set_ylabel("m/s")
    ax.legend(fontsize=7, loc="upper right")
    _finish_time_figure(fig, [ax], ctx, "ADS/ARMS: air-data velocity minus ground velocity "
                        "(wind plus sensor error; band: 2 sigma)")
    return fig


def _truth_value(st: Mapping[str, Any] | None, path: tuple[Any, ...] | None) -> float | None:
    if st is None or path is None:
        return None
    cur: Any = st
    for p in path:
        try:
            cur = cur[p]
        except (KeyError, IndexError, TypeError):
            return None
    return float(cur) if isinstance(cur, (int, float)) else None


def correction_rows(summary: Mapping[str, Any], sensor_truth: Mapping[str, Any] | None = None
                    ) -> list[dict[str, Any]]:
    """The estimated sensor corrections in display units: method, key, name, unit, value,
    two_sigma, truth (``None`` when unknown), the stored unit text."""
    rows = []
    for method, st in (summary.get("methods") or {}).items():
        corr = st.get("corrections") if isinstance(st, Mapping) else None
        if not isinstance(corr, Mapping):
            continue
        for key, val in corr.items():
            if isinstance(val, Mapping) and "value" in val:
                v, sd, note = val.get("value"), val.get("sd"), str(val.get("unit") or "")
            elif isinstance(val, (int, float)) and "_sd_" not in key and not key.endswith("_sd"):
                v, note = val, ""
                base, _, unit = key.rpartition("_")
                sd = corr.get(f"{base}_sd_{unit}", corr.get(f"{key}_sd"))
            else:
                continue
            if v is None:
                continue
            name, unit, f, tpath = CORRECTIONS.get(key, (None, None, 1.0, None))
            if name is None:
                name = key.replace("_", " ")
                unit = next((u for s, u in _UNIT_SUFFIX if key.endswith(s)), "")
            tv = _truth_value(sensor_truth, tpath)
            rows.append({"method": method, "key": key, "name": name, "unit": unit,
                         "value": float(v) * f,
                         "two_sigma": None if sd is None else 2 * float(sd) * f,
                         "truth": None if tv is None else tv * f, "note": note})
    return rows


def sensor_corrections(ctx: ReportContext) -> Figure | None:
    """Estimated sensor corrections with 2-sigma intervals, one row each on its own scale, in
    readable names and units; the simulated truth as a red cross when known."""
    rows = correction_rows(ctx.summary, ctx.sensor_truth)
    if not rows:
        return None
    fig, axes = plt.subplots(len(rows), 1, figsize=(10, 0.42 * len(rows) + 1.3), squeeze=False)
    for ax, r in zip(axes[:, 0], rows):
        v, s2, tv = r["value"], r["two_sigma"], r["truth"]
        ax.errorbar([v], [0], xerr=[s2] if s2 is not None and np.isfinite(s2) else None,
                    fmt="o", ms=4, capsize=3, color="k")
        if tv is not None:
            ax.plot([tv], [0], "x", color="tab:red", ms=8, mew=2)
        ax.axvline(0, color="0.5", lw=0.5)
        half = 1.15 * max(abs(v) + (s2 or 0), abs(tv or 0), 1e-9)
        ax.set_xlim(-half, half)
        ax.set_yticks([])
        ax.tick_params(axis="x", labelsize=6, pad=1)
        meth = METHOD_NAMES.get(r["method"], r["method"])
        ax.text(-0.01, 0.5, f"{r['name']} [{r['unit']}]  ({meth})", transform=ax.transAxes,
                ha="right", va="center", fontsize=7.5)
        txt = f"{v:.3g} ± {s2:.2g}" if s2 is not None else f"{v:.3g}"
        if tv is not None:
            txt += f"   truth {tv:.3g}"
        ax.text(1.01, 0.5, txt, transform=ax.transAxes, ha="left", va="center", fontsize=7.5)
        for s in ("top", "right", "left"):
            ax.spines[s].set_visible(False)
    fig.suptitle("Estimated sensor corrections (bars: 2 sigma"
                 + ("; red cross: simulated truth" if ctx.sensor_truth else "") + ")", fontsize=11)
    fig.subplots_adjust(left=0.42, right=0.80, top=1 - 0.55 / fig.get_figheight(),
                        bottom=0.25 / fig.get_figheight(), hspace=1.2)
    return fig


def innovation_statistics(ctx: ReportContext) -> Figure | None:
    """Mean normalised innovation squared per method and source (1 per component if consistent)."""
    rows = []
    for name, st in (ctx.summary.get("methods") or {}).items():
        if not isinstance(st, Mapping):
            continue
        for key, val in st.items():
            if "nis" in key.lower() and isinstance(val, (int, float)) and np.isfinite(val):
                rows.append((f"{METHOD_NAMES.get(name, name)}: {key.replace('_', ' ')}",
                             float(val)))
        srcs = st.get("sources")
        for src, stats in (srcs.items() if isinstance(srcs, Mapping) else ()):
            val = stats.get("mean_nis") if isinstance(stats, Mapping) else None
            if isinstance(val, (int, float)) and np.isfinite(val):
                flag = " (flagged)" if stats.get("flagged_inconsistent") else ""
                rows.append((f"{METHOD_NAMES.get(name, name)}: {src}{flag}", float(val)))
    if not rows:
        return None
    fig, ax = plt.subplots(figsize=(9, 0.35 * len(rows) + 1.5))
    ax.barh(range(len(rows)), [v for _, v in rows], color="tab:blue")
    ax.axvline(1.0, color="k", lw=0.8, ls="--")
    ax.text(1.0, 0.01, " 1 = consistent", fontsize=7, va="bottom",
            transform=ax.get_xaxis_transform())
    ax.set_yticks(range(len(rows)), [k for k, _ in rows], fontsize=8)
    ax.invert_yaxis()
    ax.set_xlabel("mean normalised innovation squared per component")
    ax.grid(alpha=0.3, axis="x")
    ax.set_title("Innovation statistics (mean NIS per component; about 1 when the noise budget "
                 "fits)", fontsize=10)
    fig.tight_layout()
    return fig


def newton_history(ctx: ReportContext) -> Figure | None:
    """Newton-Raphson iteration history of k1..k3 and of the end-point residual."""
    sab = (ctx.summary.get("methods") or {}).get("sabziev")
    if not isinstance(sab, Mapping):
        return None
    hist_axes = sab.get("history") or {}
    if not isinstance(hist_axes, Mapping) or not hist_axes:
        return None
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    names = {"x": "k1 (north)", "y": "k2 (up)", "z": "k3 (east)"}
    for axis, hist in hist_axes.items():
        if not hist:
            continue
        ks = [h[0] if isinstance(h, (list, tuple)) else h.get("k") for h in hist]
        fs = [h[1] if isinstance(h, (list, tuple)) else h.get("F") for h in hist]
        a1.plot(range(len(ks)), ks, "o-", ms=3, label=names.get(axis, axis))
        a2.semilogy(range(len(fs)), np.abs(np.asarray(fs, float)) + 1e-12, "o-", ms=3,
                    label=names.get(axis, axis))
    a1.set_xlabel("iteration")
    a1.set_ylabel("coefficient k")
    a2.set_xlabel("iteration")
    a2.set_ylabel("|end-point residual| [m]")
    for a in (a1, a2):
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    fig.suptitle("Sabziev fusion: Newton-Raphson iterations per axis", fontsize=11)
    fig.tight_layout()
    return fig


#: figure name -> (function, caption)
FIGURES: dict[str, tuple[Callable[[ReportContext], Figure | None], str]] = {
    "ground_track": (ground_track, "Ground track on a latitude/longitude grid"),
    "altitude_profile": (altitude_profile, "Altitude (MSL) and pressure altitude"),
    "speeds": (speeds, "Ground speed, airspeed and vertical speed"),
    "attitude": (attitude, "Attitude: roll, pitch, heading"),
    "load_factors": (load_factors, "Load factors"),
    "wind": (wind, "Wind: direction-from and speed"),
    "method_differences": (method_differences, "Methods compared"),
    "air_data_error": (air_data_error, "ADS/ARMS air-data error"),
    "sensor_corrections": (sensor_corrections, "Estimated sensor corrections"),
    "innovations": (innovation_statistics, "Innovation statistics"),
    "newton_history": (newton_history, "Sabziev Newton-Raphson iterations"),
}


def make_figures(track: pd.DataFrame, summary: Mapping[str, Any],
                 truth: pd.DataFrame | None = None, *, grid: pd.DataFrame | None = None,
                 gnss: pd.DataFrame | None = None,
                 sensor_truth: Mapping[str, Any] | None = None,
                 radar: pd.DataFrame | None = None) -> dict[str, Figure]:
    """Every figure the result supports, by name (see :data:`FIGURES`)."""
    ctx = ReportContext(track, summary, truth, grid, gnss, sensor_truth, radar)
    return make_figures_ctx(ctx)


def make_figures_ctx(ctx: ReportContext) -> dict[str, Figure]:
    out = {}
    for name, (fn, _caption) in FIGURES.items():
        fig = fn(ctx)
        if fig is not None:
            out[name] = fig
    return out
