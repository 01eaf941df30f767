"""Read a recorder, GNSS or radar file (CSV or Parquet) into a table of raw columns.

The format is taken from the suffix (``.csv``/``.txt`` -> CSV, ``.parquet``/``.pq`` -> Parquet)
and checked against the content: a Parquet file (magic bytes ``PAR1``) named ``.csv``, a binary
file, bytes that are text in no encoding read here or a truncated Parquet file is an
:class:`InputFileError` naming the file (exit code 3).  Text is UTF-8; a file a Windows tool
wrote in Windows-1252 / Latin-1 is read with a warning naming the encoding
(:func:`decode_text`).  Rows with the wrong number of fields are reported with their 1-based
data row numbers (header excluded).

Numeric columns are float64.  Empty cells (and Parquet nulls and NaN) mean "not sampled in this
row", which is normal in multi-rate logs.  In a CSV that uses empty cells for that, a literal
``NaN`` written by the recorder is an invalid value: it is kept apart in
:attr:`RawTable.nan_text` so that validation can tell it from a missing sample.
Text cells that are not numbers are kept as text, and validation reports them; a cell of
spaces only is an empty cell.  A Garmin avionics export (``#airframe_info`` or ``#info`` first
line, then a units line and the short names, or the long names with their units and the short
names: :mod:`.garmin_layout`) is read with its units and information line kept
(:attr:`RawTable.units`, :attr:`RawTable.preamble`); so is a parameter dump's units line under
its header (:mod:`flightrecon.ingest.units_line`, :mod:`flightrecon.ingest.ed112`).  A last row cut short (fewer fields than
the header and no line end: the recorder stopped while writing it) is dropped with a warning.
"""

from __future__ import annotations

import csv
import dataclasses
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import pandas as pd
import pyarrow as pa
import pyarrow.compute as pc
import pyarrow.csv as pacsv
import pyarrow.parquet as pq

from flightrecon.errors import InputFileError, SchemaError
from flightrecon.ingest.encoding import decode_text
from flightrecon.ingest.folder import read_folder
from flightrecon.ingest.garmin_layout import is_garmin_export, parse_layout
from flightrecon.ingest.units_line import DUMP_DIALECT, units_line

__all__ = ["RawTable", "decode_text", "read_table", "sniff_format"]

PARQUET_MAGIC = b"PAR1"
CSV_SUFFIXES = (".csv", ".txt", ".tsv")
PARQUET_SUFFIXES = (".parquet", ".pq", ".parq")
#: a cell is numeric if it matches this (decimal, exponent, nan/inf in any case)
NUMERIC_RE = r"^\s*[+-]?(?:(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?|[nN][aA][nN]|[iI][nN][fF](?:[iI][nN][iI][tT][yY])?)\s*$"


@dataclass(frozen=True)
class RawTable:
    """A file's columns before mapping.

    Attributes
    ----------
    file : path as given (for messages)
    columns : source column name -> array; float64 for numeric columns, ``datetime64[ns]`` (UTC)
        for timestamp columns, object (str or None) for text columns
    n_rows : number of data rows
    nan_text : column -> boolean mask of cells the file wrote as NaN (not empty)
    blank_rows : 1-based data rows that were empty lines (dropped by validation with a warning)
    fmt : ``"csv"``, ``"parquet"`` or ``"folder"`` (one-column files, named by their stems)
    bad_text : column -> (mask of non-numeric text cells in a numeric column, first such text)
    nan_is_missing : the file marks unsampled cells with NaN (Parquet, or a CSV without any
        empty cell), so ``nan_text`` is empty: NaN cannot tell an invalid value there
    dialect : ``"garmin"`` for a Garmin glass-cockpit export (``#airframe_info`` first line,
        then a units line, then the header; :mod:`flightrecon.ingest.garmin`),
        ``"ed112-dump"`` for a parameter dump (the header, then a units line;
        :mod:`flightrecon.ingest.ed112`), else ``""``
    units : source column -> unit text of the file's own units line (Garmin exports,
        parameter dumps)
    preamble : ``key=value`` pairs of a Garmin ``#airframe_info`` line (aircraft, software)
    long_names : source column -> long name with its unit (Garmin long-name layouts)
    layout : how a Garmin export names its columns (:mod:`.garmin_layout`), else ``""``
    warnings : repairs made while reading (a short last row dropped), each naming its row
    header_line : 1-based line of the header in the file (data row k is line
        ``header_line + k``)
    """

    file: str
    columns: dict[str, np.ndarray]
    n_rows: int
    nan_text: dict[str, np.ndarray] = field(default_factory=dict)
    blank_rows: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))
    fmt: str = "csv"
    bad_text: dict[str, tuple[np.ndarray, str]] = field(default_factory=dict)
    nan_is_missing: bool = False
    dialect: str = ""
    units: dict[str, str] = field(default_factory=dict)
    preamble: dict[str, str] = field(default_factory=dict)
    long_names: dict[str, str] = field(default_factory=dict)
    layout: str = ""
    warnings: tuple[str, ...] = ()
    header_line: int = 1


