"""What the CLI shows while it works: a stage progress display (tqdm) and a one-line notice
while the compiled kernels are built on a first run; plus the checks every command makes on
its output paths before any work (the format a suffix names).

The display goes to stderr, only on a terminal and never with ``--quiet``; the compile notice
is one line on stderr (also when not a terminal), never with ``--quiet``.
"""

from __future__ import annotations

import contextlib
import sys
import threading
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import click

COMPILE_NOTICE = ("flightrecon: compiling the numerical kernels (first run only, this can take "
                  "a few minutes; later runs load them from the cache)")


@contextlib.contextmanager
def compile_notice(quiet: bool) -> Iterator[None]:
    """While active, print :data:`COMPILE_NOTICE` once on stderr when numba starts compiling a
    kernel, i.e. when one is not in the cache yet (a first run, or after an upgrade).

    numba announces every compilation that misses its cache as a ``numba:compile`` event;
    loading from the cache announces nothing, so a warm run prints nothing.
    """
    if quiet:
        yield
        return
    try:
        import numba.core.event as ev
    except ImportError:  # no numba: nothing is compiled
        yield
        return
    said = threading.Event()

    class _Notice(ev.Listener):
        def on_start(self, event) -> None:
            if not said.is_set():
                said.set()
                from tqdm import tqdm

                tqdm.write(COMPILE_NOTICE, file=sys.stderr)

        def on_end(self, event) -> None:
            pass

    listener = _Notice()
    ev.register("numba:compile", listener)
    try:
        yield
    finally:
        ev.unregister("numba:compile", listener)


@contextlib.contextmanager
def stage_progress(quiet: bool, stages: Iterable[str], desc: str = "flightrecon"
                   ) -> Iterator[Callable[[str], None]]:
    """A tqdm bar over the expected ``stages`` on stderr; yields ``stage(name)`` to call as
    each stage starts (unknown names extend the total).  The elapsed time keeps running
    between stages.  Silent with ``quiet`` or when stderr is not a terminal; with
    ``--verbose`` (:func:`verbose_asked`) one line per stage instead (:func:`stage_lines`)."""
    if not quiet and verbose_asked():
        with stage_lines(desc) as line:
            yield line
        return
    if quiet or not sys.stderr.isatty():
        yield lambda name: None
        return
    from tqdm import tqdm

    expected = list(stages)
    bar = tqdm(total=len(expected), desc=desc, unit="stage", file=sys.stderr, leave=False,
               bar_format="{desc}: {n_fmt}/{total_fmt} stages |{bar}| {elapsed}")
    seen: list[str] = []
    lock = threading.Lock()
    stop = threading.Event()

    def refresh() -> None:
        while not stop.wait(0.5):
            with lock:
                bar.refresh()

    ticker = threading.Thread(target=refresh, name="flightrecon-progress", daemon=True)
    ticker.start()

    def stage(name: str) -> None:
        with lock:
            if seen:
                bar.update(1)
            seen.append(name)
            if len(seen) > bar.total:
                bar.total = len(seen)
            bar.set_description(f"{desc}: {name}", refresh=True)

    try:
        yield stage
    finally:
        stop.set()
        ticker.join()
        with lock:
            bar.update(bar.total - bar.n)
            bar.close()


def verbose_asked() -> bool:
    """True when the command line was given ``--verbose`` (before or after the subcommand:
    :data:`flightrecon.cli.main.CONSOLE_OPTIONS`)."""
    ctx = click.get_current_context(silent=True)
    return bool(ctx is not None and isinstance(ctx.obj, dict) and ctx.obj.get("verbose"))


@contextlib.contextmanager
def stage_lines(desc: str) -> Iterator[Callable[[str], None]]:
    """``--verbose``: one line on stderr as each stage starts, with the seconds since the
    stages began (``reconstruct: cleaning (t = 1.2 s)``), and one when they end; the same on a
    terminal and in a log file."""
    import time

    t0 = time.perf_counter()

    def stage(name: str) -> None:
        click.echo(f"{desc}: {name} (t = {time.perf_counter() - t0:.1f} s)", err=True)

    yield stage
    click.echo(f"{desc}: done in {time.perf_counter() - t0:.1f} s", err=True)


def check_format(path: Path, fmt: str | None, param: str = "-o") -> str:
    """The output format of ``path`` (``fmt`` or from the suffix), refusing a suffix that
    names another format than ``fmt`` as a usage error (exit 2), before any work."""
    from flightrecon.errors import OutputError
    from flightrecon.export.writers import format_from_path

    try:
        return format_from_path(path, fmt)
    except OutputError as exc:
        raise click.UsageError(f"{param} {path}: {exc.message}") from exc


def check_folder(path: Path) -> None:
    """The folder ``path`` goes into exists and is writable (an OutputError, exit 9, before
    any work otherwise)."""
    import os

    from flightrecon.errors import OutputError

    parent = path.parent if str(path.parent) else Path(".")
    if not parent.is_dir():
        raise OutputError(f"the output folder does not exist: {parent}", file=str(path))
    if not os.access(parent, os.W_OK | os.X_OK):
        raise OutputError(f"the output folder is not writable: {parent}", file=str(path))
    if path.is_dir():
        raise OutputError("the output is a folder, not a file", file=str(path))


def check_report_folder(folder: Path) -> None:
    """A report folder: either absent with a writable parent (it is created), or an existing
    writable folder."""
    import os

    from flightrecon.errors import OutputError

    if folder.exists():
        if not folder.is_dir():
            raise OutputError("the report folder is a file", file=str(folder))
        if not os.access(folder, os.W_OK | os.X_OK):
            raise OutputError("the report folder is not writable", file=str(folder))
        return
    check_folder(folder)
