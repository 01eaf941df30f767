"""Why the joint smoother loses to dead reckoning on some real exports, recorder only (issue 52,
item 2): the smoother run with one part of its model or its data changed at a time.

For each 1 Hz glass-cockpit export (the three real SR22T exports of ``../shared/realdata`` and
any export given on the command line, e.g. a Cessna 172S G1000 export kept in a scratch folder:
an export without a licence is never copied into the repository, only its numbers are written),
every GNSS channel withheld, the departure and arrival the first and last GPS fix on the ground
(``realexport_study.ground_ends``), the joint's horizontal RMS error against the export's own
airborne GPS fixes and its ratio to dead reckoning with a linear end correction, with:

* ``default``: the settings the tool uses;
* ``stands``: the stands also given as known positions (``--fix``, 10 m) at the first and last
  ground fix's time: the end points as exact as the baseline takes them;
* ``gps_loads``: the horizontal kinematic acceleration replaced, airborne, by the derivative of
  the GPS velocity (taken 0.5 s later: the export's GPS velocity lags its air data by about
  that, see :func:`air_data_lag`): loads without their sampling and attitude errors;
* ``no_gradient``: the wind's gradient with height held at zero (prior 0.1 (m/s)/km, its walk
  1e-4) and its walk in altitude at 0.005 m/s per sqrt(m): the wind changes with time only;
* ``steady_wind``: the wind nearly constant (walks 0.005 in time and altitude, no gradient,
  no re-estimated walk): the baseline's own assumption inside the joint model.

Against the GPS (the truth here), per export: the wind the fixes imply (GPS velocity less the
recorded airspeed along the recorded heading) and the joint's, their change over 10 minutes,
and the recorded airspeed's error per speed band (:func:`airspeed_error_by_speed`).

Writes ``docs/tables/joint_recorder_ablation.md`` and ``.json``.

Usage::

    python scripts/joint_recorder_ablation.py [EXTRA_EXPORT.csv ...]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import warnings
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
from onehz_study import dr_linear_errors, gps_reference  # noqa: E402
from realexport_study import GROUND_MPS, REALDATA, _load, ground_ends  # noqa: E402
from table_header import header  # noqa: E402

import flightrecon.methods.joint.method as joint_method  # noqa: E402
import flightrecon.methods.joint.problem as joint_problem  # noqa: E402
from flightrecon.geo.geoid import undulation_m  # noqa: E402
from flightrecon.ingest.gnss_use import GnssUse  # noqa: E402
from flightrecon.methods.joint.settings import JointNoise, JointSettings  # noqa: E402

OUT = ROOT / "docs" / "tables"
#: the export's GPS velocity lags its air data by about this [s] (:func:`air_data_lag`)
GPS_VELOCITY_LAG_S = 0.5
#: speed bands of the airspeed's error [m/s]
SPEED_BANDS = (0.0, 35.0, 40.0, 45.0, 50.0, 55.0, 60.0, 70.0, 80.0, 200.0)
#: knots of the piecewise-linear wind of the air-data fits [s]
WIND_KNOT_S = 600.0

STEADY = {"wind_rw_mps_sqrt_s": 0.005, "wind_shear_mps_per_sqrt_m": 0.005,
          "wind_gradient_per_km": 0.1, "wind_gradient_rw_per_km_sqrt_s": 1e-4}
CASES: dict[str, dict[str, Any]] = {
    "default": {},
    "stands": {"stands": True},
    "gps_loads": {"gps_loads": True},
    "no_gradient": {"noise": {"wind_gradient_per_km": 0.1, "wind_gradient_rw_per_km_sqrt_s": 1e-4,
                              "wind_shear_mps_per_sqrt_m": 0.005}},
    "steady_wind": {"noise": STEADY, "settings": {"wind_rounds": 0}},
}


def stand_fixes(flight: Any, sd_m: float = 10.0) -> list[str]:
    """``T_S,LAT,LON,ALT_MSL,SD`` of the first and last GPS fix on the ground."""
    d = flight.data.dropna(subset=["gnss_lat_deg", "gnss_lon_deg", "gnss_alt_m"])
    d = d[np.hypot(d.gnss_vn_mps, d.gnss_ve_mps).to_numpy() < GROUND_MPS]
    out = []
    for r in (d.iloc[0], d.iloc[-1]):
        msl = r.gnss_alt_m - undulation_m(r.gnss_lat_deg, r.gnss_lon_deg)
        out.append(f"{r.t_s:.2f},{r.gnss_lat_deg:.7f},{r.gnss_lon_deg:.7f},{msl:.1f},{sd_m}")
    return out


def with_gps_loads(ref: pd.DataFrame):
    """``joint_inputs`` with the airborne horizontal acceleration taken from the GPS velocity."""
    base = joint_problem.joint_inputs

    def inputs(clean: Any, noise: Any = None) -> Any:
        inp = base(clean, noise)
        t = ref.t_s.to_numpy(float)
        a = np.gradient(np.c_[ref.vn, ref.ve], t, axis=0)
        ti = inp.t_in
        m = (ti > t[0] + 2.0) & (ti < t[-1] - 2.0)
        acc = inp.acc_ned.copy()
        for k in (0, 1):
            acc[m, k] = np.interp(ti[m] + GPS_VELOCITY_LAG_S, t, a[:, k])
        return replace(inp, acc_ned=acc)
    return base, inputs


def implied_wind(clean: Any, ref: pd.DataFrame, lag_s: float = GPS_VELOCITY_LAG_S
                 ) -> tuple[np.ndarray, ...]:
    """At the fixes: the recorded TAS, heading (unwrapped) and roll, and the GPS velocity
    ``lag_s`` later."""
    g = clean.grid
    gt = g.t_s.to_numpy(float)
    t = ref.t_s.to_numpy(float)
    hr = np.radians(g.heading_deg.to_numpy(float))
    ok = np.isfinite(hr)
    psi = np.interp(t, gt[ok], np.unwrap(hr[ok]))
    tas = np.interp(t, gt, g.tas_mps.to_numpy(float))
    roll = np.interp(t, gt, g.roll_deg.to_numpy(float))
    v = np.c_[np.interp(t + lag_s, t, ref.vn), np.interp(t + lag_s, t, ref.ve)]
    return t, tas, psi, roll, v


def air_fit(t: np.ndarray, tas: np.ndarray, psi: np.ndarray, v: np.ndarray, ok: np.ndarray,
            band: np.ndarray | None = None) -> tuple[np.ndarray, float]:
    """Least squares ``v = TAS u(psi) - TAS dpsi u'(psi) + e_band u(psi) + w(t)``: a heading
    error, the airspeed's error per speed band (or one scale), a piecewise-linear wind.
    Returns the parameters (heading error [rad], then the band errors [m/s] or the scale) and
    the residual RMS [m/s]."""
    tt, p, V = t[ok], psi[ok], tas[ok]
    kn = np.arange(tt[0], tt[-1] + WIND_KNOT_S, WIND_KNOT_S)
    B = np.clip(1.0 - np.abs((tt[:, None] - kn[None, :]) / WIND_KNOT_S), 0.0, None)
    u = np.c_[np.cos(p), np.sin(p)]
    up = np.c_[-np.sin(p), np.cos(p)]
    rows = []
    for ax in (0, 1):
        if band is None:
            E = (V * u[:, ax])[:, None]
        else:
            E = np.zeros((len(tt), int(band.max()) + 1))
            E[np.arange(len(tt)), band[ok]] = u[:, ax]
        W = np.zeros((len(tt), 2 * B.shape[1]))
        W[:, ax * B.shape[1]:(ax + 1) * B.shape[1]] = B
        rows.append(np.hstack([-(V * up[:, ax])[:, None], E, W]))
    A = np.vstack(rows)
    y = np.r_[v[ok, 0] - V * u[:, 0], v[ok, 1] - V * u[:, 1]]
    x, *_ = np.linalg.lstsq(A, y, rcond=None)
    return x, float(np.sqrt(np.mean((y - A @ x) ** 2)))


def air_data_lag(clean: Any, ref: pd.DataFrame) -> dict[str, float]:
    """The air-data fit's residual with the GPS velocity taken 0, 0.5 and 1 s later (|roll| <
    45 deg: the turns show a lag)."""
    out = {}
    for lag in (0.0, 0.5, 1.0):
        t, tas, psi, roll, v = implied_wind(clean, ref, lag)
        ok = (np.abs(roll) < 45) & (tas > 25) & np.isfinite(v).all(axis=1) & np.isfinite(psi)
        out[f"{lag:g}"] = air_fit(t, tas, psi, v, ok)[1]
    return out


def airspeed_error_by_speed(clean: Any, ref: pd.DataFrame) -> dict[str, Any]:
    """True minus recorded TAS [m/s] per speed band (wings level, bands of 30 fixes or more),
    with the heading error, from the GPS."""
    t, tas, psi, roll, v = implied_wind(clean, ref)
    ok = (np.abs(roll) < 10) & (tas > 20) & np.isfinite(v).all(axis=1) & np.isfinite(psi)
    band = np.digitize(tas, SPEED_BANDS) - 1
    count = np.bincount(band[ok], minlength=len(SPEED_BANDS))
    keep = ok & (count[band] >= 30)
    used = np.unique(band[keep])
    remap = np.full(len(SPEED_BANDS), -1)
    remap[used] = np.arange(len(used))
    x, rms = air_fit(t, tas, psi, v, keep, np.where(keep, remap[band], 0))
    bands = {f"{SPEED_BANDS[b]:.0f}-{SPEED_BANDS[b + 1]:.0f}": {"error_mps": float(x[1 + i]),
                                                               "fixes": int(count[b])}
             for i, b in enumerate(used)}
    return {"heading_error_deg": float(np.degrees(x[0])), "bands": bands, "residual_mps": rms}


def wind_changes(track: pd.DataFrame, clean: Any, ref: pd.DataFrame) -> dict[str, Any]:
    """RMS per axis of the 10-minute change of the 2-minute mean wind, the GPS's (TAS above
    45 m/s, wings level) and the joint's, and of their difference."""
    t, tas, psi, roll, v = implied_wind(clean, ref)
    w = v - np.c_[tas * np.cos(psi), tas * np.sin(psi)]
    ok = (tas > 45) & (np.abs(roll) < 10) & np.isfinite(w).all(axis=1)
    edges = np.arange(t[0], t[-1], 120.0)
    gps = np.full((len(edges), 2), np.nan)
    for i, a in enumerate(edges):
        m = ok & (t >= a) & (t < a + 120.0)
        if m.sum() > 30:
            gps[i] = w[m].mean(axis=0)
    jw = np.c_[np.interp(edges + 60.0, track.t_s, track.joint_wind_n_mps),
               np.interp(edges + 60.0, track.t_s, track.joint_wind_e_mps)]
    dg, dj = gps[5:] - gps[:-5], jw[5:] - jw[:-5]
    m = np.isfinite(dg).all(axis=1)
    f = np.isfinite(gps).all(axis=1)
    return {"gps_10min_change_rms_mps": np.sqrt(np.mean(dg[m] ** 2, axis=0)).tolist(),
            "joint_10min_change_rms_mps": np.sqrt(np.mean(dj[m] ** 2, axis=0)).tolist(),
            "joint_minus_gps_rms_mps": np.sqrt(np.mean((jw - gps)[f] ** 2, axis=0)).tolist()}


