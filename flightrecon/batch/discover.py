"""Which files of a batch are recorder logs, and where their outputs go.

A *log* is a ``*.parquet`` / ``*.csv`` file whose name, once its suffix is removed, does not end
in a companion tag (``.truth``, ``.recon``, ``.gnss``, ``.radar``, ``.summary``, ...): those are
the files ``flightrecon simulate`` / ``reconstruct`` / ``clean`` write beside a log.  Files named
as companions in a log's sidecar (``[files] gnss/radar/mapping``) are not logs either.

Every output of a flight is named from its log's stem, sanitised to ``[A-Za-z0-9._-]`` and
confined to the output folder (docs/batch.md, "Outputs").
"""

from __future__ import annotations

import glob
import hashlib
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

from flightrecon.errors import FlightReconError, InputFileError, OutputError

#: suffixes of a recorder log the batch picks up
LOG_SUFFIXES: tuple[str, ...] = (".parquet", ".csv")

#: last dotted part of a stem that marks a companion, not a log (``x.truth.parquet``)
COMPANION_TAGS: frozenset[str] = frozenset({
    "truth", "recon", "gnss", "radar", "summary", "clean", "cleaning", "sensors", "meta",
    "mapping", "report", "manifest", "averages"})

#: files the batch itself writes in its output folder
BATCH_FILES: frozenset[str] = frozenset({"batch_summary.csv", "batch_summary.parquet",
                                         "aircraft_averages.csv"})

_UNSAFE = re.compile(r"[^A-Za-z0-9._-]+")


@dataclass(frozen=True)
class LogEntry:
    """One flight of a batch: its log, its sidecar (``None`` if absent) and its output name."""

    log: Path
    sidecar: Path | None
    name: str


def log_stem(path: Path) -> str:
    """The name of ``path`` without its log suffix (``a.b.parquet`` -> ``a.b``)."""
    name = path.name
    for s in LOG_SUFFIXES:
        if name.lower().endswith(s):
            return name[: -len(s)]
    return name


def is_log_name(path: Path) -> bool:
    """True for ``*.parquet`` / ``*.csv`` names that are not companions or batch outputs."""
    low = path.name.lower()
    if not low.endswith(LOG_SUFFIXES) or low in BATCH_FILES or low.startswith("."):
        return False
    stem = log_stem(path).lower()
    return not ("." in stem and stem.rsplit(".", 1)[1] in COMPANION_TAGS)


def sanitise_name(stem: str) -> str:
    """A file-name-safe output stem: runs of characters outside ``[A-Za-z0-9._-]`` become ``_``,
    leading dots and dashes are dropped (no hidden files, no option-like names)."""
    s = _UNSAFE.sub("_", stem).lstrip(".-")
    s = re.sub(r"\.{2,}", ".", s)
    return s or "flight"


def confined(out_dir: Path, name: str) -> Path:
    """``out_dir / name``, refusing a name with a separator or a result outside ``out_dir``.

    Raises
    ------
    OutputError
        The path would leave the output folder.
    """
    if not name or "/" in name or "\\" in name or "\x00" in name or name in (".", ".."):
        raise OutputError(f"unsafe output name '{name}'", file=str(out_dir))
    root = out_dir.resolve()
    target = (out_dir / name).resolve()
    if target.parent != root:
        raise OutputError(f"output '{name}' would leave the output folder", file=str(out_dir))
    return out_dir / name


def _expand(item: str | Path) -> list[Path]:
    p = Path(item)
    if p.is_dir():
        return sorted(q for q in p.rglob("*") if q.is_file())
    if p.is_file():
        return [p]
    hits = sorted(Path(h) for h in glob.glob(str(item), recursive=True))
    if not hits:
        raise InputFileError("no such file, folder or matching glob", file=str(item))
    out: list[Path] = []
    for h in hits:
        out.extend(_expand(h) if h.is_dir() else [h])
    return out


def _sidecar_companions(sidecar: Path) -> set[Path]:
    from flightrecon.ingest.sidecar import load_sidecar

    try:
        return {f.resolve() for f in load_sidecar(sidecar).files.values()}
    except FlightReconError:
        return set()  # a broken sidecar fails its own flight, with its message, in the batch


def discover_logs(inputs: Sequence[str | Path], out_dir: str | Path | None = None
                  ) -> list[LogEntry]:
    """The logs named by ``inputs`` (files, folders searched recursively, or globs).

    Parameters
    ----------
    inputs : files, folders or glob patterns
    out_dir : the batch's output folder; files inside it are never taken as logs

    Returns
    -------
    list of LogEntry
        In sorted path order, duplicates removed, each with its sidecar
        (``<stem>.meta.toml``, the normal rule of :func:`flightrecon.ingest.sidecar.discover_sidecar`)
        and a unique sanitised output name (a clash is broken by appending the log's suffix,
        then, for logs of one name in different folders, 8 hex digits of the SHA-256 of the
        resolved path).

    Raises
    ------
    InputFileError
        An input that names nothing, or no log at all.
    """
    from flightrecon.ingest.sidecar import discover_sidecar

    out_root = Path(out_dir).resolve() if out_dir is not None else None
    seen: dict[Path, Path] = {}
    for item in inputs:
        for p in _expand(item):
            r = p.resolve()
            if out_root is not None and out_root in r.parents:
                continue
            if is_log_name(p) and r not in seen:
                seen[r] = p
    entries = []
    companions: set[Path] = set()
    for r, p in sorted(seen.items()):
        sc = discover_sidecar(p)
        if sc is not None:
            companions |= _sidecar_companions(sc)
        entries.append((r, p, sc))
    entries = [e for e in entries if e[0] not in companions]
    if not entries:
        raise InputFileError("no recorder logs (*.parquet, *.csv) among the inputs",
                             file=", ".join(str(i) for i in inputs))
    names = _unique_names(entries)
    return [LogEntry(log=p, sidecar=sc, name=n) for (_, p, sc), n in zip(entries, names)]


def _clashes(names: list[str]) -> set[str]:
    counts: dict[str, int] = {}
    for n in names:
        counts[n.lower()] = counts.get(n.lower(), 0) + 1
    return {n for n, c in counts.items() if c > 1}


def _unique_names(entries: list[tuple[Path, Path, Path | None]]) -> list[str]:
    """Sanitised stems; a clash (case-insensitive) gets ``-<suffix>`` (``x.csv`` beside
    ``x.parquet``), a remaining clash 8 hex digits of the SHA-256 of the resolved path."""
    names = [sanitise_name(log_stem(p)) for _, p, _ in entries]
    clash = _clashes(names)
    names = [f"{n}-{p.suffix.lstrip('.').lower()}" if n.lower() in clash else n
             for n, (_, p, _) in zip(names, entries)]
    clash = _clashes(names)
    return [f"{n}-{hashlib.sha256(str(r).encode()).hexdigest()[:8]}" if n.lower() in clash else n
            for n, (r, _, _) in zip(names, entries)]


def output_paths(out_dir: Path, name: str, fmt: str) -> dict[str, Path]:
    """Result, summary and manifest paths of the flight ``name`` (all confined to ``out_dir``)."""
    return {"result": confined(out_dir, f"{name}.recon.{fmt}"),
            "summary": confined(out_dir, f"{name}.recon.summary.json"),
            "manifest": confined(out_dir, f"{name}.manifest.json")}

