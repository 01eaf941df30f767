"""Figures of a reconstruction (matplotlib, Agg backend).

Each function takes the result table (as written by ``reconstruct``) and the summary dict and
returns a :class:`matplotlib.figure.Figure`, or ``None`` when the result holds nothing to show.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
import pandas as pd  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402

PREFIXES = ("sabziev", "arms", "azimuth", "sns")
COLOURS = {"default": "k", "sabziev": "tab:blue", "arms": "tab:orange", "azimuth": "tab:green",
           "sns": "tab:red", "truth": "tab:gray"}


def _col(track: pd.DataFrame, name: str) -> np.ndarray | None:
    if name in track.columns:
        v = track[name].to_numpy(dtype=float)
        if np.isfinite(v).any():
            return v
    return None


def ground_track(track: pd.DataFrame, summary: dict[str, Any],
                 truth: pd.DataFrame | None = None) -> Figure | None:
    """Ground track (east vs north, km) of every method, with 2-sigma ellipses of the default."""
    n, e = _col(track, "north_m"), _col(track, "east_m")
    if n is None or e is None:
        return None
    fig, ax = plt.subplots(figsize=(7.5, 7))
    if truth is not None and {"north_m", "east_m"} <= set(truth.columns):
        ax.plot(truth["east_m"] / 1e3, truth["north_m"] / 1e3, color=COLOURS["truth"], lw=3,
                alpha=0.4, label="truth")
    for p in PREFIXES:
        pn, pe = _col(track, f"{p}_north_m"), _col(track, f"{p}_east_m")
        if pn is not None and pe is not None:
            ax.plot(pe / 1e3, pn / 1e3, color=COLOURS[p], lw=1, label=p)
    ax.plot(e / 1e3, n / 1e3, color="k", lw=1.2, ls="--", label="default result")
    sn, se = _col(track, "north_sd_m"), _col(track, "east_sd_m")
    if sn is not None and se is not None:
        idx = np.flatnonzero(np.isfinite(sn) & np.isfinite(se) & np.isfinite(n))
        for i in idx[:: max(1, len(idx) // 40)]:
            ax.add_patch(matplotlib.patches.Ellipse((e[i] / 1e3, n[i] / 1e3), 4 * se[i] / 1e3,
                                                    4 * sn[i] / 1e3, fill=False, color="k",
                                                    lw=0.6, alpha=0.6))
    ax.set_xlabel("east [km]")
    ax.set_ylabel("north [km]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.grid(alpha=0.3)
    ax.legend(loc="best", fontsize=8)
    ax.set_title("Ground track (tangent plane at departure); ellipses: 2 sigma, axis-aligned")
    fig.tight_layout()
    return fig


def altitude_profile(track: pd.DataFrame, summary: dict[str, Any],
                     truth: pd.DataFrame | None = None) -> Figure | None:
    """Reconstructed height vs pressure-derived height against time."""
    up = _col(track, "up_m")
    if up is None:
        return None
    t = track["t_s"].to_numpy() / 60.0
    fig, ax = plt.subplots(figsize=(9, 4))
    if truth is not None and "up_m" in truth.columns:
        ax.plot(truth["t_s"] / 60, truth["up_m"], color=COLOURS["truth"], lw=3, alpha=0.4,
                label="truth")
    su = _col(track, "sabziev_up_m")
    if su is not None:
        ax.plot(t, su, color=COLOURS["sabziev"], lw=1, label="sabziev")
    ax.plot(t, up, "k--", lw=1, label="default result")
    if "up_source" in track.columns:
        baro = (track["up_source"].astype(str) == "baro").to_numpy()
        if baro.any():
            ax.plot(t[baro], up[baro], ".", ms=1, color="tab:purple", label="from pressure altitude")
    ax.set_xlabel("time [min]")
    ax.set_ylabel("up [m]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title("Height above the departure tangent plane")
    fig.tight_layout()
    return fig


def method_differences(track: pd.DataFrame, summary: dict[str, Any],
                       truth: pd.DataFrame | None = None) -> Figure | None:
    """Each method's horizontal position minus the reference (truth if given, else default)."""
    ref_name = "truth" if truth is not None else "default result"
    if truth is not None:
        ref = pd.DataFrame({"t_s": track["t_s"]}).merge(truth[["t_s", "north_m", "east_m"]],
                                                        on="t_s", how="left")
        rn, re_ = ref["north_m"].to_numpy(), ref["east_m"].to_numpy()
    else:
        rn, re_ = _col(track, "north_m"), _col(track, "east_m")
    if rn is None or re_ is None:
        return None
    t = track["t_s"].to_numpy() / 60.0
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    drawn = False
    if truth is not None:
        dn, de = _col(track, "north_m"), _col(track, "east_m")
        if dn is not None and de is not None:
            drawn = True
            axes[0].plot(t, dn - rn, "k--", lw=1, label="default result")
            axes[1].plot(t, de - re_, "k--", lw=1, label="default result")
            for ax, c in ((axes[0], "north_sd_m"), (axes[1], "east_sd_m")):
                sd = _col(track, c)
                if sd is not None:
                    ax.fill_between(t, -2 * sd, 2 * sd, color="k", alpha=0.12)
    for p in PREFIXES:
        pn, pe = _col(track, f"{p}_north_m"), _col(track, f"{p}_east_m")
        if pn is None or pe is None:
            continue
        drawn = True
        axes[0].plot(t, pn - rn, color=COLOURS[p], lw=1, label=p)
        axes[1].plot(t, pe - re_, color=COLOURS[p], lw=1, label=p)
        sd = _col(track, f"{p}_north_sd_m")
        if sd is not None:
            axes[0].fill_between(t, -2 * sd, 2 * sd, color=COLOURS[p], alpha=0.12)
        sd = _col(track, f"{p}_east_sd_m")
        if sd is not None:
            axes[1].fill_between(t, -2 * sd, 2 * sd, color=COLOURS[p], alpha=0.12)
    if not drawn:
        plt.close(fig)
        return None
    axes[0].set_ylabel(f"north - {ref_name} [m]")
    axes[1].set_ylabel(f"east - {ref_name} [m]")
    axes[1].set_xlabel("time [min]")
    for a in axes:
        a.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    axes[0].set_title("Methods against each other (bands: each method's own 2 sigma)")
    fig.tight_layout()
    return fig


