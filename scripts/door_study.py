"""Every check of the door on logs the project did not tune it on (issue #34).

For each log: the door's verdicts and figures (``flightrecon info``'s "door" section), and
whether the log was accepted; then the deliberate unit errors (pressure altitude in feet,
attitude in radians, time in milliseconds, airspeed in knots, each in a canonical column)
injected into it: each must be refused.

Logs:

* the independent corpus (``../shared/corpus/``, JSBSim c172x by another generator, moderate
  Dryden turbulence, 25/10/5 Hz) and its ED-112 minimum-rate exports;
* the project's JSBSim circuits and spiral dives with turbulence from light (MIL-F-8785C
  index 1) to severe (5, 6), at their recorder rates and as ED-112 minimum-rate exports;
* with ``--svv DIR`` the real Citation II flight-test logs of the public repository
  SybrenBootsma/SVV-flight-dynamics-B22 (``DIR`` = its ``matlab`` folder, fetched by the user:
  the data have no licence and are not shipped);
* with ``--garmin FILE`` a real glass-cockpit export (read as recorded).

Usage::

    python scripts/door_study.py [--seeds 3] [--svv PATH/matlab] [--garmin FILE]

Writes ``docs/tables/door_study.json`` and ``docs/tables/door_study.md`` (numbers only).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from flightrecon.errors import FlightReconError  # noqa: E402
from flightrecon.ingest import load_flight  # noqa: E402
from flightrecon.ingest.gnss_use import GnssUse  # noqa: E402
from flightrecon.sim.ed112 import ed112_export, ed112_mapping  # noqa: E402

CORPUS = ROOT.parent / "shared" / "corpus"
SEVERITY = {1.0: "light", 3.0: "moderate", 5.0: "severe", 6.0: "severe+"}
UNIT_CHECKS = ("time unit", "baro_alt_m unit", "gnss_alt_m unit", "tas_mps unit",
               "attitude unit")


def door(path: Path, **kw) -> dict:
    """Load ``path`` and return its door verdicts, or the refusal."""
    with warnings.catch_warnings(record=True) as ws:
        warnings.simplefilter("always")
        try:
            fl = load_flight(path, **kw)
        except FlightReconError as exc:
            return {"accepted": False, "error": str(exc), "exit": exc.exit_code}
    checks = {c["check"]: c for c in fl.meta.extra["door"] if c["check"] in UNIT_CHECKS}
    return {"accepted": True,
            "checks": {k: {"verdict": v["verdict"], "figure": v["figure"]}
                       for k, v in checks.items()},
            "unit_warnings": [str(w.message) for w in ws if "unit" in str(w.message)]}


def inject(df: pd.DataFrame) -> dict[str, pd.DataFrame]:
    """The deliberate unit errors, each in its canonical column."""
    out = {}
    d = df.copy()
    d["baro_alt_m"] = d["baro_alt_m"] / 0.3048
    out["ft"] = d
    d = df.copy()
    for c in ("roll_deg", "pitch_deg", "heading_deg"):
        if c in d:
            d[c] = np.radians(d[c])
    out["rad"] = d
    d = df.copy()
    d["t_s"] = d["t_s"] * 1000.0
    out["ms"] = d
    d = df.copy()
    d["tas_mps"] = d["tas_mps"] * 3600 / 1852
    out["kt"] = d
    return out


def study_log(name: str, df: pd.DataFrame, tmp: Path, meta_kw: dict, lat: float, lon: float,
              epoch: str, rows: list[dict], export: bool = True) -> None:
    """The log, its injected errors and (``export``) its ED-112 export."""
    p = tmp / f"{name}.parquet"
    df.to_parquet(p)
    r = {"log": name, "format": "canonical", **door(p, meta_overrides=meta_kw)}
    refused = {}
    for kind, bad in inject(df).items():
        q = tmp / f"{name}-{kind}.parquet"
        bad.to_parquet(q)
        res = door(q, meta_overrides=meta_kw)
        refused[kind] = (not res["accepted"]) and res.get("exit") == 5
    r["injected_refused"] = refused
    rows.append(r)
    print(f"{name:34s} accepted={r['accepted']} refused={refused}", flush=True)
    if not export:
        return
    ex = ed112_export(df, lat_deg=lat, lon_deg=lon, epoch_utc=epoch)
    e = tmp / f"{name}-ed112.csv"
    ex.to_csv(e, index=False)
    m = tmp / f"{name}-ed112.toml"
    m.write_text(ed112_mapping(ex))
    r2 = {"log": name, "format": "ED-112 minimum rates",
          **door(e, mapping=m, meta_overrides={**meta_kw, "epoch_utc": epoch,
                                               "departure": f"{lat},{lon},0"})}
    rows.append(r2)
    print(f"{name + ' (ED-112)':34s} accepted={r2['accepted']}", flush=True)


def corpus_logs(tmp: Path, rows: list[dict]) -> None:
    for p in sorted(CORPUS.glob("c*-*.parquet")):
        if p.name.endswith("truth.parquet"):
            continue
        meta = json.loads((CORPUS / f"{p.name.split('-')[0]}-meta.json").read_text())
        lat, lon, _ = meta["departure"]
        df = pd.read_parquet(p)
        has_heading = "heading_deg" in df.columns
        study_log(f"corpus {p.stem}", df, tmp, {}, lat, lon, "2026-01-01T10:00:00Z", rows,
                  export=has_heading and "fdr" in p.stem)


def jsbsim_logs(tmp: Path, rows: list[dict], seeds: int) -> None:
    from flightrecon.sim.jsbsim_scenarios import JSBSIM_AIRFIELD, draw_weather
    from flightrecon.sim.scenarios import simulate

    for scenario in ("jsbsim-circuit", "jsbsim-spiral"):
        for seed in range(seeds):
            for sev, label in SEVERITY.items():
                if scenario == "jsbsim-spiral" and sev not in (3.0, 6.0):
                    continue
                w = dataclasses.replace(draw_weather(scenario, seed), turbulence_severity=sev)
                try:
                    kw = {"scale": 0.3} if scenario == "jsbsim-spiral" else {}
                    sim = simulate(scenario, seed, weather=w, **kw)
                except FlightReconError as exc:
                    rows.append({"log": f"{scenario} seed {seed} {label}",
                                 "format": "simulator refused", "error": str(exc)})
                    continue
                meta = {"epoch_utc": sim.meta.epoch_utc}
                study_log(f"{scenario} s{seed} {label}", sim.log, tmp, meta,
                          JSBSIM_AIRFIELD.lat_deg, JSBSIM_AIRFIELD.lon_deg, sim.meta.epoch_utc,
                          rows)


def svv_table(folder: Path) -> pd.DataFrame:
    """A Citation II flight-test folder (one header-less column per file, 10 Hz) as a
    canonical table: the normal load recorded as n - 1, the heading channel dead (the
    heading comes from the body rates), airspeed in knots, pressure altitude in feet."""
    def col(name: str) -> np.ndarray:
        for cand in (name, name.replace("Gps_", "GPS_"), name.replace("GPS_", "Gps_")):
            f = folder / f"{cand}.csv"
            if f.is_file():
                return pd.read_csv(f, header=None).iloc[:, 0].to_numpy(dtype=float)
        raise FileNotFoundError(folder / f"{name}.csv")
    kt, ft = 1852.0 / 3600.0, 0.3048
    return pd.DataFrame({
        "t_s": col("time"), "n_long_g": col("Ahrs1_bLongAcc"), "n_lat_g": col("Ahrs1_bLatAcc"),
        "n_norm_g": col("Ahrs1_bNormAcc") + 1.0, "roll_deg": col("Ahrs1_Roll"),
        "pitch_deg": col("Ahrs1_Pitch"), "p_dps": col("Ahrs1_bRollRate"),
        "q_dps": col("Ahrs1_bPitchRate"), "r_dps": col("Ahrs1_bYawRate"),
        "tas_mps": col("Dadc1_tas") * kt, "baro_alt_m": col("Dadc1_alt") * ft,
        "sat_degc": col("Dadc1_sat"), "gnss_lat_deg": col("Gps_lat"),
        "gnss_lon_deg": col("GPS_long")})


def svv_logs(tmp: Path, rows: list[dict], matlab: Path) -> None:
    for name, folder in (("Citation ref", matlab), ("Citation B22", matlab / "Our-data")):
        if not folder.is_dir():
            continue
        df = svv_table(folder)
        df["tas_mps"] = df["tas_mps"].clip(lower=0.0)    # -2.6e-304 at rest: a denormal zero
        # the injected errors on a log without a heading channel: no radian heading to test
        study_log(name, df, tmp, {}, 52.3, 4.76, "2020-03-09T09:00:00Z", rows, export=False)


def markdown(rows: list[dict]) -> str:
    head = ("| log | format | accepted | time | baro | GNSS height | airspeed | attitude | "
            "unit warnings | injected ft / rad / ms / kt refused |\n|---|---|---|---|---|---|"
            "---|---|---|---|\n")
    out = []
    for r in rows:
        if "checks" not in r:
            out.append(f"| {r['log']} | {r['format']} | {r.get('accepted', '-')} | "
                       f"{r.get('error', '')[:80]} |||||||")
            continue
        cells = []
        for k in UNIT_CHECKS:
            c = r["checks"].get(k)
            if c is None:
                cells.append("-")
            else:
                fig = "" if c["figure"] is None else f" {c['figure']:.2f}"
                cells.append(f"{c['verdict']}{fig}")
        inj = r.get("injected_refused")
        inj_txt = " / ".join("yes" if inj[k] else "**no**" for k in ("ft", "rad", "ms", "kt")) \
            if inj else "-"
        out.append(f"| {r['log']} | {r['format']} | {'yes' if r['accepted'] else '**no**'} | "
                   + " | ".join(cells) + f" | {len(r['unit_warnings'])} | {inj_txt} |")
    return head + "\n".join(out) + "\n"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--svv", type=Path, help="the fetched repository's matlab folder")
    ap.add_argument("--garmin", type=Path, help="a glass-cockpit CSV export")
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "tables" / "door_study")
    args = ap.parse_args()
    rows: list[dict] = []
    with tempfile.TemporaryDirectory() as td:
        tmp = Path(td)
        if CORPUS.is_dir():
            corpus_logs(tmp, rows)
        jsbsim_logs(tmp, rows, args.seeds)
        if args.svv:
            svv_logs(tmp, rows, args.svv)
        if args.garmin:
            for fmt, kw in (("glass-cockpit CSV as recorded", {}),
                            ("glass-cockpit CSV, GPS withheld",
                             {"gnss_use": GnssUse(withhold=True)})):
                r = {"log": args.garmin.name, "format": fmt, **door(args.garmin, **kw)}
                rows.append(r)
                print(f"{args.garmin.name:34s} {fmt}: accepted={r['accepted']}", flush=True)
    good = [r for r in rows if "accepted" in r]
    n_ok = sum(r["accepted"] for r in good)
    inj = [v for r in good for v in (r.get("injected_refused") or {}).values()]
    summary = {"logs": len(good), "accepted": n_ok,
               "injected": len(inj), "injected_refused": int(sum(inj))}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.with_suffix(".json").write_text(json.dumps({"summary": summary, "rows": rows},
                                                        indent=1, default=float))
    args.out.with_suffix(".md").write_text(
        f"Logs accepted: {n_ok} of {len(good)}; injected unit errors refused: "
        f"{summary['injected_refused']} of {len(inj)}.\n\n" + markdown(rows))
    print(summary)


if __name__ == "__main__":
    main()
