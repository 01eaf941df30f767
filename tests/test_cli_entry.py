"""The console entry point's process settings (flightrecon/cli/entry.py): the kernels compile at
LLVM level 1 unless the environment chose a level, and numba reads it at its import."""

from __future__ import annotations

import os
import subprocess
import sys


def _opt_seen(env_opt: str | None) -> str:
    """numba's optimisation level in a fresh interpreter that ran the entry point's setup (the
    CLI's ``--help``, which exits 0) and then imported numba."""
    env = {k: v for k, v in os.environ.items() if k != "NUMBA_OPT"}
    if env_opt is not None:
        env["NUMBA_OPT"] = env_opt
    code = ("import sys\n"
            "from flightrecon.cli import entry\n"
            "sys.argv = ['flightrecon', '--help']\n"
            "try:\n"
            "    entry.run()\n"
            "except SystemExit as e:\n"
            "    assert not e.code, e.code\n"
            "import numba\n"
            "print(int(numba.config.OPT))\n")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True, text=True,
                         check=True)
    return out.stdout.strip().splitlines()[-1]


def test_the_cli_compiles_at_level_1_by_default():
    assert _opt_seen(None) == "1"


def test_a_level_set_in_the_environment_wins():
    assert _opt_seen("3") == "3"
