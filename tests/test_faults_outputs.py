"""Issue #24, outputs and environments: nothing overwritten, nothing half-written, clear errors.

Each test is named after a finding of the mutation fuzzer that opened the issue.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import subprocess
import sys
import textwrap
from pathlib import Path

import pandas as pd
import pytest
from _cli import run_cli_stderr

from flightrecon.export.atomic import TMP_TAG, Publication, sweep_leftovers

ROOT = Path(__file__).resolve().parents[1]
SAMPLES = ROOT / "sample_logs"


run = run_cli_stderr


def digest(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def leftovers(folder: Path) -> list[Path]:
    return [p for p in folder.rglob("*") if TMP_TAG in p.name]


@pytest.fixture()
def handmade(tmp_path) -> Path:
    for f in ("handmade.csv", "handmade.meta.toml"):
        shutil.copy(SAMPLES / f, tmp_path / f)
    return tmp_path / "handmade.csv"


# ------------------------------------------------------------------ never touch an input


def test_summary_over_the_logs_sidecar_is_refused(handmade, capsys):
    """`reconstruct circuit.parquet -o out.parquet --summary circuit.meta.toml` replaced the
    log's own (auto-discovered) sidecar and exited 0."""
    d = handmade.parent
    before = digest(d)
    code, err = run(["reconstruct", handmade, "-o", d / "out.parquet",
                     "--summary", d / "handmade.meta.toml"], capsys)
    assert code == 9, err
    assert "handmade.meta.toml" in err and "sidecar" in err
    assert digest(d) == before and not leftovers(d)


def test_summary_over_the_result_is_refused(handmade, capsys):
    """`-o out.parquet --summary out.parquet` wrote the summary over the result (exit 0)."""
    d = handmade.parent
    code, err = run(["reconstruct", handmade, "-o", d / "out.parquet",
                     "--summary", d / "out.parquet"], capsys)
    assert code == 9, err
    assert "out.parquet" in err and "same file" in err
    assert not (d / "out.parquet").exists()


def _noise(d: Path) -> Path:
    (d / "noise.toml").write_text("[joint]\n")
    return d / "noise.toml"


@pytest.mark.parametrize("case", [
    "result-over-log", "result-over-sidecar", "summary-over-log", "result-over-noise-file",
    "result-via-symlink-to-log", "report-folder-is-log", "report-over-input-png",
    "store-over-log", "summary-over-store", "result-over-sidecar-companion",
    "store-read-only-input-under-summary"])
def test_every_output_is_checked_against_every_input(handmade, capsys, case):
    """Every output (result, summary, report folder, store) against every input (log,
    sidecar and the files it names, noise file, a store that is only read) and against the
    other outputs, before any work: exit 9, nothing changed."""
    d = handmade.parent
    log = handmade
    extra: list = []
    if case == "result-over-log":
        args = ["-o", log]
    elif case == "result-over-sidecar":
        args = ["-o", d / "handmade.meta.toml", "--format", "csv"]
    elif case == "summary-over-log":
        args = ["-o", d / "r.parquet", "--summary", log]
    elif case == "result-over-noise-file":
        args = ["-o", _noise(d), "--format", "csv", "--noise", d / "noise.toml"]
    elif case == "result-via-symlink-to-log":
        os.symlink(log, d / "link.csv")
        args = ["-o", d / "link.csv"]
    elif case == "report-folder-is-log":
        args = ["-o", d / "r.parquet", "--report", log]
    elif case == "report-over-input-png":
        # a log named like one of the report's files inside the report folder
        shutil.copy(log, d / "ground_track.png")
        log = d / "ground_track.png"
        shutil.copy(d / "handmade.meta.toml", d / "ground_track.meta.toml")
        args = ["-o", d / "r.parquet", "--report", d]
    elif case == "store-over-log":
        args = ["-o", d / "r.parquet", "--store", log]
    elif case == "summary-over-store":
        args = ["-o", d / "r.parquet", "--summary", d / "s.sqlite", "--store", d / "s.sqlite"]
    elif case == "result-over-sidecar-companion":
        (d / "gnss.csv").write_text("t_s,gnss_lat_deg,gnss_lon_deg\n0,40.46,50.05\n")
        text = (d / "handmade.meta.toml").read_text()
        (d / "handmade.meta.toml").write_text(text + '\n[files]\ngnss = "gnss.csv"\n')
        args = ["-o", d / "gnss.csv"]
    elif case == "store-read-only-input-under-summary":
        (d / "s.sqlite").write_bytes(b"")
        args = ["-o", d / "r.parquet", "--summary", d / "s.sqlite", "--store", d / "s.sqlite",
                "--use-fleet-coefficients"]
    else:  # pragma: no cover
        raise AssertionError(case)
    before = digest(d)
    code, err = run(["reconstruct", log, *args, *extra], capsys)
    assert code == 9, err
    assert "error:" in err and "Traceback" not in err
    assert digest(d) == before
    assert not leftovers(d)


