"""Every exit code of the README, each triggered from the command line (docs/exit-codes.md
lists them with these tests)."""

from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pandas as pd

from flightrecon.cli.main import main

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_logs"


def run(args: list[str], capsys=None) -> tuple[int, str]:
    try:
        main(["--quiet", *args])
        code = 0
    except SystemExit as exc:
        code = int(exc.code or 0)
    err = capsys.readouterr().err if capsys is not None else ""
    return code, err


def test_0_success(capsys):
    code, err = run(["info", str(SAMPLES / "landing.parquet")], capsys)
    assert code == 0 and err == ""


def test_1_internal_error(monkeypatch, capsys):
    import flightrecon.ingest

    def boom(*a, **k):
        raise RuntimeError("a bug")

    monkeypatch.setattr(flightrecon.ingest, "describe_flight", boom)
    code, err = run(["info", str(SAMPLES / "landing.parquet")], capsys)
    assert code == 1 and "internal error: RuntimeError: a bug" in err


def test_2_unknown_method(capsys):
    code, err = run(["reconstruct", str(SAMPLES / "circuit.parquet"), "--methods", "joint,foo"],
                    capsys)
    assert code == 2 and "unknown method(s) foo" in err


def test_2_suffix_contradicts_format(tmp_path, capsys):
    out = tmp_path / "out.parquet"
    code, err = run(["reconstruct", str(SAMPLES / "circuit.parquet"), "-o", str(out),
                     "--format", "kml"], capsys)
    assert code == 2 and "says parquet" in err and not out.exists()


def test_2_coeffs_remove_without_an_answer(tmp_path):
    """stdin closed: the confirmation gets no answer -> usage error, nothing removed (it was
    130, 'interrupted', before)."""
    store = tmp_path / "s.sqlite"
    assert run(["reconstruct", str(SAMPLES / "circuit.parquet"), "--methods", "sabziev",
                "-o", str(tmp_path / "r.parquet"), "--store", str(store)])[0] == 0
    cmd = [sys.executable, "-m", "flightrecon.cli.main", "coeffs", "remove", "--store",
           str(store), "A1"]
    p = subprocess.run(cmd, stdin=subprocess.DEVNULL, capture_output=True, text=True, cwd=ROOT,
                       timeout=120)
    assert p.returncode == 2, p.stderr
    assert "--yes" in p.stderr and "nothing removed" in p.stderr
    listed = subprocess.run([sys.executable, "-m", "flightrecon.cli.main", "coeffs", "list",
                             "--store", str(store), "--json"], capture_output=True, text=True,
                            cwd=ROOT, timeout=120)
    assert '"A1"' in listed.stdout


def test_2_plot_refuses_a_raw_log(tmp_path, capsys):
    code, err = run(["plot", str(SAMPLES / "circuit.parquet"), "-o", str(tmp_path / "r")],
                    capsys)
    assert code == 2 and "not a reconstruction result" in err
    assert not (tmp_path / "r" / "report.html").exists()


def test_2_plot_refuses_the_truth_of_another_flight(tmp_path, capsys):
    out = tmp_path / "c.parquet"
    assert run(["reconstruct", str(SAMPLES / "circuit.parquet"), "-o", str(out),
                "--methods", "sabziev"])[0] == 0
    code, err = run(["plot", str(out), "--truth", str(SAMPLES / "landing.truth.parquet"),
                     "-o", str(tmp_path / "r")], capsys)
    assert code == 2 and "--truth" in err
    # its own truth is accepted
    code, err = run(["plot", str(out), "--truth", str(SAMPLES / "circuit.truth.parquet"),
                     "-o", str(tmp_path / "r")], capsys)
    assert code == 0, err


