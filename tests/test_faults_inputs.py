"""Issue #39, third round: mapping mistakes named as such, nested Parquet columns ignored, and
the checks that replaced a heavy import.

Each test is named after a finding of the mutation fuzzer; the same faults run through the
command line in ``tests/test_fuzz_cli.py`` (cases ``round3-*``).
"""

from __future__ import annotations

import shutil
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.parquet as pq
import pytest

from flightrecon.errors import FlightReconWarning, MappingError, ValidationError
from flightrecon.ingest import load_flight, load_mapping

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_logs"

#: the acceptance export of tests/test_mapping_offset.py in short: nz - 1 with offset = 1
NZ_MINUS_1 = """\
[time]
column = "TIME"
[channels.n_norm_g]
column = "NZ_M1"
unit = "g"
offset = 1.0
"""


def test_misspelt_offset_is_a_mapping_error_not_a_polarity_error(tmp_path):
    """A misspelt key (``ofset``) must never be dropped so that the run fails later with
    "n_norm_g is 2.00 g at rest ... a flipped or mis-scaled channel" (exit 5): exit 6, naming
    the mapping file, its line, the table, the key and the nearest valid key."""
    m = tmp_path / "rec.mapping.toml"
    m.write_text(NZ_MINUS_1.replace("offset = 1.0", "ofset = 1.0"))
    with pytest.raises(MappingError) as ex:
        load_mapping(m)
    msg = str(ex.value)
    assert ex.value.exit_code == 6
    for words in ("rec.mapping.toml", "line 6", "[channels.n_norm_g]", "'ofset'",
                  "did you mean 'offset'"):
        assert words in msg, (words, msg)


@pytest.mark.parametrize("text,table,key,hint", [
    ('[tme]\ncolumn = "T"\n', "", "tme", "time"),
    ('[time]\ncolum = "T"\n', "[time]", "colum", "column"),
    ('[channels.roll_deg]\ncolumn = "R"\nunit = "dge"\n', "[channels.roll_deg]", "dge", "deg"),
    ('[channels.rol_deg]\ncolumn = "R"\n', "[channels.rol_deg]", "rol_deg", "roll_deg"),
    ('[gnss.chanels.gnss_lat_deg]\ncolumn = "LAT"\n', "", "gnss.chanels", "channels"),
])
def test_misspelt_names_get_the_nearest_valid_one(tmp_path, text, table, key, hint):
    m = tmp_path / "m.toml"
    m.write_text(text)
    with pytest.raises(MappingError) as ex:
        load_mapping(m)
    msg = str(ex.value)
    assert "m.toml" in msg and table in msg and key in msg and f"'{hint}'" in msg, msg
    assert "line " in msg, msg


@pytest.mark.parametrize("text,words", [
    ('[time]\ncolumn = "T"\n[channels.roll_deg]\ncolumn = "T"\n',
     ("[channels.roll_deg]", "also the time column")),
    ('[gnss.channels.roll_deg]\ncolumn = "R"\n', ("[gnss.channels.roll_deg]", "not a gnss")),
    ('[radar.channels.gnss_lat_deg]\ncolumn = "L"\n', ("[radar.channels.gnss_lat_deg]",
                                                       "not a radar")),
    ('[channels.tas_mps]\nfrom = "cas"\nunit = "kt"\n', ("[channels.tas_mps]", "only 'from'")),
])
def test_impossible_combinations_are_mapping_errors(tmp_path, text, words):
    m = tmp_path / "m.toml"
    m.write_text(text)
    with pytest.raises(MappingError) as ex:
        load_mapping(m)
    assert ex.value.exit_code == 6 and "m.toml" in str(ex.value)
    for w in words:
        assert w in str(ex.value), (w, str(ex.value))


def _foreign(tmp_path: Path, mapping_text: str) -> tuple[Path, Path]:
    for f in ("foreign.csv", "foreign.meta.toml"):
        shutil.copy(SAMPLES / f, tmp_path / f)
    m = tmp_path / "m.toml"
    m.write_text(mapping_text)
    return tmp_path / "foreign.csv", m


def test_derived_channel_without_its_source_names_the_mapping_line(tmp_path):
    """"tas_mps from cas needs channel cas_mps" named the log only (a schema error, exit 4):
    the mapping asked for it, so it is a mapping error naming the mapping file, the line and
    the key, with the source the mapping does have."""
    text = (SAMPLES / "foreign.mapping.toml").read_text()
    log, m = _foreign(tmp_path, text.replace('from = "ias"', 'from = "cas"'))
    line = next(i for i, s in enumerate(m.read_text().splitlines(), 1) if "from =" in s)
    with pytest.raises(MappingError) as ex:
        load_flight(log, mapping=m)
    msg = str(ex.value)
    for words in ("m.toml", f"line {line}", "[channels.tas_mps] from", "cas_mps",
                  "foreign.csv", "did you mean from = 'ias'"):
        assert words in msg, (words, msg)


