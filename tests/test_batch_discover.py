"""Batch plumbing without a cluster: log discovery, output confinement, manifests, the task."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from flightrecon.batch.discover import (
    confined,
    discover_logs,
    is_log_name,
    output_paths,
    sanitise_name,
)
from flightrecon.batch.manifest import (
    input_hashes,
    is_up_to_date,
    read_manifest,
    settings_key,
    write_manifest,
)
from flightrecon.batch.runner import batch
from flightrecon.batch.task import run_flight
from flightrecon.errors import InputFileError, OutputError
from flightrecon.pipeline import ReconstructSettings


def _touch(p: Path, text: str = "x") -> Path:
    p.parent.mkdir(parents=True, exist_ok=True)
    p.write_text(text)
    return p


@pytest.mark.parametrize("name,expected", [
    ("f1.parquet", True), ("f1.csv", True), ("F1.PARQUET", True), ("f1.v2.parquet", True),
    ("f1.truth.parquet", False), ("f1.recon.parquet", False), ("f1.recon.csv", False),
    ("f1.gnss.csv", False), ("f1.radar.parquet", False), ("f1.clean.parquet", False),
    ("f1.recon.summary.json", False), ("f1.meta.toml", False), ("f1.sensors.json", False),
    ("batch_summary.csv", False), ("aircraft_averages.csv", False), (".hidden.parquet", False),
])
def test_is_log_name(name, expected):
    assert is_log_name(Path(name)) is expected


def test_discover_folders_globs_companions_and_out_dir(tmp_path):
    """Folders are searched recursively, companions (by tag or named in the sidecar) and the
    batch's own output folder are left out, duplicates collapse."""
    a = _touch(tmp_path / "in" / "a.parquet")
    _touch(tmp_path / "in" / "a.truth.parquet")
    _touch(tmp_path / "in" / "a.recon.parquet")
    _touch(tmp_path / "in" / "a.meta.toml", '[flight]\naircraft_id = "X"\n'
                                             '[files]\ngnss = "a_fixes.csv"\n')
    _touch(tmp_path / "in" / "a_fixes.csv")
    b = _touch(tmp_path / "in" / "sub" / "b.csv")
    _touch(tmp_path / "in" / "out" / "old.parquet")
    got = discover_logs([tmp_path / "in", str(tmp_path / "in" / "*.parquet")],
                        out_dir=tmp_path / "in" / "out")
    assert [e.log.resolve() for e in got] == [a.resolve(), b.resolve()]
    assert got[0].sidecar is not None and got[0].sidecar.name == "a.meta.toml"
    assert got[1].sidecar is None
    assert [e.name for e in got] == ["a", "b"]


def test_discover_nothing_is_an_error(tmp_path):
    with pytest.raises(InputFileError):
        discover_logs([str(tmp_path / "nope*.parquet")])
    _touch(tmp_path / "x.truth.parquet")
    with pytest.raises(InputFileError):
        discover_logs([tmp_path])


def test_name_clash_across_folders_is_disambiguated(tmp_path):
    _touch(tmp_path / "ac1" / "flight.parquet")
    _touch(tmp_path / "ac2" / "flight.parquet")
    _touch(tmp_path / "ac2" / "flight.csv")
    names = [e.name for e in discover_logs([tmp_path])]
    assert len(set(names)) == 3 and all(n.startswith("flight-") for n in names)
    assert "flight-csv" in names  # same stem, other suffix: readable
    assert sum(n.startswith("flight-parquet-") for n in names) == 2  # same name: path hash


@pytest.mark.parametrize("stem", ["../../etc/passwd", "..", ".bashrc", "a b/c", "-rf", "", "é"])
def test_sanitised_names_stay_in_the_output_folder(tmp_path, stem):
    name = sanitise_name(stem)
    assert name and "/" not in name and not name.startswith((".", "-"))
    for p in output_paths(tmp_path, name, "parquet").values():
        assert p.resolve().parent == tmp_path.resolve()


@pytest.mark.parametrize("bad", ["../x", "a/b", "..", "", "x\\y"])
def test_confined_refuses_escapes(tmp_path, bad):
    with pytest.raises(OutputError):
        confined(tmp_path, bad)


def test_manifest_fingerprints(tmp_path):
    log = _touch(tmp_path / "a.parquet", "one")
    side = _touch(tmp_path / "a.meta.toml", '[flight]\naircraft_id = "X"\n')
    h = input_hashes(log, side)
    assert set(h) == {str(log.resolve()), str(side.resolve())}
    s = ReconstructSettings()
    key = settings_key(s, "parquet", None)
    assert key == settings_key(ReconstructSettings(), "parquet", None)
    assert key != settings_key(replace(s, rate_hz=8.0), "parquet", None)
    assert key != settings_key(s, "csv", None)
    assert key != settings_key(s, "parquet", tmp_path / "k.sqlite")
    out = _touch(tmp_path / "a.recon.parquet")
    m = tmp_path / "a.manifest.json"
    write_manifest(m, {"status": "ok", "inputs": h, "settings_key": key})
    doc = read_manifest(m)
    assert is_up_to_date(doc, h, key, [out])
    assert not is_up_to_date(doc, h, key, [out, tmp_path / "missing"])
    side.write_text('[flight]\naircraft_id = "Y"\n')
    assert not is_up_to_date(doc, input_hashes(log, side), key, [out])
    m.write_text("{not json")
    assert read_manifest(m) is None


def test_run_flight_reports_a_corrupt_log(tmp_path):
    """A truncated log is a failed outcome with the input error's exit code, not an exception."""
    bad = tmp_path / "bad.parquet"
    bad.write_bytes(b"PAR1" + b"\0" * 100)
    out = run_flight(str(bad), None, str(tmp_path / "bad.recon.parquet"),
                     str(tmp_path / "bad.recon.summary.json"), ReconstructSettings(), "parquet")
    assert out["status"] == "failed" and out["exit_code"] == InputFileError.exit_code
    assert "InputFileError" in out["error"]
    assert not (tmp_path / "bad.recon.parquet").exists()


def test_batch_refuses_bad_format_and_out_file(tmp_path):
    log = _touch(tmp_path / "a.parquet")
    with pytest.raises(OutputError):
        batch([log], tmp_path / "out", fmt="xlsx")
    with pytest.raises(OutputError):
        batch([log], log)


def test_batch_passes_the_gap_calibration_setting(monkeypatch, tmp_path):
    """``batch --gap-stretches N`` reaches every flight's settings as for ``reconstruct``."""
    import contextlib
    from types import SimpleNamespace

    import flightrecon.batch as fb
    from flightrecon.cli.main import main as cli_main

    seen = {}

    def fake_batch(inputs, out_dir, **kw):
        seen["settings"] = kw["settings"]
        return SimpleNamespace(averages=[], count=lambda s: 0, elapsed_s=0.0, exit_code=0,
                               summary_csv=tmp_path / "s.csv", averages_csv=tmp_path / "a.csv")

    monkeypatch.setattr(fb, "batch", fake_batch)
    monkeypatch.setattr(fb, "open_client", lambda *a: contextlib.nullcontext())
    for args, want in (([], None), (["--gap-stretches", "0"], 0), (["--gap-stretches", "3"], 3)):
        try:
            cli_main(["--quiet", "batch", str(tmp_path), "--out", str(tmp_path / "o"), *args])
        except SystemExit as exc:
            assert not exc.code
        assert seen["settings"].joint_gap_stretches == want