def test_0_output_pipe_closed_early():
    """``flightrecon info LOG | head``: the reader leaves before we write; not an error: exit
    0, silently (it was 1, the internal-error code, before)."""
    p = subprocess.Popen([sys.executable, "-m", "flightrecon.cli.main", "info",
                          str(SAMPLES / "regional.parquet")], stdout=subprocess.PIPE,
                         stderr=subprocess.PIPE, cwd=ROOT)
    p.stdout.close()  # long before the log is read: every write meets a closed pipe
    err = p.stderr.read().decode()
    assert p.wait(timeout=120) == 0
    assert err == ""


def test_3_input_unreadable(tmp_path, capsys):
    code, err = run(["info", str(tmp_path / "nope.parquet")], capsys)
    assert code == 3 and "nope.parquet" in err


def test_4_schema_error(tmp_path, capsys):
    p = tmp_path / "s.csv"
    p.write_text("t_s,foo\n0,1\n1,2\n")
    code, err = run(["info", str(p)], capsys)
    assert code == 4 and "missing required channel" in err


def test_5_validation_error(tmp_path, capsys):
    lines = (SAMPLES / "handmade.csv").read_text().splitlines()[:4]
    lines[2] = lines[2].replace("0.0349", "abc", 1)
    p = tmp_path / "v.csv"
    p.write_text("\n".join(lines) + "\n")
    code, err = run(["info", str(p)], capsys)
    assert code == 5 and "non-numeric" in err and "row 2" in err


def test_6_mapping_error(tmp_path, capsys):
    m = tmp_path / "bad.mapping.toml"
    m.write_text("this is [not toml")
    code, err = run(["info", str(SAMPLES / "foreign.csv"), "--mapping", str(m)], capsys)
    assert code == 6 and "bad.mapping.toml" in err


def test_6_misspelt_mapping_key(tmp_path, capsys):
    """A misspelt key of a mapping file names the file, its line, the table, the key and the
    nearest valid key (it was dropped and the run failed later on the data, exit 5)."""
    m = tmp_path / "typo.mapping.toml"
    m.write_text((SAMPLES / "foreign.mapping.toml").read_text().replace("sign = -1",
                                                                          "sing = -1"))
    code, err = run(["info", str(SAMPLES / "foreign.csv"), "--mapping", str(m)], capsys)
    assert code == 6, err
    assert "typo.mapping.toml" in err and "[channels.n_lat_g]" in err and "'sing'" in err
    assert "did you mean 'sign'" in err and "line 19" in err


def test_7_kml_of_a_csv_without_summary(tmp_path, capsys):
    df = pd.DataFrame({"t_s": [0.0, 1.0, 2.0], "lat_deg": [40.0, 40.001, 40.002],
                       "lon_deg": [50.0, 50.0, 50.0], "alt_m": [100.0, 101.0, 102.0]})
    csv = tmp_path / "bare.csv"
    df.to_csv(csv, index=False)
    code, err = run(["export", str(csv), "-o", str(tmp_path / "b.kml")], capsys)
    assert code == 7 and "geoid undulation" in err and not (tmp_path / "b.kml").exists()
    code, err = run(["export", str(csv), "-o", str(tmp_path / "b.kml"), "--geoid-undulation",
                     "-22"], capsys)
    assert code == 0 and (tmp_path / "b.kml").exists()


def test_8_no_physically_possible_result(tmp_path, capsys):
    # the Sabziev fusion alone on the landing sample with k2 = +0.01 (the height grows as
    # e^(0.1 t)) is unhealthy (docs/output.md; its own fit there is healthy since issue #37)
    code, err = run(["reconstruct", str(SAMPLES / "landing.parquet"), "--methods", "sabziev",
                     "--k", "-0.01,0.01,-0.01", "-o", str(tmp_path / "r.parquet")], capsys)
    assert code == 8 and "no method produced a physically possible track" in err
    assert not (tmp_path / "r.parquet").exists()


