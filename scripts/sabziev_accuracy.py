"""Accuracy of the Sabziev boundary-value fusion on simulated flights (docs/sabziev.md).

For each scenario variant and seed: simulate (``flightrecon.sim.simulate``), clean
(``flightrecon.cleaning.clean_flight``), run the fusion (``flightrecon.methods.sabziev.method``) and
compare, between lift-off and touchdown, with the truth:

* ``sabziev (airfield points)``: the product's default: lift-off point = departure airfield
  reference point, end point = arrival airfield reference point (the simulator puts each
  reference point 800 m down the runway from the take-off roll start / touchdown point);
* ``sabziev (true lift-off/touchdown)``: the same with the true lift-off and touchdown points
  (isolates the method from the end-point definition);
* ``sabziev (true points and lift-off velocity)``: also with the true lift-off ground velocity
  instead of the ground-roll estimate of the cleaning stage;
* ``air DR``: dead reckoning from airspeed and heading (plus the wind channel where the log has
  one) from the lift-off point, vertical = baro height above the departure airfield;
* ``air DR + linear correction``: the same with the end-point error removed linearly in time
  (horizontal: to the arrival airfield point; vertical: to the pressure end height).

Truth frame: north/east in the tangent plane at the departure airfield; up = height above the
departure airfield's MSL elevation (the Sabziev vertical is a pressure height: a temperature
deviation from ISA shows up as a scale error).

Usage::

    python scripts/sabziev_accuracy.py            # full size (5 seeds per variant)
    python scripts/sabziev_accuracy.py --seeds 1  # quick look
    python scripts/sabziev_accuracy.py --independent  # corpus + JSBSim flights, both policies
                                                      # (docs/tables/sabziev_independent.md)
    python scripts/sabziev_accuracy.py --fleet        # the JSBSim fleet's other aircraft and
                                                      # schedules (docs/tables/sabziev_fleet.md)
    python scripts/sabziev_accuracy.py --variants     # the same with a forecast / fleet k
                                                      # (docs/tables/sabziev_variants.md)

Writes ``docs/tables/sabziev_accuracy.md`` and ``docs/figures/sabziev_accuracy.png``,
``docs/figures/sabziev_newton.png``.
"""

from __future__ import annotations

import argparse
import sys
import time
import warnings
from pathlib import Path

import matplotlib

sys.path.insert(0, str(Path(__file__).resolve().parent))

from table_header import header  # noqa: E402

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from flightrecon.cleaning import clean_flight
from flightrecon.geo.atmosphere import field_pressure_altitude_m
from flightrecon.geo.frames import msl_to_ellipsoid, output_plane
from flightrecon.methods.sabziev import air_velocity
from flightrecon.methods.sabziev.method import run_sabziev
from flightrecon.sim import simulate
from flightrecon.types import Flight, Position

VARIANTS = (
    ("circuit", "circuit, no wind channel", {"wind_hz": 0.0}),
    ("circuit", "circuit, wind channel", {"wind_hz": 1.0}),
    ("regional", "regional, wind channel", {"wind_hz": 1.0}),
    ("regional", "regional, no wind channel", {"wind_hz": 0.0}),
)
METHODS = ("sabziev (airfield points)", "sabziev (true lift-off/touchdown)",
           "sabziev (true points and lift-off velocity)", "air DR", "air DR + linear correction")
AXES = ("north", "east", "up")


def _truth_on(t, truth, dep_elev):
    out = {}
    for ax, col in (("north", "north_m"), ("east", "east_m")):
        out[ax] = np.interp(t, truth["t_s"], truth[col])
    out["up"] = np.interp(t, truth["t_s"], truth["alt_msl_m"]) - dep_elev
    return out


def _truth_point(truth, t_s) -> Position:
    lat = float(np.interp(t_s, truth["t_s"], truth["lat_deg"]))
    lon = float(np.interp(t_s, truth["t_s"], truth["lon_deg"]))
    elev = float(np.interp(t_s, truth["t_s"], truth["alt_msl_m"]))
    return Position(lat, lon, elev)


