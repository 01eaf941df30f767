"""Every check of the door on logs the project did not tune it on (issue #34).

For each log: the door's verdicts and figures (``flightrecon info``'s "door" section), and
whether the log was accepted; then the deliberate unit errors (pressure altitude in feet,
attitude in radians, time in milliseconds, airspeed in knots, each in a canonical column)
injected into it: each must be refused.  Then issue #50's unit mutations, one channel at a
time (roll, pitch, heading in rad / deg, airspeed in kt / m/s, pressure altitude in ft / m), in
the canonical log, behind a mapping that declares the unit, and in the ED-112 export through
its mapping: each must be refused, or at least said (a warning); none accepted silently.

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

    python scripts/door_study.py [--seeds 3] [--svv PATH/matlab] [--garmin FILE ...]

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
    checks = {c["check"]: c for c in fl.meta.ingest.door if c["check"] in UNIT_CHECKS}
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


ANGLES = {"roll_deg": "roll", "pitch_deg": "pitch", "heading_deg": "heading"}
KT = 3600.0 / 1852.0


def _table(channel: str, column: str, unit: str) -> str:
    return f'[channels.{channel}]\ncolumn = "{column}"\nunit = "{unit}"\n'


def canonical_mutations(df: pd.DataFrame) -> dict[str, tuple[pd.DataFrame, str | None]]:
    """Issue #50's unit errors one channel at a time in a canonical log (no mapping), and
    the same errors behind a mapping that declares the channel's unit (``mapping: ...``):
    values in another unit than declared, and a declared unit other than the values'."""
    out: dict[str, tuple[pd.DataFrame, str | None]] = {}
    for c, short in ANGLES.items():
        if c not in df.columns:
            continue
        d = df.copy()
        d[c] = np.radians(d[c])
        out[f"{short} in rad"] = (d, None)
        out[f"mapping: {short} in rad, declared deg"] = (d, _table(c, c, "deg"))
        out[f"mapping: {short} in deg, declared rad"] = (df, _table(c, c, "rad"))
    if "tas_mps" in df.columns:
        d = df.copy()
        d["tas_mps"] = d["tas_mps"] * KT
        out["airspeed in kt"] = (d, None)
        out["mapping: airspeed in kt, declared m/s"] = (d, _table("tas_mps", "tas_mps", "m/s"))
        out["mapping: airspeed in m/s, declared kt"] = (df, _table("tas_mps", "tas_mps", "kt"))
    if "baro_alt_m" in df.columns:
        d = df.copy()
        d["baro_alt_m"] = d["baro_alt_m"] / 0.3048
        out["pressure altitude in ft"] = (d, None)
        out["mapping: pressure altitude in ft, declared m"] = (
            d, _table("baro_alt_m", "baro_alt_m", "m"))
        out["mapping: pressure altitude in m, declared ft"] = (
            df, _table("baro_alt_m", "baro_alt_m", "ft"))
    return out


ED112_UNITS = {"ROLL": ("roll", "deg", "rad"), "PTCH": ("pitch", "deg", "rad"),
               "HDG_MAG": ("heading", "deg", "rad"), "CAS_KT": ("airspeed", "kt", "m/s"),
               "TAS_KT": ("airspeed", "kt", "m/s"), "ALT_FT": ("pressure altitude", "ft", "m")}


def ed112_mutations(ex: pd.DataFrame, mapping: str) -> dict[str, tuple[pd.DataFrame, str]]:
    """The same errors in an ED-112 export read through its mapping: the mapping declaring
    another unit than the recorder's, and the recorder writing another unit than declared."""
    out = {}
    for col, (what, unit, other) in ED112_UNITS.items():
        if col not in ex.columns:
            continue
        key = f'column = "{col}"\nunit = "{unit}"'
        assert key in mapping, col
        out[f"{what} in {unit}, declared {other}"] = (
            ex, mapping.replace(key, f'column = "{col}"\nunit = "{other}"'))
        d = ex.copy()
        d[col] = {"rad": np.radians, "m/s": lambda v: v / KT,
                  "m": lambda v: v * 0.3048}[other](d[col])
        out[f"{what} in {other}, declared {unit}"] = (d, mapping)
    return out