def test_8_no_convergence_with_strict(monkeypatch, tmp_path, capsys):
    import flightrecon.pipeline.run as pl
    from flightrecon.errors import ConvergenceError

    def no_root(name, clean, settings):
        raise ConvergenceError("axis x: no root")

    monkeypatch.setattr(pl, "run_method", no_root)
    code, err = run(["reconstruct", str(SAMPLES / "circuit.parquet"), "--methods", "sabziev",
                     "--strict", "-o", str(tmp_path / "r.parquet")], capsys)
    assert code == 8 and "no root" in err and not (tmp_path / "r.parquet").exists()


def test_9_output_over_input_or_missing_folder(tmp_path, capsys):
    log = tmp_path / "c.parquet"
    shutil.copy(SAMPLES / "circuit.parquet", log)
    code, _ = run(["reconstruct", str(log), "-o", str(log)], capsys)
    assert code == 9
    code, err = run(["reconstruct", str(log), "-o", str(tmp_path / "no" / "r.parquet")], capsys)
    assert code == 9 and "does not exist" in err


def test_10_store_error(tmp_path, capsys):
    bad = tmp_path / "bad.sqlite"
    bad.write_text("garbage")
    code, err = run(["coeffs", "list", "--store", str(bad)], capsys)
    assert code == 10 and "not a flightrecon coefficient store" in err


def test_10_store_that_cannot_be_written_before_any_work(tmp_path, capsys, monkeypatch):
    """A read-only store (``--store PATH``) was reported as "out.parquet: the folder for the
    result is not writable: ." (exit 9) with a writable result folder: it is a store error
    (exit 10) naming the store, found before any work.  The same for a store folder that
    cannot be written and for a file that is not a store (os.access is patched: as root
    every file is writable)."""
    import flightrecon.pipeline as pl
    from flightrecon.store.db import connect

    def no_work(*a, **k):
        raise AssertionError("the reconstruction ran before the store was checked")

    monkeypatch.setattr(pl, "reconstruct", no_work)
    con, _, _ = connect(tmp_path / "ro.sqlite")
    con.close()
    (tmp_path / "rodir").mkdir()
    (tmp_path / "notes.sqlite").write_text("notes")
    real = os.access

    def access(p, mode, *a, **k):
        if Path(p).name in ("ro.sqlite", "rodir") and mode & os.W_OK:
            return False
        return real(p, mode, *a, **k)

    monkeypatch.setattr(os, "access", access)
    log = str(SAMPLES / "circuit.parquet")
    for store, words in ((tmp_path / "ro.sqlite", ("ro.sqlite", "read-only")),
                         (tmp_path / "rodir" / "s.sqlite", ("s.sqlite", "rodir", "not writable")),
                         (tmp_path / "notes.sqlite", ("notes.sqlite", "not a SQLite")),
                         (tmp_path / "no" / "s.sqlite", ("s.sqlite", "does not exist"))):
        code, err = run(["reconstruct", log, "-o", str(tmp_path / "out.parquet"), "--store",
                         str(store)], capsys)
        assert code == 10, (store, err)
        assert all(w in err for w in words), (words, err)
        assert "out.parquet" not in err, err
    assert not (tmp_path / "out.parquet").exists()


def test_10_batch_store_checked_before_the_cluster_starts(tmp_path, capsys, monkeypatch):
    """``batch --store`` with a file that is not a store: exit 10 naming it, before Dask."""
    import flightrecon.batch as fb

    def no_cluster(*a, **k):
        raise AssertionError("the cluster started before the store was checked")

    monkeypatch.setattr(fb, "open_client", no_cluster)
    (tmp_path / "notes.sqlite").write_text("notes")
    code, err = run(["batch", str(SAMPLES / "circuit.parquet"), "--out", str(tmp_path / "b"),
                     "--store", str(tmp_path / "notes.sqlite")], capsys)
    assert code == 10 and "notes.sqlite" in err and "not a SQLite" in err, err


def test_130_interrupted(monkeypatch, capsys):
    import flightrecon.ingest

    def ctrl_c(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(flightrecon.ingest, "describe_flight", ctrl_c)
    code, err = run(["info", str(SAMPLES / "landing.parquet")], capsys)
    assert code == 130 and "interrupted" in err