def sniff_format(path: str | os.PathLike) -> str:
    """``"csv"`` or ``"parquet"`` for ``path`` after checking its suffix against its content.

    Raises
    ------
    InputFileError
        Missing file, directory, empty file, Parquet content under a text suffix, or a file that
        is neither Parquet nor text.
    """
    p = Path(path)
    if not p.exists():
        raise InputFileError("file not found", file=str(p))
    if not p.is_file():
        raise InputFileError("not a regular file", file=str(p))
    size = p.stat().st_size
    if size == 0:
        raise InputFileError("empty file (0 bytes)", file=str(p))
    with open(p, "rb") as fh:
        head = fh.read(4096)
    suffix = p.suffix.lower()
    is_parquet = head[:4] == PARQUET_MAGIC
    if suffix in CSV_SUFFIXES:
        if is_parquet:
            raise InputFileError(f"this is a Parquet file named '{suffix}': rename it '.parquet'",
                                 file=str(p))
        return "csv"
    if suffix in PARQUET_SUFFIXES:
        if not is_parquet:
            raise InputFileError("not a Parquet file (no 'PAR1' magic bytes at its start)",
                                 file=str(p))
        return "parquet"
    return "parquet" if is_parquet else "csv"


def read_table(path: str | os.PathLike) -> RawTable:
    """Read ``path`` (CSV or Parquet, see :func:`sniff_format`; a folder of one-column files,
    :mod:`flightrecon.ingest.folder`) into a :class:`RawTable`.

    Raises
    ------
    InputFileError
        Unreadable, empty, binary, not UTF-8, truncated or corrupt file; rows with the wrong
        number of fields.
    SchemaError
        Duplicate or empty column names.
    """
    if Path(path).is_dir():          # a folder of one-column files (:mod:`.folder`)
        cols, n, warns = read_folder(path)
        return RawTable(file=str(path), columns=cols, n_rows=n, fmt="folder",
                        nan_is_missing=True, warnings=tuple(warns))
    fmt = sniff_format(path)
    table = _read_parquet(Path(path)) if fmt == "parquet" else _read_csv(Path(path))
    return table


# ------------------------------------------------------------------------------------ CSV



