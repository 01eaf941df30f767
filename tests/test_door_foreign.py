"""Issue #39, silent wrong units: the fuzzer's kinds on the shipped foreign export (no GNSS),
each now refused when certain or said loudly (console and summary) when the mapping declared
the unit (docs/door.md)."""

from __future__ import annotations

import json
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


def test_metres_per_second_in_a_knots_column_is_said_with_the_factor(tmp_path, capsys):
    """IAS_KT x 0.514 (m/s written where the mapping declares knots): the coordinated turns
    give 0.52 (the shipped log: 1.08, IAS read as CAS); the declared unit is used, and the
    warning names the column, the mapping's table and the likely unit, on the console and in
    the summary's top-level warnings."""
    d = pd.read_csv(SAMPLES / "foreign.csv")
    d["IAS_KT"] = d["IAS_KT"] * 0.514
    log = _foreign(tmp_path, "ms", d)
    warns = [w for w in _warnings(log) if "used as declared" in w]
    assert warns and "IAS_KT" in warns[0] and "[channels.ias_mps]" in warns[0]
    assert "likely unit m/s" in warns[0]
    fig = float(warns[0].split("the true airspeed is ")[1].split(" times")[0])
    assert 0.45 < fig < 0.6
    try:
        main(["reconstruct", str(log), "--mapping", str(MAPPING), "--methods", "joint",
              "-o", str(tmp_path / "r.parquet")])
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    err = capsys.readouterr().err
    assert "used as declared" in err
    if code == 0:
        summary = json.loads((tmp_path / "r.summary.json").read_text())
        assert any("used as declared" in w for w in summary["warnings"])
    else:
        assert code == 8


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
    verdicts = {c["check"]: c["verdict"] for c in fl.meta.extra["door"]}
    for check in ("time unit", "baro_alt_m unit", "tas_mps unit", "attitude unit"):
        assert verdicts[check] == "passed", verdicts
