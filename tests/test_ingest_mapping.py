"""Foreign logs through mapping files: names, units, signs, IAS -> TAS, magnetic -> true."""

from __future__ import annotations

import warnings

import numpy as np
import pandas as pd
import pytest
from test_ingest_support import handmade_frame, truth

from flightrecon.constants import FOOT_M, G0, KNOT_MPS
from flightrecon.errors import FlightReconWarning, MappingError
from flightrecon.geo.magnetic import decimal_year, declination_deg
from flightrecon.ingest import load_flight, load_mapping

SIDECAR = """[flight]
epoch_utc = "2026-03-15T09:00:00Z"
[departure]
lat_deg = 40.46
lon_deg = 50.05
elev_m = 3.0
"""

FOREIGN_MAPPING = """
[time]
column = "TIME"
unit = "timestamp"

[channels.n_norm_g]
column = "VRTG"
unit = "m/s^2"
[channels.n_long_g]
column = "LONG"
unit = "g"
sign = -1
[channels.n_lat_g]
column = "LATG"
unit = "g"
[channels.roll_deg]
column = "ROLL"
unit = "rad"
[channels.pitch_deg]
column = "PTCH"
unit = "deg"
[channels.heading_deg]
column = "HDG"
unit = "deg"
[channels.baro_alt_m]
column = "ALT_STD"
unit = "ft"
[channels.cas_mps]
column = "CAS"
unit = "kt"
[channels.sat_degc]
column = "SAT"
unit = "K"
[channels.tas_mps]
from = "cas"
"""


def _foreign(tmp_path):
    """The hand-made flight written the way a foreign recorder would: other names and units,
    n_long positive aft, timestamps; TAS replaced by CAS (from the ISA, computed with
    tas_to_cas so that mapping back must give the original TAS)."""
    from flightrecon.geo.atmosphere import tas_to_cas

    d = handmade_frame()
    d = d.drop(columns=[c for c in d if c.startswith("gnss")])
    cas = tas_to_cas(d.tas_mps, d.baro_alt_m.interpolate(), d.sat_degc.interpolate())
    f = pd.DataFrame({
        "TIME": (pd.Timestamp("2026-03-15T09:00:00Z")
                 + pd.to_timedelta(d.t_s, unit="s")).dt.strftime("%Y-%m-%dT%H:%M:%S.%fZ"),
        "VRTG": d.n_norm_g * G0, "LONG": -d.n_long_g, "LATG": d.n_lat_g,
        "ROLL": np.radians(d.roll_deg), "PTCH": d.pitch_deg, "HDG": d.heading_deg,
        "ALT_STD": d.baro_alt_m / FOOT_M, "CAS": cas / KNOT_MPS, "SAT": d.sat_degc + 273.15,
    })
    f.to_csv(tmp_path / "foreign.csv", index=False, float_format="%.10g")
    (tmp_path / "foreign.mapping.toml").write_text(FOREIGN_MAPPING)
    (tmp_path / "foreign.meta.toml").write_text(SIDECAR)
    return d, tmp_path / "foreign.csv", tmp_path / "foreign.mapping.toml"


def test_foreign_names_units_signs_round_trip(tmp_path):
    """Feet, knots, m/s^2, rad, K, a flipped sign and CAS -> TAS map back to the canonical
    values.  Tolerance 1e-9 relative: the foreign file is written with 10 significant digits."""
    d, log, mp = _foreign(tmp_path)
    fl = load_flight(log, mapping=mp)
    assert fl.meta.epoch_utc == "2026-03-15T09:00:00Z"
    np.testing.assert_allclose(fl.data.t_s, d.t_s, atol=1e-6)   # microsecond timestamps
    for c in ("n_norm_g", "n_long_g", "n_lat_g", "roll_deg", "pitch_deg", "baro_alt_m",
              "sat_degc"):
        np.testing.assert_allclose(fl.data[c], d[c], rtol=1e-9, atol=1e-9, err_msg=c)
    # TAS on the rows where CAS was recorded; the rounding of CAS to 10 digits keeps 1e-7 m/s
    ok = d.tas_mps.notna()
    np.testing.assert_allclose(fl.data.tas_mps[ok], d.tas_mps[ok], atol=1e-6)
    assert any("VRTG" in n for n in fl.meta.ingest.notes)


