"""A folder of one-column files read as one recorder table (issue #36: the MATLAB-export shape
of flight-test systems, e.g. the Citation II logs: one header-less file per channel)."""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flightrecon.cli.main import main
from flightrecon.ingest import load_flight, read_table

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
NAMES = {"t_s": "time", "n_long_g": "AccLong", "n_lat_g": "AccLat", "n_norm_g": "AccNorm",
         "roll_deg": "Roll", "pitch_deg": "Pitch", "heading_deg": "Hdg", "tas_mps": "Tas",
         "baro_alt_m": "Alt"}


def _folder(tmp_path: Path) -> Path:
    """The handmade sample's channels, each as its own header-less file (the normal load as
    n - 1, the altitude in feet), with a mapping naming the files."""
    d = pd.read_csv(SAMPLES / "handmade.csv")
    # one value per frame: the channels on the rows where all are sampled, interpolated
    d = d.interpolate(limit_direction="both")
    folder = tmp_path / "rec"
    folder.mkdir()
    for ch, name in NAMES.items():
        v = d[ch].to_numpy(float)
        if ch == "n_norm_g":
            v = v - 1.0
        if ch == "baro_alt_m":
            v = v / 0.3048
        np.savetxt(folder / f"{name}.csv", v, fmt="%.6f")
    (folder / "notes.txt").write_text("flight test 12 March\npilot A\n")
    np.savetxt(folder / "short.csv", np.arange(10.0))
    lines = ['[time]', 'column = "time"', 'unit = "s"']
    for ch, name in NAMES.items():
        if ch == "t_s":
            continue
        unit = {"n_long_g": "g", "n_lat_g": "g", "n_norm_g": "g", "roll_deg": "deg",
                "pitch_deg": "deg", "heading_deg": "deg", "tas_mps": "m/s",
                "baro_alt_m": "ft"}[ch]
        lines += [f"[channels.{ch}]", f'column = "{name}"', f'unit = "{unit}"']
        if ch == "n_norm_g":
            lines.append("offset = 1.0")
    (tmp_path / "rec.mapping.toml").write_text("\n".join(lines) + "\n")
    (tmp_path / "rec.meta.toml").write_text((SAMPLES / "handmade.meta.toml").read_text())
    return folder


def test_a_folder_reads_as_one_table_named_by_its_files(tmp_path):
    folder = _folder(tmp_path)
    raw = read_table(folder)
    assert raw.fmt == "folder" and "Pitch" in raw.columns and "time" in raw.columns
    assert "short" not in raw.columns and "notes" not in raw.columns
    assert any("short.csv" in w and "10 rows" in w for w in raw.warnings)
    assert any("notes.txt" in w for w in raw.warnings)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fl = load_flight(folder, mapping=tmp_path / "rec.mapping.toml")
    ref = pd.read_csv(SAMPLES / "handmade.csv").interpolate(limit_direction="both")
    np.testing.assert_allclose(fl.data["baro_alt_m"].to_numpy(), ref["baro_alt_m"], atol=1e-5)
    np.testing.assert_allclose(fl.data["n_norm_g"].to_numpy(), ref["n_norm_g"], atol=1e-6)


def test_the_cli_reads_a_folder_with_its_mapping_and_sidecar(tmp_path, capsys):
    folder = _folder(tmp_path)
    try:
        main(["info", str(folder), "--mapping", str(tmp_path / "rec.mapping.toml")])
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    out = capsys.readouterr().out
    assert code == 0 and "pitch_deg" in out and "HANDMADE-1" in out


def test_a_folder_without_one_column_files_is_an_input_error(tmp_path, capsys):
    (tmp_path / "empty").mkdir()
    (tmp_path / "empty" / "table.csv").write_text("a,b\n1,2\n")
    with pytest.raises(SystemExit) as ex:
        main(["info", str(tmp_path / "empty")])
    assert ex.value.code == 3
    assert "one-column" in capsys.readouterr().err