def run_case(log: Path, name: str, case: dict[str, Any], flight: Any, ref_flight: Any
             ) -> dict[str, Any]:
    """One recorder-only run of the joint with ``case``'s changes."""
    dep, arr = ground_ends(flight)
    over: dict[str, Any] = {"departure": dep, "arrival": arr}
    if case.get("stands"):
        over["fixes"] = stand_fixes(flight)
    _, clean = _load(log, meta_overrides=over, gnss_use=GnssUse(withhold=True))
    ref = gps_reference(ref_flight, clean)
    settings = replace(JointSettings(), noise=replace(JointNoise(), **case.get("noise", {})),
                       **case.get("settings", {}))
    base = joint_problem.joint_inputs
    if case.get("gps_loads"):
        base, joint_problem.joint_inputs = with_gps_loads(ref)
    t0 = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            j = joint_method.run_joint(clean, settings=settings)
    finally:
        joint_problem.joint_inputs = base
    tr = j.track
    dn = np.interp(ref.t_s, tr.t_s, tr.joint_north_m) - ref.n
    de = np.interp(ref.t_s, tr.t_s, tr.joint_east_m) - ref.e
    dr = dr_linear_errors(clean, ref)
    rms = float(np.sqrt(np.mean(dn ** 2 + de ** 2)))
    corr = j.summary.get("corrections", {})
    out = {"case": name, "rms_h_m": rms, "dr_linear_m": dr["rms_h_m"],
           "ratio": rms / dr["rms_h_m"], "seconds": time.perf_counter() - t0,
           "heading_bias_deg": corr.get("heading_bias_deg", {}).get("value"),
           "tas_scale": corr.get("tas_scale", {}).get("value"),
           "gradient_per_km": [corr.get(f"wind_gradient_{a}_per_km", {}).get("value")
                               for a in "ne"]}
    if name == "default":
        out["wind"] = wind_changes(tr, clean, ref)
        out["airspeed"] = airspeed_error_by_speed(clean, ref)
        out["air_data_lag_residual_mps"] = air_data_lag(clean, ref)
    return out


