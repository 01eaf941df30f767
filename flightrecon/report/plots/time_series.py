"""Time-series figures: altitude, speeds, attitude, load factors and wind."""

from __future__ import annotations

from collections.abc import Mapping

import matplotlib.pyplot as plt
import numpy as np
from matplotlib.figure import Figure

from flightrecon.report.plots.context import (
    COLOURS,
    FPM,
    FT,
    KT,
    ReportContext,
    column_values,
    finish_time_figure,
    twin_units,
)


def altitude_profile(ctx: ReportContext) -> Figure | None:
    """Altitude above MSL of the default result with its 2-sigma band, pressure altitude from
    the recorder, airfield elevations; metres left, feet right."""
    alt = column_values(ctx.track, "alt_m")
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
        sd = column_values(ctx.track, "up_sd_m")
        if sd is not None:
            ax.fill_between(x, msl - 2 * sd, msl + 2 * sd, color="k", alpha=0.15, lw=0,
                            label="2 sigma")
        ax.plot(x, msl, "k", lw=1.2, label="reconstructed altitude, MSL")
        ylab = "altitude [m]"
    else:
        ax.plot(x, alt, "k", lw=1.2, label="reconstructed WGS-84 ellipsoidal height "
                "(geoid undulation unknown: not MSL)")
        ylab = "height [m]"
    hp = column_values(ctx.grid, "baro_alt_m")
    g = ctx.grid
    if hp is not None and g is not None:
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
    twin_units(ax, FT, "altitude [ft]")
    ax.legend(fontsize=7, loc="best")
    finish_time_figure(fig, [ax], ctx, "Altitude above mean sea level and pressure altitude "
                        "(band: 2 sigma)")
    return fig


def speeds(ctx: ReportContext) -> Figure | None:
    """Ground speed and true airspeed (m/s, kt), vertical speed (m/s, ft/min), 2-sigma bands."""
    vn, ve = column_values(ctx.track, "vn_mps"), column_values(ctx.track, "ve_mps")
    if vn is None or ve is None:
        return None
    x = ctx.time(ctx.track["t_s"])
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    if ctx.truth is not None and "gs_mps" in ctx.truth.columns:
        a1.plot(ctx.time(ctx.truth["t_s"]), ctx.truth["gs_mps"], color=COLOURS["truth"], lw=4,
                alpha=0.35, label="ground speed, truth")
    gs = np.hypot(vn, ve)
    sdn, sde = column_values(ctx.track, "vn_sd_mps"), column_values(ctx.track, "ve_sd_mps")
    if sdn is not None and sde is not None:
        with np.errstate(invalid="ignore", divide="ignore"):
            sd = np.sqrt((vn * sdn) ** 2 + (ve * sde) ** 2) / np.where(gs > 0.1, gs, np.nan)
        sd = np.where(np.isfinite(sd), sd, np.hypot(sdn, sde))
        a1.fill_between(x, gs - 2 * sd, gs + 2 * sd, color="k", alpha=0.15, lw=0)
    a1.plot(x, gs, "k", lw=1.1, label="ground speed (reconstructed)")
    tas = column_values(ctx.grid, "tas_mps")
    if tas is not None and ctx.grid is not None:
        a1.plot(ctx.time(ctx.grid["t_s"]), tas, color="tab:orange", lw=0.9,
                label="true airspeed (recorded)")
    a1.set_ylabel("speed [m/s]")
    twin_units(a1, KT, "speed [kt]")
    a1.legend(fontsize=7, loc="upper right")
    vu = column_values(ctx.track, "vu_mps")
    if vu is not None:
        if ctx.truth is not None and "vu_mps" in ctx.truth.columns:
            a2.plot(ctx.time(ctx.truth["t_s"]), ctx.truth["vu_mps"], color=COLOURS["truth"], lw=4,
                    alpha=0.35, label="truth")
        sdu = column_values(ctx.track, "vu_sd_mps")
        if sdu is not None:
            a2.fill_between(x, vu - 2 * sdu, vu + 2 * sdu, color="k", alpha=0.15, lw=0)
        a2.plot(x, vu, "k", lw=1.0, label="vertical speed (reconstructed, up positive)")
        a2.legend(fontsize=7, loc="upper right")
    a2.axhline(0, color="k", lw=0.5)
    a2.set_ylabel("vertical speed [m/s]")
    twin_units(a2, FPM, "vertical speed [ft/min]")
    finish_time_figure(fig, [a1, a2], ctx, "Speeds (bands: 2 sigma)")
    return fig