def _read_csv(p: Path) -> RawTable:
    file = str(p)
    try:
        raw = p.read_bytes()
    except OSError as exc:
        raise InputFileError(f"cannot read: {exc.strerror}", file=file) from None
    body, enc_warn = decode_text(raw, file)
    if not body[:65536].strip() and not body.strip():
        raise InputFileError("empty file (no header, no data)", file=file)
    layout = None
    if is_garmin_export(body[:64]):
        # information line, then one or two lines of names (and units) before the data
        # (flightrecon/ingest/garmin_layout.py)
        head, cut = [], 0
        for _ in range(3):
            nl = body.find(b"\n", cut)
            if nl < 0:
                break
            head.append(body[cut:nl].decode("utf-8").rstrip("\r"))
            cut = nl + 1
        if len(head) < 2:
            raise InputFileError("Garmin export with no column names after its information "
                                 "line", file=file)
        delim = _sniff_delimiter(head[1] if not head[1].startswith("#") else head[-1])
        layout = parse_layout(head, delim)
        skip = layout.header_lines - 1     # lines before the names line
        for _ in range(skip):
            body = body[body.find(b"\n") + 1:]
    first_nl = body.find(b"\n")
    header = body if first_nl < 0 else body[:first_nl]
    if first_nl < 0 or not body[first_nl + 1:first_nl + 65537].strip() \
            and not body[first_nl + 1:].strip():
        raise InputFileError("no data rows (header only)", file=file)
    delim = _sniff_delimiter(header.decode("utf-8"))
    names = [h.strip().strip('"') for h in header.decode("utf-8").rstrip("\r").split(delim)]
    if layout is not None:
        names = list(layout.names)
    _check_names(names, file)
    header_line = layout.header_lines if layout is not None else 1
    dump_units = None if layout is not None else _units_line(body, first_nl, names, delim)
    if dump_units is not None:           # a parameter dump's units line (.units_line): skipped
        second_nl = body.find(b"\n", first_nl + 1)
        body = body[:first_nl + 1] + (body[second_nl + 1:] if second_nl >= 0 else b"")
    body, warns = _drop_short_last_row(body, len(names), delim, file, header_line)
    if enc_warn:
        warns.insert(0, enc_warn)
    read_opts = pacsv.ReadOptions(column_names=names, skip_rows=1, block_size=1 << 24)
    parse_opts = pacsv.ParseOptions(delimiter=delim, ignore_empty_lines=False)
    conv_opts = pacsv.ConvertOptions(null_values=[""], strings_can_be_null=True,
                                     quoted_strings_can_be_null=True)
    buf = pa.py_buffer(body)
    try:
        tbl = pacsv.read_csv(buf, read_options=read_opts, parse_options=parse_opts,
                             convert_options=conv_opts)
    except pa.ArrowInvalid as exc:
        if "parse error" in str(exc) or "Expected" in str(exc):
            _raise_ragged(buf, names, delim, body, file)
        raise InputFileError(f"cannot parse CSV: {exc}", file=file) from None
    table = _from_arrow(tbl, file, "csv")
    extra: dict = {"warnings": tuple(warns), "header_line": header_line}
    if dump_units is not None:
        extra.update(dialect=DUMP_DIALECT, units=dump_units)
    if layout is not None:
        extra.update(dialect="garmin", preamble=dict(layout.info), units=dict(layout.units),
                     long_names=dict(layout.long_names), layout=layout.layout)
    return dataclasses.replace(table, **extra)


def _units_line(body: bytes, first_nl: int, names: list[str], delim: str
                ) -> dict[str, str] | None:
    """The units of a parameter dump's second line (:func:`.units_line.units_line`), else
    ``None``."""
    end = body.find(b"\n", first_nl + 1)
    line = body[first_nl + 1:end if end >= 0 else len(body)].decode("utf-8").rstrip("\r")
    return units_line(names, next(csv.reader([line], delimiter=delim), []))


def _drop_short_last_row(body: bytes, n_fields: int, delim: str, file: str,
                         header_line: int) -> tuple[bytes, list[str]]:
    """``body`` without a last row cut short (fewer fields than the header and no line end: a
    recorder switched off while writing), and the warning saying so (data row named).  Any
    other row with the wrong number of fields stays an error (:func:`_raise_ragged`)."""
    stripped = body.rstrip(b"\r")
    if not stripped or stripped.endswith(b"\n"):
        return body, []
    nl = stripped.rfind(b"\n")
    if nl < 0:
        return body, []
    last = stripped[nl + 1:].decode("utf-8")
    got = len(next(csv.reader([last], delimiter=delim), []))
    if got >= n_fields:
        return body, []
    row = body[:nl + 1].count(b"\n")          # data rows before it (header line excluded)
    return body[:nl + 1], [f"{file}: the last row (data row {row}, line {row + header_line}) "
                           f"is cut short ({got} of {n_fields} fields, no line end: the "
                           "recorder stopped while writing it): dropped"]


def _sniff_delimiter(header: str) -> str:
    counts = {d: header.count(d) for d in (",", ";", "\t")}
    best = max(counts, key=lambda d: counts[d])
    return best if counts[best] > 0 else ","