def _north_east_with_bands(track: pd.DataFrame, cols: tuple[str, str], sd_cols: tuple[str, str],
                           label: str, title: str, truth: pd.DataFrame | None,
                           truth_sign: float) -> Figure | None:
    """North and east series of ``track`` with 2-sigma bands, and the truth wind (times
    ``truth_sign``) dotted when given."""
    vn, ve = _col(track, cols[0]), _col(track, cols[1])
    if vn is None or ve is None:
        return None
    t = track["t_s"].to_numpy() / 60.0
    fig, ax = plt.subplots(figsize=(9, 4))
    for v, sd_col, name, c in ((vn, sd_cols[0], "north", "tab:blue"),
                               (ve, sd_cols[1], "east", "tab:orange")):
        ax.plot(t, v, color=c, lw=1, label=f"{label} {name}")
        sd = _col(track, sd_col)
        if sd is not None:
            ax.fill_between(t, v - 2 * sd, v + 2 * sd, color=c, alpha=0.15)
    if truth is not None and {"wind_n_mps", "wind_e_mps"} <= set(truth.columns):
        sign = "-" if truth_sign < 0 else ""
        for col, name, c in (("wind_n_mps", "north", "tab:blue"), ("wind_e_mps", "east", "tab:orange")):
            ax.plot(truth["t_s"] / 60, truth_sign * truth[col], ":", color=c,
                    label=f"{sign}wind {name} (truth)")
    ax.set_xlabel("time [min]")
    ax.set_ylabel("m/s")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(title)
    fig.tight_layout()
    return fig


def corrections_and_wind(track: pd.DataFrame, summary: dict[str, Any],
                         truth: pd.DataFrame | None = None) -> Figure | None:
    """Estimated air-data error (wind plus sensor error) from ADS/ARMS, with 2-sigma bands."""
    return _north_east_with_bands(
        track, ("arms_dvn_mps", "arms_dve_mps"), ("arms_dvn_sd_mps", "arms_dve_sd_mps"),
        "air-data error", "ADS/ARMS: estimated air-data error (air-data velocity minus ground "
        "velocity)", truth, -1.0)


def sensor_corrections(track: pd.DataFrame, summary: dict[str, Any],
                       truth: pd.DataFrame | None = None) -> Figure | None:
    """Estimated sensor corrections with their 2-sigma intervals (from the summary)."""
    items = []
    for name, st in (summary.get("methods") or {}).items():
        corr = st.get("corrections") if isinstance(st, dict) else None
        if not isinstance(corr, dict):
            continue
        for key, val in corr.items():
            if isinstance(val, dict) and "value" in val:
                items.append((f"{name}: {key}", float(val["value"]), float(val.get("sd") or np.nan)))
    if not items:
        return None
    # one row per correction, each on its own scale (the units differ: deg, m, g, ratios)
    fig, axes = plt.subplots(len(items), 1, figsize=(8, 0.55 * len(items) + 1.2), squeeze=False)
    for ax, (name, v, sd) in zip(axes[:, 0], items):
        ax.errorbar([v], [0], xerr=[2 * sd] if np.isfinite(sd) else None, fmt="o", capsize=4)
        ax.axvline(0, color="k", lw=0.5)
        half = max(abs(v) + 2.5 * (sd if np.isfinite(sd) else 0), 1e-12)
        ax.set_xlim(-half, half)
        ax.set_yticks([])
        ax.set_ylabel(name, rotation=0, ha="right", va="center", fontsize=8)
        ax.tick_params(axis="x", labelsize=7)
        ax.text(0.99, 0.5, f"{v:.4g} +- {2 * sd:.2g}", transform=ax.transAxes, ha="right",
                va="center", fontsize=7)
    axes[0, 0].set_title("Estimated sensor corrections (bars: 2 sigma; units in the names)")
    fig.tight_layout()
    return fig


