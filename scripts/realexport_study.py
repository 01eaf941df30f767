"""Every real recorder export through the command line, measured against its own GPS (issue 49,
item 8).

For each export (the three real SR22T exports of ``../shared/realdata`` and any path given on
the command line, e.g. a Cessna 172S G1000 export kept in a scratch folder: an export without a
licence is never copied into the repository, only its numbers are written here), the script
runs the tool as an analyst would, each as its own process:

* ``flightrecon info LOG``;
* ``flightrecon reconstruct LOG`` with its GNSS;
* ``flightrecon reconstruct LOG --no-gnss --departure D --arrival A``: recorder only, the ends
  taken from the export's own first and last GPS fixes on the ground (their MSL elevation the
  GPS height less EGM96's undulation, :mod:`flightrecon.geo.geoid`);
* ``flightrecon reconstruct LOG --withhold-gnss A:B`` three times: gaps of 600, 300 and 120 s in
  the middle of the airborne span, 240 s of GPS between them (``scripts/onehz_study.py``'s
  windows).

Each run's exit code and, on an error, its message are recorded: an export the reader refuses
is a row of the table, never a crash.  Against the export's GPS (the fixes at their stamps, in
the tangent plane of the run being measured; the library reads the export for that,
``load_flight`` and ``clean_flight``, as ``scripts/onehz_study.py`` does, whose functions
compute the reference, the errors, NEES and the baselines here):

* recorder only: the default result's horizontal RMS error over the airborne fixes, and that of
  dead reckoning with a linear end correction (:func:`flightrecon.methods.baselines.dead_reckoning`,
  ``corrected=True``), and their ratio (the bar of issue 49: at most 1.0);
* per gap: the result's RMS error inside it, that of dead reckoning from the last fix before
  it with the wind of the minute before (``onehz_study.dr_in_gap``), their ratio (bar 0.5),
  and the mean NEES per axis (north, east; the SBAS fixes' own 5 m per axis added to the
  reported variance; bar 5);
* ``alt_msl_m`` of the results (``flightrecon.export.writers.with_utc_and_msl``: the
  ellipsoidal height less the model's undulation at each sample) against the export's own
  ``AltMSL`` at its fixes (bar: within 2 m), and EGM96 against the export's ``AltGPS - AltMSL``.

Writes ``docs/tables/realexports.md`` and ``.json``; the header names the command that made it.

Usage::

    python scripts/realexport_study.py [EXTRA_EXPORT.csv ...] [--work DIR]
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
import warnings
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
from onehz_study import (  # noqa: E402  (a script beside this one, not a package)
    REF_SD,
    dr_in_gap,
    dr_linear_errors,
    gap_windows,
    gps_reference,
)

REALDATA = ROOT.parent / "shared" / "realdata"
OUT = ROOT / "docs" / "tables"
FT_M = 0.3048
#: ground speed below which a fix is on the ground [m/s] (taxi at most 15 kt)
GROUND_MPS = 8.0
#: the bars of issue 49
BAR_RECORDER, BAR_GAP, BAR_NEES, BAR_MSL_M = 1.0, 0.5, 5.0, 2.0


def run_cli(args: list[str]) -> dict[str, Any]:
    """``python -m flightrecon ARGS`` as its own process: exit code, seconds, and the error
    message (the last ``error:`` line of its standard error) when it failed."""
    t0 = time.time()
    p = subprocess.run([sys.executable, "-m", "flightrecon", "--quiet", *args],
                       capture_output=True, text=True, cwd=ROOT)
    out: dict[str, Any] = {"exit": p.returncode, "seconds": round(time.time() - t0, 1)}
    if p.returncode != 0:
        lines = [ln for ln in p.stderr.splitlines() if ln.strip()]
        errs = [ln for ln in lines if ln.startswith("error:")]
        out["message"] = (errs or lines or [""])[-1][:400]
    return out


def _load(log: Path, **kw: Any):
    """The export through the library (warnings caught): ``(flight, clean)``."""
    from flightrecon.cleaning import clean_flight
    from flightrecon.ingest import load_flight

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        flight = load_flight(log, **kw)
        return flight, clean_flight(flight)


def ground_ends(flight: Any) -> tuple[str, str]:
    """``LAT,LON,ELEV_M`` of the first and last GPS fix on the ground (ground speed below
    :data:`GROUND_MPS`), MSL: the GPS height less EGM96's undulation."""
    from flightrecon.geo.geoid import undulation_m

    d = flight.data.dropna(subset=["gnss_lat_deg", "gnss_lon_deg", "gnss_alt_m"])
    if "gnss_quality" in d:
        d = d[d.gnss_quality > 0]
    gs = np.hypot(d.gnss_vn_mps, d.gnss_ve_mps) if "gnss_vn_mps" in d else pd.Series(0.0,
                                                                                     d.index)
    d = d[gs.to_numpy() < GROUND_MPS]
    out = []
    for r in (d.iloc[0], d.iloc[-1]):
        msl = r.gnss_alt_m - undulation_m(r.gnss_lat_deg, r.gnss_lon_deg)
        out.append(f"{r.gnss_lat_deg:.7f},{r.gnss_lon_deg:.7f},{msl:.1f}")
    return out[0], out[1]


