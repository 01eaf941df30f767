"""The Sabziev independent-flight table again: with a winds-aloft forecast and with the fleet k.

For every flight of ``scripts/sabziev_flights.py`` without a recorded wind channel (the corpus,
JSBSim circuits, cross-country flights at scale 0.3, jets at scale 0.2, spiral dives and spins
to the ground; issue #37), the stable policy:

* ``base``: departure and arrival, no wind (the table of ``--independent``);
* ``forecast``: the same with a winds-aloft forecast (``FlightMeta.wind_aloft``, as ``--wind``
  gives it; docs/wind.md). The corpus ships its own (``c<i>-wind.csv``); for a JSBSim flight
  the forecast is derived from the truth as an analyst gets it: the truth's mean wind in bands
  300 m deep over the altitudes flown, each level's speed off by 1-2 m/s and its direction by
  2-6 deg (signs and sizes drawn from a generator seeded by the flight), sd 2 m/s. Its baseline
  is dead reckoning with the same forecast and a linear end correction;
* ``fleet``: **no arrival** (an accident flight's situation), the initial-value mode with the
  aircraft's fleet coefficients learned from its other routine flights (leave-one-out; the
  spirals and spins, which are not routine, use all the routine flights of their airframe):
  each routine flight's ``base`` fit becomes a store record
  (:func:`flightrecon.store.from_sabziev_summary`) and the fleet mean is the store's
  (:func:`flightrecon.store.stats.fleet_mean`, at least two stable-branch fits per axis as
  ``--use-fleet-coefficients`` asks, an axis with fewer taking the stable policy's fixed
  coefficient). Its baseline is dead reckoning without an end correction;
* ``fixed``: no arrival, the stable policy's fixed coefficients on every axis (what the fleet
  path falls back to), to see whether the fleet mean is worth more than them.

Usage::

    python scripts/sabziev_variants.py        # ~2-4 min; docs/tables/sabziev_variants.md, .json
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
import warnings
import zlib
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from sabziev_flights import (  # noqa: E402
    SHARED,
    TruthFlight,
    corpus_flight,
    evaluate,
    jsbsim_flight,
)
from table_header import command_line, header  # noqa: E402

from flightrecon.types import WindLevel  # noqa: E402

FLIGHTS: tuple[tuple[str, int, dict[str, Any]], ...] = (
    *(("corpus", i, {}) for i in (1, 2)),
    *(("jsbsim-circuit", s, {}) for s in (1, 2, 3, 4, 5)),
    *(("jsbsim-xc", s, {"scale": 0.3}) for s in (1, 2, 3)),
    *(("jsbsim-jet", s, {"scale": 0.2}) for s in (1, 2, 3)),
    *(("jsbsim-spiral", s, {}) for s in (1, 2, 3)),
    *(("jsbsim-spin", s, {}) for s in (1, 2, 3)),
)
"""The flights of ``sabziev_flights.FLIGHTS`` without a recorded wind channel."""

AIRFRAME = {"corpus": "c172x", "jsbsim-circuit": "c172p", "jsbsim-xc": "c172p",
            "jsbsim-spiral": "c172p", "jsbsim-spin": "c172p", "jsbsim-jet": "737"}
ROUTINE = {"corpus", "jsbsim-circuit", "jsbsim-xc", "jsbsim-jet"}
LEVEL_SPACING_M = 300.0
FORECAST_SD_MPS = 2.0


def forecast_from_truth(f: TruthFlight, seed: int) -> tuple[WindLevel, ...]:
    """A winds-aloft forecast from a JSBSim flight's truth (module docstring)."""
    tr = f.truth
    assert tr is not None
    air = ~tr["on_ground"].to_numpy(bool) if "on_ground" in tr.columns else np.ones(len(tr), bool)
    alt = tr["alt_msl_m"].to_numpy(float)[air]
    wn, we = (tr[c].to_numpy(float)[air] for c in ("wind_n_mps", "wind_e_mps"))
    rng = np.random.default_rng(seed)
    lo = math.floor(alt.min() / LEVEL_SPACING_M) * LEVEL_SPACING_M
    hi = math.ceil(alt.max() / LEVEL_SPACING_M) * LEVEL_SPACING_M
    levels = []
    for a in np.arange(lo, hi + 1.0, LEVEL_SPACING_M):
        band = np.abs(alt - a) <= LEVEL_SPACING_M / 2
        if not band.any():
            band = np.abs(alt - a) == np.abs(alt - a).min()
        n, e = float(wn[band].mean()), float(we[band].mean())
        speed = max(0.0, math.hypot(n, e) + rng.choice((-1, 1)) * rng.uniform(1.0, 2.0))
        from_deg = (math.degrees(math.atan2(-e, -n)) + rng.choice((-1, 1))
                    * rng.uniform(2.0, 6.0)) % 360.0
        levels.append(WindLevel(float(a), from_deg, speed, FORECAST_SD_MPS))
    return tuple(levels)


