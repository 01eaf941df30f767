"""Diagnostic figures: the methods compared, the air-data error, the estimated sensor corrections,
innovation statistics and the Sabziev Newton iterations."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import matplotlib.pyplot as plt
import numpy as np
import pandas as pd
from matplotlib.figure import Figure

from flightrecon.report.plots.context import (
    COLOURS,
    METHOD_NAMES,
    PREFIXES,
    ReportContext,
    column_values,
    finish_time_figure,
)

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
        rn, re_ = column_values(track, "north_m"), column_values(track, "east_m")
    if rn is None or re_ is None:
        return None
    x = ctx.time(track["t_s"])
    fig, axes = plt.subplots(2, 1, figsize=(10, 6), sharex=True)
    drawn = False
    if truth is not None:
        dn, de = column_values(track, "north_m"), column_values(track, "east_m")
        if dn is not None and de is not None:
            drawn = True
            axes[0].plot(x, dn - rn, "k", lw=1, label="default result")
            axes[1].plot(x, de - re_, "k", lw=1, label="default result")
            for ax, c in ((axes[0], "north_sd_m"), (axes[1], "east_sd_m")):
                sd = column_values(track, c)
                if sd is not None:
                    ax.fill_between(x, -2 * sd, 2 * sd, color="k", alpha=0.12, lw=0)
    diffs = {}
    for p in PREFIXES:
        pn, pe = column_values(track, f"{p}_north_m"), column_values(track, f"{p}_east_m")
        if pn is not None and pe is not None:
            diffs[p] = (pn - rn, pe - re_)
    # the scale: the well-determined methods (a method kilometres off would flatten the rest
    # to a line); one whose error leaves it is drawn clipped and named "off scale"
    sizes = {p: float(np.nanpercentile(np.abs(np.r_[d[0], d[1]]), 95))
             for p, d in diffs.items() if np.isfinite(np.r_[d[0], d[1]]).any()}
    dn_, de_ = column_values(track, "north_m"), column_values(track, "east_m")
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
            sd = column_values(track, c)
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
    finish_time_figure(fig, list(axes), ctx, f"Methods against the {ref_name} (bands: each "
                        "method's own 2 sigma)")
    return fig


def air_data_error(ctx: ReportContext) -> Figure | None:
    """Estimated air-data error of ADS/ARMS (air-data velocity minus ground velocity)."""
    vn, ve = column_values(ctx.track, "arms_dvn_mps"), column_values(ctx.track, "arms_dve_mps")
    if vn is None or ve is None:
        return None
    x = ctx.time(ctx.track["t_s"])
    fig, ax = plt.subplots(figsize=(10, 4))
    for v, sdc, name, c in ((vn, "arms_dvn_sd_mps", "north", "tab:blue"),
                            (ve, "arms_dve_sd_mps", "east", "tab:orange")):
        ax.plot(x, v, color=c, lw=1, label=f"air-data error, {name}")
        sd = column_values(ctx.track, sdc)
        if sd is not None:
            ax.fill_between(x, v - 2 * sd, v + 2 * sd, color=c, alpha=0.15, lw=0)
    if ctx.truth is not None and {"wind_n_mps", "wind_e_mps"} <= set(ctx.truth.columns):
        xt = ctx.time(ctx.truth["t_s"])
        ax.plot(xt, -ctx.truth["wind_n_mps"], ":", color="tab:blue", label="-wind north (truth)")
        ax.plot(xt, -ctx.truth["wind_e_mps"], ":", color="tab:orange", label="-wind east (truth)")
    ax.set_ylabel("m/s")
    ax.legend(fontsize=7, loc="upper right")
    finish_time_figure(fig, [ax], ctx, "ADS/ARMS: air-data velocity minus ground velocity "
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


