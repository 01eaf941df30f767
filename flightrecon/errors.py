"""One error hierarchy for the whole project, with documented exit codes.

Every error a user can provoke with bad input is a :class:`FlightReconError`.  It names the
file, the column and the row(s) where it can, and carries the process exit code the CLI uses.
The CLI prints ``error: <message>`` without a traceback (``--debug`` shows it).

Exit codes
----------
====  ==============================================================
0     success
1     internal error (a bug: please report it with ``--debug`` output)
2     command-line usage error (click)
3     input file unreadable: missing, empty, not text, corrupt or truncated
4     schema error: missing required column, unknown unit or channel
5     validation error: non-numeric, impossible values, bad timestamps, polarity, a unit
      the physics shows to be wrong, a log too short to reconstruct
6     mapping file error
7     metadata / sidecar error (airfields, station, aircraft)
8     no physically possible result (every method failed or is unhealthy); with
      ``--strict``, any method that did not converge or is unhealthy
9     output error: would overwrite an input, cannot write
10    coefficient store error
130   interrupted (Ctrl-C, SIGINT)
143   terminated (SIGTERM, what ``timeout`` and batch systems send); other catchable
      signals 128 + their number (SIGHUP 129); handled like Ctrl-C: nothing half-written
====  ==============================================================
"""

from __future__ import annotations

from collections.abc import Collection, Sequence


def _format_rows(rows: Sequence[int] | None, limit: int = 5) -> str:
    if rows is None or len(rows) == 0:
        return ""
    rows = [int(r) for r in rows]
    shown = ", ".join(str(r) for r in rows[:limit])
    more = f" (+{len(rows) - limit} more)" if len(rows) > limit else ""
    word = "row" if len(rows) == 1 else "rows"
    return f"{word} {shown}{more}"


class FlightReconError(Exception):
    """Base of every error flightrecon raises on purpose.

    Parameters
    ----------
    message
        What is wrong, in words an analyst understands.
    file, column
        Where it is (optional).
    rows
        Row numbers in the *file* (1-based data rows, header excluded) where it is (optional).
    """

    exit_code: int = 1

    def __init__(
        self,
        message: str,
        *,
        file: str | None = None,
        column: str | None = None,
        rows: Collection[int] | None = None,
    ) -> None:
        self.message = message
        self.file = None if file is None else str(file)
        self.column = column
        self.rows = None if rows is None else [int(r) for r in rows]
        super().__init__(self.__str__())

    def __str__(self) -> str:  # noqa: D105
        where = []
        if self.file:
            where.append(self.file)
        if self.column:
            where.append(f"column '{self.column}'")
        r = _format_rows(self.rows)
        if r:
            where.append(r)
        prefix = ": ".join([", ".join(where)]) + ": " if where else ""
        return f"{prefix}{self.message}"


class InputFileError(FlightReconError):
    """File missing, empty, not text, corrupt or truncated."""

    exit_code = 3


class SchemaError(FlightReconError):
    """Missing required column, unknown unit or unknown channel."""

    exit_code = 4


class ValidationError(FlightReconError):
    """Values that cannot be right: non-numeric, impossible, bad timestamps, wrong polarity."""

    exit_code = 5


class MappingError(FlightReconError):
    """A column-mapping file that cannot be used."""

    exit_code = 6


class MetadataError(FlightReconError):
    """Flight metadata (sidecar or command line) missing or malformed."""

    exit_code = 7


class ConvergenceError(FlightReconError):
    """An estimator did not converge or diverged, in strict mode."""

    exit_code = 8


class NoResultError(ConvergenceError):
    """No method produced a finite, physically possible track: there is no result to write.

    ``warnings`` holds the run's warnings (the console shows them before the error: a unit
    used as declared against the physics may be why).
    """

    warnings: tuple[str, ...] = ()


class OutputError(FlightReconError):
    """An output cannot be written (or would overwrite an input)."""

    exit_code = 9


class StoreError(FlightReconError):
    """The coefficient store is corrupt, foreign or cannot be written."""

    exit_code = 10


class FlightReconWarning(UserWarning):
    """A recoverable defect in the input, reported and carried into the summary."""