def _check_names(names: list[str], file: str) -> None:
    seen: dict[str, int] = {}
    for i, n in enumerate(names):
        if n == "":
            raise SchemaError(f"header field {i + 1} is empty", file=file)
        if n in seen:
            raise SchemaError(f"duplicate column name (header fields {seen[n] + 1} and {i + 1})",
                              file=file, column=n)
        seen[n] = i


def _raise_ragged(buf: pa.Buffer, names: list[str], delim: str, body: bytes, file: str) -> None:
    """Re-read single-threaded to find the rows with the wrong number of fields, then raise."""
    bad: list[tuple[int, int]] = []

    def handler(row) -> str:
        # row.number is the 1-based line number counted after the skipped header line
        bad.append((int(row.number) if row.number is not None else -1, int(row.actual_columns)))
        return "skip"

    try:
        pacsv.read_csv(buf, read_options=pacsv.ReadOptions(column_names=names, skip_rows=1,
                                                           use_threads=False),
                       parse_options=pacsv.ParseOptions(delimiter=delim, ignore_empty_lines=False,
                                                        invalid_row_handler=handler),
                       convert_options=pacsv.ConvertOptions(null_values=[""],
                                                            strings_can_be_null=True))
    except pa.ArrowInvalid as exc:
        raise InputFileError(f"cannot parse CSV: {exc}", file=file) from None
    # the handler's number is the file's line number (header = line 1): data row = line - 1
    rows = [r - 1 for r, _ in bad if r > 1]
    n_data = body.count(b"\n") + (0 if body.endswith(b"\n") else 1) - 1
    got = bad[0][1] if bad else 0
    if bad and len(bad) == 1 and rows and rows[0] == n_data and not body.endswith(b"\n"):
        raise InputFileError(f"file is truncated: the last row has {got} of {len(names)} fields "
                             "and no line end", file=file, rows=rows)
    raise InputFileError(f"wrong number of fields (expected {len(names)}, first bad row has {got})",
                         file=file, rows=rows or None)


# -------------------------------------------------------------------------------- Parquet


def _read_parquet(p: Path) -> RawTable:
    file = str(p)
    size = p.stat().st_size
    with open(p, "rb") as fh:
        fh.seek(max(0, size - 4))
        tail = fh.read(4)
    if size < 12 or tail != PARQUET_MAGIC:
        raise InputFileError("truncated or corrupt Parquet file (no 'PAR1' footer)", file=file)
    try:
        tbl = pq.read_table(p)
    except (pa.ArrowException, OSError, ValueError) as exc:
        raise InputFileError(f"corrupt Parquet file: {exc}", file=file) from None
    if tbl.num_rows == 0:
        raise InputFileError("no data rows", file=file)
    _check_names([str(n) for n in tbl.column_names], file)
    return _from_arrow(tbl, file, "parquet")


# ----------------------------------------------------------------------------- conversion


