"""A recorder with the normal acceleration alone (issue 49, item 5): the lateral load of
coordinated flight (0 g) taken in place of the missing ``n_lat_g``, the assumption said in
``info``, the ingest notes and the cleaning report (docs/ingest.md, "Normal acceleration
alone")."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flightrecon.constants import FOOT_M, KNOT_MPS
from flightrecon.errors import SchemaError
from flightrecon.ingest import load_flight
from tests._cli import run_cli

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"


def without(tmp_path: Path, *drop: str) -> Path:
    """The hand-made sample without the columns ``drop``, its sidecar beside it."""
    log = tmp_path / "s.csv"
    pd.read_csv(SAMPLES / "handmade.csv").drop(columns=list(drop)).to_csv(log, index=False)
    (tmp_path / "s.meta.toml").write_text((SAMPLES / "handmade.meta.toml").read_text())
    return log


def load(log: Path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_flight(log, **kw)


def test_a_log_without_the_lateral_load_takes_coordinated_flights(tmp_path):
    fl = load(without(tmp_path, "n_lat_g"))
    d = fl.data
    ref = pd.read_csv(SAMPLES / "handmade.csv")
    sampled = ref["n_norm_g"].notna().to_numpy()
    assert np.all(d["n_lat_g"].to_numpy()[sampled] == 0.0)
    assert np.isnan(d["n_lat_g"].to_numpy()[~sampled]).all()
    assert "n_lat_g" in fl.meta.ingest.derived_channels
    assert "coordinated flight" in fl.meta.ingest.derived_channels["n_lat_g"]
    assert any("n_lat_g not recorded" in w and "coordinated flight" in w for w in fl.warnings)
    # the recorded channels are untouched
    np.testing.assert_allclose(d["n_norm_g"].to_numpy()[sampled], ref["n_norm_g"][sampled])


def test_info_states_the_assumption(tmp_path, capsys):
    code = run_cli(["info", str(without(tmp_path, "n_lat_g"))])
    out = capsys.readouterr().out
    assert code == 0
    said = [ln for ln in out.splitlines() if "n_lat_g not recorded" in ln]
    assert said and said[0].lstrip().startswith("converted:") and "0 g" in said[0]


def test_the_cleaning_report_lists_the_lateral_load_as_derived(tmp_path, capsys):
    log = without(tmp_path, "n_lat_g")
    code = run_cli(["clean", str(log), "-o", str(tmp_path / "g.parquet"), "--json"])
    doc = json.loads(capsys.readouterr().out)
    assert code == 0
    entries = [e for e in doc["report"] if e.get("action") == "derived_channel"
               and e.get("channel") == "n_lat_g"]
    assert entries and "coordinated flight" in entries[0]["why"]


def test_without_the_normal_load_either_the_refusal_names_it(tmp_path):
    with pytest.raises(SchemaError) as exc:
        load(without(tmp_path, "n_lat_g", "n_norm_g"))
    assert "n_norm_g" in str(exc.value) and "n_lat_g" in str(exc.value)


def test_an_airline_decode_with_the_normal_load_alone_reads_through_its_mapping(tmp_path):
    """An A310-like decode at 1 s: normal acceleration, pitch and roll, magnetic heading, CAS
    in knots, pressure altitude in feet; neither a longitudinal nor a lateral load."""
    ref = pd.read_csv(SAMPLES / "handmade.csv").interpolate(limit_direction="both")
    one = ref[np.isclose(ref["t_s"] % 1.0, 0.0)]
    dec = pd.DataFrame({"SEC": one["t_s"], "VRTG": one["n_norm_g"], "PTCH": one["pitch_deg"],
                        "ROLL": one["roll_deg"], "HDG_MAG": one["heading_deg"] - 5.0,
                        "CAS_KT": one["tas_mps"] / KNOT_MPS,
                        "ALT_STD_FT": one["baro_alt_m"] / FOOT_M})
    log = tmp_path / "a310.csv"
    dec.to_csv(log, index=False)
    (tmp_path / "a310.meta.toml").write_text((SAMPLES / "handmade.meta.toml").read_text())
    m = tmp_path / "a310.mapping.toml"
    m.write_text("\n".join([
        "[time]", 'column = "SEC"', 'unit = "s"',
        "[channels.n_norm_g]", 'column = "VRTG"', 'unit = "g"',
        "[channels.pitch_deg]", 'column = "PTCH"', 'unit = "deg"',
        "[channels.roll_deg]", 'column = "ROLL"', 'unit = "deg"',
        "[channels.heading_deg]", 'column = "HDG_MAG"', 'unit = "deg"',
        'reference = "magnetic"',
        "[channels.cas_mps]", 'column = "CAS_KT"', 'unit = "kt"',
        "[channels.baro_alt_m]", 'column = "ALT_STD_FT"', 'unit = "ft"']) + "\n")
    fl = load(log, mapping=m)
    derived = fl.meta.ingest.derived_channels
    assert {"n_lat_g", "n_long_g", "tas_mps"} <= set(derived)
    assert np.all(fl.data["n_lat_g"].dropna().to_numpy() == 0.0)
    assert fl.data["n_lat_g"].notna().sum() == len(dec)


def test_the_joint_smoother_widens_its_loads_noise_for_the_assumed_lateral_load(tmp_path):
    from flightrecon.cleaning import clean_flight
    from flightrecon.methods.joint import JointSettings
    from flightrecon.methods.joint.settings import (
        DERIVED_LAT_ACCEL_NOISE,
        derived_lat_noise,
    )

    base = JointSettings()
    assumed = clean_flight(load(without(tmp_path, "n_lat_g")))
    widened = derived_lat_noise(assumed, base).noise.accel_noise_mps2_sqrt_hz
    assert widened == DERIVED_LAT_ACCEL_NOISE > base.noise.accel_noise_mps2_sqrt_hz
    recorded = clean_flight(load(SAMPLES / "handmade.csv"))
    assert derived_lat_noise(recorded, base) == base