def outcome(res: dict) -> str:
    """``refused`` (exit 5, a named cause), ``refused (exit N)``, ``warned`` (accepted with a
    unit warning) or ``silent`` (accepted without a word: the failure this study looks for)."""
    if not res["accepted"]:
        return "refused" if res.get("exit") == 5 else f"refused (exit {res.get('exit')})"
    return "warned" if res["unit_warnings"] else "silent"


def run_mutations(cases: dict, tmp: Path, stem: str, suffix: str, load_kw: dict,
                  causes: dict | None = None) -> dict:
    """Each mutation's outcome (:func:`outcome`); ``causes`` gets the start of each refusal's
    message or of its first unit warning."""
    out = {}
    for i, (kind, (bad, mapping)) in enumerate(cases.items()):
        q = tmp / f"{stem}-m{i}{suffix}"
        if suffix == ".csv":
            bad.to_csv(q, index=False)
        else:
            bad.to_parquet(q)
        kw = dict(load_kw)
        if mapping is not None:
            m = tmp / f"{stem}-m{i}.toml"
            m.write_text(mapping)
            kw["mapping"] = m
        res = door(q, **kw)
        out[kind] = outcome(res)
        if causes is not None:
            causes[kind] = (res.get("error") or " | ".join(res.get("unit_warnings") or [])
                            )[:240]
    return out


def study_log(name: str, df: pd.DataFrame, tmp: Path, meta_kw: dict, lat: float, lon: float,
              epoch: str, rows: list[dict], export: bool = True, mutations: bool = True
              ) -> None:
    """The log, its injected errors, issue #50's unit mutations (``mutations``) and
    (``export``) its ED-112 export with its own mutations."""
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
    if mutations:
        r["mutation_causes"] = {}
        r["mutations"] = run_mutations(canonical_mutations(df), tmp, name, ".parquet",
                                       {"meta_overrides": meta_kw}, r["mutation_causes"])
    rows.append(r)
    print(f"{name:34s} accepted={r['accepted']} refused={refused} "
          f"{_tally(r.get('mutations'))}", flush=True)
    if not export:
        return
    ex = ed112_export(df, lat_deg=lat, lon_deg=lon, epoch_utc=epoch)
    e = tmp / f"{name}-ed112.csv"
    ex.to_csv(e, index=False)
    m = tmp / f"{name}-ed112.toml"
    text = ed112_mapping(ex)
    m.write_text(text)
    kw = {"meta_overrides": {**meta_kw, "epoch_utc": epoch, "departure": f"{lat},{lon},0"}}
    r2 = {"log": name, "format": "ED-112 minimum rates", **door(e, mapping=m, **kw)}
    if mutations:
        r2["mutation_causes"] = {}
        r2["mutations"] = run_mutations(ed112_mutations(ex, text), tmp, f"{name}-ed112", ".csv",
                                        kw, r2["mutation_causes"])
    rows.append(r2)
    print(f"{name + ' (ED-112)':34s} accepted={r2['accepted']} {_tally(r2.get('mutations'))}",
          flush=True)


def _tally(m: dict | None) -> str:
    if not m:
        return ""
    silent = [k for k, v in m.items() if v == "silent"]
    return (f"mutations: {sum(v.startswith('refused') for v in m.values())} refused, "
            f"{sum(v == 'warned' for v in m.values())} warned, {len(silent)} silent"
            + (f" ({'; '.join(silent)})" if silent else ""))


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


#: the Citation II folder's files whose unit the mutations change: file -> (what, the unit
#: recorded, the other unit)
SVV_UNITS = {"Ahrs1_Roll": ("roll", "deg", "rad"), "Ahrs1_Pitch": ("pitch", "deg", "rad"),
             "Dadc1_tas": ("airspeed", "kt", "m/s"), "Dadc1_alt": ("pressure altitude", "ft", "m")}