def newton_history(track: pd.DataFrame, summary: dict[str, Any],
                   truth: pd.DataFrame | None = None) -> Figure | None:
    """Newton-Raphson iteration history of k1..k3 and of the end-point residual."""
    sab = (summary.get("methods") or {}).get("sabziev")
    if not isinstance(sab, dict):
        return None
    axes_hist = sab.get("history") or {}
    if not isinstance(axes_hist, dict) or not axes_hist:
        return None
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(10, 4))
    for axis, hist in axes_hist.items():
        if not hist:
            continue
        ks = [h[0] if isinstance(h, (list, tuple)) else h.get("k") for h in hist]
        fs = [h[1] if isinstance(h, (list, tuple)) else h.get("F") for h in hist]
        a1.plot(range(len(ks)), ks, "o-", label=axis)
        a2.semilogy(range(len(fs)), np.abs(np.asarray(fs, float)) + 1e-12, "o-", label=axis)
    a1.set_xlabel("iteration")
    a1.set_ylabel("k")
    a2.set_xlabel("iteration")
    a2.set_ylabel("|end-point residual| [m]")
    for a in (a1, a2):
        a.grid(alpha=0.3)
        a.legend(fontsize=8)
    fig.suptitle("Sabziev fusion: Newton-Raphson iterations")
    fig.tight_layout()
    return fig


def innovation_statistics(track: pd.DataFrame, summary: dict[str, Any],
                          truth: pd.DataFrame | None = None) -> Figure | None:
    """Mean normalised innovation squared per method and source (1 per component if consistent)."""
    rows = []
    for name, st in (summary.get("methods") or {}).items():
        if not isinstance(st, dict):
            continue
        for key, val in st.items():
            if "nis" in key.lower() and isinstance(val, (int, float)) and np.isfinite(val):
                rows.append((f"{name}: {key}", float(val)))
        # the joint smoother's statistics per source
        for src, stats in (st.get("sources") or {}).items() if isinstance(st.get("sources"), dict) else ():
            val = stats.get("mean_nis") if isinstance(stats, dict) else None
            if isinstance(val, (int, float)) and np.isfinite(val):
                flag = " (flagged)" if stats.get("flagged_inconsistent") else ""
                rows.append((f"{name}: {src}{flag}", float(val)))
    if not rows:
        return None
    fig, ax = plt.subplots(figsize=(8, 0.45 * len(rows) + 1.5))
    ax.barh(range(len(rows)), [v for _, v in rows])
    ax.axvline(1.0, color="k", lw=0.8, ls="--")
    ax.text(1.0, len(rows) - 0.4, " consistent: 1 per component", fontsize=7)
    ax.set_yticks(range(len(rows)), [k for k, _ in rows])
    ax.grid(alpha=0.3)
    ax.set_title("Innovation statistics per method (mean NIS)")
    fig.tight_layout()
    return fig


def wind(track: pd.DataFrame, summary: dict[str, Any],
         truth: pd.DataFrame | None = None) -> Figure | None:
    """Wind estimated by the joint smoother (where the air moves to), with 2-sigma bands."""
    return _north_east_with_bands(
        track, ("wind_n_mps", "wind_e_mps"), ("wind_n_sd_mps", "wind_e_sd_mps"), "wind (joint)",
        "Wind (velocity of the air over the ground); unobservable on the ground", truth, 1.0)


FIGURES: dict[str, Callable[..., Figure | None]] = {
    "ground_track": ground_track,
    "altitude_profile": altitude_profile,
    "method_differences": method_differences,
    "wind": wind,
    "air_data_error": corrections_and_wind,
    "sensor_corrections": sensor_corrections,
    "innovations": innovation_statistics,
    "newton_history": newton_history,
}


def make_figures(track: pd.DataFrame, summary: dict[str, Any],
                 truth: pd.DataFrame | None = None) -> dict[str, Figure]:
    """Every figure the result supports, by name."""
    out = {}
    for name, fn in FIGURES.items():
        fig = fn(track, summary, truth)
        if fig is not None:
            out[name] = fig
    return out
