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


def run_cli_stderr(args: list, capsys) -> tuple[int, str]:
    """Run ``flightrecon --quiet ARGS`` in-process; return its exit code and what it wrote on
    stderr (``capsys`` of the calling test)."""
    code = run_cli([str(a) for a in args])
    return code, capsys.readouterr().err