@pytest.mark.parametrize("h_m,p_hpa,t_k", [
    # ICAO standard atmosphere (Doc 7488) at 3048 m (10 000 ft) and 6096 m (20 000 ft)
    (3048.0, 696.82, 268.34),
    (6096.0, 465.63, 248.53),
])
def test_cas_to_tas_against_standard_atmosphere(tmp_path, h_m, p_hpa, t_k):
    """TAS computed at ingest from CAS 150 kt equals the compressible-flow value built from the
    published ISA pressure and temperature at that height (St Venant: qc from CAS at sea level,
    Mach from qc/p, TAS = M a(T)).  Tolerance 0.05 %: the table values are given to 5 digits."""
    cas = 150.0 * KNOT_MPS
    p0, a0 = 101325.0, 340.294   # ISA sea-level pressure [Pa] and speed of sound [m/s]
    qc = p0 * ((1 + 0.2 * (cas / a0) ** 2) ** 3.5 - 1)
    mach = np.sqrt(5 * ((qc / (p_hpa * 100) + 1) ** (2 / 7) - 1))
    tas_ref = mach * np.sqrt(1.4 * 287.05287 * t_k)
    d = handmade_frame()
    d = d.drop(columns="tas_mps").assign(cas_mps=cas, baro_alt_m=h_m, sat_degc=t_k - 273.15)
    d.to_csv(tmp_path / "c.csv", index=False)
    (tmp_path / "c.toml").write_text('[channels.tas_mps]\nfrom = "cas"\n')
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FlightReconWarning)
        fl = load_flight(tmp_path / "c.csv", mapping=tmp_path / "c.toml")
    np.testing.assert_allclose(fl.data.tas_mps, tas_ref, rtol=5e-4)


def test_ias_without_tas_is_derived_with_warning(tmp_path):
    """A canonical log with ias_mps and no tas_mps: TAS derived, IAS-as-CAS said in a warning."""
    d = handmade_frame().rename(columns={"tas_mps": "ias_mps"})
    d.to_csv(tmp_path / "i.csv", index=False)
    with pytest.warns(FlightReconWarning, match="IAS treated as CAS"):
        fl = load_flight(tmp_path / "i.csv")
    assert fl.data.tas_mps.notna().sum() == d.ias_mps.notna().sum()


# NOAA/BGS, "WMM2025 test values" (WMM2025testvalues.pdf, published with the model,
# https://www.ncei.noaa.gov/products/world-magnetic-model): height 0 km, declination in degrees.
WMM2025_TEST_VALUES = [
    (2025.0, 80.0, 0.0, 1.28),
    (2025.0, 0.0, 120.0, -0.16),
    (2025.0, -80.0, 240.0, 68.78),
    (2027.5, 80.0, 0.0, 2.59),
]


@pytest.mark.parametrize("year,lat,lon,d_pub", WMM2025_TEST_VALUES)
def test_declination_against_published_wmm_values(year, lat, lon, d_pub):
    """Tolerance 0.006 deg: NOAA prints D to 0.01 deg (rounding <= 0.005) plus margin."""
    d, note = declination_deg(lat, lon, 0.0, year)
    assert note is None
    assert abs(float(d) - d_pub) < 0.006


def test_magnetic_heading_to_true_through_load_flight(tmp_path):
    """Magnetic heading at the departure airfield (80 N, 0 E) on 2025-01-01 (decimal year
    2025.0) becomes magnetic + 1.28 deg (published WMM2025 test value; tolerance as above)."""
    d = handmade_frame()
    d = d.drop(columns=[c for c in d if c.startswith("gnss")]).rename(
        columns={"heading_deg": "HDG_MAG"})
    d["HDG_MAG"] = np.where(d.HDG_MAG.notna(), 100.0, np.nan)
    d.to_csv(tmp_path / "m.csv", index=False)
    (tmp_path / "m.meta.toml").write_text('[flight]\nepoch_utc = "2025-01-01T00:00:00Z"\n'
                                          "[departure]\nlat_deg = 80.0\nlon_deg = 0.0\n"
                                          "elev_m = 0.0\n")
    (tmp_path / "m.toml").write_text('[channels.heading_deg]\ncolumn = "HDG_MAG"\nunit = "deg"\n'
                                     'reference = "magnetic"\n')
    fl = load_flight(tmp_path / "m.csv", mapping=tmp_path / "m.toml")
    h = fl.data.heading_deg.dropna().to_numpy()
    assert np.all(np.abs(h - 101.28) < 0.006)
    assert any("magnetic -> true" in n for n in fl.meta.ingest.notes)


def test_magnetic_uses_gnss_track_when_present(tmp_path):
    """With GNSS positions the declination is taken along the track: equal to the WMM value at
    the departure point here (the 4-minute track spans 15 km; tolerance 0.05 deg, the change of
    D over 15 km at 40 N 50 E is below 0.02 deg)."""
    d = handmade_frame().rename(columns={"heading_deg": "HDG_MAG"})
    d.to_csv(tmp_path / "g.csv", index=False)
    (tmp_path / "g.meta.toml").write_text(SIDECAR)
    (tmp_path / "m.toml").write_text('[channels.heading_deg]\ncolumn = "HDG_MAG"\nunit = "deg"\n'
                                     'reference = "magnetic"\n')
    fl = load_flight(tmp_path / "g.csv", mapping=tmp_path / "m.toml")
    d_ref, _ = declination_deg(40.46, 50.05, 0.0, decimal_year("2026-03-15T09:00:00Z"))
    got = (fl.data.heading_deg - d.HDG_MAG).dropna().to_numpy()
    got = (got + 180.0) % 360.0 - 180.0
    assert np.all(np.abs(got - float(d_ref)) < 0.05)
    assert any("GNSS track" in n for n in fl.meta.ingest.notes)