def dead_reckoning(clean, sl, end_neu) -> tuple[dict, dict]:
    """Air-data dead reckoning and its linearly end-corrected version on the interval."""
    g = clean.grid
    t = g["t_s"].to_numpy()[sl]
    tas = np.interp(t, t[np.isfinite(g["tas_mps"].to_numpy()[sl])],
                    g["tas_mps"].to_numpy()[sl][np.isfinite(g["tas_mps"].to_numpy()[sl])])
    psi = np.radians(g["heading_deg"].to_numpy()[sl])
    hp_dep = field_pressure_altitude_m(clean.meta.departure.elev_m,
                                       clean.meta.qnh_departure_hpa)
    h = g["baro_alt_m"].to_numpy()[sl] - hp_dep
    climb = np.gradient(h, t)
    wind = None
    if "wind_speed_mps" in g.columns and np.isfinite(g["wind_speed_mps"].to_numpy()[sl]).any():
        ws = g["wind_speed_mps"].to_numpy()[sl]
        wf = np.radians(g["wind_from_deg"].to_numpy()[sl])
        ok = np.isfinite(ws) & np.isfinite(wf)
        ws = np.interp(t, t[ok], ws[ok])
        wf = np.interp(t, t[ok], wf[ok])
        wind = np.column_stack([-ws * np.cos(wf), -ws * np.sin(wf)])
    vn, ve = air_velocity(tas, psi, climb, wind)
    dt = np.diff(t)
    north = np.concatenate([[0.0], np.cumsum(0.5 * (vn[1:] + vn[:-1]) * dt)])
    east = np.concatenate([[0.0], np.cumsum(0.5 * (ve[1:] + ve[:-1]) * dt)])
    dr = {"north": north, "east": east, "up": h}
    frac = (t - t[0]) / (t[-1] - t[0])
    corr = {ax: dr[ax] + (end_neu[i] - dr[ax][-1]) * frac for i, ax in enumerate(AXES)}
    return dr, corr


def one_flight(scenario: str, overrides: dict, seed: int) -> dict:
    """All methods on one simulated flight: errors per method and axis, and the fits."""
    sim = simulate(scenario, seed, **overrides)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        clean = clean_flight(Flight(data=sim.log, meta=sim.meta))
        meta = clean.meta
        res_a = run_sabziev(clean)
        ph = clean.phases
        pts = {"liftoff": _truth_point(sim.truth, ph.liftoff_t_s),
               "arrival": _truth_point(sim.truth, ph.touchdown_t_s)}
        res_t = run_sabziev(clean, **pts)
        v0 = tuple(float(np.interp(ph.liftoff_t_s, sim.truth["t_s"], sim.truth[c]))
                   for c in ("vn_mps", "ve_mps", "vu_mps"))
        res_v = run_sabziev(clean, liftoff_velocity_ned=(v0[0], v0[1], -v0[2]), **pts)
    t_all = clean.grid["t_s"].to_numpy()
    i0, i1 = (int(np.searchsorted(t_all, x)) for x in res_a.summary["interval_s"])
    sl = slice(i0, i1 + 1)
    t = t_all[sl]
    truth = _truth_on(t, sim.truth, meta.departure.elev_m)
    plane = output_plane(meta)
    e, n, _ = plane.forward(meta.arrival.lat_deg, meta.arrival.lon_deg,
                            msl_to_ellipsoid(meta.arrival.elev_m, meta.geoid_undulation_m))
    y_T = res_a.summary["end_point"]["up_m"]
    dr, corr = dead_reckoning(clean, sl, (float(n), float(e), y_T))
    tracks = {}
    for name, res in ((METHODS[0], res_a), (METHODS[1], res_t), (METHODS[2], res_v)):
        tracks[name] = {ax: res.track[f"sabziev_{ax}_m"].to_numpy()[sl] for ax in AXES}
    tracks[METHODS[3]] = dr
    tracks[METHODS[4]] = corr
    errors = {}
    for name, tr in tracks.items():
        errors[name] = {}
        for ax in AXES:
            err = tr[ax] - truth[ax]
            errors[name][ax] = (float(np.sqrt(np.mean(err**2))), float(np.max(np.abs(err))))
    return {"errors": errors, "summary_a": res_a.summary, "summary_v": res_v.summary,
            "t": t, "tracks": tracks, "truth": truth, "duration_s": float(t[-1] - t[0])}


