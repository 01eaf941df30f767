"""A recorder whose time is its frame count, read with its rate given once (issue 49, item 5):
a folder of one-column files with no time file (a flight-test export whose time is the frame
count), by ``[time] rate_hz`` in the mapping or ``--frame-rate`` on the command line."""

from __future__ import annotations

import json
import warnings
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from flightrecon.errors import MappingError, SchemaError
from flightrecon.ingest import load_flight, load_mapping
from tests._cli import run_cli

SAMPLES = Path(__file__).resolve().parents[1] / "sample_logs"
#: the hand-made sample's channels, by the file each is written to
FILES = {"n_long_g": ("AccLong", "g"), "n_lat_g": ("AccLat", "g"),
         "n_norm_g": ("AccNorm", "g"), "roll_deg": ("Roll", "deg"),
         "pitch_deg": ("Pitch", "deg"), "heading_deg": ("Hdg", "deg"),
         "tas_mps": ("Tas", "m/s"), "baro_alt_m": ("Alt", "ft")}
RATE_HZ = 8.0          # the hand-made sample's frame: one row every 0.125 s


def reference() -> pd.DataFrame:
    """The hand-made sample with every channel on every frame (8 Hz, from 0 s)."""
    d = pd.read_csv(SAMPLES / "handmade.csv").interpolate(limit_direction="both")
    assert np.allclose(np.diff(d["t_s"]), 1.0 / RATE_HZ) and d["t_s"].iloc[0] == 0.0
    return d


def write_folder(tmp_path: Path, time_lines: list[str], counter_start: int | None = None
                 ) -> tuple[Path, Path]:
    """The sample as a folder of header-less one-column files with **no time file** (the
    altitude in feet), the sidecar beside it and a mapping whose ``[time]`` table is
    ``time_lines`` (none when empty); with ``counter_start`` a frame-counter file ``frame``."""
    d = reference()
    folder = tmp_path / "rec"
    folder.mkdir()
    for ch, (name, _) in FILES.items():
        v = d[ch].to_numpy(float) / (0.3048 if ch == "baro_alt_m" else 1.0)
        np.savetxt(folder / f"{name}.csv", v, fmt="%.6f")
    if counter_start is not None:
        np.savetxt(folder / "frame.csv", counter_start + np.arange(len(d)), fmt="%d")
    lines = list(time_lines)
    for ch, (name, unit) in FILES.items():
        lines += [f"[channels.{ch}]", f'column = "{name}"', f'unit = "{unit}"']
    mapping = tmp_path / "rec.mapping.toml"
    mapping.write_text("\n".join(lines) + "\n")
    (tmp_path / "rec.meta.toml").write_text((SAMPLES / "handmade.meta.toml").read_text())
    return folder, mapping