def test_mapping_sub_tables_for_gnss_file(tmp_path):
    """A foreign GNSS file with its own [gnss] mapping (feet, knots are not allowed for lat)."""
    d = handmade_frame()
    log = d.drop(columns=[c for c in d if c.startswith("gnss")])
    log.to_csv(tmp_path / "l.csv", index=False)
    g = d[["t_s", "gnss_lat_deg", "gnss_lon_deg", "gnss_alt_m"]].dropna()
    pd.DataFrame({"SEC": g.t_s + 0.02, "LAT": g.gnss_lat_deg, "LON": g.gnss_lon_deg,
                  "HGT_FT": g.gnss_alt_m / FOOT_M}).to_csv(tmp_path / "g.csv", index=False)
    (tmp_path / "m.toml").write_text(
        '[gnss.time]\ncolumn = "SEC"\nunit = "s"\n'
        '[gnss.channels.gnss_lat_deg]\ncolumn = "LAT"\n'
        '[gnss.channels.gnss_lon_deg]\ncolumn = "LON"\n'
        '[gnss.channels.gnss_alt_m]\ncolumn = "HGT_FT"\nunit = "ft"\n')
    fl = load_flight(tmp_path / "l.csv", gnss=tmp_path / "g.csv", mapping=tmp_path / "m.toml")
    got = fl.data.dropna(subset=["gnss_alt_m"])
    np.testing.assert_allclose(got.gnss_alt_m.to_numpy(), g.gnss_alt_m.to_numpy(), rtol=1e-12)
    np.testing.assert_allclose(got.t_s.to_numpy(), g.t_s.to_numpy() + 0.02, atol=1e-9)


@pytest.mark.parametrize("text,words", [
    ('[chanels.n_norm_g]\ncolumn = "V"\n', "unknown table or key 'chanels'"),
    ('[channels.n_norm_g]\ncolumn = "V"\nunits = "g"\n', "unknown key 'units'"),
    ('[channels.tas_mps]\nfrom = "gps"\n', "cannot derive tas_mps from 'gps'"),
    ('[channels.roll_deg]\ncolumn = "R"\nreference = "magnetic"\n', "only applies to"),
    ('[channels.roll_deg]\ncolumn = "R"\n[channels.pitch_deg]\ncolumn = "R"\n',
     "several channels"),
    ('[time]\ncolumn = "T"\nunit = "ms"\n', "unit 'ms'"),
    ('[channels.n_norm_g]\nunit = "g"\n', "missing key 'column'"),
])
def test_mapping_file_errors(tmp_path, text, words):
    (tmp_path / "m.toml").write_text(text)
    with pytest.raises(MappingError, match=words) as ex:
        load_mapping(tmp_path / "m.toml")
    assert ex.value.exit_code == 6
    assert "m.toml" in str(ex.value)


def test_truth_loads_are_consistent_with_conventions():
    """The support generator obeys METHODS.md: n_norm = +1 at rest and 1/cos(roll) in the
    level-speed turn (here climbing at 6 deg: n_norm = cos(gamma)/cos(roll) with pitch terms;
    checked at rest only to 1e-12), n_long = sin(pitch) at rest."""
    tr = truth()
    rest = tr.t_s < 29
    np.testing.assert_allclose(tr.n_norm_g[rest], np.cos(np.radians(2.0)), atol=1e-12)
    np.testing.assert_allclose(tr.n_long_g[rest], np.sin(np.radians(2.0)), atol=1e-12)


def test_time_format_and_sidecar_epoch(tmp_path):
    """Text timestamps in a custom strptime format; with an epoch in the sidecar, t_s counts
    from that epoch (here 10 s before the first row)."""
    d = handmade_frame().iloc[:100]
    ts = pd.Timestamp("2026-03-15T09:00:10Z") + pd.to_timedelta(d.t_s, unit="s")
    f = d.drop(columns="t_s").assign(CLOCK=ts.dt.strftime("%d/%m/%Y %H:%M:%S.%f"))
    f.to_csv(tmp_path / "c.csv", index=False)
    (tmp_path / "c.meta.toml").write_text('[flight]\nepoch_utc = "2026-03-15T09:00:00Z"\n')
    (tmp_path / "c.toml").write_text('[time]\ncolumn = "CLOCK"\nunit = "timestamp"\n'
                                     'format = "%d/%m/%Y %H:%M:%S.%f"\n')
    fl = load_flight(tmp_path / "c.csv", mapping=tmp_path / "c.toml")
    np.testing.assert_allclose(fl.data.t_s, d.t_s + 10.0, atol=1e-6)  # microsecond text


def test_derived_channel_source_must_be_a_name(tmp_path):
    """Regression (found by hypothesis): ``from = [1, 2]`` raised TypeError, not MappingError."""
    import pytest

    from flightrecon.errors import MappingError
    from flightrecon.ingest import load_mapping

    p = tmp_path / "m.toml"
    p.write_text('[channels.tas_mps]\nfrom = [1, 2]\n')
    with pytest.raises(MappingError):
        load_mapping(p)