def _fmt(x: float) -> str:
    if not np.isfinite(x):
        return "n/a"
    return f"{x:.0f}" if abs(x) >= 10 else f"{x:.1f}"


def write_table(results: dict, path: Path, seeds: list[int], elapsed: float) -> None:
    intro = (f"Generated by `scripts/sabziev_accuracy.py` (seeds {seeds[0]}..{seeds[-1]} per "
             f"variant, {elapsed:.0f} s). Errors between lift-off and touchdown, metres: mean "
             "over seeds of the per-flight RMS, and the largest per-flight maximum. A flight "
             "where an axis found no root is counted in `no root` and left out of that axis's "
             "statistics.")
    lines = ["# Sabziev fusion: track error against simulated truth", "", intro, ""]
    for label, flights in results.items():
        dur = np.mean([f["duration_s"] for f in flights])
        head = ("| method | RMS north | RMS east | RMS up | max north | max east | max up "
                "| no root |")
        lines += [f"## {label} ({len(flights)} flights, {dur / 60:.0f} min airborne)", "",
                  head, "|---|---:|---:|---:|---:|---:|---:|---:|"]
        for m in METHODS:
            rms, mx, bad = [], [], 0
            for ax in AXES:
                vals = [f["errors"][m][ax] for f in flights
                        if np.isfinite(f["errors"][m][ax][0])]
                rms.append(np.mean([v[0] for v in vals]) if vals else np.nan)
                mx.append(np.max([v[1] for v in vals]) if vals else np.nan)
                bad = max(bad, len(flights) - len(vals))
            lines.append(f"| {m} | " + " | ".join(_fmt(x) for x in rms + mx) + f" | {bad} |")
        head = ("| flight, fit | k1 [1/s] | k2 [1/s^2] | k3 [1/s] | branches (x, y, z) "
                "| converged |")
        lines += ["", head, "|---|---:|---:|---:|---|---|"]
        for i, f in enumerate(flights):
            for key, fit in (("summary_a", "airfield points"),
                             ("summary_v", "true points and v0")):
                s = f[key]
                br = ", ".join(s["axes"][a].get("branch", "-") for a in ("x", "y", "z"))
                ks = [("n/a" if s[k] is None else f"{s[k]:.3e}") for k in ("k1", "k2", "k3")]
                lines.append(f"| seed {seeds[i]}, {fit} | " + " | ".join(ks) + f" | {br} | "
                             f"{s['converged']} |")
        lines.append("")
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(header() + "\n".join(lines))


def plot_flight(f: dict, title: str, path: Path) -> None:
    fig, axs = plt.subplots(2, 2, figsize=(12, 9))
    tr, truth, t = f["tracks"], f["truth"], (f["t"] - f["t"][0]) / 60.0
    colours = dict(zip(METHODS, ("tab:blue", "tab:cyan", "tab:green", "tab:red", "tab:orange")))
    ax = axs[0, 0]
    ax.plot(truth["east"] / 1e3, truth["north"] / 1e3, "k", lw=2, label="truth")
    for m in METHODS:
        ax.plot(tr[m]["east"] / 1e3, tr[m]["north"] / 1e3, color=colours[m], lw=1, label=m)
    ax.set_xlabel("east [km]")
    ax.set_ylabel("north [km]")
    ax.set_aspect("equal", adjustable="datalim")
    ax.legend(fontsize=7)
    ax.set_title("ground track")
    for k, axis in enumerate(AXES):
        ax = axs.flat[k + 1]
        for m in METHODS:
            ax.plot(t, tr[m][axis] - truth[axis], color=colours[m], lw=1, label=m)
        ax.axhline(0, color="k", lw=0.5)
        ax.set_xlabel("time since lift-off [min]")
        ax.set_ylabel(f"{axis} error [m]")
        ax.set_title(f"{axis} error")
    for ax in axs.flat:
        ax.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(path, dpi=110)
    plt.close(fig)


