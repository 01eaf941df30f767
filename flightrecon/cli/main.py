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


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
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


def main(argv: list[str] | None = None) -> None:
    """Console entry point: run the CLI and map project errors to exit codes."""
    debug = "--debug" in (argv if argv is not None else sys.argv[1:])
    try:
        # with standalone_mode=False click returns a ctx.exit(code) as the code
        rv = cli.main(args=argv, prog_name="flightrecon", standalone_mode=False)
    except FlightReconError as exc:
        if debug:
            raise
        click.echo(f"error: {exc}", err=True)
        sys.exit(exc.exit_code)
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