def svv_folder_logs(tmp: Path, rows: list[dict], matlab: Path) -> None:
    """The Citation II folders read as ``scripts/realflight_study.py`` reads them (the tool's
    one-column folder reader, its mapping and sidecar: recorder channels, no GPS), then the
    mapping declaring another unit for a file, and a file rewritten in another unit."""
    import shutil

    sys.path.insert(0, str(ROOT / "scripts"))
    import realflight_study as rf

    for name, folder in (("Citation ref", matlab), ("Citation B22", matlab / "Our-data")):
        if not folder.is_dir():
            continue
        df, stems = rf.analyst_table(folder)
        stem = name.split()[-1].lower()
        side = rf.write_case(rf.flight_facts(df), stems, tmp / stem, stem, arrival="none",
                             gnss=False)
        mapping = (tmp / stem / f"{stem}.mapping.toml").read_text()
        r = {"log": name, "format": "one-column folder through its mapping",
             **door(folder, sidecar=side)}
        r["mutations"], r["mutation_causes"] = {}, {}
        for i, (f, (what, unit, other)) in enumerate(SVV_UNITS.items()):
            key = f'column = "{stems[f]}"\nunit = "{unit}"'
            assert key in mapping, f
            m = tmp / stem / f"m{i}.toml"
            m.write_text(mapping.replace(key, f'column = "{stems[f]}"\nunit = "{other}"'))
            kind = f"{what} in {unit}, declared {other}"
            res = door(folder, sidecar=side, mapping=m)
            r["mutations"][kind] = outcome(res)
            r["mutation_causes"][kind] = (res.get("error") or " | ".join(
                res.get("unit_warnings") or []))[:240]
            bad = tmp / stem / f"data{i}"
            shutil.copytree(folder, bad, ignore=shutil.ignore_patterns("Our-data"))
            v = pd.read_csv(bad / f"{stems[f]}.csv", header=None)
            v[0] = {"rad": np.radians, "m/s": lambda x: x / KT,
                    "m": lambda x: x * 0.3048}[other](v[0])
            v.to_csv(bad / f"{stems[f]}.csv", header=False, index=False)
            kind = f"{what} in {other}, declared {unit}"
            res = door(bad, sidecar=side)
            r["mutations"][kind] = outcome(res)
            r["mutation_causes"][kind] = (res.get("error") or " | ".join(
                res.get("unit_warnings") or []))[:240]
            shutil.rmtree(bad)
        rows.append(r)
        print(f"{name:34s} folder: accepted={r['accepted']} {_tally(r['mutations'])}",
              flush=True)


def markdown(rows: list[dict]) -> str:
    head = ("| log | format | accepted | time | baro | GNSS height | airspeed | attitude | "
            "unit warnings | injected ft / rad / ms / kt refused | unit mutations refused / "
            "warned / silent |\n|---|---|---|---|---|---|---|---|---|---|---|\n")
    out = []
    for r in rows:
        if "checks" not in r:
            acc = {True: "yes", False: "**no**"}.get(r.get("accepted"), "-")
            out.append(f"| {r['log']} | {r['format']} | {acc}: {r.get('error', '')[:160]} "
                       "||||||||")
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
        if not r["accepted"]:
            out.append(f"| {r['log']} | {r['format']} | **no**: {r['error'][:160]} "
                       "||||||||")
            continue
        mut = r.get("mutations")
        mut_txt = "-" if not mut else (
            f"{sum(v.startswith('refused') for v in mut.values())} / "
            f"{sum(v == 'warned' for v in mut.values())} / "
            f"{sum(v == 'silent' for v in mut.values())}")
        out.append(f"| {r['log']} | {r['format']} | {'yes' if r['accepted'] else '**no**'} | "
                   + " | ".join(cells) + f" | {len(r['unit_warnings'])} | {inj_txt} | "
                   f"{mut_txt} |")
    return head + "\n".join(out) + "\n" + mutation_table(rows)