def recorded_msl(log: Path, flight: Any) -> pd.DataFrame:
    """The export's ``AltMSL`` and ``AltGPS - AltMSL`` [m] at its rows' times (``t_s``, with
    the fix's latitude and longitude), where recorded."""
    from flightrecon.ingest.readers import read_table

    c = read_table(log).columns
    rows = flight.data["row"].to_numpy(int) - 1
    msl = np.asarray(c["AltMSL"], float)[rows] * FT_M
    und = (np.asarray(c["AltGPS"], float)[rows] * FT_M) - msl
    d = pd.DataFrame({"t_s": flight.data.t_s.to_numpy(float), "alt_msl": msl, "und": und,
                      "lat": flight.data.get("gnss_lat_deg"),
                      "lon": flight.data.get("gnss_lon_deg")})
    return d.dropna().reset_index(drop=True)


def result_ne(result: Path, clean: Any, ref: pd.DataFrame) -> tuple[np.ndarray, ...]:
    """A written result against the GPS ``ref`` (``clean``'s plane) at its times: its offset
    north and east of each fix [m] (from latitude and longitude with the WGS-84 radii of
    curvature at the fix: a result without heights, such as a 2-D track, is measured too),
    its reported sd per axis, and its ``alt_msl_m`` (:func:`with_utc_and_msl`)."""
    from flightrecon.export.writers import read_parquet_metadata, with_utc_and_msl
    from flightrecon.geo.frames import output_plane
    from flightrecon.geo.wgs84 import WGS84_A, WGS84_E2

    tr = with_utc_and_msl(pd.read_parquet(result), read_parquet_metadata(result))
    t = ref.t_s.to_numpy(float)
    lat_g, lon_g, _ = output_plane(clean.meta).inverse(ref.e.to_numpy(float),
                                                       ref.n.to_numpy(float),
                                                       ref.u.to_numpy(float))
    ts = tr.t_s.to_numpy(float)
    lat, lon, sdn, sde, msl = (np.interp(t, ts, tr[c].to_numpy(float)) for c in
                               ("lat_deg", "lon_deg", "north_sd_m", "east_sd_m", "alt_msl_m"))
    w = 1.0 - WGS84_E2 * np.sin(np.radians(lat_g)) ** 2
    n_radius = WGS84_A / np.sqrt(w)
    dn = np.radians(lat - lat_g) * n_radius * (1.0 - WGS84_E2) / w
    de = np.radians(lon - lon_g) * n_radius * np.cos(np.radians(lat_g))
    return dn, de, sdn, sde, msl


def msl_errors(result: Path, rec: pd.DataFrame) -> dict[str, Any]:
    """``alt_msl_m`` of a result against the export's ``AltMSL`` over the record."""
    from flightrecon.export.writers import read_parquet_metadata, with_utc_and_msl

    t = rec.t_s.to_numpy(float)
    tr = with_utc_and_msl(pd.read_parquet(result), read_parquet_metadata(result))
    d = np.interp(t, tr.t_s.to_numpy(float), tr.alt_msl_m.to_numpy(float)) \
        - rec.alt_msl.to_numpy()
    ok = np.isfinite(d)          # a result without heights (its method's track is 2-D)
    if not ok.any():
        return {"fixes": 0, "fixes_without_result": int(ok.size),
                "note": "the result has no height (alt_m empty)"}
    d = d[ok]
    return {"mean_m": float(np.mean(d)), "rms_m": float(np.sqrt(np.mean(d ** 2))),
            "max_abs_m": float(np.max(np.abs(d))), "fixes": int(ok.sum()),
            "fixes_without_result": int((~ok).sum())}


def horizontal(result: Path, clean: Any, ref: pd.DataFrame, mask: np.ndarray | None = None
               ) -> dict[str, float]:
    """A result's horizontal RMS and largest error against the GPS ``ref`` (in ``clean``'s
    plane) over ``mask``, and its mean NEES per axis (the fixes' own sd :data:`REF_SD`)."""
    from flightrecon.export.writers import read_parquet_metadata

    dn, de, sdn, sde, _ = result_ne(result, clean, ref)
    m = np.ones(len(ref), bool) if mask is None else mask
    dn, de = dn[m], de[m]
    h = np.hypot(dn, de)
    return {"method": (read_parquet_metadata(result).get("result") or {}).get("method"),
            "rms_m": float(np.sqrt(np.mean(h ** 2))), "max_m": float(np.max(h)),
            "nees_n": float(np.mean(dn ** 2 / (sdn[m] ** 2 + REF_SD[0] ** 2))),
            "nees_e": float(np.mean(de ** 2 / (sde[m] ** 2 + REF_SD[1] ** 2)))}


