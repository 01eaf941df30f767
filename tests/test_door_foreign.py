"""Issue #39, silent wrong units: the fuzzer's kinds on the shipped foreign export (no GNSS),
each now refused when certain (also against a unit the mapping declared, issue #50) or said
loudly (console and summary) when not (docs/door.md)."""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import numpy as np
import pandas as pd

from flightrecon.cli.main import main
from flightrecon.ingest import load_flight

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
MAPPING = SAMPLES / "foreign.mapping.toml"


def _foreign(tmp_path: Path, name: str, df: pd.DataFrame, **csv) -> Path:
    p = tmp_path / f"{name}.csv"
    df.to_csv(p, index=False, **csv)
    shutil.copy(SAMPLES / "foreign.meta.toml", tmp_path / f"{name}.meta.toml")
    return p


def _warnings(path: Path) -> list[str]:
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        load_flight(path, mapping=MAPPING)
    return [str(x.message) for x in w]


def test_metres_per_second_in_a_knots_column_is_refused_with_the_factor(tmp_path, capsys):
    """IAS_KT x 0.514 (m/s written where the mapping declares knots): the coordinated turns
    give 0.52 (the shipped log: 1.08, IAS read as CAS), a certain contradiction of the
    declared unit: refused (exit 5) naming the column, the mapping's line, the factor and the
    likely unit (issue #50; it was used as declared with a warning)."""
    d = pd.read_csv(SAMPLES / "foreign.csv")
    d["IAS_KT"] = d["IAS_KT"] * 0.514
    log = _foreign(tmp_path, "ms", d)
    try:
        main(["--quiet", "reconstruct", str(log), "--mapping", str(MAPPING), "--methods",
              "joint", "-o", str(tmp_path / "r.parquet")])
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    err = capsys.readouterr().err
    assert code == 5, err
    assert "IAS_KT" in err and "likely unit m/s" in err
    assert "foreign.mapping.toml line" in err and "[channels.ias_mps] unit" in err
    fig = float(err.split("the true airspeed is ")[1].split(" times")[0])
    assert 0.45 < fig < 0.6
    assert not (tmp_path / "r.parquet").exists()


def test_a_channel_mostly_literal_nan_is_reported(tmp_path):
    d = pd.read_csv(SAMPLES / "foreign.csv")
    rng = np.random.default_rng(1)
    d.loc[rng.choice(len(d), int(0.9 * len(d)), replace=False), "LONG"] = np.nan
    warns = _warnings(_foreign(tmp_path, "nan", d, na_rep="NaN"))
    assert any("'LONG'" in w and "mostly missing" in w for w in warns), warns


def test_the_shipped_foreign_export_passes_every_unit_check(tmp_path):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fl = load_flight(SAMPLES / "foreign.csv", mapping=MAPPING)
    verdicts = {c["check"]: c["verdict"] for c in fl.meta.ingest.door}
    for check in ("time unit", "baro_alt_m unit", "tas_mps unit", "attitude unit"):
        assert verdicts[check] == "passed", verdicts
