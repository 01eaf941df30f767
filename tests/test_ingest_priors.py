"""Known positions (``--fix``) and winds aloft (``--wind``): parsed, validated with errors that
name the file, column and row, and carried in the flight's metadata."""

from __future__ import annotations

import pytest

from flightrecon.cli.main import main
from flightrecon.errors import (
    FlightReconWarning,
    InputFileError,
    MetadataError,
    SchemaError,
    ValidationError,
)
from flightrecon.ingest import load_flight
from flightrecon.ingest.priors import (
    DEFAULT_FIX_SD_M,
    DEFAULT_WIND_SD_MPS,
    parse_fix,
    read_wind_table,
)
from flightrecon.sim import simulate, write_simulation
from flightrecon.types import PositionFix, WindLevel


def test_parse_fix_forms():
    assert parse_fix("120.5, 40.5, 50.1") == PositionFix(120.5, 40.5, 50.1, None,
                                                         DEFAULT_FIX_SD_M)
    assert parse_fix("10,40,50,1500") == PositionFix(10.0, 40.0, 50.0, 1500.0, DEFAULT_FIX_SD_M)
    assert parse_fix("10,40,50,,250") == PositionFix(10.0, 40.0, 50.0, None, 250.0)
    assert parse_fix("10,40,350,1500,30").lon_deg == pytest.approx(-10.0)


@pytest.mark.parametrize("text,match", [
    ("10,40", "T_S,LAT,LON"), ("10,40,50,1,2,3", "T_S,LAT,LON"), ("a,40,50", "not a number"),
    ("10,nan,50", "not finite"), ("10,91,50", "latitude"), ("10,40,400", "longitude"),
    ("10,40,50,30000", "altitude"), ("10,40,50,100,0", "positive"),
])
def test_parse_fix_refuses(text, match):
    with pytest.raises(MetadataError, match=match):
        parse_fix(text)


def _write(tmp_path, text, name="w.csv"):
    p = tmp_path / name
    p.write_text(text)
    return p


def test_wind_table_sorted_with_defaults(tmp_path):
    p = _write(tmp_path, "alt_msl_m,from_deg,speed_mps\n3000,-10,12\n0,270,5\n")
    levels = read_wind_table(p)
    assert levels == (WindLevel(0.0, 270.0, 5.0, DEFAULT_WIND_SD_MPS),
                      WindLevel(3000.0, 350.0, 12.0, DEFAULT_WIND_SD_MPS))
    p = _write(tmp_path, "alt_msl_m,from_deg,speed_mps,sd_mps\n0,90,3,1.5\n")
    assert read_wind_table(p)[0].sd_mps == 1.5


@pytest.mark.parametrize("text,err,where", [
    ("alt_msl_m,from_deg\n0,90\n", SchemaError, None),
    ("alt_msl_m,from_deg,speed_mps,gust\n0,90,3,1\n", SchemaError, None),
    ("alt_msl_m,from_deg,speed_mps\n0,90,3\n100,90,x\n", ValidationError, ("speed_mps", 2)),
    ("alt_msl_m,from_deg,speed_mps\n0,90,-1\n", ValidationError, ("speed_mps", 1)),
    ("alt_msl_m,from_deg,speed_mps\n0,800,1\n", ValidationError, ("from_deg", 1)),
    ("alt_msl_m,from_deg,speed_mps,sd_mps\n0,80,1,0\n", ValidationError, ("sd_mps", 1)),
    ("alt_msl_m,from_deg,speed_mps\n0,90,3\n0,80,4\n", ValidationError, ("alt_msl_m", None)),
    ("alt_msl_m,from_deg,speed_mps\n0,90\n", ValidationError, (None, 1)),
    ("alt_msl_m,from_deg,speed_mps\n", InputFileError, None),
    ("", InputFileError, None),
])
def test_wind_table_refuses(tmp_path, text, err, where):
    p = _write(tmp_path, text)
    with pytest.raises(err) as info:
        read_wind_table(p)
    assert info.value.file == str(p)
    if where is not None:
        column, row = where
        assert info.value.column == column
        assert info.value.rows == (None if row is None else [row])


def test_missing_wind_file(tmp_path):
    with pytest.raises(InputFileError, match="not found"):
        read_wind_table(tmp_path / "none.csv")


@pytest.fixture(scope="module")
def log(tmp_path_factory):
    d = tmp_path_factory.mktemp("priors")
    r = simulate("seed-ads-arms", 1, duration_s=120.0)
    return write_simulation(r, d / "x.csv")["log"]


def test_carried_in_the_metadata(log, tmp_path):
    w = _write(tmp_path, "alt_msl_m,from_deg,speed_mps\n0,270,5\n2000,280,9\n")
    with pytest.warns(FlightReconWarning, match=r"known positions \(--fix\) and a "
                      r"winds-aloft prior \(--wind\): used by the joint smoother"):
        f = load_flight(log, meta_overrides={"fixes": ["60,40.1,48.5,1000,50", "30,40.1,48.4"],
                                             "wind_aloft": str(w)})
    assert [x.t_s for x in f.meta.fixes] == [30.0, 60.0]  # sorted by time
    assert f.meta.fixes[1].sd_m == 50.0 and f.meta.fixes[1].alt_msl_m == 1000.0
    assert [lv.alt_msl_m for lv in f.meta.wind_aloft] == [0.0, 2000.0]


def test_fix_outside_the_record(log):
    with pytest.raises(MetadataError, match="outside the record"):
        load_flight(log, meta_overrides={"fixes": ["5000,40.1,48.5"]})


def test_cli_refuses_a_bad_fix_and_wind(log, tmp_path):
    def run(args):
        try:
            main(["--quiet", *args])
        except SystemExit as exc:
            return int(exc.code or 0)
        return 0

    out = tmp_path / "r.csv"
    assert run(["reconstruct", str(log), "--fix", "10,95,50", "-o", str(out)]) == 7
    bad = _write(tmp_path, "alt_msl_m,from_deg,speed_mps\n0,90,-3\n", "bad.csv")
    assert run(["reconstruct", str(log), "--wind", str(bad), "-o", str(out)]) == 5
    assert not out.exists()
