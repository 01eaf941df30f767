"""A folder of one-column files as one recorder table (a common MATLAB / flight-test export).

Some flight-test systems export each recorded parameter as its own header-less text file of one
column (``time.csv``, ``Ahrs1_Pitch.csv``, ``Dadc1_alt.csv``, ...), every file with one value
per recorder frame.  :func:`read_folder` reads such a folder as one table whose column names
are the files' names without their suffix, so that a mapping file names the files::

    [time]
    column = "time"          # time.csv
    unit = "s"
    [channels.pitch_deg]
    column = "Ahrs1_Pitch"   # Ahrs1_Pitch.csv
    unit = "deg"

The files read are the folder's ``.csv``, ``.txt`` and ``.dat`` files of one numeric column
(a header line of text is allowed and skipped); subfolders are not read.  Every file used must
have as many rows as the table: the row count of most files (the frames of the record).  A file
of another length, several columns or text is left out with a warning naming it (it cannot be
placed against the others' frames); a folder with no such file is an input error.
"""

from __future__ import annotations

import os
from collections import Counter
from pathlib import Path

import numpy as np

from flightrecon.errors import InputFileError
from flightrecon.ingest.encoding import decode_text

__all__ = ["FOLDER_SUFFIXES", "read_folder"]

FOLDER_SUFFIXES = (".csv", ".txt", ".dat")


def _one_column(path: Path) -> np.ndarray | None:
    """The numbers of a one-column text file (a first line of text is a header), or
    ``None`` when the file is not one numeric column."""
    try:        # UTF-8, or a Windows tool's Windows-1252 / Latin-1 (its header only is text)
        text = decode_text(path.read_bytes(), str(path))[0].decode("utf-8")
    except (OSError, InputFileError):
        return None
    lines = text.splitlines()
    while lines and not lines[-1].strip():
        lines.pop()
    if not lines:
        return None
    try:
        float(lines[0].strip())
    except ValueError:
        lines = lines[1:]           # a header line
    if not lines or any(("," in ln or ";" in ln or "\t" in ln.strip()) for ln in lines[:5]):
        return None
    out = np.empty(len(lines))
    for i, ln in enumerate(lines):
        s = ln.strip()
        try:
            out[i] = float(s) if s else np.nan
        except ValueError:
            return None
    return out


def read_folder(path: str | os.PathLike) -> tuple[dict[str, np.ndarray], int, list[str]]:
    """The folder's one-column files as columns (module docstring).

    Returns
    -------
    columns : file name without suffix -> float64 values (NaN for an empty line)
    n_rows : the table's row count
    warnings : the files left out, and why

    Raises
    ------
    InputFileError
        No readable one-column file in the folder, or two files whose names differ only in
        their suffix.
    """
    folder = Path(path)
    files = sorted(p for p in folder.iterdir()
                   if p.is_file() and p.suffix.lower() in FOLDER_SUFFIXES)
    read: dict[str, np.ndarray] = {}
    where: dict[str, Path] = {}
    warns: list[str] = []
    for f in files:
        v = _one_column(f)
        if v is None:
            warns.append(f"{f}: not one numeric column: left out of the table")
            continue
        if f.stem in read:
            raise InputFileError(f"two files are named '{f.stem}' (with other suffixes): "
                                 "rename one", file=str(f))
        read[f.stem] = v
        where[f.stem] = f
    if not read:
        raise InputFileError("a folder of recorder files needs one-column numeric files "
                             f"({', '.join(FOLDER_SUFFIXES)}); none found", file=str(folder))
    n_rows = Counter(v.size for v in read.values()).most_common(1)[0][0]
    columns = {}
    for name, v in read.items():
        if v.size != n_rows:
            warns.append(f"{where[name]}: {v.size} rows where the record has {n_rows}: left "
                         "out of the table (it cannot be placed against the other files' "
                         "frames)")
            continue
        columns[name] = v
    return columns, n_rows, warns