def recorder_only(log: Path, flight: Any, work: Path, rec: pd.DataFrame | None
                  ) -> dict[str, Any]:
    """``reconstruct --no-gnss --departure --arrival`` against the GPS and dead reckoning
    with a linear end correction."""
    from flightrecon.ingest.gnss_use import GnssUse

    dep, arr = ground_ends(flight)
    res = work / f"{log.stem}.recorder.parquet"
    out = run_cli(["reconstruct", str(log), "--no-gnss", "--departure", dep, "--arrival", arr,
                   "-o", str(res)])
    out.update({"departure": dep, "arrival": arr})
    _, clean = _load(log, meta_overrides={"departure": dep, "arrival": arr},
                     gnss_use=GnssUse(withhold=True))
    ref = gps_reference(flight, clean)
    out["dr_linear"] = dr_linear_errors(clean, ref)
    if out["exit"] == 0:
        out["result"] = horizontal(res, clean, ref)
        out["ratio_to_dr"] = out["result"]["rms_m"] / out["dr_linear"]["rms_h_m"]
        if rec is not None:
            out["alt_msl"] = msl_errors(res, rec)
    return out


def gaps(log: Path, clean: Any, ref: pd.DataFrame, work: Path) -> dict[str, Any]:
    """One ``reconstruct --withhold-gnss`` run with gaps of 600, 300 and 120 s: per gap the
    result's error, dead reckoning's with the wind of the minute before, their ratio and
    the mean NEES per axis."""
    windows = gap_windows(ref)
    res = work / f"{log.stem}.gaps.parquet"
    args = ["reconstruct", str(log), "-o", str(res)]
    for a, b in windows:
        args += ["--withhold-gnss", f"{a:.0f}:{b:.0f}"]
    out = run_cli(args)
    out["gaps"] = []
    if out["exit"] != 0:
        return out
    for a, b in windows:
        a, b = float(round(a)), float(round(b))
        m = ((ref.t_s >= a) & (ref.t_s <= b)).to_numpy()
        if m.sum() < 10:
            continue
        g: dict[str, Any] = {"t0_s": a, "length_s": b - a, **horizontal(res, clean, ref, m)}
        dr = dr_in_gap(clean, ref, a, b)
        g["dr_wind_rms_m"] = float(np.sqrt(np.mean(dr ** 2)))
        g["ratio_to_dr"] = g["rms_m"] / g["dr_wind_rms_m"]
        out["gaps"].append(g)
    return out


def study(log: Path, work: Path) -> dict[str, Any]:
    """Every run on one export (module docstring); a refusal is recorded, not raised."""
    from flightrecon.errors import FlightReconError
    from flightrecon.geo.geoid import undulation_m

    out: dict[str, Any] = {"export": log.name, "info": run_cli(["info", str(log)])}
    res = work / f"{log.stem}.gnss.parquet"
    out["gnss"] = run_cli(["reconstruct", str(log), "-o", str(res)])
    try:
        flight, clean = _load(log)
    except FlightReconError as exc:
        out["reference"] = {"exit": exc.exit_code, "message": str(exc)[:400]}
        return out
    ref = gps_reference(flight, clean)
    rec: pd.DataFrame | None
    try:
        rec = recorded_msl(log, flight)
        d = undulation_m(rec.lat.to_numpy(), rec.lon.to_numpy()) - rec.und.to_numpy()
        out["egm96_minus_recorded_m"] = {"mean": float(np.mean(d)),
                                         "max_abs": float(np.max(np.abs(d))),
                                         "recorded_range": [float(rec.und.min()),
                                                            float(rec.und.max())]}
    except KeyError:                                   # no AltMSL / AltGPS in this export
        rec = None
    if out["gnss"]["exit"] == 0:
        out["gnss"]["result"] = horizontal(res, clean, ref)
        if rec is not None:
            out["gnss"]["alt_msl"] = msl_errors(res, rec)
    for key, fn in (("recorder", lambda: recorder_only(log, flight, work, rec)),
                    ("gap_runs", lambda: gaps(log, clean, ref, work))):
        try:
            out[key] = fn()
        except (FlightReconError, ValueError, IndexError) as exc:
            out[key] = {"exit": getattr(exc, "exit_code", 1), "message": str(exc)[:400]}
    return out


def _f(x: Any, fmt: str = ".0f") -> str:
    return "-" if x is None or not np.isfinite(x) else format(x, fmt)


