"""``flightrecon`` command line: a thin layer over the library API.

Each subcommand lives in its own module under :mod:`flightrecon.cli` and registers itself on
the :data:`cli` group; heavy imports happen inside the commands.  Errors of the project's
hierarchy are printed as ``error: ...`` with their exit code; ``--debug`` shows the traceback.
"""

from __future__ import annotations

import contextlib
import errno
import importlib
import os
import signal
import sys
import threading
from typing import Any

import click

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
        from flightrecon.cli.console import console_warnings

        try:
            # the tool's warnings as console lines, every command; none with --quiet
            with console_warnings(ctx.ensure_object(dict)):
                return super().invoke(ctx)
        except BrokenPipeError as exc:  # before click turns it into a silent exit 1
            raise _PipeClosed() from exc


def _print_version(ctx: click.Context, param: click.Parameter, value: bool) -> None:
    """``--version``: the installed version, looked up only when asked for."""
    if not value or ctx.resilient_parsing:
        return
    from flightrecon import __version__

    click.echo(f"flightrecon, version {__version__}")
    ctx.exit()


#: the options of the whole command line: (name, flags, help); accepted before the subcommand
#: and after it (:func:`add_console_options`), with the same meaning
CONSOLE_OPTIONS = (
    ("debug", ("--debug",), "Show the full traceback on errors."),
    ("quiet", ("--quiet", "-q"),
     "No progress bars, chatter or warnings on the console (for scripts); reconstruct and "
     "clean keep their warnings in the summary and the cleaning report."),
    ("verbose", ("--verbose", "-v"),
     "Print each stage as it starts, with the time elapsed (also when the output is not a "
     "terminal)."),
)


def _set_console_option(ctx: click.Context, param: click.Parameter, value: bool) -> None:
    """Record a console option given after a subcommand in the run's shared settings (the
    ``obj`` every context of the run shares with the root); a flag is never unset there."""
    if value and param.name:
        ctx.ensure_object(dict)[param.name] = True
        _check_quiet_or_verbose(ctx)


def _check_quiet_or_verbose(ctx: click.Context) -> None:
    """``--quiet`` and ``--verbose`` together: a usage error (exit 2)."""
    if ctx.obj.get("quiet") and ctx.obj.get("verbose"):
        raise click.UsageError("--quiet and --verbose exclude each other", ctx=ctx)


def add_console_options(cmd: click.Command) -> None:
    """Give ``cmd`` and every subcommand under it the options of :data:`CONSOLE_OPTIONS`, so
    that ``flightrecon reconstruct LOG --quiet`` means what ``flightrecon --quiet reconstruct
    LOG`` means."""
    for name, flags, text in CONSOLE_OPTIONS:
        if not any(p.name == name for p in cmd.params):
            cmd.params.append(click.Option([name, *flags], is_flag=True, help=text,
                                           show_default=False, expose_value=False,
                                           callback=_set_console_option))
    if isinstance(cmd, click.Group):
        for sub in cmd.commands.values():
            add_console_options(sub)


@click.group(cls=_Group, context_settings={"help_option_names": ["-h", "--help"]})
@click.option("--version", is_flag=True, expose_value=False, is_eager=True,
              callback=_print_version, help="Show the version and exit.")
@click.option(*CONSOLE_OPTIONS[0][1], is_flag=True, help=CONSOLE_OPTIONS[0][2])
@click.option(*CONSOLE_OPTIONS[1][1], is_flag=True, help=CONSOLE_OPTIONS[1][2])
@click.option(*CONSOLE_OPTIONS[2][1], is_flag=True, help=CONSOLE_OPTIONS[2][2])
@click.pass_context
def cli(ctx: click.Context, debug: bool, quiet: bool, verbose: bool) -> None:
    """Reconstruct an aircraft's trajectory from its recorded flight data.

    --debug, --quiet and --verbose may also follow the subcommand
    (flightrecon reconstruct LOG --quiet)."""
    ctx.ensure_object(dict)
    ctx.obj.update(debug=debug, quiet=quiet, verbose=verbose)
    _check_quiet_or_verbose(ctx)


for _name in COMMAND_MODULES:
    try:
        _mod = importlib.import_module(_name)
    except ModuleNotFoundError as exc:  # a command module not yet written in this checkout
        if exc.name != _name:
            raise
        continue
    add_console_options(_mod.command)
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


