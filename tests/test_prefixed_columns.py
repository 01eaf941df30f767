"""Every method's prefixed columns mean what the unprefixed ones mean (docs/output.md; issue 52,
item 6): ``<p>_north_m, <p>_east_m, <p>_up_m`` in the output tangent plane,
``<p>_lat_deg, <p>_lon_deg, <p>_alt_m`` the same point in WGS-84 with its ellipsoidal height,
all built by the one builder (flightrecon/tracks.py).  Before, ``sabziev_up_m`` was a height
above the departure airfield (20 km from the plane's up 509 km from the origin) and only the
joint smoother wrote latitude, longitude and height."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pytest

from flightrecon.geo.frames import TangentPlane, output_plane
from flightrecon.tracks import TrackColumns

ROOT = Path(__file__).resolve().parents[1]
LANDING = ROOT / "sample_logs" / "landing.parquet"   # every method runs on it
METHODS = ("joint", "sabziev", "arms", "azimuth", "sns")


@pytest.fixture(scope="module")
def landing():
    from flightrecon.pipeline import ReconstructSettings, reconstruct

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        rec = reconstruct(LANDING, settings=ReconstructSettings(), record=False)
    return rec, output_plane(rec.clean.meta)


def _agrees_with_its_plane(tr, plane: TangentPlane, p: str) -> int:
    """``p`` (a prefix with its underscore, or "" for the default): lat/lon/alt are the plane
    position converted by PROJ; returns the number of samples checked."""
    e, n, u = (tr[f"{p}{c}_m"].to_numpy(float) for c in ("east", "north", "up"))
    ok = np.isfinite(e) & np.isfinite(n) & np.isfinite(u)
    lat, lon, alt = plane.inverse(e[ok], n[ok], u[ok])
    # 1e-8 deg is 1 mm; PROJ's round trip is good to far below that
    assert np.abs(tr[f"{p}lat_deg"].to_numpy(float)[ok] - lat).max() < 1e-8
    assert np.abs(tr[f"{p}lon_deg"].to_numpy(float)[ok] - lon).max() < 1e-8
    assert np.abs(tr[f"{p}alt_m"].to_numpy(float)[ok] - alt).max() < 1e-3
    return int(ok.sum())


@pytest.mark.parametrize("method", METHODS)
def test_each_method_has_the_defaults_columns_with_their_meaning(landing, method):
    rec, plane = landing
    tr = rec.track
    p = f"{method}_"
    for c in ("north_m", "east_m", "up_m", "lat_deg", "lon_deg", "alt_m", "vn_mps", "ve_mps",
              "north_sd_m", "east_sd_m"):
        assert p + c in tr.columns, (method, c)
    assert _agrees_with_its_plane(tr, plane, p) > 100
    # where the method supplies the default's horizontal position, the two are one
    mine = (tr["source"] == method).to_numpy(bool)
    if mine.any():
        for c in ("north_m", "east_m", "north_sd_m", "east_sd_m"):
            np.testing.assert_array_equal(tr[c].to_numpy(float)[mine],
                                          tr[p + c].to_numpy(float)[mine])


def test_the_default_columns_have_the_same_meaning(landing):
    rec, plane = landing
    assert _agrees_with_its_plane(rec.track, plane, "") > 100


def test_sabziev_height_is_kept_and_its_up_is_the_planes(landing):
    rec, plane = landing
    tr = rec.track
    h = tr["sabziev_height_m"].to_numpy(float)
    ok = np.isfinite(h)
    # the ellipsoidal height is the origin's plus the height above it along the local vertical
    np.testing.assert_allclose(tr["sabziev_alt_m"].to_numpy(float)[ok], plane.h0_m + h[ok],
                               atol=1e-3)
    # the up of the plane is below the height by the plane's drop (d^2 / 2R, ~0.3 m at 2 km)
    d = np.hypot(tr["sabziev_east_m"].to_numpy(float), tr["sabziev_north_m"].to_numpy(float))
    drop = h - tr["sabziev_up_m"].to_numpy(float)
    np.testing.assert_allclose(drop[ok], d[ok] ** 2 / (2 * 6.371e6), rtol=0.02, atol=1e-3)


def test_a_height_far_from_the_origin_becomes_the_planes_up():
    # 509 km from the origin the plane is 20 km below the ellipsoid: a height of 1000 m there
    # is an up of about -19.3 km, and its ellipsoidal height is the origin's + 1000 m
    plane = TangentPlane(50.0, 2.0, 100.0)
    east, north, height = np.array([509e3, 0.0]), np.array([0.0, 1e3]), np.array([1000.0, 500.0])
    out = TrackColumns("x", np.array([0.0, 1.0]))
    out.add_place(plane, east, north, height=height, up_sd=np.array([5.0, 5.0]))
    tr = out.frame()
    assert tr["x_height_m"].tolist() == [1000.0, 500.0]
    np.testing.assert_allclose(tr["x_alt_m"], 100.0 + height, atol=1e-3)
    assert tr["x_up_m"].iloc[0] == pytest.approx(1000.0 - 509e3 ** 2 / (2 * 6.39e6), rel=0.01)
    assert tr["x_up_sd_m"].tolist() == [5.0, 5.0]


def test_a_position_without_a_vertical_has_lat_lon_and_no_alt():
    plane = TangentPlane(50.0, 2.0, 100.0)
    out = TrackColumns("x", np.array([0.0, 1.0]))
    out.add_place(plane, np.array([1e3, 2e3]), np.array([0.0, 0.0]), up=np.array([10.0, np.nan]))
    tr = out.frame()
    assert np.isfinite(tr["x_lat_deg"]).all() and np.isfinite(tr["x_lon_deg"]).all()
    assert np.isfinite(tr["x_alt_m"].iloc[0]) and np.isnan(tr["x_alt_m"].iloc[1])


def test_rows_not_covered_are_nan():
    plane = TangentPlane(50.0, 2.0, 100.0)
    out = TrackColumns("x", np.arange(4.0), slice(1, 3))
    out.add_place(plane, np.array([1.0, 2.0]), np.array([3.0, 4.0]), up=np.array([5.0, 6.0]))
    tr = out.frame()
    assert tr["x_up_m"].isna().tolist() == [True, False, False, True]
    assert tr["x_lat_deg"].isna().tolist() == [True, False, False, True]
