"""No airfield needed when GNSS or radar fixes the position: the output frame's origin from the
first fix (flightrecon.cleaning.origin)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flightrecon.cleaning.origin import frame_origin
from flightrecon.errors import MetadataError
from flightrecon.geo.frames import TangentPlane, output_plane
from flightrecon.pipeline import reconstruct
from flightrecon.sim.io import meta_toml
from flightrecon.types import FlightMeta, Position

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"


def _no_airfields(tmp: Path, name: str) -> Path:
    from flightrecon.ingest.sidecar import load_sidecar

    log = tmp / f"{name}.csv"
    log.write_bytes((SAMPLES / f"{name}.csv").read_bytes())
    meta = load_sidecar(SAMPLES / f"{name}.meta.toml").meta
    (tmp / f"{name}.meta.toml").write_text(meta_toml(dataclasses.replace(
        meta, departure=None, arrival=None)))
    return log


def test_gnss_only_regional_without_departure(tmp_path):
    """The regional flight (300 km, 1 Hz GNSS) without any airfield: joint and SNS run, the
    origin is the first fix, and the joint track is as close to the truth as with airfields."""
    rec = reconstruct(_no_airfields(tmp_path, "regional"), record=False)
    st = {k: v["status"] for k, v in rec.summary["methods"].items()}
    assert st["joint"] == "ok" and st["sns"] == "ok" and st["sabziev"] == "skipped"
    o = rec.clean.meta.origin
    first = rec.clean.gnss.iloc[0]
    assert (o.lat_deg, o.lon_deg) == (first["gnss_lat_deg"], first["gnss_lon_deg"])
    assert o.elev_m == pytest.approx(first["gnss_alt_m"] + 22.0)   # ellipsoid -> MSL (N = -22)
    assert any(e["action"] == "origin" for e in rec.clean.report)
    assert "first position fix" in rec.summary["output"]["frame"]
    tr = pd.read_parquet(SAMPLES / "regional.truth.parquet")
    e, n, _ = output_plane(rec.clean.meta).forward(tr.lat_deg.to_numpy(), tr.lon_deg.to_numpy(),
                                                   tr.alt_m.to_numpy())
    t = rec.track["t_s"].to_numpy()
    dn = rec.track["north_m"].to_numpy() - np.interp(t, tr.t_s, n)
    de = rec.track["east_m"].to_numpy() - np.interp(t, tr.t_s, e)
    rms = float(np.sqrt(np.nanmean(dn ** 2 + de ** 2)))
    assert rms < 3.0   # measured 1.56 m (fixes: 2.5 m sd per axis)


def test_radar_origin_from_station():
    """First radar plot: range 10 km due east at 0 deg elevation -> 10 km east of the
    station."""
    st = Position(45.0, 10.0, 100.0)
    meta = FlightMeta(station=st)
    radar = pd.DataFrame({"t_s": [5.0, 6.0], "arms_range_m": [10_000.0, 10_100.0],
                          "arms_azimuth_deg": [90.0, 90.0], "arms_elevation_deg": [0.0, 0.0]})
    grid = pd.DataFrame({"t_s": [0.0, 10.0], "baro_alt_m": [1000.0, 1000.0]})
    o, how = frame_origin(meta, grid, pd.DataFrame(), radar)
    e, n, _ = TangentPlane(45.0, 10.0, 0.0).forward(o.lat_deg, o.lon_deg, 0.0)
    assert float(e) == pytest.approx(10_000.0, abs=0.5) and abs(float(n)) < 10.0
    assert o.elev_m == 1000.0 and "radar" in how


def test_no_fix_no_departure_still_refused():
    with pytest.raises(MetadataError, match="no GNSS or radar fix"):
        output_plane(FlightMeta())