def _with_meta(f: TruthFlight, **changes: Any) -> TruthFlight:
    clean = replace(f.clean, meta=replace(f.clean.meta, **changes))
    return replace(f, clean=clean)


def _run(f: TruthFlight, run_on: TruthFlight, **kw: Any) -> tuple[dict[str, Any], Any]:
    from flightrecon.methods.sabziev.method import run_sabziev
    from flightrecon.pipeline.health import method_health

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        res = run_sabziev(run_on.clean, **kw)
        ev = evaluate(f, res)
        h = method_health(res, run_on.clean)
    ev["health"] = "ok" if h["healthy"] else "unhealthy: " + "; ".join(
        p["what"] for p in h["problems"])
    ev["fallback_axes"] = res.summary.get("fallback_axes", [])
    ev["k_defaults"] = res.summary.get("k_defaults", [])
    ev["wind_source"] = res.summary.get("wind_source")
    ev["ratio_dr"] = (ev["hor_rms_m"] / ev["hor_rms_dr_m"] if ev["hor_rms_dr_m"] > 0
                      else float("nan"))
    return ev, res


def study(out: Path) -> list[dict[str, Any]]:
    """Run every flight in the four variants; write the tables; return the rows."""
    from flightrecon.store import from_sabziev_summary
    from flightrecon.store.records import AXES
    from flightrecon.store.stats import aircraft_stats, fleet_mean

    t0 = time.perf_counter()
    flights, rows, fits = [], [], {}
    for kind, i, over in FLIGHTS:
        f = corpus_flight(i) if kind == "corpus" else jsbsim_flight(kind, i, **over)
        flights.append((kind, i, f))
        ev, res = _run(f, f)
        ev["variant"] = "base"
        rows.append(ev)
        fits[f.name] = from_sabziev_summary(res.summary, aircraft_id=AIRFRAME[kind],
                                            flight_id=f.name.replace(" ", "_"),
                                            flight_date_utc="2026-12-01T00:00:00Z")
        if kind == "corpus":
            from flightrecon.ingest.priors import read_wind_table

            levels = read_wind_table(SHARED / "corpus" / f"c{i}-wind.csv")
        else:
            levels = forecast_from_truth(f, 9000 + 100 * (zlib.crc32(kind.encode()) % 50) + i)
        fw = _with_meta(f, wind_aloft=levels)
        ev, _ = _run(fw, fw)
        ev["variant"] = "forecast"
        ev["forecast_levels"] = len(levels)
        rows.append(ev)
        print(f"{f.name:20s} base {rows[-2]['hor_rms_m']:8.0f} m ({rows[-2]['ratio_drl']:.2f}) "
              f"forecast {ev['hor_rms_m']:8.0f} m ({ev['ratio_drl']:.2f})", flush=True)
    for kind, _i, f in flights:
        others = [fits[g.name] for k2, _, g in flights
                  if g.name != f.name and k2 in ROUTINE and AIRFRAME[k2] == AIRFRAME[kind]]
        info: dict[str, Any] = {"fleet_flights": len(others)}
        try:
            fm = fleet_mean(aircraft_stats(AIRFRAME[kind], others), min_flights=2,
                            allow_missing=True)
            k, sd = fm.k, fm.sd
            info.update({"fleet_n": list(fm.n), "fleet_missing": list(fm.missing)})
        except Exception as exc:  # no usable fit at all: every axis takes the fixed value
            k, sd = (math.nan,) * 3, (math.nan,) * 3
            info.update({"fleet_n": [0, 0, 0], "fleet_missing": ["k1", "k2", "k3"],
                         "fleet_error": str(exc)})
        fn = _with_meta(f, arrival=None)
        for variant, kk, ss in (("fleet", k, sd), ("fixed", (math.nan,) * 3, None)):
            ev, _ = _run(f, fn, k=kk, k_sd=ss)
            ev.update(info)
            ev["variant"] = variant
            ev["k_fleet"] = [None if not np.isfinite(x) else x for x in kk]
            rows.append(ev)
            print(f"{f.name:20s} {variant:6s} {ev['hor_rms_m']:8.0f} m, DR "
                  f"{ev['hor_rms_dr_m']:8.0f} m ({ev['ratio_dr']:.2f}), finite {ev['finite']}, "
                  f"{ev['health'][:60]}",
                  flush=True)
    props = []
    for air in sorted(set(AIRFRAME.values())):
        recs = [fits[g.name] for k2, _, g in flights if k2 in ROUTINE and AIRFRAME[k2] == air]
        st = aircraft_stats(air, recs)
        for a in st.axes:
            p = a.prop
            assert p is not None
            props.append({"airframe": air, "axis": a.axis, "fits": len(recs), "n": p.n,
                          "quantity": p.quantity, "weighted": p.weighted, "mean": p.mean,
                          "se": p.se, "spread": p.spread, "chi2_dof": p.chi2_dof, "k": p.k,
                          "k_sd": p.k_sd, "values": [
                              getattr(r, a.axis) for r in recs
                              if r.axis_converged[AXES.index(a.axis)]],
                          "k_sd_fits": [r.k_sd[AXES.index(a.axis)] for r in recs
                                        if r.k_sd is not None
                                        and r.axis_converged[AXES.index(a.axis)]]})
    write_tables(rows, out, time.perf_counter() - t0, props)
    return rows


