"""Mapping files that fit real exports: ``scale`` and ``offset`` per channel, the mapping hint
beside the log, and the acceptance case of issue 19: a foreign CSV with the normal load factor
recorded as nz - 1, speeds in knots and altitudes in feet reconstructs through a mapping with
``offset`` to the same result as the canonical log."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flightrecon.constants import FOOT_M, KNOT_MPS
from flightrecon.errors import MappingError, SchemaError
from flightrecon.ingest import load_flight
from flightrecon.pipeline import ReconstructSettings, reconstruct

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"

MAPPING = """\
[time]
column = "TIME"
unit = "s"
[channels.n_norm_g]
column = "NZ_M1"        # recorded as nz - 1 (0 at rest)
unit = "g"
offset = 1.0
[channels.n_long_g]
column = "NX"
unit = "g"
[channels.n_lat_g]
column = "NY_CENTI"     # hundredths of g, positive toward the left wing
unit = "g"
scale = 0.01
sign = -1
[channels.roll_deg]
column = "PHI"
[channels.pitch_deg]
column = "THETA"
[channels.heading_deg]
column = "PSI"
[channels.tas_mps]
column = "TAS_KT"
unit = "kt"
[channels.baro_alt_m]
column = "ALT_FT"
unit = "ft"
[channels.sat_degc]
column = "OAT"
[gnss.time]
column = "TIME"
unit = "s"
[gnss.channels.gnss_lat_deg]
column = "LAT"
[gnss.channels.gnss_lon_deg]
column = "LON"
[gnss.channels.gnss_alt_m]
column = "HGT_FT"
unit = "ft"
[gnss.channels.gnss_vn_mps]
column = "VN_KT"
unit = "kt"
[gnss.channels.gnss_ve_mps]
column = "VE_KT"
unit = "kt"
"""


def _foreign(tmp: Path) -> tuple[Path, Path, Path]:
    """circuit.csv (canonical, multi-rate, with GNSS) written as a foreign export: a recorder
    file and a separate GNSS file, foreign names and units, nz - 1, lateral load in centi-g."""
    d = pd.read_csv(SAMPLES / "circuit.csv")
    rec = pd.DataFrame({
        "TIME": d["t_s"], "NZ_M1": d["n_norm_g"] - 1.0, "NX": d["n_long_g"],
        "NY_CENTI": -100.0 * d["n_lat_g"], "PHI": d["roll_deg"], "THETA": d["pitch_deg"],
        "PSI": d["heading_deg"], "TAS_KT": d["tas_mps"] / KNOT_MPS,
        "ALT_FT": d["baro_alt_m"] / FOOT_M, "OAT": d["sat_degc"]})
    g = d[d["gnss_lat_deg"].notna()]
    gnss = pd.DataFrame({"TIME": g["t_s"], "LAT": g["gnss_lat_deg"], "LON": g["gnss_lon_deg"],
                         "HGT_FT": g["gnss_alt_m"] / FOOT_M, "VN_KT": g["gnss_vn_mps"] / KNOT_MPS,
                         "VE_KT": g["gnss_ve_mps"] / KNOT_MPS})
    log = tmp / "ext.csv"
    rec.to_csv(log, index=False, float_format="%.17g")
    gnss.to_csv(tmp / "ext_gnss.csv", index=False, float_format="%.17g")
    (tmp / "ext.mapping.toml").write_text(MAPPING)
    shutil.copy(SAMPLES / "circuit.meta.toml", tmp / "ext.meta.toml")
    return log, tmp / "ext_gnss.csv", tmp / "ext.mapping.toml"


def test_offset_scale_applied(tmp_path):
    log, gnss, mp = _foreign(tmp_path)
    fl = load_flight(log, gnss=gnss, mapping=mp)
    ref = load_flight(SAMPLES / "circuit.csv")
    for c in ("n_norm_g", "n_lat_g", "tas_mps", "baro_alt_m", "gnss_alt_m", "gnss_vn_mps"):
        a, b = fl.data[c].to_numpy(), ref.data[c].to_numpy()
        assert np.array_equal(np.isnan(a), np.isnan(b)), c
        # unit round trip x / f * f: a few ulp
        np.testing.assert_allclose(a, b, rtol=1e-12, atol=1e-12, equal_nan=True, err_msg=c)
    notes = fl.meta.ingest.notes
    assert any("n_norm_g <- NZ_M1 [g] +1 g" in n for n in notes)
    assert any("n_lat_g <- NY_CENTI x 0.01 [g] x -1" in n for n in notes)


def test_foreign_reconstructs_like_canonical(tmp_path):
    """The acceptance case: same track as the canonical log (the inputs agree to 1e-12
    relative, so the tracks agree to far below a millimetre)."""
    log, gnss, mp = _foreign(tmp_path)
    s = ReconstructSettings(methods=("joint", "sabziev", "sns"))
    a = reconstruct(log, gnss=gnss, mapping=mp, settings=s, record=False)
    b = reconstruct(SAMPLES / "circuit.csv", settings=s, record=False)
    assert {k: v["status"] for k, v in a.summary["methods"].items()} == \
        {k: v["status"] for k, v in b.summary["methods"].items()}
    assert a.summary["methods"]["joint"]["status"] == "ok"
    for c in ("north_m", "east_m", "up_m", "vn_mps", "north_sd_m", "sabziev_north_m",
              "sns_east_m"):
        np.testing.assert_allclose(a.track[c], b.track[c], rtol=0, atol=1e-4, err_msg=c)


@pytest.mark.parametrize("key,value,words", [("offset", '"one"', "offset must be a finite"),
                                             ("scale", "0", "scale must not be zero"),
                                             ("scale", "true", "scale must be a finite")])
def test_bad_offset_scale(tmp_path, key, value, words):
    log, gnss, mp = _foreign(tmp_path)
    mp.write_text(MAPPING.replace("offset = 1.0", f"{key} = {value}"))
    with pytest.raises(MappingError, match=words):
        load_flight(log, gnss=gnss, mapping=mp)


def test_mapping_beside_log_is_pointed_at(tmp_path):
    """Unknown columns and a mapping file beside the log: the error names it."""
    log, _, mp = _foreign(tmp_path)
    (tmp_path / "ext.meta.toml").unlink()
    with pytest.raises(SchemaError, match="a mapping file lies beside the log .*ext.mapping.toml"):
        load_flight(log)


def test_batch_takes_mapping(tmp_path):
    """``batch --mapping`` reads the foreign log (local cluster of one worker)."""
    from flightrecon.batch import batch, open_client

    log, gnss, mp = _foreign(tmp_path)
    sc = tmp_path / "ext.meta.toml"
    sc.write_text(sc.read_text() + '\n[files]\ngnss = "ext_gnss.csv"\n')
    with open_client(None, 1) as client:
        res = batch([log], tmp_path / "out", client=client, mapping=mp,
                    settings=ReconstructSettings(methods=("joint",)))
    (oc,) = res.outcomes
    assert oc.status == "ok", oc.row
