"""The EGM96 geoid undulation (``flightrecon.geo.geoid``; issue 49, item 4).

Before: a flight whose sidecar gave no ``geoid_undulation_m`` used 0 m, so the ``alt_msl_m`` of
a Garmin result was its ellipsoidal height (47 m high at Reims).  Now EGM96 gives it, checked
against NGA's published test values and against the undulation the real exports record
(``AltGPS - AltMSL``); a value given in the sidecar or on the command line still wins.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from test_ingest_support import handmade_frame, load_quiet

from flightrecon.constants import FOOT_M
from flightrecon.export.writers import with_utc_and_msl
from flightrecon.geo.geoid import MODEL, undulation_m
from flightrecon.ingest.readers import read_table

ROOT = Path(__file__).resolve().parents[1]
REAL = sorted((ROOT.parent / "shared" / "realdata").glob("g1000_*.csv"))
SHIPPED = ROOT / "sample_logs" / "g1000_sr22_LFQA_20220417.csv"

#: NGA's test values of the EGM96 distribution (geoid heights from the spherical harmonics to
#: degree 360 at six points: lat, lon, N [m])
NGA_EGM96 = [(38.6281550, 269.7791550, -31.628), (-14.6212170, 305.0211140, -2.969),
             (46.8743190, 102.4487290, -43.575), (-23.6174460, 133.8747120, 15.871),
             (38.6254730, 359.9995000, 50.066), (-0.4667440, 0.0023000, 17.329)]


def test_nga_published_values():
    """Within 0.06 m of NGA's values: the 15' grid's bilinear error there (0.056 m at worst,
    measured when the grid was made: scripts/make_geoid_grid.py)."""
    lat, lon, n = (np.array(c) for c in zip(*NGA_EGM96, strict=True))
    np.testing.assert_allclose(undulation_m(lat, lon), n, atol=0.06)


def test_scalars_wrap_and_poles():
    assert isinstance(undulation_m(49.2, 4.1), float)
    assert undulation_m(10.0, -170.0) == pytest.approx(undulation_m(10.0, 190.0), abs=1e-9)
    assert undulation_m(10.0, 180.0) == pytest.approx(undulation_m(10.0, -180.0), abs=1e-9)
    # one value at each pole whatever the longitude (EGM96: +13.6 m north, -29.5 m south)
    north = undulation_m(np.full(5, 90.0), np.linspace(-180, 180, 5))
    south = undulation_m(np.full(5, -95.0), np.linspace(-180, 180, 5))
    np.testing.assert_allclose(north, 13.6, atol=0.1)
    np.testing.assert_allclose(south, -29.5, atol=0.1)


def _recorded(path: Path):
    """Latitude, longitude and recorded undulation ``AltGPS - AltMSL`` [m] of an export."""
    c = read_table(path).columns
    lat, lon = np.asarray(c["Latitude"], float), np.asarray(c["Longitude"], float)
    n = (np.asarray(c["AltGPS"], float) - np.asarray(c["AltMSL"], float)) * FOOT_M
    ok = np.isfinite(lat) & np.isfinite(lon) & np.isfinite(n)
    return lat[ok], lon[ok], n[ok], np.asarray(c["AltGPS"], float)[ok] * FOOT_M


@pytest.mark.parametrize("path", REAL or [SHIPPED], ids=lambda p: p.name)
def test_against_the_undulation_the_export_records(path):
    """The Garmin's own ``AltGPS - AltMSL`` at every fix (44.5 to 49.7 m over the flights):
    EGM96 within 1 m (the 15' grid's worst interpolation error, 0.68 m, plus the export's
    0.1 ft rounding of both heights); measured 0.31 m at most, 0.16 m RMS."""
    lat, lon, n, _ = _recorded(path)
    e = undulation_m(lat, lon) - n
    assert n.size > 1000 and np.abs(e).max() < 1.0 and abs(e.mean()) < 0.3


def _flight(tmp_path, sidecar_geoid: str = "", **kw):
    d = handmade_frame()
    d.to_csv(tmp_path / "h.csv", index=False)
    (tmp_path / "h.meta.toml").write_text(
        '[flight]\nepoch_utc = "2026-03-15T09:00:00Z"\n' + sidecar_geoid
        + "[departure]\nlat_deg = 40.46\nlon_deg = 50.05\nelev_m = 3.0\n")
    return load_quiet(tmp_path / "h.csv", **kw)[0]


def test_model_when_not_given(tmp_path):
    """No undulation in the sidecar: EGM96's at the departure airfield, said in a note."""
    fl = _flight(tmp_path)
    assert fl.meta.geoid_model == MODEL
    assert fl.meta.geoid_undulation_m == pytest.approx(undulation_m(40.46, 50.05), abs=0.01)
    assert abs(fl.meta.geoid_undulation_m) > 5.0        # not the 0 m of before
    assert any("EGM96 at the departure airfield" in n for n in fl.meta.ingest.notes)


def test_given_value_wins(tmp_path):
    fl = _flight(tmp_path, "geoid_undulation_m = 0.0\n")
    assert fl.meta.geoid_undulation_m == 0.0 and fl.meta.geoid_model is None
    assert any("as given" in n for n in fl.meta.ingest.notes)
    fl = _flight(tmp_path, meta_overrides={"geoid_undulation_m": -12.5})
    assert fl.meta.geoid_undulation_m == -12.5 and fl.meta.geoid_model is None


def test_alt_msl_per_sample_on_the_shipped_export():
    """The result's ``alt_msl_m`` (ellipsoidal height less the model's N at each sample),
    fed with the export's own GPS positions and heights, within 2 m of its ``AltMSL``
    (measured 0.3 m); a given undulation stays one constant."""
    fl, _ = load_quiet(SHIPPED)
    assert fl.meta.geoid_model == MODEL
    lat, lon, n, alt = _recorded(SHIPPED)
    track = pd.DataFrame({"t_s": np.arange(lat.size, dtype=float), "lat_deg": lat,
                          "lon_deg": lon, "alt_m": alt})
    flight = {"geoid_undulation_m": fl.meta.geoid_undulation_m,
              "geoid_model": fl.meta.geoid_model}
    msl = with_utc_and_msl(track, {"flight": flight})["alt_msl_m"].to_numpy()
    assert np.abs(msl - (alt - n)).max() < 2.0
    const = with_utc_and_msl(track, {"flight": {"geoid_undulation_m": 40.0}})
    np.testing.assert_allclose(const["alt_msl_m"], alt - 40.0)
