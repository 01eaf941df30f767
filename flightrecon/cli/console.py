"""How every command shows the tool's warnings on the console: one line each on stderr,
``  warning: <message>``, the form ``reconstruct`` prints its run's warnings in.

The library warns with :class:`flightrecon.errors.FlightReconWarning` (a guess the user should
know about: a unit taken for another, a column ignored); Python would print such a warning as
``<installed file>:<line>: FlightReconWarning: <message>`` and the source line, which says
where the tool's code noticed it, not what the analyst should look at.  While a command runs
(:func:`console_warnings`, around every subcommand), those warnings go through
:func:`echo_warning` instead; every other warning (a library's deprecation, numpy's) keeps
Python's format, and the filters in force (``-W``, ``PYTHONWARNINGS``) still decide which
warnings are shown at all.
"""

from __future__ import annotations

import contextlib
import warnings
from collections.abc import Iterator, Mapping
from typing import Any, TextIO

import click

from flightrecon.errors import FlightReconWarning

#: one warning on the console (stderr)
WARNING_LINE = "  warning: {message}"


def echo_warning(message: object) -> None:
    """Print one warning on stderr in the console's form (:data:`WARNING_LINE`)."""
    click.echo(WARNING_LINE.format(message=message), err=True)


@contextlib.contextmanager
def console_warnings(settings: Mapping[str, Any] | None = None) -> Iterator[None]:
    """While active, the tool's warnings are shown with :func:`echo_warning`, or not at all
    when ``settings`` (the run's shared options, read when a warning comes: ``--quiet`` may
    follow the subcommand) has ``quiet``, as ``reconstruct`` never printed them then (they
    are in its summary, and in the report ``clean`` writes); other warnings as before.  The
    previous display (and the filters) are restored on exit."""
    with warnings.catch_warnings():
        previous = warnings.showwarning

        def show(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                 file: TextIO | None = None, line: str | None = None) -> Any:
            if issubclass(category, FlightReconWarning):
                if not (settings and settings.get("quiet")):
                    echo_warning(message)
                return None
            return previous(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        yield


@contextlib.contextmanager
def collected_warnings() -> Iterator[list[str]]:
    """While active, each of the tool's warnings is also kept, once per message, in the list
    yielded (for a report file), and shown as it comes by the display in force (the console's,
    :func:`console_warnings`)."""
    kept: list[str] = []
    with warnings.catch_warnings():
        warnings.simplefilter("always", FlightReconWarning)   # each message once, below
        previous = warnings.showwarning

        def show(message: Warning | str, category: type[Warning], filename: str, lineno: int,
                 file: TextIO | None = None, line: str | None = None) -> Any:
            if issubclass(category, FlightReconWarning):
                if str(message) in kept:
                    return None
                kept.append(str(message))
            return previous(message, category, filename, lineno, file, line)

        warnings.showwarning = show
        yield kept
