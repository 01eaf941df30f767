"""What info and clean print: plain text for people (no Python reprs, no 'nan'), --json for
machines."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from flightrecon.cli.main import main
from flightrecon.errors import FlightReconWarning

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_logs"


def run(args, capsys):
    try:
        main(["--quiet", *args])
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    out = capsys.readouterr()
    return code, out.out, out.err


def test_info_is_plain_text(capsys):
    code, out, _ = run(["info", str(SAMPLES / "landing.parquet")], capsys)
    assert code == 0
    assert "arrival:   39.89933°N 49.21415°E, -20 m MSL; runway 100° true" in out
    for bad in ("None", "{'", "99.9999", "nan"):
        assert bad not in out


def test_info_json_is_standard_json(capsys):
    code, out, _ = run(["info", str(SAMPLES / "landing.parquet"), "--json"], capsys)
    assert code == 0
    doc = json.loads(out, parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
    assert doc["rows"] == 3145 and doc["metadata"]["arrival"]["elev_m"] == -20.0


def test_clean_never_prints_nan_and_says_airborne(tmp_path, capsys):
    # the seed flight starts and ends in the air: no lift-off, no touchdown
    code, out, err = run(["clean", str(SAMPLES / "seed-ads-arms.parquet"), "-o",
                          str(tmp_path / "s.parquet")], capsys)
    assert code == 0 and err == ""  # --quiet: only the written paths
    from flightrecon.cleaning import clean_flight
    from flightrecon.cli.clean import summary_lines
    from flightrecon.ingest import load_flight

    # the seed flight ends at 89 m/s with an arrival given: taken as the last position
    with pytest.warns(FlightReconWarning, match="the record ends fast"):
        lines = summary_lines(clean_flight(load_flight(SAMPLES / "seed-ads-arms.parquet")))
    text = "\n".join(lines)
    assert "nan" not in text.lower()
    assert "lift-off: none in the record (it starts airborne)" in text
    assert "touchdown: none in the record (it ends airborne)" in text
    lines = summary_lines(clean_flight(load_flight(SAMPLES / "circuit.parquet")))
    assert lines[0].startswith("lift-off: 10:01:13.750 UTC (t = 73.75 s)")


def test_clean_json(tmp_path, capsys):
    code, out, _ = run(["clean", str(SAMPLES / "circuit.parquet"), "-o",
                        str(tmp_path / "c.csv"), "--json"], capsys)
    assert code == 0
    doc = json.loads(out)
    assert doc["grid_samples"] == 7201 and doc["phases"]["liftoff_t_s"] == 73.75
