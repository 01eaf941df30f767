"""Separate GNSS and radar files merged on UTC time; readers, sidecar and warnings."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from test_ingest_support import EPOCH, handmade_frame

from flightrecon.errors import FlightReconWarning, MetadataError
from flightrecon.ingest import describe_flight, load_flight, parse_position
from flightrecon.ingest.merge import Rows, merge_rows
from flightrecon.types import Position

ROOT = Path(__file__).resolve().parents[1]


def _split(tmp_path):
    d = handmade_frame()
    log = d.drop(columns=[c for c in d if c.startswith("gnss")])
    log.to_csv(tmp_path / "log.csv", index=False)
    g = d[["t_s", "gnss_lat_deg", "gnss_lon_deg", "gnss_alt_m"]].dropna().copy()
    # half the fixes on recorder times, half 0.05 s after (between recorder rows)
    g.loc[g.index[1::2], "t_s"] += 0.05
    g.to_csv(tmp_path / "gnss.csv", index=False)
    # radar plots every 4 s with UTC timestamps, 0.3 s after the second
    r_t = np.arange(0.3, 240.0, 4.0)
    pd.DataFrame({"time_utc": (pd.Timestamp(EPOCH) + pd.to_timedelta(r_t, unit="s"))
                  .strftime("%Y-%m-%dT%H:%M:%S.%fZ"),
                  "arms_range_m": 1000.0 + 10 * r_t, "arms_azimuth_deg": 45.0 + 0 * r_t}
                 ).to_csv(tmp_path / "radar.csv", index=False)
    (tmp_path / "log.meta.toml").write_text(f'[flight]\nepoch_utc = "{EPOCH}"\n'
                                            "[station]\nlat_deg = 40.4\nlon_deg = 50.0\n")
    return log, g, r_t


def test_gnss_and_radar_merge_each_fix_once_at_its_time(tmp_path):
    log, g, r_t = _split(tmp_path)
    fl = load_flight(tmp_path / "log.csv", gnss=tmp_path / "gnss.csv",
                     radar=tmp_path / "radar.csv")
    d = fl.data
    assert np.all(np.diff(d.t_s.to_numpy()) > 0)
    # coinciding fixes go on recorder rows, the others (every second fix) are new rows
    n_new_gnss = len(g.iloc[1::2])
    assert len(d) == len(log) + n_new_gnss + len(r_t)
    gd = d.dropna(subset=["gnss_lat_deg"])
    np.testing.assert_allclose(gd.t_s.to_numpy(), g.t_s.to_numpy(), atol=1e-9)
    np.testing.assert_array_equal(gd.gnss_lat_deg.to_numpy(), g.gnss_lat_deg.to_numpy())
    rd = d.dropna(subset=["arms_range_m"])
    np.testing.assert_allclose(rd.t_s.to_numpy(), r_t, atol=1e-6)  # timestamps carry 1 us
    # rows added for measurements carry no input values
    new = d.src_file > 0
    assert d.loc[new, ["n_norm_g", "roll_deg", "tas_mps"]].isna().all().all()
    assert fl.sources[1].endswith("gnss.csv") and fl.sources[2].endswith("radar.csv")
    assert set(d.loc[d.src_file == 2, "row"]) == set(range(1, len(r_t) + 1))
    assert fl.meta.station == Position(40.4, 50.0, 0.0)


def test_companions_from_sidecar_files_table(tmp_path):
    _split(tmp_path)
    with open(tmp_path / "log.meta.toml", "a") as fh:
        fh.write('[files]\ngnss = "gnss.csv"\nradar = "radar.csv"\n')
    fl = load_flight(tmp_path / "log.csv")
    assert len(fl.sources) == 3


def test_merge_rows_unit():
    """Coinciding within 1 us -> same row; otherwise a new row; stable order on equal times."""
    base = Rows(t=np.array([0.0, 1.0, 2.0]), values={"a": np.array([1.0, 2.0, 3.0])},
                src_file=np.zeros(3, int), row=np.array([1, 2, 3]), nan_text={})
    add = Rows(t=np.array([1.0 + 5e-7, 1.5, 3.0]), values={"g": np.array([10.0, 20.0, 30.0])},
               src_file=np.ones(3, int), row=np.array([1, 2, 3]), nan_text={})
    m = merge_rows(base, add)
    np.testing.assert_array_equal(m.t, [0.0, 1.0, 1.5, 2.0, 3.0])
    np.testing.assert_array_equal(m.values["g"], [np.nan, 10.0, 20.0, np.nan, 30.0])
    np.testing.assert_array_equal(m.values["a"], [1.0, 2.0, np.nan, 3.0, np.nan])
    np.testing.assert_array_equal(m.src_file, [0, 0, 1, 0, 1])


def test_shipped_sample_loads_without_warnings():
    with warnings.catch_warnings():
        warnings.simplefilter("error", FlightReconWarning)
        fl = load_flight(ROOT / "sample_logs" / "handmade.csv")
    info = describe_flight(fl)
    assert info["channels"]["n_norm_g"]["rate_hz"] == pytest.approx(8.0)
    assert info["channels"]["gnss_lat_deg"]["rate_hz"] == pytest.approx(1.0)
    assert info["duration_s"] == pytest.approx(240.0)
    assert fl.meta.departure == Position(40.46, 50.05, 3.0)


def test_handmade_is_reproducible():
    """The shipped sample equals its generator (values written with pandas' float repr)."""
    shipped = pd.read_csv(ROOT / "sample_logs" / "handmade.csv")
    pd.testing.assert_frame_equal(shipped, handmade_frame(), check_exact=False, rtol=1e-12)


def test_parquet_and_timestamps_equal_csv(tmp_path):
    d = handmade_frame()
    d.to_parquet(tmp_path / "a.parquet")
    ts = d.drop(columns="t_s")
    ts.insert(0, "time_utc", pd.Timestamp(EPOCH) + pd.to_timedelta(d.t_s, unit="s"))
    ts.to_parquet(tmp_path / "b.parquet")           # a datetime64[UTC] column
    a = load_flight(tmp_path / "a.parquet").data
    b = load_flight(tmp_path / "b.parquet")
    assert b.meta.epoch_utc == EPOCH
    np.testing.assert_allclose(b.data.t_s, a.t_s, atol=1e-9)
    pd.testing.assert_frame_equal(a.drop(columns="t_s"), b.data.drop(columns="t_s"))


def test_recoverable_defects_are_warnings(tmp_path):
    """A few literal NaN, blank lines, an unknown column and an unknown sidecar key: loaded,
    each reported in Flight.warnings and through warnings.warn."""
    d = handmade_frame()
    d["CUSTOM"] = 1.0
    d["roll_deg"] = d["roll_deg"].astype(object)
    d.loc[4, "roll_deg"] = "NaN"
    lines = d.to_csv(index=False).splitlines()
    lines.insert(20, "")
    (tmp_path / "w.csv").write_text("\n".join(lines) + "\n")
    (tmp_path / "w.meta.toml").write_text('[flight]\nepoch_utc = "2026-03-15T09:00:00Z"\n'
                                          'pilot = "X"\n')
    with pytest.warns(FlightReconWarning) as rec:
        fl = load_flight(tmp_path / "w.csv")
    text = " | ".join(fl.warnings)
    assert "1 NaN value(s) (first: row 5)" in text
    assert "empty row(s) skipped (first: row 20)" in text
    assert "CUSTOM" in text and "pilot" in text
    assert len(rec) >= 4
    assert fl.data.roll_deg.notna().sum() == d.roll_deg.notna().sum() - 1


def test_allow_unsorted_sorts_with_warning(tmp_path):
    d = handmade_frame()
    d.iloc[[10, 11]] = d.iloc[[11, 10]].to_numpy()
    d.to_csv(tmp_path / "u.csv", index=False)
    with pytest.warns(FlightReconWarning, match="backward"):
        fl = load_flight(tmp_path / "u.csv", allow_unsorted=True)
    assert np.all(np.diff(fl.data.t_s) > 0)
    assert fl.data.row.iloc[10] == 12       # the row numbers still point into the file


def test_overrides_win_over_sidecar(tmp_path):
    handmade_frame().to_csv(tmp_path / "o.csv", index=False)
    (tmp_path / "o.meta.toml").write_text("[departure]\nlat_deg = 1.0\nlon_deg = 2.0\n")
    fl = load_flight(tmp_path / "o.csv", meta_overrides={"departure": "40.46,50.05,3",
                                                          "aircraft_id": "Z9",
                                                          "arrival": None})
    assert fl.meta.departure == Position(40.46, 50.05, 3.0)
    assert fl.meta.aircraft_id == "Z9"
    with pytest.raises(MetadataError, match="unknown metadata override 'departur'"):
        load_flight(tmp_path / "o.csv", meta_overrides={"departur": "1,2,3"})


@pytest.mark.parametrize("text,pos", [("40.46,50.05,3", (40.46, 50.05, 3.0)),
                                      (" -33.9, 151.2 ", (-33.9, 151.2, 0.0)),
                                      ("10,350,0", (10.0, -10.0, 0.0))])
def test_parse_position(text, pos):
    assert parse_position(text).as_tuple() == pytest.approx(pos)


@pytest.mark.parametrize("text", ["40.46", "a,b,c", "1,2,3,4", "91,0,0", "0,400,0", "nan,0,0",
                                  "0,0,99999"])
def test_parse_position_rejects(text):
    with pytest.raises(MetadataError) as ex:
        parse_position(text)
    assert ex.value.exit_code == 7


def test_nan_for_unsampled_cells_is_not_a_storm(tmp_path):
    """Multi-rate logs that write NaN (not empty cells) for unsampled rows, as CSV (numpy /
    MATLAB style) or as Parquet written straight from arrays, load like the canonical sample."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    d = handmade_frame()
    d.to_csv(tmp_path / "n.csv", index=False, na_rep="NaN")
    pq.write_table(pa.table({c: pa.array(d[c].to_numpy(), from_pandas=False) for c in d}),
                   tmp_path / "n.parquet")
    ref = load_flight(ROOT / "sample_logs" / "handmade.csv").data
    for name in ("n.csv", "n.parquet"):
        fl = load_flight(tmp_path / name)
        pd.testing.assert_frame_equal(fl.data.drop(columns="src_file"),
                                      ref.drop(columns="src_file"))
        assert any("NaN cells read as 'not sampled'" in n for n in fl.meta.ingest.notes)
