"""Foundation pieces: errors, atomic writes, frames, standard atmosphere."""

import numpy as np
import pytest
from pyproj import Geod

from flightrecon.errors import (
    FlightReconError,
    InputFileError,
    OutputError,
    SchemaError,
    ValidationError,
)
from flightrecon.export.atomic import atomic_path, check_not_input, sweep_leftovers
from flightrecon.geo import atmosphere as isa
from flightrecon.geo.frames import TangentPlane, ecef_to_geodetic, geodetic_to_ecef


def test_error_message_names_file_column_rows():
    e = ValidationError("value out of range", file="log.csv", column="tas_mps", rows=[3, 4, 5, 6, 7, 8])
    s = str(e)
    assert "log.csv" in s and "tas_mps" in s and "rows 3, 4, 5, 6, 7 (+1 more)" in s
    assert e.exit_code == 5 and isinstance(e, FlightReconError)
    assert InputFileError("x").exit_code == 3 and SchemaError("x").exit_code == 4


def test_atomic_write_replaces_only_on_success(tmp_path):
    target = tmp_path / "out.txt"
    target.write_text("old")
    with pytest.raises(RuntimeError):
        with atomic_path(target) as tmp:
            tmp.write_text("half")
            raise RuntimeError("killed")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["out.txt"]
    with atomic_path(target) as tmp:
        tmp.write_text("new")
    assert target.read_text() == "new"


def test_sweep_leftovers_and_refuse_input(tmp_path):
    left = tmp_path / ".out.parquet.flightrecon-tmp-123-abcd"
    left.write_text("x")
    assert sweep_leftovers(tmp_path) == [left]
    assert not left.exists()
    log = tmp_path / "log.csv"
    log.write_text("t_s\n0\n")
    with pytest.raises(OutputError):
        check_not_input(tmp_path / "." / "log.csv", [log])


def test_tangent_plane_round_trip_and_geometry():
    tp = TangentPlane(40.4675, 50.0467, 10.0)
    rng = np.random.default_rng(0)
    e, n, u = rng.uniform(-2e5, 2e5, 50), rng.uniform(-2e5, 2e5, 50), rng.uniform(0, 1e4, 50)
    lat, lon, h = tp.inverse(e, n, u)
    e2, n2, u2 = tp.forward(lat, lon, h)
    # PROJ's iterative inverse is accurate to well below a millimetre
    np.testing.assert_allclose(np.c_[e2, n2, u2], np.c_[e, n, u], atol=1e-6)
    # a point 10 km due north on the ellipsoid surface: north ~ 10 km, up < 0 (earth curvature)
    lon2, lat2, _ = Geod(ellps="WGS84").fwd(50.0467, 40.4675, 0.0, 10_000.0)
    e3, n3, u3 = tp.forward(lat2, lon2, 10.0)
    assert abs(float(e3)) < 1e-6 and abs(float(n3) - 10_000) < 1.0
    assert -8.5 < float(u3) < -7.5  # d^2 / (2 R) = 7.85 m


def test_ecef_round_trip():
    x, y, z = geodetic_to_ecef([0.0, 45.0], [0.0, 90.0], [0.0, 1000.0])
    assert abs(float(x[0]) - 6378137.0) < 1e-6
    lat, lon, h = ecef_to_geodetic(x, y, z)
    np.testing.assert_allclose(lat, [0, 45], atol=1e-10)
    np.testing.assert_allclose(h, [0, 1000], atol=1e-6)


@pytest.mark.parametrize("h, p", [(0.0, 101325.0), (1000.0, 89874.6), (5000.0, 54019.9),
                                  (11000.0, 22632.1), (15000.0, 12044.6)])
def test_isa_pressure_table(h, p):
    # ICAO standard atmosphere table values, quoted to 0.1 Pa (relative 2e-6)
    assert abs(float(isa.isa_pressure_pa(h)) - p) / p < 5e-6
    assert abs(float(isa.pressure_altitude_m(p)) - h) < 0.5


def test_cas_tas_sea_level_and_altitude():
    # in ISA at sea level CAS = TAS
    assert abs(float(isa.cas_to_tas(120.0, 0.0, 15.0)) - 120.0) < 1e-9
    # 250 kt CAS at FL100 ISA (-4.8 degC) is about 288 kt TAS (E6B / standard tables)
    tas_kt = float(isa.cas_to_tas(250 * 0.514444, 3048.0, -4.8)) / 0.514444
    assert 286.0 < tas_kt < 290.0
    v = np.linspace(50, 250, 9)
    np.testing.assert_allclose(isa.tas_to_cas(isa.cas_to_tas(v, 9000.0, -40.0), 9000.0, -40.0), v,
                               rtol=1e-12)


def test_tangent_plane_accepts_numpy_scalars():
    """Regression: a numpy scalar's repr in the PROJ string was read as 0 (plane at 0N 0E)."""
    a = TangentPlane(np.float64(40.1), np.float64(49.5), np.float64(12.0))
    b = TangentPlane(40.1, 49.5, 12.0)
    np.testing.assert_allclose(a.forward(40.2, 49.6, 100.0), b.forward(40.2, 49.6, 100.0))
    lat, lon, _ = a.inverse(0.0, 0.0, 0.0)
    assert abs(float(lat) - 40.1) < 1e-9 and abs(float(lon) - 49.5) < 1e-9


def test_wgs84_parameters_equal_proj():
    """flightrecon.geo.wgs84 writes the defining parameters instead of reading them from PROJ at
    import (so the ingest and ``info`` need no pyproj): they must equal PROJ's to the bit."""
    from pyproj.crs import Ellipsoid

    from flightrecon.geo.wgs84 import WGS84_A, WGS84_E2, WGS84_F

    e = Ellipsoid.from_name("WGS84")
    assert WGS84_A == float(e.semi_major_metre)
    assert WGS84_F == 1.0 / float(e.inverse_flattening)
    assert WGS84_E2 == WGS84_F * (2.0 - WGS84_F)
