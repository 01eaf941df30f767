"""The ``flightrecon`` key/value metadata of the Parquet files the tool writes is standard
JSON with a format version (docs/output.md, "Formats"): readable by pyarrow, by pandas with
pyarrow, by polars where installed and by ``json.loads`` alone; the tool reads its own block
back (``export``), and a block that is not JSON is refused naming the file, not a traceback."""

from __future__ import annotations

import json
from pathlib import Path

import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from _cli import run_cli

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"


@pytest.fixture(scope="module")
def result(tmp_path_factory) -> Path:
    """``reconstruct`` of the shipped circuit (joint smoother): result and summary."""
    out = tmp_path_factory.mktemp("md") / "circuit.recon.parquet"
    assert run_cli(["reconstruct", str(SAMPLES / "circuit.parquet"), "--methods", "joint",
                    "-o", str(out)]) == 0
    return out


def _block(path: Path) -> bytes:
    return pq.read_schema(path).metadata[b"flightrecon"]


def test_result_block_is_the_summary_as_json(result):
    """``json.loads`` of the raw bytes gives the summary the run wrote beside the result
    (the same document: its schema_version, software, inputs with their SHA-256, flight)."""
    doc = json.loads(_block(result))
    summary = json.loads(result.with_name("circuit.recon.summary.json").read_text())
    assert doc["schema_version"] == summary["schema_version"] == 1
    for key in ("software", "inputs", "flight", "settings", "methods", "result", "events"):
        assert doc[key] == summary[key], key
    assert doc["software"]["name"] == "flightrecon"
    assert doc["flight"]["epoch_utc"] == "2026-01-01T10:00:00Z"


def test_other_readers_see_the_same_text(result):
    """The file footer as pyarrow's ParquetFile and pandas' read path see it: one text."""
    raw = _block(result)
    assert pq.ParquetFile(result).metadata.metadata[b"flightrecon"] == raw
    table = pq.read_table(result)
    assert table.schema.metadata[b"flightrecon"] == raw
    assert len(table.to_pandas()) == len(pd.read_parquet(result))


def test_polars_reads_it_where_installed(result):
    """polars: ``read_parquet_metadata`` gives the text, ``json.loads`` the summary."""
    pl = pytest.importorskip("polars", reason="polars is not installed (optional reader)")
    doc = json.loads(pl.read_parquet_metadata(result)["flightrecon"])
    assert doc == json.loads(_block(result))


def test_export_reads_its_own_block_back(result, tmp_path):
    """``export`` to CSV with the summary file moved away: the UTC time and the MSL altitude
    come from the Parquet block alone."""
    moved = tmp_path / "summary.json"
    result.with_name("circuit.recon.summary.json").rename(moved)
    try:
        out = tmp_path / "x.csv"
        assert run_cli(["export", str(result), "-o", str(out)]) == 0
        df = pd.read_csv(out, nrows=2)
        assert df["time_utc"].iloc[0].startswith("2026-01-01T10:00:")
        assert "alt_msl_m" in df.columns
    finally:
        moved.rename(result.with_name("circuit.recon.summary.json"))


def test_clean_tables_carry_a_versioned_block(tmp_path):
    """``clean``: the grid and the GNSS table each carry ``schema_version``, ``table`` and the
    cleaning figures, as JSON."""
    out = tmp_path / "g.parquet"
    assert run_cli(["clean", str(SAMPLES / "circuit.parquet"), "-o", str(out)]) == 0
    for path, table in ((out, "grid"), (tmp_path / "g.gnss.parquet", "gnss")):
        doc = json.loads(_block(path))
        assert doc["schema_version"] == 1 and doc["table"] == table
        assert doc["cleaning"]["rate_hz"] == 8.0
        assert doc["cleaning"]["grid_samples"] == len(pd.read_parquet(out))


def test_a_block_that_is_not_json_is_refused_naming_the_file(result, tmp_path, capsys):
    """A Python-literal block (what the issue feared) under our key: exit 3, the file and the
    key named; nothing evaluated."""
    table = pq.read_table(result)
    md = dict(table.schema.metadata)
    md[b"flightrecon"] = repr({"flight": {"aircraft_id": "X"}}).encode()
    bad = tmp_path / "bad.parquet"
    pq.write_table(table.replace_schema_metadata(md), bad)
    assert run_cli(["export", str(bad), "-o", str(tmp_path / "b.csv")]) == 3
    err = capsys.readouterr().err
    assert "bad.parquet" in err and "'flightrecon' metadata is not JSON" in err
    md[b"flightrecon"] = b"[1, 2]"
    pq.write_table(pa.Table.from_pandas(table.to_pandas()).replace_schema_metadata(md), bad)
    assert run_cli(["export", str(bad), "-o", str(tmp_path / "b.csv")]) == 3
    assert "not a JSON object" in capsys.readouterr().err