def study(log: Path) -> dict[str, Any]:
    flight, _ = _load(log)
    rows = []
    for name, case in CASES.items():
        r = run_case(log, name, case, flight, flight)
        print(f"{log.stem} {name}: {r['rms_h_m']:.0f} m, {r['ratio']:.2f} x", flush=True)
        rows.append(r)
    return {"export": log.name, "rows": rows}


def markdown(results: list[dict[str, Any]], extra: list[Path]) -> str:
    """The two tables; the command names a further export by its file name only (it lives
    outside the repository)."""
    out = [header(argv=[p.name for p in extra]),
           "| export | " + " | ".join(CASES) + " | dead reckoning + linear |",
           "|---|" + "---|" * (len(CASES) + 1)]
    for r in results:
        cells = [f"{x['rms_h_m']:.0f} ({x['ratio']:.2f})" for x in r["rows"]]
        out.append(f"| {r['export']} | " + " | ".join(cells)
                   + f" | {r['rows'][0]['dr_linear_m']:.0f} |")
    out += ["", "| export | joint heading bias / TAS scale / gradient n, e [(m/s)/km] "
            "| 10-min wind change n, e: GPS / joint [m/s] | joint - GPS wind n, e [m/s] "
            "| GPS: heading error; true - recorded TAS per band [m/s] |", "|---|---|---|---|---|"]
    for r in results:
        d = r["rows"][0]
        w, a = d["wind"], d["airspeed"]
        g = "/".join(f"{x:+.1f}" for x in d["gradient_per_km"])
        bands = ", ".join(f"{k}: {v['error_mps']:+.1f}" for k, v in a["bands"].items())
        out.append(f"| {r['export']} | {d['heading_bias_deg']:+.2f} deg / {d['tas_scale']:+.3f}"
                   f" / {g} | {w['gps_10min_change_rms_mps'][0]:.1f}, "
                   f"{w['gps_10min_change_rms_mps'][1]:.1f} / "
                   f"{w['joint_10min_change_rms_mps'][0]:.1f}, "
                   f"{w['joint_10min_change_rms_mps'][1]:.1f} | "
                   f"{w['joint_minus_gps_rms_mps'][0]:.1f}, {w['joint_minus_gps_rms_mps'][1]:.1f}"
                   f" | {a['heading_error_deg']:+.2f} deg; {bands} |")
    return "\n".join(out) + "\n"


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("exports", nargs="*", type=Path, help="further exports (not copied)")
    ap.add_argument("--no-write", action="store_true", help="print only")
    a = ap.parse_args(argv)
    logs = sorted(REALDATA.glob("g1000_*.csv")) + list(a.exports)
    results = [study(p) for p in logs]
    md = markdown(results, list(a.exports))
    print(md)
    if not a.no_write:
        (OUT / "joint_recorder_ablation.md").write_text(md)
        (OUT / "joint_recorder_ablation.json").write_text(json.dumps(results, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