def test_clean_outputs_are_checked_against_the_sidecar(handmade, capsys):
    d = handmade.parent
    before = digest(d)
    code, err = run(["clean", handmade, "-o", d / "handmade.parquet"], capsys)
    assert code == 0, err      # beside the log, not over any input
    before = digest(d)
    (d / "x.meta.toml").write_text((d / "handmade.meta.toml").read_text())
    shutil.copy(handmade, d / "x.csv")
    before = digest(d)
    code, err = run(["clean", d / "x.csv", "-o", d / "x.meta.toml"], capsys)
    assert code == 9, err
    assert digest(d) == before


# ------------------------------------------------------------------ clear errors


def test_empty_output_path_is_a_usage_error(handmade, capsys):
    """`-o ''` was an internal error (exit 1)."""
    for cmd in (["reconstruct", handmade, "-o", ""], ["clean", handmade, "-o", ""],
                ["reconstruct", handmade, "--summary", ""],
                ["reconstruct", handmade, "--report", ""]):
        code, err = run(cmd, capsys)
        assert code == 2, (cmd, err)
        assert "empty" in err


def test_unwritable_output_folder_is_exit_9(handmade, capsys, monkeypatch):
    """An output folder that is not writable was a PermissionError (exit 1).  Checked
    before any work, naming the folder (os.access is patched: as root every folder is
    writable)."""
    d = handmade.parent
    ro = d / "ro"
    ro.mkdir()
    real = os.access

    def access(p, mode, *a, **k):
        if Path(p).resolve() == ro.resolve() and mode & os.W_OK:
            return False
        return real(p, mode, *a, **k)

    monkeypatch.setattr(os, "access", access)
    code, err = run(["reconstruct", handmade, "-o", ro / "r.parquet"], capsys)
    assert code == 9, err
    assert "not writable" in err and "ro" in err
    code, err = run(["clean", handmade, "-o", ro / "c.parquet"], capsys)
    assert code == 9, err
    assert list(ro.iterdir()) == []


@pytest.mark.skipif(sys.platform == "win32" or os.geteuid() == 0,
                    reason="POSIX permissions (root writes anywhere)")
def test_unwritable_output_folder_is_exit_9_real_permissions(handmade, capsys):
    ro = handmade.parent / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        code, err = run(["reconstruct", handmade, "-o", ro / "r.parquet"], capsys)
    finally:
        ro.chmod(0o755)
    assert code == 9, err


def test_permission_error_while_writing_is_exit_9(tmp_path, monkeypatch):
    """A write refused by the operating system half-way (quota, permissions changed) is an
    OutputError naming the file, not an internal error; nothing is left behind."""
    from flightrecon.errors import OutputError
    from flightrecon.export.atomic import atomic_path

    with pytest.raises(OutputError, match="cannot write") as ex, \
            atomic_path(tmp_path / "x.json") as tmp:
        tmp.write_text("{}")
        raise PermissionError(13, "Permission denied")
    assert "x.json" in str(ex.value)
    assert not leftovers(tmp_path)


def test_one_row_log_message_names_the_file(handmade, capsys):
    d = handmade.parent
    lines = handmade.read_text().splitlines()
    (d / "one.csv").write_text("\n".join(lines[:2]) + "\n")
    shutil.copy(d / "handmade.meta.toml", d / "one.meta.toml")
    code, err = run(["reconstruct", d / "one.csv", "-o", d / "r.parquet"], capsys)
    assert code == 5, err
    assert "one.csv" in err and "too short" in err
    code, err = run(["clean", d / "one.csv", "-o", d / "c.parquet"], capsys)
    assert code == 5, err
    assert "one.csv" in err


