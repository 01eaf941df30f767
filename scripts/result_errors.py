"""A written result against a reference: the log's own GPS fixes or a simulated flight's truth.

For a real log that recorded GNSS (a Garmin export, for example), the log's own fixes are the
independent reference of a recorder-only reconstruction (``flightrecon reconstruct LOG
--no-gnss ...``) and the consistency check of a reconstruction that used them. For a simulated
flight (``flightrecon simulate``, the shipped ``sample_logs/*.parquet``) the reference is its
``<stem>.truth.parquet``, sampled at the truth's rows.

The result's ``lat_deg``, ``lon_deg`` (WGS-84) and ``alt_m`` (ellipsoidal height) are
interpolated linearly in time to each fix's time stamp plus ``--latency`` (the receiver's
latency: the time the position was the aircraft's; the joint smoother estimates it as its GNSS
clock offset, the summary's ``methods.joint.clock_offsets_s.gnss``); the horizontal error is the
geodesic distance on the WGS-84 ellipsoid, the vertical error the difference of ellipsoidal
heights (the log's ``gnss_alt_m`` must be ellipsoidal, as a Garmin export's ``AltGPS`` is).
With ``--truth`` the truth's ``lat_deg``, ``lon_deg``, ``alt_m`` (ellipsoidal) are the reference.
Only references between lift-off and touchdown (the result summary's ``phases``) count, and of
the fixes only those of quality above 0. Nothing is written.

Usage: ``python scripts/result_errors.py RESULT (--log LOG | --truth TRUTH) [--summary FILE]
[--latency S]`` (the summary defaults to ``<result stem>.summary.json`` beside the result).
"""

from __future__ import annotations

import argparse
import json
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
from pyproj import Geod

from flightrecon.ingest import load_flight


def read_result(path: Path) -> pd.DataFrame:
    """The written result (Parquet or CSV) with its ``t_s``, ``lat_deg``, ``lon_deg``, ``alt_m``."""
    if path.suffix == ".csv":
        return pd.read_csv(path)
    return pd.read_parquet(path)


def airborne_fixes(log: Path, liftoff_t_s: float, touchdown_t_s: float) -> pd.DataFrame:
    """The log's GNSS fixes of quality above 0 strictly between lift-off and touchdown."""
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        data = load_flight(log).data
    g = data.dropna(subset=["gnss_lat_deg", "gnss_lon_deg", "gnss_alt_m"])
    if "gnss_quality" in g:
        g = g[g.gnss_quality > 0]
    return g[(g.t_s > liftoff_t_s) & (g.t_s < touchdown_t_s)]


def airborne_truth(truth: Path, liftoff_t_s: float, touchdown_t_s: float) -> pd.DataFrame:
    """A simulated flight's truth rows strictly between lift-off and touchdown, in the fixes'
    column names."""
    t = pd.read_parquet(truth, columns=["t_s", "lat_deg", "lon_deg", "alt_m"])
    t = t[(t.t_s > liftoff_t_s) & (t.t_s < touchdown_t_s)]
    return t.rename(columns={"lat_deg": "gnss_lat_deg", "lon_deg": "gnss_lon_deg",
                             "alt_m": "gnss_alt_m"})


def errors_m(result: pd.DataFrame, fixes: pd.DataFrame,
             latency_s: float) -> tuple[np.ndarray, np.ndarray]:
    """Horizontal (geodesic) and vertical (result minus reference) error at each reference
    point [m]."""
    t = fixes.t_s.to_numpy(float) + latency_s
    lat = np.interp(t, result.t_s, result.lat_deg)
    lon = np.interp(t, result.t_s, result.lon_deg)
    alt = np.interp(t, result.t_s, result.alt_m)
    _, _, dist = Geod(ellps="WGS84").inv(lon, lat, fixes.gnss_lon_deg.to_numpy(float),
                                         fixes.gnss_lat_deg.to_numpy(float))
    return np.asarray(dist), alt - fixes.gnss_alt_m.to_numpy(float)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("result", type=Path, help="a result written by flightrecon reconstruct")
    refs = ap.add_mutually_exclusive_group(required=True)
    refs.add_argument("--log", type=Path, help="the log it was reconstructed from, with its GNSS")
    refs.add_argument("--truth", type=Path, help="the simulated flight's <stem>.truth.parquet")
    ap.add_argument("--summary", type=Path, default=None,
                    help="the result's summary (default <result stem>.summary.json)")
    ap.add_argument("--latency", type=float, default=0.0,
                    help="the fixes' latency [s] added to their time stamps (default 0)")
    args = ap.parse_args()
    summary_path = args.summary or args.result.with_name(args.result.stem + ".summary.json")
    phases = json.loads(summary_path.read_text())["phases"]
    ends = (phases["liftoff_t_s"], phases["touchdown_t_s"])
    if args.log is not None:
        ref = airborne_fixes(args.log, *ends)
        what = f"airborne GPS fixes, latency {args.latency:g} s"
    else:
        ref = airborne_truth(args.truth, *ends)
        what = "airborne truth rows"
    h_m, v_m = errors_m(read_result(args.result), ref, args.latency)
    print(f"{len(h_m)} {what}")
    print(f"horizontal: RMS {np.sqrt(np.mean(h_m ** 2)):.1f} m, max {np.max(h_m):.1f} m")
    print(f"vertical:   RMS {np.sqrt(np.mean(v_m ** 2)):.1f} m, mean {np.mean(v_m):+.1f} m")


if __name__ == "__main__":
    main()
