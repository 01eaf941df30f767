"""The header lines of a Garmin avionics CSV export, in each layout the family writes.

Every unit of the family starts its export with an information line, ``#airframe_info,
key="value", ...`` (the G1000, G1000 NXi, Perspective, G3X / G3X Touch) or ``#info, ...`` (the
standalone instruments: G5), then names its columns in one of three ways (docs/ingest.md,
"Garmin glass-cockpit exports", with the evidence for each):

* **units line** (G1000, G1000 NXi, Perspective / Perspective+): line 2 is the units, starting
  with ``#`` (``#yyy-mm-dd, hh:mm:ss, hh:mm, ident, degrees, ..., ft Baro, inch, ...``), line 3
  the short names (``Lcl Date, Lcl Time, UTCOfst, ..., AltInd, BaroA, ...``);
* **long and short names** (G3X, G3X Touch: GDU 4xx / 37x): line 2 the long names with their
  unit in brackets (``Latitude (deg)``, ``GPS Altitude (ft)``, ``Normal Acceleration (G)``),
  line 3 the short names of the same vocabulary, some left empty;
* **long names** only: line 2 the names, the data from line 3.

A spreadsheet that re-saved the file may have quoted every field of the information line
(each field in double quotes, the quotes inside doubled): the line is read as CSV first.
"""

from __future__ import annotations

import csv
import re
from dataclasses import dataclass, field

__all__ = ["GarminLayout", "is_garmin_export", "parse_layout"]

#: first bytes of the information line of a Garmin export
INFO_PREFIXES = (b"#airframe_info", b"#info,", b'"#airframe_info"', b'"#info"')
#: a long name and its bracketed unit: ``GPS Altitude (WGS84 ft)``
_LONG = re.compile(r"^(.*?)\s*\(([^()]*)\)\s*$")
#: a data cell: a number, a date or a time of day
_DATA_CELL = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$|^\d{1,4}[-/.]\d{1,2}[-/.]\d{1,4}$"
                        r"|^\d{1,2}:\d{2}(:\d{2})?")


@dataclass(frozen=True)
class GarminLayout:
    """How a Garmin export names its columns.

    Attributes
    ----------
    info : ``key -> value`` pairs of the information line (quotes removed)
    names : column names: the short name, or the long name without its unit where the short
        name is empty (or repeats one before it)
    units : column -> unit text (the units line's, or the bracket of the long name; ``""``)
    long_names : column -> long name as written (long-name layouts)
    layout : ``"units line"``, ``"long and short names"`` or ``"long names"``
    header_lines : lines before the first data row (the last of them is the names line)
    """

    info: dict[str, str]
    names: tuple[str, ...]
    units: dict[str, str] = field(default_factory=dict)
    long_names: dict[str, str] = field(default_factory=dict)
    layout: str = "units line"
    header_lines: int = 3


def is_garmin_export(head: bytes) -> bool:
    """Whether ``head`` (the file's first bytes, BOM removed) opens a Garmin export."""
    return head.lstrip(b" ").startswith(INFO_PREFIXES)


def _cells(line: str, delim: str) -> list[str]:
    return next(csv.reader([line], delimiter=delim, skipinitialspace=False), [])


def _info(line: str, delim: str) -> dict[str, str]:
    """``key=value`` pairs of the information line (CSV-unquoted first: a re-saved file)."""
    out: dict[str, str] = {}
    for part in _cells(line, delim)[1:]:
        k, eq, v = part.partition("=")
        if eq and k.strip():
            out[k.strip()] = v.strip().strip('"').strip()
    return out


def _is_names_line(cells: list[str]) -> bool:
    """A line of column names, not data: no cell is a number, a date or a time of day."""
    filled = [c.strip() for c in cells if c.strip()]
    return bool(filled) and not any(_DATA_CELL.match(c) for c in filled)


def _unique(names: list[str], longs: list[str]) -> list[str]:
    """Names made unique: an empty or repeated short name is replaced by its long name, then by
    the long name with its position."""
    out: list[str] = []
    seen: set[str] = set()
    for i, n in enumerate(names):
        cand = n or longs[i] or f"column {i + 1}"
        if cand in seen:
            cand = longs[i] if longs[i] and longs[i] not in seen else f"{cand} ({i + 1})"
        seen.add(cand)
        out.append(cand)
    return out


def parse_layout(lines: list[str], delim: str) -> GarminLayout:
    """The layout of a Garmin export from its first three lines (module docstring).

    Parameters
    ----------
    lines : the first three lines of the file (without line ends; fewer if the file is short)
    delim : the field delimiter
    """
    info = _info(lines[0], delim)
    second = _cells(lines[1], delim) if len(lines) > 1 else []
    third = _cells(lines[2], delim) if len(lines) > 2 else []
    if lines[1].lstrip().startswith("#"):                       # G1000 family
        units = [u.strip() for u in _cells(lines[1].lstrip()[1:], delim)]
        names = [n.strip().strip('"') for n in third]
        cols = _unique(names, [""] * len(names))
        return GarminLayout(info, tuple(cols), {c: (units[i] if i < len(units) else "")
                                                for i, c in enumerate(cols)},
                            {}, "units line", 3)
    if _is_names_line(third):
        nf = max(len(second), len(third))
        second = second + [""] * (nf - len(second))
        third = third + [""] * (nf - len(third))
    longs_raw = [c.strip() for c in second]
    parsed = [_LONG.match(c) for c in longs_raw]
    stems = [m.group(1).strip() if m else c for m, c in zip(parsed, longs_raw, strict=True)]
    units = [m.group(2).strip() if m else "" for m in parsed]
    if _is_names_line(third):
        cols = _unique([c.strip() for c in third], stems)
        layout, n = "long and short names", 3
    else:
        cols = _unique(stems, longs_raw)
        layout, n = "long names", 2
    return GarminLayout(info, tuple(cols), {c: units[i] for i, c in enumerate(cols)},
                        {c: longs_raw[i] for i, c in enumerate(cols)}, layout, n)
