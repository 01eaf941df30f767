"""Atomic output: write to a hidden temporary file in the target folder, then rename.

A killed run leaves at most a hidden ``.<name>.flightrecon-tmp-<pid>-<random>`` file, which
:func:`sweep_leftovers` removes on the next run.  An output never replaces an input file.
"""

from __future__ import annotations

import contextlib
import os
import secrets
from collections.abc import Iterable, Iterator
from pathlib import Path

from flightrecon.errors import OutputError

TMP_TAG = ".flightrecon-tmp-"


def check_not_input(out: str | os.PathLike, inputs: Iterable[str | os.PathLike]) -> Path:
    """Refuse an output path that is one of the inputs (after resolving links)."""
    out_p = Path(out)
    for i in inputs:
        ip = Path(i)
        if ip.exists() and out_p.exists() and os.path.samefile(ip, out_p):
            raise OutputError("refusing to overwrite an input file", file=str(out_p))
        if ip.resolve() == out_p.resolve():
            raise OutputError("refusing to overwrite an input file", file=str(out_p))
    return out_p


def sweep_leftovers(folder: str | os.PathLike) -> list[Path]:
    """Remove temporary files left by killed runs in ``folder``; return what was removed."""
    removed = []
    folder = Path(folder)
    if not folder.is_dir():
        return removed
    for p in folder.glob(f".*{TMP_TAG}*"):
        with contextlib.suppress(OSError):
            p.unlink()
            removed.append(p)
    return removed


@contextlib.contextmanager
def atomic_path(target: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``target``; on success rename it onto ``target``.

    On any exception (KeyboardInterrupt included) the temporary file is removed and the
    previous ``target`` is left untouched.
    """
    target = Path(target)
    folder = target.parent if str(target.parent) else Path(".")
    if not folder.is_dir():
        raise OutputError("output folder does not exist", file=str(folder))
    tmp = folder / f".{target.name}{TMP_TAG}{os.getpid()}-{secrets.token_hex(4)}"
    try:
        yield tmp
        if not tmp.exists():
            raise OutputError("writer produced no file", file=str(target))
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_text_atomic(target: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``target`` atomically."""
    with atomic_path(target) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(target)
