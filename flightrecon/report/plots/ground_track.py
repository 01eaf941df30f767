"""The map: the ground track of every method, the sources and the airfields (WGS-84
latitude/longitude)."""

from __future__ import annotations

import math
from collections.abc import Mapping
from datetime import timedelta
from typing import Any

import matplotlib
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import LineCollection
from matplotlib.figure import Figure
from matplotlib.patches import Ellipse

from flightrecon.report.plots.context import (
    COLOURS,
    METHOD_NAMES,
    PREFIXES,
    ReportContext,
    column_values,
    event_numbers,
)


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
    n, e = column_values(ctx.track, f"{prefix}_north_m"), column_values(ctx.track, f"{prefix}_east_m")
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
    r, az = column_values(rd, "arms_range_m"), column_values(rd, "arms_azimuth_deg")
    if r is None or az is None:
        return None
    el = column_values(rd, "arms_elevation_deg")
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
    known positions (``--fix``) with their 2-sd circles, start/end, numbered events, every
    method, the default result coloured by its horizontal 2-sigma and its 2-sigma ellipses (to
    scale)."""
    lat, lon = column_values(ctx.track, "lat_deg"), column_values(ctx.track, "lon_deg")
    if lat is None or lon is None:
        return None
    fig, ax = plt.subplots(figsize=(9, 8.2))
    lat0 = float(np.nanmean(lat))
    coslat = math.cos(math.radians(lat0))
    _draw_sources(ax, ctx)
    ok = np.isfinite(lat) & np.isfinite(lon)
    _draw_default(fig, ax, ctx, lat, lon, ok, coslat)
    first, last = np.flatnonzero(ok)[[0, -1]]
    ax.plot(lon[first], lat[first], "o", color="tab:green", ms=8, zorder=6, label="start of record")
    ax.plot(lon[last], lat[last], "s", color="tab:red", ms=8, zorder=6, label="end of record")
    _draw_airfields(ax, ctx, coslat)
    _draw_known_positions(ax, ctx, coslat)
    _draw_map_events(ax, ctx, lat, lon, ok)
    _finish_map(fig, ax, coslat)
    return fig


def _draw_sources(ax, ctx: ReportContext) -> None:
    """Truth, GNSS fixes, radar plots and every method's track."""
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


def _draw_default(fig, ax, ctx: ReportContext, lat: np.ndarray, lon: np.ndarray,
                  ok: np.ndarray, coslat: float) -> None:
    """The default result coloured by its horizontal 2-sigma radius, with 2-sigma ellipses."""
    sn, se = column_values(ctx.track, "north_sd_m"), column_values(ctx.track, "east_sd_m")
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


def _draw_airfields(ax, ctx: ReportContext, coslat: float) -> None:
    """Airfields, runways and the radar station from the metadata."""
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


def known_positions(ctx: ReportContext) -> list[Mapping[str, Any]]:
    """The known positions given with ``--fix`` (``t_s``, ``lat_deg``, ``lon_deg``, ``sd_m``):
    the flight metadata's ``fixes`` in the summary, else the joint smoother's ``fixes`` report."""
    fixes = ctx.flight.get("fixes")
    if not fixes:
        joint = (ctx.summary.get("methods") or {}).get("joint")
        fixes = joint.get("fixes") if isinstance(joint, Mapping) else None
    return [f for f in fixes or () if isinstance(f, Mapping) and f.get("lat_deg") is not None
            and f.get("lon_deg") is not None]


def _draw_known_positions(ax, ctx: ReportContext, coslat: float) -> None:
    """Known positions (``--fix``): a marker each, its 2-sd circle (sd per horizontal axis,
    to scale) where an sd is given, labelled with its time (UTC where the epoch is known,
    else seconds from the record start)."""
    fixes = known_positions(ctx)
    if not fixes:
        return
    for f in fixes:
        la, lo = float(f["lat_deg"]), float(f["lon_deg"])
        ax.plot(lo, la, "*", ms=13, mfc="gold", mec="saddlebrown", mew=1.0, zorder=8,
                gid="known_position")
        sd = f.get("sd_m")
        if sd is not None and np.isfinite(float(sd)) and float(sd) > 0:
            ax.add_patch(Ellipse((lo, la), 4 * float(sd) / (111320.0 * coslat),
                                 4 * float(sd) / 110540.0, fill=False, color="saddlebrown",
                                 lw=1.2, ls="--", zorder=8, gid="known_position_2sd"))
        t = f.get("t_s")
        if t is not None and np.isfinite(float(t)):
            when = (f"{ctx.epoch + timedelta(seconds=float(t)):%H:%M:%S} UTC"
                    if ctx.epoch is not None else f"t = {float(t):.0f} s")
            ax.annotate(f"fix {when}", (lo, la), xytext=(8, 6), textcoords="offset points",
                        fontsize=7, color="saddlebrown", zorder=8)
    ax.plot([], [], "*", ms=11, mfc="gold", mec="saddlebrown",
            label=f"known positions (--fix, {len(fixes)}), dashed: 2-sd circle")


def _draw_map_events(ax, ctx: ReportContext, lat: np.ndarray, lon: np.ndarray,
                     ok: np.ndarray) -> None:
    """Numbered events along the track (numbers: the events table)."""
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


def _finish_map(fig, ax, coslat: float) -> None:
    """Grid, axis labels, scale bar, north arrow, legend and title."""
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