def test_unmapped_column_message_names_the_mapping_line(tmp_path):
    text = (SAMPLES / "foreign.mapping.toml").read_text()
    log, m = _foreign(tmp_path, text.replace('"VRTG"', '"VRTGX"'))
    with pytest.raises(MappingError) as ex:
        load_flight(log, mapping=m)
    msg = str(ex.value)
    assert "foreign.csv" in msg and "VRTGX" in msg and "[channels.n_norm_g] column" in msg
    assert "line 7" in msg and "did you mean 'VRTG'" in msg


def _with_columns(tmp_path: Path, **cols: pa.Array) -> Path:
    t = pq.read_table(SAMPLES / "circuit.parquet")
    for name, arr in cols.items():
        if name in t.column_names:
            t = t.set_column(t.column_names.index(name), name, arr)
        else:
            t = t.append_column(name, arr)
    p = tmp_path / "c.parquet"
    pq.write_table(t, p)
    shutil.copy(SAMPLES / "circuit.meta.toml", tmp_path / "c.meta.toml")
    return p


def test_nested_parquet_columns_are_ignored_with_a_note(tmp_path):
    """An extra struct or list column was refused (exit 4) where every other unknown column is
    ignored: it is ignored too, and the warning names it; the flight is the same."""
    n = pq.read_metadata(SAMPLES / "circuit.parquet").num_rows
    p = _with_columns(tmp_path,
                      extra_struct=pa.array([{"a": i, "b": "x"} for i in range(n)]),
                      extra_list=pa.array([[1.0, float(i)] for i in range(n)]),
                      extra_map=pa.array([[("k", 1)]] * n, pa.map_(pa.string(), pa.int64())),
                      extra_category=pa.array(["A"] * n).dictionary_encode())
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always", FlightReconWarning)
        fl = load_flight(p)
    text = " ".join(str(x.message) for x in w)
    for c in ("extra_struct", "extra_list", "extra_map", "extra_category"):
        assert c in text, text
    ref = load_flight(SAMPLES / "circuit.parquet")
    pd.testing.assert_frame_equal(fl.data, ref.data)


def test_nested_column_used_as_a_channel_is_refused_naming_it(tmp_path):
    n = pq.read_metadata(SAMPLES / "circuit.parquet").num_rows
    p = _with_columns(tmp_path, n_norm_g=pa.array([[1.0]] * n))
    with pytest.raises(ValidationError) as ex:
        load_flight(p)
    assert "c.parquet" in str(ex.value) and "n_norm_g" in str(ex.value)
    assert "list" in str(ex.value)


def test_numeric_dictionary_column_is_read_by_its_values(tmp_path):
    """A dictionary-encoded (categorical) numeric channel reads like a plain one."""
    t = pq.read_table(SAMPLES / "circuit.parquet")
    col = t.column("sat_degc").combine_chunks()
    p = _with_columns(tmp_path, sat_degc=col.dictionary_encode())
    got = load_flight(p).data["sat_degc"].to_numpy()
    ref = load_flight(SAMPLES / "circuit.parquet").data["sat_degc"].to_numpy()
    np.testing.assert_array_equal(got, ref)


def test_threshold_distance_without_pyproj_matches_the_tangent_plane():
    """The sidecar's runway-threshold check measures its distance without pyproj (so that the
    ingest and ``info`` do not import it): within 0.1 m of the tangent-plane projection up to
    10 km from the reference point at latitudes up to 80 deg."""
    from flightrecon.geo.frames import TangentPlane
    from flightrecon.ingest.sidecar import _ground_distance_m
    from flightrecon.types import Position

    rng = np.random.default_rng(39)
    for _ in range(500):
        lat, lon = rng.uniform(-80, 80), rng.uniform(-180, 180)
        d, az = rng.uniform(0, 10_000), rng.uniform(0, 2 * np.pi)
        b_lat = lat + np.degrees(d * np.cos(az) / 6.36e6)
        b_lon = (lon + np.degrees(d * np.sin(az) / (6.38e6 * np.cos(np.radians(lat))))
                 + 180.0) % 360.0 - 180.0
        e, n, _ = TangentPlane(lat, lon).forward(b_lat, b_lon, 0.0)
        got = _ground_distance_m(Position(lat, lon, 0.0), Position(b_lat, b_lon, 0.0))
        assert abs(float(np.hypot(e, n)) - got) < 0.1
