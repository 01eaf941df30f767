"""Issue #50, faults fourth round: a unit contradicted with certainty or a dead channel never
yields a confident track.  Each test is a mutation of the fuzzer that ended in exit 0 with a
track 7-12 km from the truth (or in exit 8 without naming the mapping's line)."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from _cli import run_cli_stderr

from flightrecon.cleaning import clean_flight
from flightrecon.cli.main import main
from flightrecon.errors import FlightReconWarning
from flightrecon.ingest import load_flight
from flightrecon.pipeline.unit_doubts import doubt, unit_doubts

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_logs"
CORPUS = ROOT.parent / "shared" / "corpus"


run = run_cli_stderr


def _circuit(tmp_path: Path, name: str, df: pd.DataFrame) -> Path:
    p = tmp_path / f"{name}.csv"
    df.to_csv(p, index=False)
    shutil.copy(SAMPLES / "circuit.meta.toml", tmp_path / f"{name}.meta.toml")
    return p


def _foreign(tmp_path: Path, df: pd.DataFrame | None = None,
             mapping: tuple[str, str] | None = None) -> tuple[Path, Path]:
    """The shipped foreign export (15-minute circuit, no GNSS) and its mapping, one of them
    changed."""
    log = tmp_path / "foreign.csv"
    (df if df is not None else pd.read_csv(SAMPLES / "foreign.csv")).to_csv(log, index=False)
    shutil.copy(SAMPLES / "foreign.meta.toml", tmp_path / "foreign.meta.toml")
    text = (SAMPLES / "foreign.mapping.toml").read_text()
    if mapping is not None:
        assert mapping[0] in text
        text = text.replace(*mapping)
    (tmp_path / "m.toml").write_text(text)
    return log, tmp_path / "m.toml"


def test_roll_and_heading_in_radians_without_gnss_are_refused(tmp_path, capsys):
    """Roll and heading in radians under _deg columns, no GNSS (roll never above 0.4, heading
    0-6.3 over the circuit): accepted without a word, the track 8 km off.  The turns the
    loads show say radians (roll 0.017, heading 0.020 times what they give)."""
    d = pd.read_csv(SAMPLES / "circuit.csv")
    d = d[[c for c in d.columns if not c.startswith("gnss_")]]
    for c in ("roll_deg", "heading_deg"):
        d[c] = np.radians(d[c])
    p = _circuit(tmp_path, "rad", d)
    code, err = run(["reconstruct", p, "-o", tmp_path / "r.parquet"], capsys)
    assert code == 5, err
    assert "rad.csv" in err and "column 'roll_deg'" in err and "likely unit rad" in err
    assert "the canonical column name" in err and "unit_confirmed = true" in err
    fig = float(err.split("the roll is ")[1].split(" times")[0])
    assert abs(fig * np.degrees(1.0) - 1.0) < 0.1
    assert not (tmp_path / "r.parquet").exists()


def test_roll_and_heading_in_radians_behind_a_mapping_are_refused(tmp_path, capsys):
    """The same through the foreign export's mapping (declared deg): refused naming the
    column and the mapping's line where the unit comes from."""
    d = pd.read_csv(SAMPLES / "foreign.csv")
    for c in ("ROLL", "HDG_MAG"):
        d[c] = np.radians(d[c])
    log, m = _foreign(tmp_path, d)
    code, err = run(["info", log, "--mapping", m], capsys)
    assert code == 5, err
    assert "column 'ROLL'" in err and "likely unit rad" in err
    roll_unit_line = m.read_text().splitlines().index('column = "ROLL"') + 2
    assert f"m.toml line {roll_unit_line}, [channels.roll_deg] unit" in err


def test_heading_declared_in_radians_while_in_degrees_is_refused(tmp_path, capsys):
    """The magnetic heading declared ``rad`` while in degrees: accepted, 7 km off; now
    refused naming the mapping's line (values up to 360 cannot be radians)."""
    log, m = _foreign(tmp_path, mapping=('column = "HDG_MAG"\nunit = "deg"',
                                         'column = "HDG_MAG"\nunit = "rad"'))
    code, err = run(["reconstruct", log, "--mapping", m, "-o", tmp_path / "r.parquet"], capsys)
    assert code == 5, err
    line = m.read_text().splitlines().index('column = "HDG_MAG"') + 2
    assert f"m.toml line {line}, [channels.heading_deg] unit = \"rad\"" in err
    assert "HDG_MAG" in err and "likely unit deg" in err


def test_airspeed_declared_mps_while_in_knots_is_refused(tmp_path, capsys):
    """The airspeed declared ``mps`` while in knots: the door said so, the declared unit won
    with a warning, and the track was 8 km off with exit 0 and every method ok."""
    log, m = _foreign(tmp_path, mapping=('column = "IAS_KT"\nunit = "kt"',
                                         'column = "IAS_KT"\nunit = "mps"'))
    code, err = run(["reconstruct", log, "--mapping", m, "-o", tmp_path / "r.parquet"], capsys)
    assert code == 5, err
    line = m.read_text().splitlines().index('column = "IAS_KT"') + 2
    assert f"m.toml line {line}, [channels.ias_mps] unit" in err
    assert "IAS_KT" in err and "likely unit kt" in err
    fig = float(err.split("factor ")[1].split(" ")[0])
    assert 1.8 < fig < 2.1