def test_log_without_sidecar_message_names_the_file(handmade, capsys):
    """A recorder-only log (no GNSS: nothing fixes the frame's origin) without its sidecar: the
    message names the log and where the sidecar was looked for."""
    import pandas as pd

    d = handmade.parent
    log = pd.read_csv(handmade)
    log.drop(columns=[c for c in log.columns if c.startswith("gnss_")]).to_csv(
        d / "bare.csv", index=False)
    code, err = run(["reconstruct", d / "bare.csv", "-o", d / "r.parquet"], capsys)
    assert code == 7, err
    assert "bare.csv" in err and "bare.meta.toml" in err


# ------------------------------------------------------------------ one unit


def _prior(d: Path) -> tuple[Path, Path, dict]:
    out, summ = d / "old.parquet", d / "old.summary.json"
    pd.DataFrame({"t_s": [0.0], "north_m": [1.0], "east_m": [2.0]}).to_parquet(out)
    summ.write_text(json.dumps({"old": True}))
    return out, summ, digest(d)


def test_interrupt_before_publication_leaves_every_old_output(handmade, capsys, monkeypatch):
    """Ctrl-C after the result was written but before the summary: the result is only
    staged, so the old result and the old summary stay, and nothing is left behind."""
    from flightrecon import report

    d = handmade.parent
    out, summ, before = _prior(d)

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(report, "write_report", interrupted)
    code, err = run(["reconstruct", handmade, "-o", out, "--summary", summ,
                     "--report", d / "rep"], capsys)
    assert code == 130, err
    assert digest(d) == before
    assert not leftovers(d) and not (d / "rep").exists()


def test_publication_renames_all_or_none_with_signals_deferred(tmp_path):
    """A signal arriving between the renames waits until the last one is done (all new)."""
    import signal

    from flightrecon.export import atomic

    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    a.write_text("old a")
    b.write_text("old b")
    got = []
    previous = signal.signal(signal.SIGTERM, lambda s, f: got.append("raised"))
    real = atomic._move_into_place
    calls = []

    def move(src, dst, kind):
        real(src, dst, kind)
        calls.append(dst)
        if len(calls) == 1:
            os.kill(os.getpid(), signal.SIGTERM)
            assert not got      # held back while publishing

    try:
        atomic._move_into_place = move
        with Publication() as pub:
            pub.file(a).write_text("new a")
            pub.file(b).write_text("new b")
            pub.commit()
        assert got == ["raised"]     # delivered once the publication is complete
    finally:
        atomic._move_into_place = real
        signal.signal(signal.SIGTERM, previous)
    assert a.read_text() == "new a" and b.read_text() == "new b"
    assert not leftovers(tmp_path)


def test_kill_during_publication_is_rolled_forward(tmp_path):
    """SIGKILL between the renames (nothing can catch it): the next run's sweep finds the
    journal and completes the publication, so the pair ends up all new."""
    a, b = tmp_path / "a.txt", tmp_path / "b.txt"
    a.write_text("old a")
    b.write_text("old b")
    script = textwrap.dedent(f"""
        import os, signal
        from pathlib import Path
        import flightrecon.export.atomic as atomic
        real = atomic._move_into_place
        def move(src, dst, kind):
            real(src, dst, kind)
            os.kill(os.getpid(), signal.SIGKILL)
        atomic._move_into_place = move
        with atomic.Publication() as pub:
            pub.file(Path({str(a)!r})).write_text("new a")
            pub.file(Path({str(b)!r})).write_text("new b")
            pub.commit()
    """)
    p = subprocess.run([sys.executable, "-c", script], cwd=ROOT, capture_output=True,
                       env={**os.environ, "PYTHONPATH": str(ROOT)}, timeout=120, check=False)
    assert p.returncode == -9, p.stderr.decode()
    assert a.read_text() == "new a" and b.read_text() == "old b"   # half done
    removed = sweep_leftovers(tmp_path)
    assert removed
    assert a.read_text() == "new a" and b.read_text() == "new b"
    assert not leftovers(tmp_path)


