"""The CLI's progress display and first-run compile notice."""

from __future__ import annotations

import numba
import pytest

from flightrecon.cli.progress import COMPILE_NOTICE, compile_notice, stage_progress


def test_compile_notice_printed_once_when_numba_compiles(capsys):
    @numba.njit(cache=False)
    def f(x):
        return x + 1

    @numba.njit(cache=False)
    def g(x):
        return x * 2

    with compile_notice(quiet=False):
        assert f(1) == 2 and g(2) == 4
    err = capsys.readouterr().err
    assert err.count(COMPILE_NOTICE) == 1


def test_no_notice_when_nothing_compiles_or_quiet(capsys):
    @numba.njit(cache=False)
    def h(x):
        return x - 1

    h(1)  # compiled before the notice is armed
    with compile_notice(quiet=False):
        assert h(3) == 2
    with compile_notice(quiet=True):
        @numba.njit(cache=False)
        def k(x):
            return x

        k(1)
    assert COMPILE_NOTICE not in capsys.readouterr().err


def test_stage_progress_is_silent_off_a_terminal(capsys):
    # pytest captures stderr: not a terminal, so no bar garbage in logs
    with stage_progress(False, ["a", "b"]) as stage:
        stage("a")
        stage("b")
        stage("c")  # an unexpected stage is fine
    assert capsys.readouterr().err == ""


@pytest.mark.parametrize("quiet", [False, True])
def test_stage_progress_on_a_terminal(monkeypatch, quiet, capsys):
    import sys

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True, raising=False)
    with stage_progress(quiet, ["ingest", "cleaning"], "reconstruct") as stage:
        stage("ingest")
        stage("cleaning")
        stage("export")
    err = capsys.readouterr().err
    assert ("reconstruct: export" in err) is (not quiet)