#: blocks from this size up are mapped fresh and unmapped when freed (:func:`_tune_memory`)
MMAP_THRESHOLD_BYTES = 8 * 1024 * 1024


def _tune_memory() -> None:
    """Process-level memory settings for a reconstruction (the library never changes them).

    * glibc keeps and reuses freed memory instead of returning it to the OS: a
      reconstruction allocates and frees arrays of tens to hundreds of megabytes stage after
      stage, and by default each large block is mapped fresh and unmapped when freed, so every
      stage pays the kernel's page faults again. Blocks below ``MMAP_THRESHOLD_BYTES`` then
      come from the heap, and the heap is not trimmed. Measured on the 10-hour benchmark
      flight with 32 MB (glibc's ceiling for this setting): minor faults 240-260k -> 178k,
      about 1 s less system time, peak memory 1.43 -> 1.49 GB. With 8 MB the blocks of a
      whole flight's column and larger (a 16 Hz, 10-hour column of pairs is 9.2 MB) are
      mapped and returned again, while the many smaller ones are still reused: peak 998 ->
      952 MiB, wall 0.95 (4 alternating pairs; docs/performance.md). With 4 MB every 16 Hz
      column is mapped: 945 MiB, but 1.15 x the wall time.
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
        libc.mallopt(m_mmap_threshold, MMAP_THRESHOLD_BYTES)
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


class Interrupted(KeyboardInterrupt):
    """A catchable signal that ends the run (SIGTERM, SIGHUP, ...; SIGINT as well).

    A subclass of :class:`KeyboardInterrupt`, so every clean-up written for Ctrl-C (temporary
    files removed, staged outputs discarded, store transaction rolled back) runs for it too.
    """

    def __init__(self, signum: int) -> None:
        super().__init__(signal.Signals(signum).name)
        self.signum = signum


_first_signal: list[int] = []


def _on_signal(signum: int, frame) -> None:
    """Raise :class:`Interrupted` in the main thread; while outputs are being published the
    signal waits (:func:`flightrecon.export.atomic.deferred_signals`); a second signal while
    the first one's clean-up runs is ignored, so the clean-up is not cut short.

    A signal that lands on the import machinery's own frames (a module being imported at C
    level, e.g. by a C callback) is not raised there, where the C caller would print it as a
    bare traceback and go on: it is delivered again 50 ms later, once the import has moved
    on (:func:`_redeliver`)."""
    if _first_signal:
        return
    if frame is not None and frame.f_code.co_filename.startswith("<frozen importlib"):
        _redeliver(signum)
        return
    _first_signal.append(signum)
    raise Interrupted(signum)


def _on_unraisable(unraisable: Any) -> None:
    """An :class:`Interrupted` raised while the main thread ran a C callback (numba's LLVM
    object cache, while a kernel compiles) is swallowed there and printed as "Exception
    ignored ... Traceback", and the run would go on: instead it is delivered again, silently,
    once the callback has returned; anything else goes to the previous hook."""
    exc = unraisable.exc_value
    if isinstance(exc, Interrupted):
        _first_signal.clear()
        _redeliver(exc.signum)
        return
    _previous_unraisablehook[0](unraisable)


_previous_unraisablehook: list[Any] = [sys.unraisablehook]


def _redeliver(signum: int, delay_s: float = 0.05) -> None:
    """Send ``signum`` to the main thread again after ``delay_s`` (a daemon timer)."""
    timer = threading.Timer(delay_s, signal.pthread_kill,
                            (threading.main_thread().ident, signum))
    timer.daemon = True
    timer.start()


def install_signal_handlers() -> dict[int, Any]:
    """Handle every catchable terminating signal like SIGINT (:data:`CATCHABLE_SIGNALS`);
    signals the caller chose to ignore (``nohup``: SIGHUP) stay ignored.  Returns the
    previous handlers."""
    from flightrecon.export.atomic import CATCHABLE_SIGNALS

    previous: dict[int, Any] = {}
    if threading.current_thread() is not threading.main_thread():
        return previous
    if sys.unraisablehook is not _on_unraisable:
        _previous_unraisablehook[0] = sys.unraisablehook
        sys.unraisablehook = _on_unraisable
    for s in CATCHABLE_SIGNALS:
        try:
            h = signal.getsignal(s)
            if h == signal.SIG_IGN:
                continue
            previous[s] = signal.signal(s, _on_signal)
        except (OSError, ValueError):
            pass
    return previous


def _signal_exit_code(exc: BaseException) -> int:
    """128 + the signal number (SIGINT 130, SIGTERM 143) for an interrupt."""
    seen: set[int] = set()
    e: BaseException | None = exc
    while e is not None and id(e) not in seen:
        seen.add(id(e))
        if isinstance(e, Interrupted):
            return 128 + e.signum
        e = e.__cause__ or e.__context__
    if _first_signal:  # the Interrupted was swallowed on the way (see _run)
        return 128 + _first_signal[0]
    return 128 + int(signal.SIGINT)


def _exit_interrupted(exc: BaseException) -> None:
    """Report an interrupt and end the process now: the estimators' worker threads are not
    waited for (nothing they hold is an output; every temporary file was removed on the way
    out)."""
    code = _signal_exit_code(exc)
    name = signal.Signals(code - 128).name if code - 128 in signal.Signals._value2member_map_ \
        else "signal"
    click.echo("interrupted" if code == 130 else f"interrupted ({name})", err=True)
    if _handlers_installed:
        with contextlib.suppress(Exception):
            sys.stdout.flush()
            sys.stderr.flush()
        os._exit(code)
    sys.exit(code)


_handlers_installed: list[int] = []


def main(argv: list[str] | None = None) -> None:
    """Console entry point: run the CLI and map project errors to exit codes."""
    _tune_memory()
    debug = "--debug" in (argv if argv is not None else sys.argv[1:])
    previous = install_signal_handlers() if argv is None else {}
    if previous:
        _handlers_installed.append(1)
    try:
        try:
            _run(argv, debug)
        except SystemExit:
            _flush_stdout()
            raise
    finally:
        for s, h in previous.items():
            with contextlib.suppress(OSError, ValueError, TypeError):
                signal.signal(s, h)
        if previous:
            sys.unraisablehook = _previous_unraisablehook[0]
        _handlers_installed.clear()


def _flush_stdout() -> None:
    """Flush the output now: a reader that closed the pipe early (``| head``) ends the run
    silently with exit 0 (as :class:`_PipeClosed`; docs/exit-codes.md), instead of a failed
    flush at exit."""
    try:
        sys.stdout.flush()
    except BrokenPipeError:
        with contextlib.suppress(OSError, ValueError):
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
        sys.exit(0)
    except (OSError, ValueError):
        pass


def _run(argv: list[str] | None, debug: bool) -> None:
    try:
        # with standalone_mode=False click returns a ctx.exit(code) as the code
        rv = cli.main(args=argv, prog_name="flightrecon", standalone_mode=False)
    except FlightReconError as exc:
        if debug:
            raise
        click.echo(f"error: {exc}", err=True)
        sys.exit(exc.exit_code)
    except _PipeClosed:
        # not an error: the reader stopped reading (``| head``); what it read is complete up
        # to there: exit 0, silently, as _flush_stdout. Point stdout at /dev/null so the
        # interpreter's final flush does not fail again.
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
        sys.exit(0)
    except click.exceptions.Abort as exc:
        _exit_interrupted(exc)
    except KeyboardInterrupt as exc:
        _exit_interrupted(exc)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except SystemExit as exc:
        # a pipe closed where click saw it first: click ends such a run with exit 1 (the code
        # of an internal error) and marks it by wrapping sys.stdout; like _PipeClosed, 0
        ctx = exc.__context__
        epipe = isinstance(ctx, OSError) and ctx.errno == errno.EPIPE
        if exc.code == 1 and (epipe or type(sys.stdout).__name__ == "_PacifyFlushWrapper"):
            sys.exit(0)
        raise
    except Exception as exc:
        if _first_signal:
            # a signal arrived and its Interrupted surfaced disguised: raised inside a C
            # extension's import it becomes "ImportError: initialization failed", inside
            # numba's cache loading another error; the run was interrupted, not broken
            _exit_interrupted(exc)
        if debug:
            raise
        click.echo(f"internal error: {type(exc).__name__}: {exc} (rerun with --debug)", err=True)
        sys.exit(1)
    sys.exit(rv if isinstance(rv, int) else 0)


if __name__ == "__main__":  # pragma: no cover
    main()