def test_sweep_keeps_the_staging_of_a_running_process(tmp_path):
    """Two runs writing into one folder: the sweep of one does not remove the other's
    staged outputs (the old sweep removed every temporary file, whoever's)."""
    with Publication() as pub:
        pub.file(tmp_path / "x.txt").write_text("staged")
        assert sweep_leftovers(tmp_path) == []          # ours, and we are alive
        assert leftovers(tmp_path)
        pub.commit()
    assert (tmp_path / "x.txt").read_text() == "staged"
    dead = tmp_path / f".y.txt{TMP_TAG}999999999-abcd"
    dead.write_text("left by a killed run")
    assert sweep_leftovers(tmp_path) == [dead]


def test_store_is_written_with_the_outputs_not_before(handmade, capsys, monkeypatch):
    """The coefficient store is recorded in the same deferred block as the renames: an
    interrupt while staging leaves no record and no output."""
    from flightrecon.export import writers

    d = handmade.parent
    text = (d / "handmade.meta.toml").read_text()
    if "[arrival]" not in text:
        (d / "handmade.meta.toml").write_text(text + "\n[arrival]\nlat_deg = 40.4738\n"
                                              "lon_deg = 50.0424\nelev_m = 3.0\n")

    def interrupted(*a, **k):
        raise KeyboardInterrupt

    monkeypatch.setattr(writers, "write_track", interrupted)
    store = d / "s.sqlite"
    code, err = run(["reconstruct", handmade, "-o", d / "r.parquet", "--store", store,
                     "--aircraft", "HM1"], capsys)
    assert code == 130, err
    assert not store.exists() and not (d / "r.parquet").exists()
    assert not leftovers(d)


# ------------------------------------------------------------------ signals (subprocesses)

SIGNAL_DELAYS_S = (0.3, 2.0, 3.5, 5.0)