def _run_cell(r: dict[str, Any] | None) -> str:
    """A run's exit code, with its message when it failed."""
    if not r:
        return "-"
    if r.get("exit") == 0:
        return "0"
    return f"{r.get('exit')}: {str(r.get('message', '')).replace('|', '/')[:160]}"


def markdown(results: list[dict[str, Any]], command: str) -> str:
    """The tables of docs/tables/realexports.md."""
    lines = [f"Regenerate: `{command}`", "", "# Real recorder exports through the command line",
             "", "The figures are in realexports.json. Against each export's own GPS; bars of "
             "issue 49: recorder "
             f"only at most {BAR_RECORDER:g} x dead reckoning with a linear end correction, each "
             f"gap at most {BAR_GAP:g} x dead reckoning with the wind of the minute before, "
             f"mean NEES per gap and axis at most {BAR_NEES:g}, alt_msl_m within "
             f"{BAR_MSL_M:g} m of AltMSL.", "",
             "## Exit codes", "",
             "| export | info | reconstruct (GNSS) | --no-gnss --departure --arrival | "
             "withheld gaps |", "|---|---|---|---|---|"]
    for r in results:
        lines.append(f"| {r['export']} | {_run_cell(r.get('info'))} | "
                     f"{_run_cell(r.get('gnss'))} | {_run_cell(r.get('recorder'))} | "
                     f"{_run_cell(r.get('gap_runs'))} |")
    lines += ["", "## Recorder only, and MSL heights", "",
              "| export | GNSS run: RMS [m] (result from) | recorder only: RMS [m] (result "
              "from) | DR, linear end correction: RMS [m] | ratio | alt_msl_m - AltMSL, GNSS "
              "run: mean / max [m] | the same, recorder only [m] | EGM96 - (AltGPS - AltMSL): "
              "mean / max [m] |", "|---|---|---|---|---|---|---|---|"]
    for r in results:
        ro, g = r.get("recorder") or {}, r.get("gnss") or {}
        gr, rr = g.get("result") or {}, ro.get("result") or {}
        u = r.get("egm96_minus_recorded_m") or {}
        am, bm = g.get("alt_msl") or {}, ro.get("alt_msl") or {}
        note = f" ({am['note']})" if "note" in am else ""
        lines.append(
            f"| {r['export']} | {_f(gr.get('rms_m'))} ({gr.get('method', '-')}) | "
            f"{_f(rr.get('rms_m'))} ({rr.get('method', '-')}) | "
            f"{_f((ro.get('dr_linear') or {}).get('rms_h_m'))} | "
            f"{_f(ro.get('ratio_to_dr'), '.2f')} | {_f(am.get('mean_m'), '+.2f')} / "
            f"{_f(am.get('max_abs_m'), '.2f')}{note} | {_f(bm.get('mean_m'), '+.1f')} / "
            f"{_f(bm.get('max_abs_m'), '.1f')} | {_f(u.get('mean'), '+.2f')} / "
            f"{_f(u.get('max_abs'), '.2f')} |")
    lines += ["", "## Withheld GNSS gaps", "",
              "| export | gap [s] | result RMS (max) [m] (from) | DR, wind of the minute "
              "before, RMS [m] | ratio | mean NEES north / east |", "|---|---|---|---|---|---|"]
    for r in results:
        for g in (r.get("gap_runs") or {}).get("gaps", []):
            lines.append(f"| {r['export']} | {g['length_s']:.0f} (from {g['t0_s']:.0f} s) | "
                         f"{g['rms_m']:.0f} ({g['max_m']:.0f}) ({g.get('method')}) | "
                         f"{g['dr_wind_rms_m']:.0f} | "
                         f"{g['ratio_to_dr']:.2f} | {g['nees_n']:.2f} / {g['nees_e']:.2f} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("exports", nargs="*", type=Path,
                    help="more exports beyond ../shared/realdata (never copied: numbers only)")
    ap.add_argument("--work", type=Path, default=None,
                    help="folder for the results (default: a temporary folder)")
    args = ap.parse_args(argv)
    logs = sorted(REALDATA.glob("*.csv")) + [p.resolve() for p in args.exports]
    command = "python scripts/realexport_study.py " + " ".join(str(p) for p in args.exports)
    with tempfile.TemporaryDirectory() as tmp:
        work = args.work or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        results = []
        for log in logs:
            t0 = time.time()
            results.append(study(log, work))
            print(f"{log.name}: {time.time() - t0:.0f} s", flush=True)
    OUT.mkdir(parents=True, exist_ok=True)
    (OUT / "realexports.json").write_text(json.dumps({"command": command.strip(),
                                                      "exports": results}, indent=1) + "\n")
    (OUT / "realexports.md").write_text(markdown(results, command.strip()))
    print(f"wrote {OUT / 'realexports.md'} and .json")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
