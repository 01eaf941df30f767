"""The command line as the tests call it: ``run_cli([...])`` returns the exit code."""

from __future__ import annotations

from flightrecon.cli.main import main


def run_cli(args: list[str]) -> int:
    """Run ``flightrecon --quiet ARGS`` in-process and return its exit code."""
    try:
        main(["--quiet", *args])
    except SystemExit as exc:
        return int(exc.code or 0)
    return 0