def _reconstruct_process(log: Path, out: Path, report: Path | None = None):
    cmd = [sys.executable, "-m", "flightrecon", "--quiet", "reconstruct", str(log),
           "-o", str(out), "--summary", str(out.with_suffix(".json"))]
    if report is not None:
        cmd += ["--report", str(report)]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT,
                            env={**os.environ, "PYTHONPATH": str(ROOT)})


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
@pytest.mark.parametrize("signame", ["SIGTERM", "SIGHUP"])
@pytest.mark.parametrize("delay_s", SIGNAL_DELAYS_S)
def test_sigterm_is_handled_like_sigint(handmade, delay_s, signame):
    """SIGTERM (what `timeout` and batch systems send) had no handler and left the temporary
    file behind.  Now: exit 128 + signal (143 for SIGTERM), the old result and summary both
    kept or both replaced, no temporary file or staging folder left."""
    import signal
    import time

    d = handmade.parent
    out = d / "r.parquet"
    pd.DataFrame({"t_s": [0.0], "north_m": [0.0], "east_m": [0.0]}).to_parquet(out)
    out.with_suffix(".json").write_text('{"old": true}')
    old = digest(d)
    sig = getattr(signal, signame)
    p = _reconstruct_process(handmade, out, d / "rep")
    time.sleep(delay_s)
    p.send_signal(sig)
    _, err = p.communicate(timeout=600)
    err = err.decode()
    # finished first (0), handled (128 + n), or killed while the interpreter was still
    # starting, before any output existed (-n)
    assert p.returncode in (0, 128 + sig, -sig), err
    assert "Traceback" not in err
    assert not leftovers(d)
    new = digest(d)
    changed = {k for k in ("r.parquet", "r.json") if new.get(k) != old.get(k)}
    assert changed in (set(), {"r.parquet", "r.json"}), (changed, p.returncode)
    if p.returncode == 0:
        assert (d / "rep" / "report.html").exists()


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals")
@pytest.mark.parametrize("delay_s", (2.0, 5.0, 8.0))
def test_sigterm_keeps_the_store_and_the_outputs_together(tmp_path, delay_s):
    """The store keeps its transactional guarantees and goes with the outputs: after a
    SIGTERM at any moment the store is intact, and it holds the flight's record exactly when
    the new result and summary were published."""
    import signal
    import sqlite3
    import time

    for f in ("circuit.parquet", "circuit.meta.toml"):
        shutil.copy(SAMPLES / f, tmp_path / f)
    out, store = tmp_path / "r.parquet", tmp_path / "s.sqlite"
    cmd = [sys.executable, "-m", "flightrecon", "--quiet", "reconstruct",
           str(tmp_path / "circuit.parquet"), "-o", str(out), "--store", str(store)]
    p = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, cwd=ROOT,
                         env={**os.environ, "PYTHONPATH": str(ROOT)})
    time.sleep(delay_s)
    p.send_signal(signal.SIGTERM)
    _, err = p.communicate(timeout=600)
    assert p.returncode in (0, 143, -signal.SIGTERM), err.decode()
    assert not leftovers(tmp_path)
    published = out.exists()
    assert published == (tmp_path / "r.summary.json").exists()
    rows = 0
    if store.exists():
        con = sqlite3.connect(store)
        try:
            assert con.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
            tables = [r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE "
                                                "type='table'")]
            for t in tables:
                if t.startswith("flights"):   # one row per recorded flight
                    rows += con.execute(f"SELECT COUNT(*) FROM {t}").fetchone()[0]
        finally:
            con.close()
    if published:
        summary = json.loads((tmp_path / "r.summary.json").read_text())
        assert summary["stored_coefficients"]["recorded"] is True
        assert rows >= 1
    else:
        assert rows == 0


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX pipes")
def test_closed_output_pipe_is_not_an_internal_error():
    """`flightrecon info LOG | head -1` could end with exit 1, the internal-error code (click's
    broken-pipe path, taken when the output is flushed by click); now 0, silently, however
    the pipe breaks (the console entry, buffered output; docs/exit-codes.md)."""
    for _ in range(4):
        p = subprocess.Popen([sys.executable, "-m", "flightrecon", "info",
                              str(SAMPLES / "circuit.parquet")], stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, cwd=ROOT,
                             env={**os.environ, "PYTHONPATH": str(ROOT)})
        p.stdout.readline()
        p.stdout.close()
        err = p.stderr.read().decode()
        p.wait(timeout=120)
        assert p.returncode == 0, err
        assert "Traceback" not in err and "error" not in err


def test_plot_report_folder_is_checked_against_the_truth_and_the_result(tmp_path, capsys):
    """`plot` reads a result, its summary and a truth file: a report folder whose figures
    would replace one of them is refused before any work (exit 9)."""
    shutil.copy(SAMPLES / "circuit.truth.parquet", tmp_path / "wind.png")
    pd.DataFrame({"t_s": [0.0, 1.0], "north_m": [0.0, 1.0],
                  "east_m": [0.0, 1.0]}).to_parquet(tmp_path / "r.parquet")
    before = digest(tmp_path)
    code, err = run(["plot", tmp_path / "r.parquet", "-o", tmp_path,
                     "--truth", tmp_path / "wind.png"], capsys)
    assert code == 9, err
    assert "wind.png" in err and "truth" in err
    assert digest(tmp_path) == before


def test_signal_disguised_as_import_error_is_an_interrupt(monkeypatch, capsys):
    """A SIGTERM that lands while a C extension is being imported (a cold kernel cache, a fresh
    CI machine) surfaces as "ImportError: initialization failed": it was reported as an internal
    error, exit 1.  The handler records the signal, so the run ends as interrupted, 143."""
    import signal

    from flightrecon.cli import main as cli_main

    def interrupted_import(*args, **kwargs):
        cli_main._first_signal.append(int(signal.SIGTERM))
        raise ImportError("initialization failed")

    monkeypatch.setattr(cli_main, "_first_signal", [])
    monkeypatch.setattr(cli_main, "_handlers_installed", [])
    monkeypatch.setattr(cli_main.cli, "main", interrupted_import)
    with pytest.raises(SystemExit) as exc:
        cli_main._run(["info", "x"], debug=False)
    assert exc.value.code == 128 + int(signal.SIGTERM)
    err = capsys.readouterr().err
    assert "interrupted (SIGTERM)" in err and "internal error" not in err
