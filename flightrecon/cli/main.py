"""``flightrecon`` command line: a thin layer over the library API.

Each subcommand lives in its own module under :mod:`flightrecon.cli` and registers itself on
the :data:`cli` group; heavy imports happen inside the commands.  Errors of the project's
hierarchy are printed as ``error: ...`` with their exit code; ``--debug`` shows the traceback.
"""

from __future__ import annotations

import importlib
import sys

import click

from flightrecon import __version__
from flightrecon.errors import FlightReconError

#: subcommand modules; each defines ``command`` (a click command or group)
COMMAND_MODULES = (
    "flightrecon.cli.info",
    "flightrecon.cli.clean",
    "flightrecon.cli.simulate",
    "flightrecon.cli.reconstruct",
    "flightrecon.cli.coeffs",
    "flightrecon.cli.export",
    "flightrecon.cli.plot",
    "flightrecon.cli.batch",
)


class _PipeClosed(Exception):
    """The reader of our standard output went away (``flightrecon info LOG | head``)."""


class _Group(click.Group):
    def invoke(self, ctx: click.Context):
        try:
            return super().invoke(ctx)
        except BrokenPipeError as exc:  # before click turns it into a silent exit 1
            raise _PipeClosed() from exc


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="flightrecon")
@click.option("--debug", is_flag=True, help="Show the full traceback on errors.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bars or chatter (for scripts).")
@click.pass_context
def cli(ctx: click.Context, debug: bool, quiet: bool) -> None:
    """Reconstruct an aircraft's trajectory from its recorded flight data."""
    ctx.ensure_object(dict)
    ctx.obj["debug"] = debug
    ctx.obj["quiet"] = quiet


for _name in COMMAND_MODULES:
    try:
        _mod = importlib.import_module(_name)
    except ModuleNotFoundError as exc:  # a command module not yet written in this checkout
        if exc.name != _name:
            raise
        continue
    cli.add_command(_mod.command)


def _thp_stalls_on_madvise() -> bool:
    """True where the kernel compacts memory synchronously for regions that asked for
    transparent huge pages (THP ``defrag`` mode ``always`` or ``madvise``)."""
    try:
        text = open("/sys/kernel/mm/transparent_hugepage/defrag", encoding="ascii").read()
    except OSError:
        return False
    chosen = text[text.find("[") + 1:text.find("]")] if "[" in text else ""
    return chosen in ("always", "madvise")


def _tune_memory() -> None:
    """Process-level memory settings for a reconstruction (the library never changes them).

    * glibc keeps and reuses freed memory instead of returning it to the OS: a
      reconstruction allocates and frees arrays of tens to hundreds of megabytes stage after
      stage, and by default each large block is mapped fresh and unmapped when freed, so every
      stage pays the kernel's page faults again. Blocks up to 32 MB (glibc's ceiling for this
      setting) then come from the heap, and the heap is not trimmed. Measured on the 10-hour
      benchmark flight: minor faults 240-260k -> 178k, about 1 s less system time, peak memory
      1.43 -> 1.49 GB.
    * numpy asks for transparent huge pages for arrays of 4 MB and more; where the kernel then
      compacts memory synchronously on first touch (THP defrag ``always``/``madvise``, as on
      our 2-core VMs) that costs far more than it saves: the estimators on the 10-hour flight
      spent 2.3-2.6 s in the kernel with it and 0.4-0.5 s without, ingest and cleaning
      1.7-1.9 s against 1.1-1.2 s (same process, warm kernels). It is turned off there.

    Neither changes a result. Skipped where not Linux/glibc or where numpy lacks the switch.
    """
    if not sys.platform.startswith("linux"):
        return
    try:
        import ctypes

        libc = ctypes.CDLL("libc.so.6")
        m_trim_threshold, m_mmap_threshold = -1, -3
        libc.mallopt(m_mmap_threshold, 32 * 1024 * 1024)
        libc.mallopt(m_trim_threshold, 1 << 30)
    except (OSError, AttributeError):  # not glibc
        pass
    if _thp_stalls_on_madvise():
        try:
            from numpy._core.multiarray import _set_madvise_hugepage
        except ImportError:  # numpy < 2
            try:
                from numpy.core.multiarray import _set_madvise_hugepage
            except ImportError:
                return
        _set_madvise_hugepage(False)


def main(argv: list[str] | None = None) -> None:
    """Console entry point: run the CLI and map project errors to exit codes."""
    _tune_memory()
    debug = "--debug" in (argv if argv is not None else sys.argv[1:])
    try:
        # with standalone_mode=False click returns a ctx.exit(code) as the code
        rv = cli.main(args=argv, prog_name="flightrecon", standalone_mode=False)
    except FlightReconError as exc:
        if debug:
            raise
        click.echo(f"error: {exc}", err=True)
        sys.exit(exc.exit_code)
    except _PipeClosed:
        # not an error: the reader stopped reading; what it read is complete up to there.
        # Point stdout at /dev/null so the interpreter's final flush does not fail again.
        import os

        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        sys.exit(0)
    except click.exceptions.Abort:
        click.echo("interrupted", err=True)
        sys.exit(130)
    except KeyboardInterrupt:
        click.echo("interrupted", err=True)
        sys.exit(130)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except Exception as exc:  # noqa: BLE001 - last resort: no traceback without --debug
        if debug:
            raise
        click.echo(f"internal error: {type(exc).__name__}: {exc} (rerun with --debug)", err=True)
        sys.exit(1)
    sys.exit(rv if isinstance(rv, int) else 0)


if __name__ == "__main__":  # pragma: no cover
    main()
