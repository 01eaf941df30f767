"""The README's console examples run as written on the shipped samples.

Every ```console block of README.md is one example: its ``$ `` lines are the commands, run in
order in a scratch copy of ``sample_logs/`` (the commands write their results beside the logs),
with ``flightrecon`` as ``python -m flightrecon`` and ``python`` as this interpreter, from a
folder where ``scripts/`` is the repository's. Each must exit 0. Where the README shows what a
command of ``scripts/`` prints (the errors of a result against its reference), the lines shown
must be what it prints: they are the README's figures. The install and test lines (```bash
blocks) are not run here.
"""

from __future__ import annotations

import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
#: an example of more commands than this is marked slow: the real export's six commands took
#: 93 s on the 2-core machine under load (the circuit's two: 31 s)
FAST_COMMANDS = 2


def console_blocks(text: str) -> list[list[tuple[str, list[str]]]]:
    """Each ```console block as a list of (command, output lines shown under it)."""
    blocks = []
    for body in re.findall(r"^```console\n(.*?)^```", text, flags=re.M | re.S):
        block: list[tuple[str, list[str]]] = []
        for line in body.splitlines():
            if line.startswith("$ "):
                block.append((line[2:].strip(), []))
            elif block and line.strip():
                block[-1][1].append(line.strip())
        blocks.append(block)
    return blocks


def argv(command: str) -> list[str]:
    """The command as an argument vector for this interpreter."""
    words = shlex.split(command)
    if words[0] == "flightrecon":
        return [sys.executable, "-m", "flightrecon", *words[1:]]
    if words[0] == "python":
        return [sys.executable, *words[1:]]
    raise AssertionError(f"README console command of an unknown program: {command}")


BLOCKS = console_blocks(README.read_text(encoding="utf-8"))


def test_the_readme_has_console_examples() -> None:
    """Guards the extraction itself: a README whose examples were all lost (or whose fences
    changed) would otherwise pass the test below vacuously."""
    assert len(BLOCKS) >= 2
    assert all(block for block in BLOCKS)
    assert any(cmd.startswith("flightrecon reconstruct sample_logs/g1000_sr22")
               for block in BLOCKS for cmd, _ in block)


@pytest.mark.parametrize("index", [
    pytest.param(i, marks=[pytest.mark.slow] if len(block) > FAST_COMMANDS else [])
    for i, block in enumerate(BLOCKS)])
def test_readme_console_example_runs_as_written(index: int, tmp_path: Path) -> None:
    """Each README example exits 0 on the shipped samples; the figures it shows for a script's
    output are the script's (a README that promised numbers the tool no longer gives fails)."""
    shutil.copytree(ROOT / "sample_logs", tmp_path / "sample_logs",
                    ignore=shutil.ignore_patterns("*.recon.*", "*.report"))
    (tmp_path / "scripts").symlink_to(ROOT / "scripts", target_is_directory=True)
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        p for p in (str(ROOT), os.environ.get("PYTHONPATH", "")) if p))
    for command, shown in BLOCKS[index]:
        done = subprocess.run(argv(command), cwd=tmp_path, env=env, capture_output=True,
                              text=True, timeout=600)
        assert done.returncode == 0, f"{command}\nexit {done.returncode}\n{done.stderr[-2000:]}"
        if command.startswith("python scripts/"):
            printed = [line.strip() for line in done.stdout.splitlines()]
            for line in shown:
                assert line in printed, f"{command}: README shows {line!r}, printed {printed}"