def plot_newton(summary: dict, title: str, path: Path) -> None:
    fig, (a1, a2) = plt.subplots(1, 2, figsize=(11, 4))
    for axis, hist in summary["history"].items():
        h = np.asarray([(k, F) for k, F in hist if k is not None and F is not None], float)
        if len(h) == 0:
            continue
        a1.plot(np.arange(len(h)), h[:, 0], "o-", ms=3, label=axis)
        a2.semilogy(np.arange(len(h)), np.abs(h[:, 1]) + 1e-12, "o-", ms=3, label=axis)
    a1.set_yscale("symlog", linthresh=1e-6)
    a1.set_xlabel("iteration")
    a1.set_ylabel("k")
    a2.set_xlabel("iteration")
    a2.set_ylabel("|F(k)| = |end-point residual| [m]")
    for a in (a1, a2):
        a.grid(alpha=0.3)
        a.legend()
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=5, help="flights per variant (seeds 1..N)")
    ap.add_argument("--out", type=Path, default=Path(__file__).resolve().parents[1] / "docs")
    ap.add_argument("--independent", action="store_true",
                    help="the independent flights (shared corpus and JSBSim; "
                    "scripts/sabziev_flights.py) with both policies instead")
    ap.add_argument("--variants", action="store_true",
                    help="the independent flights again with a winds-aloft forecast and, "
                    "without the arrival, with the fleet k (scripts/sabziev_variants.py)")
    ap.add_argument("--fleet", action="store_true",
                    help="the JSBSim fleet's other aircraft and schedules (airwork, holding, "
                    "go-around), both policies (docs/tables/sabziev_fleet.md)")
    args = ap.parse_args(argv)
    if args.fleet:
        import sys

        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from sabziev_flights import FLEET_FLIGHTS, study

        study(args.out / "tables", FLEET_FLIGHTS, "sabziev_fleet")
        return
    if args.variants:
        import sys

        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from sabziev_variants import study as variants

        variants(args.out / "tables")
        return
    if args.independent:
        import sys

        sys.path.insert(0, str(Path(__file__).resolve().parent))
        from sabziev_flights import study

        study(args.out / "tables")
        return
    seeds = list(range(1, args.seeds + 1))
    t0 = time.perf_counter()
    results: dict[str, list] = {}
    for scenario, label, overrides in VARIANTS:
        results[label] = []
        for seed in seeds:
            f = one_flight(scenario, overrides, seed)
            results[label].append(f)
            e = f["errors"][METHODS[0]]
            print(f"{label:28s} seed {seed}: sabziev RMS n/e/u = "
                  + "/".join(_fmt(e[a][0]) for a in AXES)
                  + f"  converged={f['summary_a']['converged']}", flush=True)
    elapsed = time.perf_counter() - t0
    write_table(results, args.out / "tables" / "sabziev_accuracy.md", seeds, elapsed)
    first = results["regional, wind channel"][0]
    plot_flight(first, f"Sabziev fusion vs dead reckoning, regional flight (seed {seeds[0]}, "
                "wind channel)", args.out / "figures" / "sabziev_accuracy.png")
    circ = results["circuit, no wind channel"][0]
    plot_flight(circ, f"Sabziev fusion vs dead reckoning, circuit (seed {seeds[0]}, no wind "
                "channel)", args.out / "figures" / "sabziev_accuracy_circuit.png")
    plot_newton(first["summary_a"], "Newton-Raphson / bracket refinement history, regional "
                f"flight (seed {seeds[0]})", args.out / "figures" / "sabziev_newton.png")
    print(f"done in {elapsed:.0f} s")


if __name__ == "__main__":
    main()