def _f(x: Any, fmt: str = ".0f") -> str:
    if x is None or (isinstance(x, float) and not np.isfinite(x)):
        return "-"
    return format(x, fmt)


def _summ(rows: list[dict[str, Any]], key: str) -> str:
    v = np.array([r[key] for r in rows if r[key] is not None and np.isfinite(r[key])])
    return f"{np.median(v):.2f} / {np.max(v):.2f}" if len(v) else "-"


def write_tables(rows: list[dict[str, Any]], out: Path, elapsed: float,
                 props: list[dict[str, Any]]) -> None:
    """``docs/tables/sabziev_variants.md`` and ``.json``."""
    out.mkdir(parents=True, exist_ok=True)
    (out / "sabziev_variants.json").write_text(json.dumps(
        {"command": command_line(), "rows": rows, "fleet": props}, indent=1, default=str))
    lines = ["# Sabziev fusion on independent flights: forecast wind and fleet k (issue #37)", "",
             f"Generated by `python scripts/sabziev_variants.py` ({elapsed:.0f} s); the variants "
             "are described in the script's docstring. Stable policy throughout. `hor RMS` of "
             "the horizontal distance to the truth over the fusion interval; `DR+lin` air-data "
             "dead reckoning with a linear end correction (with the forecast's wind in the "
             "`forecast` variant), `DR` the same without the correction (no wind; the "
             "forecast's in the `forecast` variant); `ratio` = "
             "hor RMS / DR+lin (`base`, `forecast`) or hor RMS / DR (`fleet`, `fixed`, no "
             "arrival). `k used` the coefficients of the track (`fleet`: the fleet mean of the "
             "other routine flights of the airframe; `-` where the axis took the fixed stable "
             "value). `n fleet` the stable-branch fits behind k1/k2/k3.", "",
             "## Summary", "",
             "| variant | flights | finite | healthy | ratio median / max | up RMS median / max "
             "[m] |", "|---|---|---|---|---|---|"]
    for variant in ("base", "forecast", "fleet", "fixed"):
        rs = [r for r in rows if r["variant"] == variant]
        key = "ratio_drl" if variant in ("base", "forecast") else "ratio_dr"
        lines.append(f"| {variant} | {len(rs)} | {sum(r['finite'] for r in rs)} | "
                     f"{sum(r['health'] == 'ok' for r in rs)} | {_summ(rs, key)} | "
                     f"{_summ(rs, 'up_rms_m')} |")
    lines += ["", "## The fleet property over all routine flights of each airframe", "",
              "Store rule (`flightrecon.store.stats.property_stats`): fits with a root on the "
              "stable branch; `tau = -1/k` [s] for k1, k3, `w = sqrt(-k2)` [rad/s] for k2; "
              "weighted by the inverse variance from each root's conditioning (`k_sd` = 50 m / "
              "|dF/dk|). `chi2/dof` about 1 if the fits scatter as their conditioning says.", "",
              "| airframe | axis | fits | with a stable root | weighted mean | se | spread "
              "(sd over flights) | chi2/dof | k of the mean |",
              "|---|---|---|---|---|---|---|---|---|"]
    for p in props:
        lines.append(f"| {p['airframe']} | {p['axis']} ({p['quantity']}) | {p['fits']} | "
                     f"{p['n']} | {_f(p['mean'], '.4g')} | {_f(p['se'], '.2g')} | "
                     f"{_f(p['spread'], '.2g')} | {_f(p['chi2_dof'], '.3g')} | "
                     f"{_f(p['k'], '.4g')} |")
    lines += ["", "## Per flight", "",
              "| flight | variant | finite | hor RMS [m] | DR+lin [m] | DR [m] | ratio "
              "| up RMS [m] | k used (k1, k2, k3) | n fleet | health |",
              "|---|---|---|---|---|---|---|---|---|---|---|"]
    for r in rows:
        ratio = r["ratio_drl"] if r["variant"] in ("base", "forecast") else r["ratio_dr"]
        ks = ", ".join("-" if x is None else f"{x:.3g}" for x in r["k"])
        nf = "/".join(str(x) for x in r.get("fleet_n", [])) or "-"
        lines.append(f"| {r['flight']} | {r['variant']} | {r['finite']} | {_f(r['hor_rms_m'])} "
                     f"| {_f(r['hor_rms_drl_m'])} | {_f(r['hor_rms_dr_m'])} | "
                     f"{_f(ratio, '.2f')} | {_f(r['up_rms_m'], '.1f')} | {ks} | {nf} | "
                     f"{r['health'][:90]} |")
    (out / "sabziev_variants.md").write_text(header() + "\n".join(lines) + "\n")


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path,
                    default=Path(__file__).resolve().parents[1] / "docs" / "tables")
    a = ap.parse_args(argv)
    study(a.out)


if __name__ == "__main__":
    main()