def mutation_table(rows: list[dict]) -> str:
    """Each unit mutation (issue #50) over the logs it was made on: how many were refused,
    warned about, accepted silently, and the silent ones."""
    kinds: dict[tuple[str, str], list[tuple[str, str]]] = {}
    for r in rows:
        for k, v in (r.get("mutations") or {}).items():
            fmt = "ED-112" if r["format"].startswith("ED-112") else (
                "Citation folder" if r["format"].startswith("one-column") else
                "mapping" if k.startswith("mapping: ") else "canonical")
            kinds.setdefault((fmt, k.removeprefix("mapping: ")), []).append((r["log"], v))
    why: dict[tuple[str, str], set[str]] = {}
    for r in rows:
        for k, c in (r.get("mutation_causes") or {}).items():
            fmt = "ED-112" if r["format"].startswith("ED-112") else (
                "Citation folder" if r["format"].startswith("one-column") else
                "mapping" if k.startswith("mapping: ") else "canonical")
            why.setdefault((fmt, k.removeprefix("mapping: ")), set()).add(_cause(c))
    out = ["", "| rates, columns | unit mutation | logs | refused | warned | silent "
           "(the logs) | refused by |", "|---|---|---|---|---|---|---|"]
    for (fmt, k), res in kinds.items():
        silent = [lg for lg, v in res if v == "silent"]
        other = sorted({v for _, v in res if v.startswith("refused (")})
        out.append(f"| {fmt} | {k} | {len(res)} | "
                   f"{sum(v.startswith('refused') for _, v in res)}"
                   + (f" ({', '.join(other)})" if other else "")
                   + f" | {sum(v == 'warned' for _, v in res)} | {len(silent)}"
                   + (f" ({', '.join(silent)})" if silent else "") + " | "
                   + ", ".join(sorted(why.get((fmt, k), ()))) + " |")
    return "\n".join(out) + "\n"


#: the door's evidence a refusal's message names -> its short name in the table
CAUSES = (("turns the load factors show", "the loads' turns"),
          ("sin(pitch)", "pitch against n_long"), ("GNSS track", "GNSS track"),
          ("is declared in rad (", "radian range"), ("true airspeed is", "airspeed (turns, wind)"),
          ("pressure altitude changes", "vertical acceleration"),
          ("GNSS height", "GNSS height"), ("physical range", "range check"))


def _cause(text: str) -> str:
    """The short name of the evidence a refusal's (or a warning's) message gives."""
    return next((name for key, name in CAUSES if key in text), "other")


def _shown(p: Path) -> str:
    """A path for the table's header: relative to the repository's parent where it can be."""
    try:
        return str(Path("..") / p.resolve().relative_to(ROOT.parent))
    except ValueError:
        return str(p)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--svv", type=Path, help="the fetched repository's matlab folder")
    ap.add_argument("--garmin", type=Path, nargs="*", default=[],
                    help="glass-cockpit CSV exports (read as recorded)")
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
            svv_folder_logs(tmp, rows, args.svv)
        for g in args.garmin:
            for fmt, kw in (("glass-cockpit CSV as recorded", {}),
                            ("glass-cockpit CSV, GPS withheld",
                             {"gnss_use": GnssUse(withhold=True)})):
                r = {"log": g.name, "format": fmt, **door(g, **kw)}
                rows.append(r)
                print(f"{g.name:34s} {fmt}: accepted={r['accepted']}", flush=True)
    good = [r for r in rows if "accepted" in r]
    n_ok = sum(r["accepted"] for r in good)
    inj = [v for r in good for v in (r.get("injected_refused") or {}).values()]
    muts = [v for r in good for v in (r.get("mutations") or {}).values()]
    summary = {"logs": len(good), "accepted": n_ok,
               "injected": len(inj), "injected_refused": int(sum(inj)),
               "mutations": len(muts),
               "mutations_refused": sum(v.startswith("refused") for v in muts),
               "mutations_warned": sum(v == "warned" for v in muts),
               "mutations_silent": sum(v == "silent" for v in muts)}
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.with_suffix(".json").write_text(json.dumps({"summary": summary, "rows": rows},
                                                        indent=1, default=float))
    command = "python scripts/door_study.py " + " ".join(
        a if not Path(a).is_absolute() else _shown(Path(a)) for a in sys.argv[1:])
    write_markdown(args.out, command, summary, rows)
    print(summary)


def write_markdown(out: Path, command: str, summary: dict, rows: list[dict]) -> None:
    """The table (``.md``) with its command, from the rows."""
    n_ok, good = summary["accepted"], summary["logs"]
    out.with_suffix(".md").write_text(
        f"Regenerate: `{command}`\n\n"
        f"Logs accepted: {n_ok} of {good}; injected unit errors refused: "
        f"{summary['injected_refused']} of {summary['injected']}; unit mutations (issue #50): "
        f"{summary['mutations_refused']} refused, {summary['mutations_warned']} warned, "
        f"{summary['mutations_silent']} accepted silently, of {summary['mutations']}.\n\n"
        + markdown(rows))


if __name__ == "__main__":
    main()