def test_pressure_altitude_declared_metres_while_in_feet_is_refused_by_name(tmp_path, capsys):
    """Pressure altitude declared ``m`` while in feet: exit 8 'no method produced a physically
    possible track'; now the canonical log's named refusal, with the mapping's line."""
    log, m = _foreign(tmp_path, mapping=('column = "ALT_FT"\nunit = "ft"',
                                         'column = "ALT_FT"\nunit = "m"'))
    code, err = run(["reconstruct", log, "--mapping", m, "-o", tmp_path / "r.parquet"], capsys)
    assert code == 5, err
    line = m.read_text().splitlines().index('column = "ALT_FT"') + 2
    assert f"m.toml line {line}, [channels.baro_alt_m] unit = \"m\"" in err
    assert "likely unit ft" in err and "ALT_FT" in err


def test_an_overridden_contradiction_is_recorded_and_said_on_the_status_lines(tmp_path,
                                                                              capsys):
    """``unit_confirmed = true`` beside the wrong airspeed unit: used as declared, the door
    records ``overridden`` with its figure, and every method's status line that leans on the
    airspeed says so (status ``doubtful``, the factor given); never ``ok``."""
    log, m = _foreign(tmp_path, mapping=('column = "IAS_KT"\nunit = "kt"',
                                         'column = "IAS_KT"\nunit = "mps"\n'
                                         'unit_confirmed = true'))
    try:
        main(["reconstruct", str(log), "--mapping", str(m), "-o", str(tmp_path / "r.parquet")])
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    err = capsys.readouterr().err
    assert code in (0, 8), err
    assert "unit_confirmed = true" in err and "likely unit kt" in err
    if code == 0:
        s = json.loads((tmp_path / "r.summary.json").read_text())
        door = {c["check"]: c for c in s["door"]}
        assert door["tas_mps unit"]["verdict"] == "overridden"
        ran = {k: v for k, v in s["methods"].items() if v["status"] not in ("skipped",
                                                                              "failed")}
        assert ran and all(v["status"] != "ok" for v in ran.values()), s["methods"]
        doubtful = [k for k, v in ran.items() if v["status"] == "doubtful"]
        for k in doubtful:
            assert "tas_mps used against a certain contradiction" in s["methods"][k]["reason"]
            line = next(ln for ln in err.splitlines() if ln.startswith(f"  {k:8s} doubtful"))
            assert "the door's evidence: tas_mps used against a certain contradiction" in line
            assert float(line.split("factor ")[1].split(";")[0]) > 1.8


def test_a_doubted_unit_makes_the_methods_leaning_on_it_doubtful():
    """An uncertain unit warning (verdict ``warned``) is carried into the status of the
    methods whose inputs include the channel, not into the others'."""
    door = [{"check": "tas_mps unit", "channel": "tas_mps", "verdict": "warned",
             "figure": 1.7, "detail": ""},
            {"check": "baro_alt_m unit", "channel": "baro_alt_m", "verdict": "passed",
             "figure": 0.97, "detail": ""}]
    assert set(unit_doubts(door)) == {"tas_mps"}
    assert "factor 1.7" in (doubt("joint", door) or "")
    assert doubt("azimuth", door) is None
    door[0]["verdict"] = "passed"
    assert doubt("joint", door) is None


def test_a_heading_zero_from_start_to_end_is_not_used(tmp_path, capsys):
    """'dead_channel: heading_deg never changes over the whole record (value 0)' was reported
    and the channel then used: 8-12 km off, exit 0.  Now it is dropped: the methods that
    need it are skipped with that reason (this log has no body rates to replace it)."""
    d = pd.read_csv(SAMPLES / "circuit.csv")
    d["heading_deg"] = 0.0
    p = _circuit(tmp_path, "hdg0", d)
    code, err = run(["reconstruct", p, "-o", tmp_path / "r.parquet"], capsys)
    assert code != 0 and not (tmp_path / "r.parquet").exists(), err
    assert "heading_deg (dropped: heading_deg never changes over the whole record" in err


def test_a_heading_stuck_through_the_flight_is_dropped():
    """A heading holding one value on every sample in flight (it moved on the ground only)
    is stuck: dropped like a dead one, with the reason in the cleaning report."""
    fl = load_flight(SAMPLES / "circuit.parquet")
    d = fl.data.copy()
    air = d["tas_mps"].interpolate().to_numpy() > 30.0     # the airspeed is sampled at 4 Hz
    d.loc[air, "heading_deg"] = 123.4
    clean = clean_flight(type(fl)(data=d, meta=fl.meta, sources=fl.sources))
    assert "heading_deg" not in clean.grid.columns
    hit = [e for e in clean.report if e["action"] == "dead_channel"]
    assert hit and hit[0]["channel"] == "heading_deg" and "stuck" in hit[0]["why"]


@pytest.mark.shared_data
def test_a_dead_heading_is_replaced_by_the_body_rates():
    """With body rates, a dead heading is replaced by the heading propagated from them and
    anchored on the GNSS track (cleaning/attitude.py), not used."""
    d = pd.read_parquet(CORPUS / "c1-rates.parquet")
    d["heading_deg"] = 0.0
    meta = json.loads((CORPUS / "c1-meta.json").read_text())
    lat, lon, elev = meta["departure"]
    with pytest.warns(FlightReconWarning, match="outside the physical range"):
        fl = load_flight_from(d, f"{lat},{lon},{elev}")   # the corpus's first airspeed sample
    with pytest.warns(FlightReconWarning, match="heading from the body rates"):
        clean = clean_flight(fl)
    acts = {e["action"] for e in clean.report if e["channel"] == "heading_deg"}
    assert {"dead_channel", "heading_from_rates"} <= acts
    assert np.ptp(clean.grid["heading_deg"].to_numpy()) > 90.0


def load_flight_from(df: pd.DataFrame, departure: str):
    import tempfile

    with tempfile.TemporaryDirectory() as td:
        p = Path(td) / "rates.parquet"
        df.to_parquet(p)
        return load_flight(p, meta_overrides={"departure": departure,
                                              "epoch_utc": "2026-01-01T10:00:00Z"})
