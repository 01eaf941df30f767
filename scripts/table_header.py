"""The first line of every table a study script writes under ``docs/``: the command that wrote it.

A table in ``docs/tables/`` is only as good as the means to regenerate it, so each study script
starts its Markdown tables with :func:`header`, the command line it was run with (its own
options, as typed after the script's name), e.g.::

    Regenerate: `python scripts/mc_arms.py --runs 200`

The scripts import it from beside themselves (``scripts/`` is first on ``sys.path`` when a
script is run as ``python scripts/<name>.py``).
"""

from __future__ import annotations

import shlex
import sys
from collections.abc import Sequence
from pathlib import Path


def command_line(script: str | None = None, argv: Sequence[str] | None = None) -> str:
    """``python scripts/<script's file name> <argv>``: the script run (``sys.argv[0]``, so a
    table written by a helper of another script names the script that was run) and its
    options (``sys.argv[1:]``) unless given."""
    name = Path(sys.argv[0] if script is None else script).name
    args = list(sys.argv[1:] if argv is None else argv)
    return "python " + shlex.join([f"scripts/{name}", *args])


def header(script: str | None = None, argv: Sequence[str] | None = None) -> str:
    """The table's first line and a blank line: ``Regenerate: `<command line>```."""
    return f"Regenerate: `{command_line(script, argv)}`\n\n"