def load(folder: Path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_flight(folder, sidecar=folder.parent / "rec.meta.toml", **kw)


def test_without_a_rate_the_refusal_says_how_to_give_it(tmp_path):
    folder, mapping = write_folder(tmp_path, [])
    with pytest.raises(SchemaError) as exc:
        load(folder, mapping=mapping)
    msg = str(exc.value)
    assert "no time column" in msg and "--frame-rate" in msg and "rate_hz" in msg
    assert run_cli(["info", str(folder), "--mapping", str(mapping)]) == SchemaError.exit_code


def test_the_mapping_rate_gives_the_frames_their_times(tmp_path):
    folder, mapping = write_folder(tmp_path, ["[time]", f"rate_hz = {RATE_HZ:g}"])
    fl = load(folder, mapping=mapping)
    ref = reference()
    np.testing.assert_allclose(fl.data["t_s"].to_numpy(), ref["t_s"].to_numpy(), atol=1e-9)
    np.testing.assert_allclose(fl.data["baro_alt_m"].to_numpy(), ref["baro_alt_m"], atol=1e-5)
    np.testing.assert_array_equal(fl.data["row"].to_numpy(), np.arange(1, len(ref) + 1))


def test_a_frame_counter_column_is_read_at_the_rate(tmp_path):
    folder, mapping = write_folder(tmp_path, ["[time]", 'column = "frame"',
                                              f"rate_hz = {RATE_HZ:g}"], counter_start=400)
    fl = load(folder, mapping=mapping)
    t = fl.data["t_s"].to_numpy()
    assert t[0] == pytest.approx(400 / RATE_HZ) and np.allclose(np.diff(t), 1 / RATE_HZ)


def test_the_command_line_rate_reads_the_folder_and_wins_over_the_mapping(tmp_path, capsys):
    folder, mapping = write_folder(tmp_path, [])
    code = run_cli(["info", str(folder), "--mapping", str(mapping), "--sidecar",
                    str(tmp_path / "rec.meta.toml"), "--frame-rate", "8", "--json"])
    out = capsys.readouterr().out
    assert code == 0 and json.loads(out)["duration_s"] == pytest.approx(240.0)
    fl = load(folder, mapping=mapping, frame_rate_hz=RATE_HZ)
    assert fl.data["t_s"].iloc[-1] == pytest.approx(240.0)
    assert any("frame count at 8 Hz" in n for n in fl.meta.ingest.notes)
    # the mapping says 8 Hz; the command line's 4 Hz wins, and the note gives both
    (tmp_path / "b").mkdir()
    folder2, mapping2 = write_folder(tmp_path / "b", ["[time]", "rate_hz = 8"])
    fl2 = load(folder2, mapping=mapping2, frame_rate_hz=4.0)
    assert fl2.data["t_s"].iloc[-1] == pytest.approx(480.0)
    assert any("in place of the mapping's rate_hz = 8" in n
               for n in fl2.meta.ingest.notes)


def test_a_file_with_its_own_time_keeps_it_and_says_the_rate_was_not_used(tmp_path):
    log = tmp_path / "own.csv"
    d = reference()
    d.to_csv(log, index=False)
    (tmp_path / "own.meta.toml").write_text((SAMPLES / "handmade.meta.toml").read_text())
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fl = load_flight(log, frame_rate_hz=2.0)
    assert fl.data["t_s"].iloc[-1] == pytest.approx(240.0)
    assert any("--frame-rate 2 Hz not used" in w and "'t_s'" in w for w in fl.warnings)


def test_a_table_without_a_time_column_reads_at_the_rate(tmp_path):
    log = tmp_path / "frames.csv"
    reference().drop(columns=["t_s"]).to_csv(log, index=False)
    (tmp_path / "frames.meta.toml").write_text((SAMPLES / "handmade.meta.toml").read_text())
    with pytest.raises(SchemaError, match="--frame-rate"):
        load_flight(log)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fl = load_flight(log, frame_rate_hz=RATE_HZ)
    np.testing.assert_allclose(fl.data["t_s"].to_numpy(), reference()["t_s"], atol=1e-9)


@pytest.mark.parametrize("lines, words", [
    (["rate_hz = 0"], "positive"),
    (["rate_hz = -10"], "positive"),
    (['rate_hz = "10"'], "finite number"),
    (["rate_hz = 10", 'format = "%H"'], "format does not apply"),
    (["rate_hz = 10", 'unit = "timestamp"'], "seconds"),
])
def test_a_bad_rate_in_the_mapping_is_a_mapping_error_naming_its_line(tmp_path, lines, words):
    m = tmp_path / "m.toml"
    m.write_text("\n".join(["# a recorder's frame", "[time]", *lines]) + "\n")
    with pytest.raises(MappingError) as exc:
        load_mapping(m)
    assert words in str(exc.value) and "line " in str(exc.value)


def test_a_bad_command_line_rate_is_refused(tmp_path):
    folder, mapping = write_folder(tmp_path, [])
    with pytest.raises(MappingError, match="--frame-rate must be a positive"):
        load(folder, mapping=mapping, frame_rate_hz=0.0)


def test_reconstruct_takes_the_frame_rate(tmp_path):
    folder, mapping = write_folder(tmp_path, [])
    out = tmp_path / "r.csv"
    code = run_cli(["reconstruct", str(folder), "--mapping", str(mapping), "--sidecar",
                    str(tmp_path / "rec.meta.toml"), "--frame-rate", "8", "--methods",
                    "joint", "-o", str(out)])
    assert code == 0
    t = pd.read_csv(out)["t_s"].to_numpy()
    assert t[0] >= 0.0 and t[-1] <= 240.0 + 1e-6 and t[-1] > 200.0
    assert json.loads((tmp_path / "r.summary.json").read_text())["result"]["method"] == "joint"
