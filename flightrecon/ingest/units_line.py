"""The units line under a header (a flight-data team's parameter dump: header, units, rows),
recognised from the cells of a CSV's second line (:mod:`flightrecon.ingest.ed112` reads the
dump; :mod:`flightrecon.ingest.readers` skips the line and keeps the units)."""

from __future__ import annotations

import re

from flightrecon.ingest.units import lookup_unit

__all__ = ["DUMP_DIALECT", "units_line"]

#: ``RawTable.dialect`` of a parameter dump (a header, then a units line)
DUMP_DIALECT = "ed112-dump"
#: a cell that is a number (decimal, exponent, nan/inf)
_NUMBER = re.compile(r"^\s*[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|nan|inf(?:inity)?)\s*$",
                     re.IGNORECASE)


def units_line(names: list[str], cells: list[str]) -> dict[str, str] | None:
    """The units of the columns ``names`` when ``cells`` (the line under the header, split)
    is a units line, else ``None``.

    A units line has the header's field count, no cell that is a number, and at least two
    cells (and half of the non-empty ones) that are units flightrecon knows
    (:func:`flightrecon.ingest.units.lookup_unit`): a data row's cells are numbers, so a CSV
    whose second line is data is never taken for one.
    """
    if len(cells) != len(names):
        return None
    text = [c.strip().strip('"') for c in cells]
    if any(_NUMBER.match(c) for c in text if c):
        return None
    filled = [c for c in text if c and c != "-"]
    known = sum(lookup_unit(c) is not None for c in filled)
    if known < 2 or 2 * known < len(filled):
        return None
    return dict(zip(names, text, strict=True))


