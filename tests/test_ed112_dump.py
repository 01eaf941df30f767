"""A flight-data team's parameter dump of an ED-112 / ARINC 717 recorder read as recorded, with
no mapping (issue 49, item 6; docs/ingest.md, "Parameter dumps of a flight data recorder"):
the header of mnemonics, the units line under it, the frame and subframe counters as the time.
The rows are generated from a simulated flight's ED-112 minimum-rate export
(:func:`flightrecon.sim.ed112.ed112_export`) by scripts/ed112_dump_study.py's ``write_dump``."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flightrecon.errors import SchemaError, ValidationError
from flightrecon.ingest import load_flight, read_table
from flightrecon.sim import simulate, write_simulation
from flightrecon.sim.ed112 import ed112_export
from tests._cli import run_cli
from tests._scripts import load_script

STUDY = load_script("ed112_dump_study")
FIRST_FRAME = STUDY.FIRST_FRAME           # the 12-bit frame counter wraps two frames in


@pytest.fixture(scope="module")
def flight(tmp_path_factory):
    """A simulated circuit (its log, truth and sidecar) and its ED-112 export."""
    d = tmp_path_factory.mktemp("dump")
    r = simulate("circuit", 5)
    log = d / "c.parquet"
    write_simulation(r, log)
    dep = r.meta.departure
    ex = ed112_export(r.log, lat_deg=dep.lat_deg, lon_deg=dep.lon_deg,
                      epoch_utc=r.meta.epoch_utc)
    return d, log, ex


def write_dump(folder: Path, ex: pd.DataFrame, name: str = "dump.csv",
               lat_positive_left: bool = False) -> tuple[Path, np.ndarray]:
    """The export as a parameter dump (scripts/ed112_dump_study.py, ``write_dump``): eight
    rows a subframe, ``FRAME`` / ``SUBFRAME`` counters from frame 4094, the units line."""
    return STUDY.write_dump(folder, ex, name, lat_positive_left)


def load(path: Path, sidecar: Path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_flight(path, sidecar=sidecar, **kw)


def test_the_units_line_is_recognised_and_skipped(flight, tmp_path):
    _, _, ex = flight
    path, _ = write_dump(tmp_path, ex)
    raw = read_table(path)
    assert raw.dialect == "ed112-dump"
    assert raw.units["VRTG"] == "g" and raw.units["ALT_FT"] == "ft"
    assert raw.columns["FRAME"][0] == FIRST_FRAME        # the first data row, not the units
    # a CSV whose second line is data is not a dump
    plain = tmp_path / "plain.csv"
    plain.write_text("t_s,n_norm_g\n0,1\n1,1\n")
    assert read_table(plain).dialect == ""


def test_a_dump_reads_as_recorded_with_no_mapping(flight, tmp_path):
    d, log, ex = flight
    path, t_rows = write_dump(tmp_path, ex)
    fl = load(path, d / "c.meta.toml")
    data = fl.data
    # the frame and subframe counters give each row's time (8 rows a second, across the
    # 12-bit counter's wrap), from the first row at 0 s
    np.testing.assert_allclose(data["t_s"].to_numpy(), t_rows[data["row"].to_numpy() - 1],
                               atol=1e-9)
    src = pd.read_parquet(log)

    def truth(ch: str) -> np.ndarray:
        ok = src[ch].notna()
        return np.interp(data["t_s"], src["t_s"][ok], src[ch][ok])
    at = data["n_norm_g"].notna()
    # loads in 12-bit words over -3..+6 g (0.0022 g), sampled up to 1/8 s late in their row
    assert np.nanmedian(np.abs(data["n_norm_g"][at] - truth("n_norm_g")[at])) < 0.01
    alt = data["baro_alt_m"].notna()
    assert np.nanmedian(np.abs(data["baro_alt_m"][alt] - truth("baro_alt_m")[alt])) < 1.0
    hdg = data["heading_deg"].notna()
    dh = (data["heading_deg"][hdg] - truth("heading_deg")[hdg] + 180) % 360 - 180
    assert np.nanmedian(np.abs(dh)) < 0.5           # magnetic -> true with the WMM
    tas = data["tas_mps"].notna()
    assert np.nanmedian(np.abs(data["tas_mps"][tas] - truth("tas_mps")[tas])) < 0.5
    lat = data["n_lat_g"].notna()
    # the sign (the lateral load is mostly white noise here: not 1)
    assert np.corrcoef(data["n_lat_g"][lat], truth("n_lat_g")[lat])[0, 1] > 0.5
    notes = " ".join(fl.meta.ingest.notes)
    assert "parameter dump" in notes and "1 wrap(s) of the 12-bit frame counter" in notes
    assert any("taken as magnetic" in w for w in fl.warnings)
    assert any("positive toward the right" in w for w in fl.warnings)
    assert not any("ignored" in w and "FRAME" in w for w in fl.warnings)


def test_a_user_mapping_wins_channel_by_channel(flight, tmp_path):
    d, log, ex = flight
    path, _ = write_dump(tmp_path, ex, lat_positive_left=True)
    m = tmp_path / "m.toml"
    m.write_text('[channels.n_lat_g]\ncolumn = "LATG"\nunit = "g"\nsign = -1\n')
    fl = load(path, d / "c.meta.toml", mapping=m)
    src = pd.read_parquet(log)
    data = fl.data
    lat = data["n_lat_g"].notna()
    ok = src["n_lat_g"].notna()
    ref = np.interp(data["t_s"][lat], src["t_s"][ok], src["n_lat_g"][ok])
    assert np.corrcoef(data["n_lat_g"][lat], ref)[0, 1] > 0.5     # the sign
    assert data["n_norm_g"].notna().sum() > 0          # the built-in channels still read


def test_info_reads_a_dump_and_says_so(flight, tmp_path, capsys):
    d, _, ex = flight
    path, _ = write_dump(tmp_path, ex)
    code = run_cli(["info", str(path), "--sidecar", str(d / "c.meta.toml")])
    out = capsys.readouterr().out
    assert code == 0 and "parameter dump" in out and "frame counter 'FRAME'" in out


def test_a_frame_counter_that_goes_back_is_refused_naming_the_row(flight, tmp_path):
    d, _, ex = flight
    path, _ = write_dump(tmp_path, ex)
    lines = path.read_text().splitlines()
    cells = lines[40].split(",")
    cells[0] = "100"                                    # data row 39: a frame from the past
    lines[40] = ",".join(cells)
    path.write_text("\n".join(lines) + "\n")
    with pytest.raises(ValidationError) as exc:
        load(path, d / "c.meta.toml")
    assert "frame counter goes back" in str(exc.value) and "39" in str(exc.value)


def test_a_dump_with_a_time_column_in_seconds_reads_it(flight, tmp_path):
    d, _, ex = flight
    path, t_rows = write_dump(tmp_path, ex)
    df = pd.read_csv(path, skiprows=[1]).drop(columns=["FRAME", "SUBFRAME"])
    df.insert(0, "TIME", 100.0 + t_rows)
    with open(tmp_path / "timed.csv", "w") as fh:
        fh.write(",".join(df.columns) + "\ns," + ",".join(
            read_table(path).units[c] for c in df.columns[1:]) + "\n")
        df.to_csv(fh, header=False, index=False, na_rep="")
    fl = load(tmp_path / "timed.csv", d / "c.meta.toml")
    assert fl.data["t_s"].iloc[0] == pytest.approx(100.0)
    assert "TIME" not in " ".join(w for w in fl.warnings if "ignored" in w)


def test_a_dump_without_a_time_takes_the_frame_rate(flight, tmp_path):
    d, _, ex = flight
    path, t_rows = write_dump(tmp_path, ex)
    df = pd.read_csv(path, skiprows=[1]).drop(columns=["FRAME", "SUBFRAME"])
    units = [read_table(path).units[c] for c in df.columns]
    with open(tmp_path / "frames.csv", "w") as fh:
        fh.write(",".join(df.columns) + "\n" + ",".join(units) + "\n")
        df.to_csv(fh, header=False, index=False, na_rep="")
    with pytest.raises(SchemaError, match="--frame-rate"):
        load(tmp_path / "frames.csv", d / "c.meta.toml")
    fl = load(tmp_path / "frames.csv", d / "c.meta.toml", frame_rate_hz=8.0)
    np.testing.assert_allclose(fl.data["t_s"].to_numpy(),
                               t_rows[fl.data["row"].to_numpy() - 1], atol=1e-9)
