"""The ``--start`` / ``--end`` options of ``clean``, ``reconstruct`` and ``batch``
(:func:`flightrecon.cleaning.trim.trim_flight`)."""

from __future__ import annotations

import click

__all__ = ["trim_options"]


def trim_options(f):
    """Add ``--start`` and ``--end`` (seconds from the flight's epoch, i.e. ``t_s``, or a UTC
    timestamp) to a command; they arrive as ``start`` / ``end`` (text or ``None``)."""
    for opt in reversed([
        click.option("--start", metavar="T", help="Use the record from T on: seconds (t_s, "
                     "from the flight's epoch_utc) or a UTC time (2026-01-01T10:05:00Z)."),
        click.option("--end", metavar="T", help="Use the record up to T (as --start)."),
    ]):
        f = opt(f)
    return f