def _from_arrow(tbl: pa.Table, file: str, fmt: str) -> RawTable:
    n = tbl.num_rows
    if n == 0:
        raise InputFileError("no data rows", file=file)
    cols: dict[str, np.ndarray] = {}
    nan_text: dict[str, np.ndarray] = {}
    bad_text: dict[str, tuple[np.ndarray, str]] = {}
    all_null = np.ones(n, dtype=bool)
    any_null = False
    for name in tbl.column_names:
        col = tbl.column(name).combine_chunks() if tbl.column(name).num_chunks != 1 \
            else tbl.column(name).chunk(0)
        no_null = col.null_count == 0
        valid = np.ones(n, dtype=bool) if no_null else col.is_valid().to_numpy(
            zero_copy_only=False)
        if not no_null:
            all_null &= ~valid
        else:
            all_null[:] = False
        any_null = any_null or not no_null
        if pa.types.is_dictionary(col.type):   # categorical columns: their values
            col = col.dictionary_decode()
        t = col.type
        if pa.types.is_integer(t) or pa.types.is_floating(t) or pa.types.is_boolean(t) \
                or pa.types.is_decimal(t) or pa.types.is_null(t):
            arr = pc.cast(col, pa.float64()) if not pa.types.is_null(t) else \
                pa.array(np.full(n, np.nan))
            # Arrow converts the nulls of a floating array to NaN: no masking pass needed
            vals = arr.to_numpy(zero_copy_only=False).astype(np.float64, copy=False)
            nan_mask = np.isnan(vals)
            if not no_null:
                nan_mask &= valid
            if nan_mask.any():
                nan_text[name] = nan_mask
            cols[name] = vals
        elif pa.types.is_timestamp(t) or pa.types.is_date(t):
            s = pd.Series(col.to_pandas())
            s = pd.to_datetime(s, utc=True)
            cols[name] = s.dt.tz_convert("UTC").dt.tz_localize(None).to_numpy("datetime64[ns]")
        elif pa.types.is_string(t) or pa.types.is_large_string(t):
            cols[name], bad, first_bad = _string_column(col, valid)
            if bad is not None:
                bad_text[name] = (bad, first_bad)
            if cols[name].dtype == np.float64:
                txt = pc.fill_null(pc.match_substring_regex(pc.utf8_lower(pc.utf8_trim_whitespace(
                    col)), r"^[+-]?nan$"), False).to_numpy(zero_copy_only=False)
                if txt.any():
                    nan_text[name] = txt
        else:
            # another type: a time of day, a duration (kept as text: the glass-cockpit
            # reader parses its time of day), or one that holds no number or time (struct,
            # list, map, binary: kept as text naming its type); an unused column is ignored
            # like any unknown one (a warning names it), a used one is refused as non-numeric
            # naming its rows
            try:
                txt_col = pc.cast(col, pa.string())
                cols[name] = np.asarray(txt_col.to_pandas(), dtype=object)
            except (pa.ArrowInvalid, pa.ArrowNotImplementedError):
                cols[name] = np.where(valid, f"<{t} column: not read>", None).astype(object)
    blank = np.flatnonzero(all_null) + 1 if fmt == "csv" else np.zeros(0, np.int64)
    nan_is_missing = False
    if nan_text and (fmt == "parquet" or not any_null):
        # Parquet has no empty cell, and a CSV with no empty cell at all writes NaN for "not
        # sampled" (numpy/MATLAB style): there NaN cannot mark an invalid value
        nan_text = {}
        nan_is_missing = True
    return RawTable(file=file, columns=cols, n_rows=n, nan_text=nan_text,
                    blank_rows=blank.astype(np.int64), fmt=fmt, bad_text=bad_text,
                    nan_is_missing=nan_is_missing)


def _string_column(col: pa.Array, valid: np.ndarray) -> tuple[np.ndarray, np.ndarray | None,
                                                                 str | None]:
    """A text column, classified in one vectorised pass.

    Returns ``(values, bad, first_bad)``: float64 values and ``bad=None`` if every non-empty
    cell is a number; float64 values (NaN at the bad cells), the mask of non-numeric cells and
    the first bad text if the column is mostly numbers; an object array of str and ``None`` if
    no cell is a number (timestamps, identifiers).
    """
    blank = pc.fill_null(pc.utf8_is_space(col), False)
    if pc.any(blank).as_py():
        # a cell of spaces only (fixed-width exports pad empty cells) is an empty cell
        col = pc.if_else(blank, pa.scalar(None, pa.string()), col)
        valid = valid & ~blank.to_numpy(zero_copy_only=False)
    ok_arr = pc.fill_null(pc.match_substring_regex(col, NUMERIC_RE), True)
    ok = ok_arr.to_numpy(zero_copy_only=False)
    if ok.all():
        trimmed = pc.utf8_trim_whitespace(col)
        vals = pc.cast(trimmed, pa.float64()).to_numpy(zero_copy_only=False)
        return vals.astype(np.float64), None, None
    if not ok[valid].any():
        return np.asarray(col.to_pandas(), dtype=object), None, None
    kept = pc.if_else(ok_arr, pc.utf8_trim_whitespace(col), pa.scalar(None, pa.string()))
    vals = pc.cast(kept, pa.float64()).to_numpy(zero_copy_only=False).astype(np.float64)
    bad = ~ok
    return vals, bad, str(col[int(np.argmax(bad))].as_py())