def attitude(ctx: ReportContext) -> Figure | None:
    """Recorded roll, pitch and heading (truth overlaid), with the reconstructed track angle."""
    cols = [c for c in ("roll_deg", "pitch_deg", "heading_deg") if column_values(ctx.grid, c) is not None]
    if not cols:
        return None
    g = ctx.grid
    if not cols or g is None:
        return None
    fig, ax_grid = plt.subplots(len(cols), 1, figsize=(10, 2.2 * len(cols) + 1), sharex=True,
                                squeeze=False)
    axes = list(ax_grid[:, 0])
    names = {"roll_deg": "roll [deg] (right wing down +)", "pitch_deg": "pitch [deg] (nose up +)",
             "heading_deg": "heading [deg true]"}
    for ax, c in zip(axes, cols):
        v = column_values(g, c)
        if v is None:
            continue
        if c == "heading_deg":
            v = np.mod(v, 360.0)
        if ctx.truth is not None and c in ctx.truth.columns:
            tv = ctx.truth[c].to_numpy(float)
            ax.plot(ctx.time(ctx.truth["t_s"]), np.mod(tv, 360) if c == "heading_deg" else tv,
                    ".", ms=1, color=COLOURS["truth"], alpha=0.5, label="truth")
        ax.plot(ctx.time(g["t_s"]), v, "." if c == "heading_deg" else "-", ms=1, lw=0.8,
                color="tab:blue", label="recorded")
        if c == "heading_deg":
            vn, ve = column_values(ctx.track, "vn_mps"), column_values(ctx.track, "ve_mps")
            if vn is not None and ve is not None:
                trk = np.mod(np.degrees(np.arctan2(ve, vn)), 360.0)
                trk[np.hypot(vn, ve) < 5] = np.nan
                ax.plot(ctx.time(ctx.track["t_s"]), trk, ".", ms=1, color="k",
                        label="track angle (reconstructed)")
            ax.set_ylim(0, 360)
            ax.set_yticks([0, 90, 180, 270, 360])
        ax.set_ylabel(names[c], fontsize=8)
        ax.legend(fontsize=7, loc="upper right", markerscale=6)
    finish_time_figure(fig, axes, ctx, "Attitude (recorded; shaded red: exceedances)")
    return fig


def load_factors(ctx: ReportContext) -> Figure | None:
    """Recorded body load factors with the envelope limits of the events."""
    cols = [c for c in ("n_long_g", "n_lat_g", "n_norm_g") if column_values(ctx.grid, c) is not None]
    if not cols:
        return None
    from flightrecon.events import Envelope

    env = Envelope()
    grid = ctx.grid
    if grid is None:
        return None
    fig, ax_grid = plt.subplots(len(cols), 1, figsize=(10, 2.0 * len(cols) + 1), sharex=True,
                                squeeze=False)
    axes = list(ax_grid[:, 0])
    names = {"n_long_g": "longitudinal [g]\n(forward +)", "n_lat_g": "lateral [g]\n(right +)",
             "n_norm_g": "normal [g]\n(1 in level flight)"}
    for ax, c in zip(axes, cols):
        if ctx.truth is not None and c in ctx.truth.columns:
            ax.plot(ctx.time(ctx.truth["t_s"]), ctx.truth[c], color=COLOURS["truth"], lw=3,
                    alpha=0.35, label="truth")
        ax.plot(ctx.time(grid["t_s"]), column_values(grid, c), lw=0.6, color="tab:blue",
                label="recorded")
        if c == "n_norm_g":
            for lim in (env.n_max_g, env.n_min_g):
                ax.axhline(lim, color="tab:red", lw=0.8, ls="--")
            ax.text(0.005, env.n_max_g, f"limit {env.n_max_g:+g} g", color="tab:red", fontsize=7,
                    transform=ax.get_yaxis_transform(), va="bottom")
            vn = column_values(grid, c)
            lo, hi = np.nanpercentile(vn if vn is not None else np.full(1, np.nan),
                                      [0.05, 99.95])
            ax.set_ylim(min(lo - 0.2, env.n_min_g - 0.2), max(hi + 0.2, env.n_max_g + 0.2))
        ax.set_ylabel(names[c], fontsize=8)
        ax.legend(fontsize=7, loc="upper right")
    finish_time_figure(fig, axes, ctx, "Load factors (recorded, body axes; dashed: limit load "
                        "factors)")
    return fig


def wind_from_speed(wn: np.ndarray, we: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Direction the wind blows from [deg true, 0..360) and its speed, from the velocity of
    the air (north, east: where it moves to)."""
    return np.mod(np.degrees(np.arctan2(-we, -wn)), 360.0), np.hypot(wn, we)


def wind(ctx: ReportContext) -> Figure | None:
    """Wind of the joint smoother as direction-from and speed (m/s and kt), 2-sigma bands; the
    recorded wind channel and the truth overlaid; grey where the aircraft is on the ground."""
    wn, we = column_values(ctx.track, "wind_n_mps"), column_values(ctx.track, "wind_e_mps")
    if wn is None or we is None:
        return None
    x = ctx.time(ctx.track["t_s"])
    dirn, spd = wind_from_speed(wn, we)
    sdn, sde = column_values(ctx.track, "wind_n_sd_mps"), column_values(ctx.track, "wind_e_sd_mps")
    fig, (a1, a2) = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    if ctx.truth is not None and {"wind_n_mps", "wind_e_mps"} <= set(ctx.truth.columns):
        wd_t, ts = wind_from_speed(ctx.truth["wind_n_mps"].to_numpy(float),
                                  ctx.truth["wind_e_mps"].to_numpy(float))
        xt = ctx.time(ctx.truth["t_s"])
        a1.plot(xt, wd_t, ".", ms=3, color=COLOURS["truth"], alpha=0.4, label="truth")
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
    twin_units(a2, KT, "wind speed [kt]")
    a2.set_ylim(bottom=0)
    ph = ctx.summary.get("phases") or {}
    tt = ctx.track["t_s"].to_numpy(float)
    for ax in (a1, a2):
        lo, td = ph.get("liftoff_t_s"), ph.get("touchdown_t_s")
        if lo is not None and np.isfinite(lo) and tt[0] < lo:
            ax.axvspan(*ctx.time([tt[0], lo]), color="0.85", lw=0, zorder=0)
        if td is not None and np.isfinite(td) and td < tt[-1]:
            ax.axvspan(*ctx.time([td, tt[-1]]), color="0.85", lw=0, zorder=0)
        ax.legend(fontsize=7, loc="upper right", markerscale=6)
    finish_time_figure(fig, [a1, a2], ctx, "Wind: direction it blows from and speed (light "
                        "grey: on the ground, wind unobservable)")
    return fig
