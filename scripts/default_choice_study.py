"""Which track the default result comes from, and what it costs: every healthy method's error
and sd against a truth, the default's, and dead reckoning with a linear end correction (issue
52, items 1 and 3; docs/output.md, "How the default result is chosen").

Cases: the shipped simulated samples with their sensors and recorder only (``-ro``: GNSS
withheld); the independent corpus of ``../shared/corpus`` recorder only with both ends
(``cN-fdr``) and with GNSS (``cN-gnss``); two JSBSim flights (airwork in the C172P, a jet
flight in the 737 at 0.3 of its legs, seed 1) at their ED-112 minimum rates and recorder
only; the three real SR22T exports of ``../shared/realdata`` recorder only, with the first and
last ground GPS fix as departure and arrival (scripts/realexport_study.py), against their own
GPS.  Each case runs through :func:`flightrecon.pipeline.reconstruct` and appends one JSON line
to ``--out``: every method's status, horizontal RMS error and RMS sd over the airborne samples,
the default's, the baseline's, and a hash of the default columns (so that two runs, before and
after a change, tell whether the default changed at all).

Usage::

    python scripts/default_choice_study.py --out after.jsonl [--cases ...] [--work DIR]
    python scripts/default_choice_study.py --table before.jsonl after.jsonl

The second form writes ``docs/tables/default_choice.md`` (the "before" file made by the same
script run on the code before the change).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
from table_header import header  # noqa: E402  (a script beside this one)

SAMPLES = ROOT / "sample_logs"
CORPUS = ROOT.parent / "shared" / "corpus"
REALDATA = ROOT.parent / "shared" / "realdata"
OUT = ROOT / "docs" / "tables" / "default_choice.md"
#: JSBSim flights at ED-112 minimum rates: (scenario, airframe, seed, --scale)
SIMS = (("jsbsim-airwork", "c172p", 1, None), ("jsbsim-jet", "737", 1, 0.3))


def cases(work: Path) -> dict[str, dict[str, Any]]:
    """Every case: log, truth (a file, or "gps": the log's own fixes), metadata given,
    whether GNSS is withheld, mapping and sidecar."""
    out: dict[str, dict[str, Any]] = {}
    for s in ("circuit", "landing", "regional", "seed-ads-arms"):
        for ro in (False, True):
            out[s + ("-ro" if ro else "")] = {"log": SAMPLES / f"{s}.parquet",
                                             "truth": SAMPLES / f"{s}.truth.parquet",
                                             "ov": {}, "withhold": ro}
    for c in ("c1", "c2"):
        m = json.loads((CORPUS / f"{c}-meta.json").read_text())

        def f(p: list[float]) -> str:
            return ",".join(str(x) for x in p)

        out[c + "-fdr"] = {"log": CORPUS / f"{c}-fdr.parquet",
                           "truth": CORPUS / f"{c}-truth.parquet",
                           "ov": {"departure": f(m["departure"]), "arrival": f(m["arrival"])},
                           "withhold": False}
        out[c + "-gnss"] = {"log": CORPUS / f"{c}-gnss.parquet",
                            "truth": CORPUS / f"{c}-truth.parquet",
                            "ov": {"departure": f(m["departure"])}, "withhold": False}
    for scen, air, seed, _ in SIMS:
        stem = work / f"{scen}_{air}_{seed}"
        out[f"{scen}-{air}-ed112"] = {"log": Path(f"{stem}.ed112.csv"),
                                      "truth": Path(f"{stem}.truth.parquet"), "ov": {},
                                      "withhold": False,
                                      "mapping": Path(f"{stem}.ed112.mapping.toml"),
                                      "sidecar": Path(f"{stem}.ed112.meta.toml")}
        out[f"{scen}-{air}-ro"] = {"log": Path(f"{stem}.parquet"),
                                   "truth": Path(f"{stem}.truth.parquet"), "ov": {},
                                   "withhold": True}
    for f_ in sorted(REALDATA.glob("g1000_*.csv")):
        out["garmin-" + f_.stem.split("_")[2]] = {"log": f_, "truth": "gps", "ov": "ground_ends",
                                                   "withhold": True}
    return out


def simulate_flights(work: Path) -> None:
    """The JSBSim flights and their ED-112 exports in ``work`` (made once), through
    ``flightrecon simulate SCENARIO --airframe A --seed S [--scale X] --export ed112``."""
    import subprocess

    for scen, air, seed, scale in SIMS:
        path = work / f"{scen}_{air}_{seed}.parquet"
        if path.with_suffix(".ed112.csv").is_file():
            continue
        args = [sys.executable, "-m", "flightrecon", "simulate", scen, "--airframe", air,
                "--seed", str(seed), "--export", "ed112", "-o", str(path), "-q"]
        if scale is not None:
            args += ["--scale", str(scale)]
        subprocess.run(args, check=True)


def truth_ne(case: dict[str, Any], clean: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The reference's time, north and east in the flight's output plane."""
    from flightrecon.geo.frames import output_plane
    from flightrecon.ingest import load_flight

    if case["truth"] == "gps":
        d = load_flight(case["log"]).data.dropna(subset=["gnss_lat_deg", "gnss_lon_deg"])
        if "gnss_quality" in d:
            d = d[d.gnss_quality > 0]
        t, lat, lon = d["t_s"], d["gnss_lat_deg"], d["gnss_lon_deg"]
        h = d["gnss_alt_m"]
    else:
        tr = pd.read_parquet(case["truth"])
        t = tr["t_s"] if "t_s" in tr.columns else tr["time_s"]
        lat, lon = tr["lat_deg"], tr["lon_deg"]
        h = tr["alt_m"] if "alt_m" in tr.columns else tr["alt_geod_m"]
    e, n, _ = output_plane(clean.meta).forward(lat.to_numpy(float), lon.to_numpy(float),
                                               h.to_numpy(float))
    return t.to_numpy(float), np.asarray(n), np.asarray(e)


def errors(t: np.ndarray, n: np.ndarray, e: np.ndarray, sd: tuple[Any, Any] | None,
           ref: tuple[np.ndarray, np.ndarray, np.ndarray], air: np.ndarray
           ) -> dict[str, Any] | None:
    """Horizontal RMS error [m] over the airborne samples, the RMS sd and NEES per axis."""
    ok = np.isfinite(n) & np.isfinite(e) & air
    if not ok.any():
        return None
    dn = n[ok] - np.interp(t[ok], ref[0], ref[1])
    de = e[ok] - np.interp(t[ok], ref[0], ref[2])
    out: dict[str, Any] = {"rms_m": float(np.sqrt(np.mean(dn ** 2 + de ** 2)))}
    if sd is not None and sd[0] is not None:
        sn, se = sd[0][ok], sd[1][ok]
        out["sd_m"] = float(np.sqrt(np.mean(sn ** 2 + se ** 2)))
        out["nees"] = [float(np.mean(dn ** 2 / sn ** 2)), float(np.mean(de ** 2 / se ** 2))]
    return out


def baseline(clean: Any, ref: tuple[np.ndarray, np.ndarray, np.ndarray]
             ) -> dict[str, Any] | None:
    """Dead reckoning corrected linearly to the known end (the arrival at touchdown, or at the
    last sample of a record that ends fast and keeps it)."""
    from flightrecon.geo.frames import output_plane
    from flightrecon.methods.baselines import dead_reckoning

    arr = clean.meta.arrival
    if arr is None or clean.meta.departure is None:
        return None
    dr = dead_reckoning(clean)
    t = dr["t_s"].to_numpy(float)
    n, e = dr["north_m"].to_numpy(float).copy(), dr["east_m"].to_numpy(float).copy()
    fin = np.flatnonzero(np.isfinite(n) & np.isfinite(e))
    if len(fin) < 2:
        return None
    a, b = fin[0], fin[-1]
    ea, na, _ = output_plane(clean.meta).forward(arr.lat_deg, arr.lon_deg,
                                                 arr.elev_m + clean.meta.geoid_undulation_m)
    frac = (t[a:b + 1] - t[a]) / (t[b] - t[a])
    n[a:b + 1] += frac * (float(na) - n[b])
    e[a:b + 1] += frac * (float(ea) - e[b])
    return errors(t, n, e, None, ref, np.isfinite(n))


def one(name: str, case: dict[str, Any]) -> dict[str, Any]:
    """One case through the pipeline, measured."""
    from flightrecon.ingest import load_flight
    from flightrecon.ingest.gnss_use import GnssUse
    from flightrecon.pipeline.run import reconstruct

    case = dict(case)
    t0 = time.time()
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        if case["ov"] == "ground_ends":
            from realexport_study import ground_ends

            dep, arr = ground_ends(load_flight(case["log"]))
            case["ov"] = {"departure": dep, "arrival": arr}
        try:
            rec = reconstruct(case["log"], meta_overrides=case["ov"] or None, record=False,
                              mapping=case.get("mapping"), sidecar=case.get("sidecar"),
                              gnss_use=GnssUse(withhold=True) if case["withhold"] else None)
        except Exception as exc:  # a refusal is a result of the case
            return {"case": name, "error": f"{type(exc).__name__}: {exc}"[:300]}
        clean, tr = rec.clean, rec.track
        ref = truth_ne(case, clean)
    t = tr["t_s"].to_numpy(float)
    ph = clean.phases
    lo = ph.liftoff_t_s if np.isfinite(ph.liftoff_t_s) else t[0]
    hi = ph.touchdown_t_s if np.isfinite(ph.touchdown_t_s) else t[-1]
    air = (t >= lo) & (t <= hi)

    def col(c: str) -> np.ndarray | None:
        return tr[c].to_numpy(float) if c in tr.columns else None

    out: dict[str, Any] = {"case": name, "seconds": round(time.time() - t0),
                           "result": rec.summary["result"].get("method"),
                           "why": rec.summary["result"].get("why"), "methods": {}}
    out["default"] = errors(t, col("north_m"), col("east_m"),  # type: ignore[arg-type]
                            (col("north_sd_m"), col("east_sd_m")), ref, air)
    for m, st in rec.summary["methods"].items():
        d: dict[str, Any] = {"status": st.get("status"), "reason": (st.get("reason") or "")[:300]}
        if f"{m}_north_m" in tr.columns:
            d.update(errors(t, col(f"{m}_north_m"), col(f"{m}_east_m"),  # type: ignore[arg-type]
                            (col(f"{m}_north_sd_m"), col(f"{m}_east_sd_m")), ref, air) or {})
        out["methods"][m] = d
    out["baseline"] = baseline(clean, ref)
    dcols = [c for c in ("north_m", "east_m", "north_sd_m", "east_sd_m", "up_m", "lat_deg",
                         "lon_deg", "source") if c in tr.columns]
    out["default_hash"] = hashlib.sha256(pd.util.hash_pandas_object(
        tr[dcols], index=False).to_numpy().tobytes()).hexdigest()[:16]
    if rec.summary["result"].get("evidence"):
        out["evidence"] = rec.summary["result"]["evidence"]
    return out


def _f(x: float | None) -> str:
    return "-" if x is None else f"{x:.0f}" if x >= 10 else f"{x:.2f}"


def markdown(before: dict[str, dict[str, Any]], after: dict[str, dict[str, Any]]) -> str:
    """The table: per case each method's error / sd after (its status, and before where it
    changed), the default before and after, the baseline, whether the default changed."""
    rows = ["| case | methods that ran: RMS error / RMS sd [m], status | default before [m] | "
            "default after [m] | dead reckoning + linear end correction [m] | default columns "
            "identical |", "|---|---|---|---|---|---|"]
    for c, ra in after.items():
        rb = before.get(c, {})
        ms = []
        for m, d in ra.get("methods", {}).items():
            if d["status"] == "skipped":
                continue
            was = (rb.get("methods") or {}).get(m, {}).get("status")
            st = d["status"] + ("" if was in (None, d["status"]) else f" (was {was})")
            ms.append(f"{m} {_f(d.get('rms_m'))} / {_f(d.get('sd_m'))} {st}")
        db, da = (rb.get("default") or {}).get("rms_m"), (ra.get("default") or {}).get("rms_m")
        same = "yes" if rb.get("default_hash") == ra.get("default_hash") else "no"
        rows.append(f"| {c} | {'; '.join(ms) or ra.get('error', '')} | "
                    f"{rb.get('result') or '-'} {_f(db)} | {ra.get('result') or '-'} {_f(da)} | "
                    f"{_f((ra.get('baseline') or {}).get('rms_m'))} | {same} |")
    return "\n".join(rows) + "\n"


def _read(path: Path) -> dict[str, dict[str, Any]]:
    out = {}
    for line in path.read_text().splitlines():
        r = json.loads(line)
        out[r["case"]] = r
    return out


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--out", type=Path, help="append one JSON line per case here")
    ap.add_argument("--cases", nargs="*", default=None, help="run only these cases")
    ap.add_argument("--work", type=Path, default=Path("default_choice_work"),
                    help="scratch folder for the simulated flights")
    ap.add_argument("--table", nargs=2, type=Path, metavar=("BEFORE", "AFTER"),
                    help="write docs/tables/default_choice.md from two runs' files")
    a = ap.parse_args(argv)
    if a.table:
        OUT.write_text(
            header(argv=["--table", "BEFORE.jsonl", "AFTER.jsonl"])
            + "BEFORE.jsonl and AFTER.jsonl: `python scripts/default_choice_study.py --out FILE` "
            "run on the code before the evidence rule (commit 8e6aaaa) and after it. Errors "
            "over the airborne samples against the truth (the real exports: their own GPS), "
            "recorder only where the case says `-ro`, `-fdr`, `-ed112` or `garmin-`.\n\n"
            + markdown(_read(a.table[0]), _read(a.table[1])))
        return 0
    if a.out is None:
        ap.error("--out or --table")
    a.work.mkdir(parents=True, exist_ok=True)
    all_cases = cases(a.work)
    chosen = a.cases or list(all_cases)
    if any("ed112" in c or "jsbsim" in c for c in chosen):
        simulate_flights(a.work)
    with open(a.out, "a") as fh:
        for name in chosen:
            r = one(name, all_cases[name])
            fh.write(json.dumps(r, default=str) + "\n")
            fh.flush()
            print(name, r.get("result"), (r.get("default") or {}).get("rms_m"), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
