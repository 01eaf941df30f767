"""The console entry point's process settings (flightrecon/cli/entry.py): the kernels compile at
LLVM level 1 unless the environment chose a level, and numba reads it at its import."""

from __future__ import annotations

import os
import subprocess
import sys


def _opt_seen(env_opt: str | None) -> str:
    """numba's optimisation level in a fresh interpreter that ran the entry point's process
    settings and then imported numba."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_OPT"}
    if env_opt is not None:
        env["NUMBA_OPT"] = env_opt
    code = ("from flightrecon.cli import entry\n"
            "entry.process_settings()\n"
            "import numba\n"
            "print(int(numba.config.OPT))\n")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True)
    return out.stdout.strip().splitlines()[-1]


def test_the_cli_compiles_at_level_1_by_default():
    assert _opt_seen(None) == "1"


def test_a_level_set_in_the_environment_wins():
    assert _opt_seen("3") == "3"


def test_the_command_leaves_with_its_exit_code_and_its_output(tmp_path):
    """The fast exit (os._exit after the command) keeps the exit code and everything written
    to stdout and stderr; with FLIGHTRECON_FAST_EXIT=0 the interpreter exits as usual, with
    the same code and output."""
    missing = tmp_path / "missing.csv"
    for fast in ("", "0"):
        env = dict(os.environ, FLIGHTRECON_FAST_EXIT=fast)
        ok = subprocess.run([sys.executable, "-m", "flightrecon", "--help"], env=env,
                            capture_output=True, text=True)
        assert ok.returncode == 0 and "reconstruct" in ok.stdout
        bad = subprocess.run([sys.executable, "-m", "flightrecon", "info", str(missing)],
                             env=env, capture_output=True, text=True)
        assert bad.returncode not in (0, None) and "missing.csv" in bad.stderr


def test_no_fast_exit_under_a_profiler():
    """Under a profiler (cProfile writes its results at exit) the process exits as usual:
    leave() returns instead of ending it."""
    import cProfile

    from flightrecon.cli import entry

    prof = cProfile.Profile()
    prof.enable()
    try:
        entry.leave(0)          # would end the test process if it did not return
    finally:
        prof.disable()
    entry.leave("not an int")   # a message as the code: the usual exit prints it


def test_no_fast_exit_after_a_child_process(monkeypatch):
    """A first run that started a child process (pipeline/coldstart.py) exits the usual way, so
    that the interpreter releases its queues' semaphores (else the resource tracker warns of
    leaked ones): leave() returns."""
    from flightrecon.cli import entry
    from flightrecon.pipeline import coldstart

    monkeypatch.setattr(coldstart, "_started", [1])
    assert coldstart.child_was_started()
    entry.leave(0)              # would end the test process if it did not return
