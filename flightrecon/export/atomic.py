"""Atomic output: outputs are staged beside their targets, then published together.

* :func:`atomic_path` writes one file: a hidden temporary file in the target folder, renamed
  onto the target when complete (``os.replace``: readers see the old file or the new one).
* :class:`Publication` publishes several outputs as one unit (a result, its summary, its report
  folder): each is written completely into a hidden staging folder beside its target, and only
  then are all of them renamed into place, with the signals the process can catch deferred
  until the last rename is done. An interrupt before the publication leaves every old output; an
  interrupt during it is held back until the outputs are all new. Before the renames a small
  journal is written into the first staging folder, so that even a ``SIGKILL`` in the middle
  of the renames is completed (rolled forward) by the next run's :func:`sweep_leftovers`.
* :func:`check_outputs` refuses, before any work, an output path that is an input of the run,
  that another output also uses, or whose folder cannot be written (exit code 9).

A killed run leaves at most hidden ``.<name>.flightrecon-tmp-<pid>-<random>`` files or staging
folders, which :func:`sweep_leftovers` removes (or completes) on the next run, unless the process
that made them is still running.
"""

from __future__ import annotations

import contextlib
import json
import os
import re
import secrets
import shutil
import signal
import threading
from collections.abc import Callable, Iterable, Iterator, Mapping
from pathlib import Path
from typing import Self

from flightrecon.errors import OutputError

TMP_TAG = ".flightrecon-tmp-"
JOURNAL = "publish.journal.json"

#: signals a process can catch whose default action ends it: handled like Ctrl-C (the CLI
#: installs handlers for them; see :mod:`flightrecon.cli.main`), deferred while publishing
CATCHABLE_SIGNALS: tuple[int, ...] = tuple(
    getattr(signal, n) for n in ("SIGINT", "SIGTERM", "SIGHUP", "SIGQUIT", "SIGUSR1", "SIGUSR2",
                                 "SIGALRM", "SIGXCPU", "SIGXFSZ", "SIGVTALRM", "SIGPROF")
    if hasattr(signal, n))

_PID_RE = re.compile(re.escape(TMP_TAG) + r"(\d+)-")


def _same(a: Path, b: Path) -> bool:
    """True when ``a`` and ``b`` name the same file (same inode, or the same resolved path)."""
    try:
        if a.exists() and b.exists() and os.path.samefile(a, b):
            return True
    except OSError:
        pass
    try:
        return a.resolve() == b.resolve()
    except (OSError, RuntimeError):
        return os.path.abspath(a) == os.path.abspath(b)


def _inside(p: Path, folder: Path) -> bool:
    try:
        p.resolve().relative_to(folder.resolve())
        return True
    except (ValueError, OSError, RuntimeError):
        return False


def check_not_input(out: str | os.PathLike, inputs: Iterable[str | os.PathLike]) -> Path:
    """Refuse an output path that is one of the inputs (after resolving links)."""
    out_p = Path(out)
    for i in inputs:
        if _same(Path(i), out_p):
            raise OutputError(f"refusing to overwrite an input file ({i})", file=str(out_p))
    return out_p


def _folder_of(p: Path) -> Path:
    return p.parent if str(p.parent) else Path(".")


def check_writable_folder(folder: Path, what: str, target: Path) -> None:
    """Raise :class:`OutputError` unless ``folder`` exists and files can be created in it."""
    if not folder.exists():
        raise OutputError(f"the folder for the {what} does not exist: {folder}", file=str(target))
    if not folder.is_dir():
        raise OutputError(f"the folder for the {what} is not a folder: {folder}",
                          file=str(target))
    if not os.access(folder, os.W_OK | os.X_OK):
        raise OutputError(f"the folder for the {what} is not writable: {folder}",
                          file=str(target))


def check_outputs(outputs: Mapping[str, str | os.PathLike | None],
                  inputs: Mapping[str, str | os.PathLike | None], *,
                  folders: Mapping[str, str | os.PathLike | None] | None = None,
                  folder_names: Callable[[str], bool] | None = None,
                  created_folders: Iterable[str] = (),
                  own_checks: Iterable[str] = ()) -> None:
    """Check every output of a run against every input and against the other outputs.

    Parameters
    ----------
    outputs : label -> file the run writes (``None`` entries are ignored), e.g.
        ``{"result": ..., "summary": ..., "store": ...}``
    inputs : label -> file the run reads (``None`` ignored)
    folders : label -> folder the run writes files into (a report folder)
    folder_names : predicate on a file name: True for the names the run writes into
        ``folders`` (an input with such a name inside such a folder would be replaced)
    created_folders : labels of outputs whose folder is created by their writer: their
        folder is not required to exist
    own_checks : labels of outputs whose folder and file the caller checks itself, with its
        own error (a coefficient store: a store error, exit code 10); only the checks against
        the inputs and the other outputs are made here

    Raises
    ------
    OutputError
        An output that is an input (same path or same file through a link), two outputs on one
        path, an output that is an existing folder, a report folder that is a file or an input,
        or an output folder that does not exist or cannot be written.  Exit code 9.
    """
    outs = {k: Path(v) for k, v in outputs.items() if v is not None}
    ins = {k: Path(v) for k, v in inputs.items() if v is not None}
    dirs = {k: Path(v) for k, v in (folders or {}).items() if v is not None}
    for label, p in outs.items():
        if str(p) in ("", "."):
            raise OutputError(f"the {label} path is empty", file=str(p))
        for ilabel, ip in ins.items():
            if _same(ip, p):
                raise OutputError(f"refusing to write the {label} over the {ilabel} (an input "
                                  "of this run)", file=str(p))
        if p.is_dir() and label not in own_checks:
            raise OutputError(f"the {label} path is an existing folder", file=str(p))
    labels = list(outs)
    for i, a in enumerate(labels):
        for b in labels[i + 1:]:
            if _same(outs[a], outs[b]):
                raise OutputError(f"the {a} and the {b} would be written to the same file",
                                  file=str(outs[a]))
    for label, d in dirs.items():
        for ilabel, ip in ins.items():
            if _same(ip, d):
                raise OutputError(f"the {label} folder is the {ilabel} (an input of this run)",
                                  file=str(d))
        if d.exists() and not d.is_dir():
            raise OutputError(f"the {label} folder is an existing file", file=str(d))
        for ilabel, ip in ins.items():
            if folder_names is not None and _same(_folder_of(ip), d) and folder_names(ip.name):
                raise OutputError(f"the {label} would replace the {ilabel} {ip} (an input of this "
                                  "run)", file=str(d))
        for olabel, op in outs.items():
            if _same(op, d):
                raise OutputError(f"the {olabel} and the {label} folder are the same path",
                                  file=str(d))
            if folder_names is not None and _same(_folder_of(op), d) and folder_names(op.name):
                raise OutputError(f"the {label} would replace the {olabel} {op}", file=str(d))
        parent = d
        while not parent.exists() and parent != _folder_of(parent):
            parent = _folder_of(parent)
        if parent.exists() and (not parent.is_dir()
                                or not os.access(parent, os.W_OK | os.X_OK)):
            raise OutputError(f"the {label} folder cannot be written ({parent} is not a writable "
                              "folder)", file=str(d))
    for label, p in outs.items():
        if label in own_checks:
            continue
        if label not in created_folders or _folder_of(p).exists():
            check_writable_folder(_folder_of(p), label, p)


# ------------------------------------------------------------------ leftovers of killed runs

def _pid_alive(pid: int) -> bool:
    if pid == os.getpid():
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else
        return True
    except OSError:
        return False
    return True


def _roll_forward(journal: Path) -> None:
    """Finish a publication whose renames a killed process left half done."""
    try:
        moves = json.loads(journal.read_text(encoding="utf-8"))["moves"]
    except (OSError, ValueError, KeyError, TypeError):
        return
    for src, dst, kind in moves:
        _move_into_place(Path(src), Path(dst), kind)


def sweep_leftovers(folder: str | os.PathLike) -> list[Path]:
    """Remove temporary files and staging folders of killed runs in ``folder``.

    Leftovers of a process that is still running are kept; a staging folder with a complete
    publication journal is published first (its renames completed).  Returns what was removed.
    """
    removed: list[Path] = []
    folder = Path(folder)
    if not folder.is_dir():
        return removed
    try:
        entries = list(folder.iterdir())
    except OSError:
        return removed
    for p in entries:
        if not p.name.startswith(".") or TMP_TAG not in p.name:
            continue
        m = _PID_RE.search(p.name)
        if m and _pid_alive(int(m.group(1))):
            continue
        with contextlib.suppress(OSError):
            if p.is_dir() and not p.is_symlink():
                j = p / JOURNAL
                if j.is_file():
                    _roll_forward(j)
                shutil.rmtree(p)
            else:
                p.unlink()
            removed.append(p)
    return removed


# ------------------------------------------------------------------ single files

@contextlib.contextmanager
def atomic_path(target: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``target``; on success rename it onto ``target``.

    On any exception (KeyboardInterrupt and the CLI's signal exceptions included) the temporary
    file is removed and the previous ``target`` is left untouched.  A folder that does not
    exist or cannot be written is an :class:`OutputError` (exit code 9).
    """
    target = Path(target)
    folder = _folder_of(target)
    if not folder.is_dir():
        raise OutputError(f"the output folder does not exist: {folder}", file=str(target))
    tmp = folder / f".{target.name}{TMP_TAG}{os.getpid()}-{secrets.token_hex(4)}"
    try:
        yield tmp
        if not tmp.exists():
            raise OutputError("writer produced no file", file=str(target))
        with open(tmp, "rb+") as fh:
            os.fsync(fh.fileno())
        os.replace(tmp, target)
    except PermissionError as exc:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise OutputError(f"cannot write: {exc.strerror or exc}", file=str(target)) from exc
    except BaseException:
        with contextlib.suppress(OSError):
            tmp.unlink()
        raise


def write_text_atomic(target: str | os.PathLike, text: str) -> Path:
    """Write ``text`` (UTF-8) to ``target`` atomically."""
    with atomic_path(target) as tmp:
        tmp.write_text(text, encoding="utf-8")
    return Path(target)


# ------------------------------------------------------------------ deferred signals

_pending: list[int] = []
_lock = threading.Lock()
_depth = [0]


def signals_are_deferred() -> bool:
    """True inside :func:`deferred_signals`."""
    return _depth[0] > 0


def defer_signal(signum: int) -> None:
    """Record ``signum`` to be acted on when the current :func:`deferred_signals` block ends."""
    with _lock:
        _pending.append(signum)


@contextlib.contextmanager
def deferred_signals() -> Iterator[None]:
    """Hold back the catchable signals (:data:`CATCHABLE_SIGNALS`) while the block runs.

    In the main thread the handlers are replaced for the duration by one that only records the
    signal; at the end the previous handlers are restored and the first recorded signal is
    delivered to them (the CLI's handler then raises, a default disposition ends the process as
    it would have).  Elsewhere (not the main thread) the block runs as is.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = {}

    def record(signum, frame):
        defer_signal(signum)

    for s in CATCHABLE_SIGNALS:
        try:
            previous[s] = signal.signal(s, record)
        except (OSError, ValueError):
            pass
    _depth[0] += 1
    try:
        yield
    finally:
        _depth[0] -= 1
        for s, h in previous.items():
            with contextlib.suppress(OSError, ValueError, TypeError):
                signal.signal(s, h)
        with _lock:
            pending = list(_pending)
            _pending.clear()
        if pending:
            s = pending[0]
            h = previous.get(s)
            if callable(h):
                h(s, None)
            elif h == signal.SIG_DFL:
                os.kill(os.getpid(), s)


# ------------------------------------------------------------------ several outputs, one unit

def _move_into_place(src: Path, dst: Path, kind: str) -> None:
    """Rename a staged file onto its target, or move a staged folder's files into the target
    folder (renaming the folder itself into place when the target does not exist yet)."""
    if kind == "file":
        if src.exists():
            os.replace(src, dst)
        return
    if not src.is_dir():
        return
    if not dst.exists():
        with contextlib.suppress(OSError):
            os.rename(src, dst)
            return
    dst.mkdir(parents=True, exist_ok=True)
    for f in sorted(src.iterdir()):
        if f.name.startswith(".") and TMP_TAG in f.name:
            continue
        os.replace(f, dst / f.name)


class Publication:
    """Publish several outputs as one unit: all new, or (on any error or interrupt before
    :meth:`commit`) all old.

    Usage::

        with Publication() as pub:
            write_track(pub.file(out), ...)          # staged beside out, with out's name
            write_report(pub.folder(report_dir), ...)
            pub.commit()                              # renames, signals deferred

    Leaving the ``with`` block without :meth:`commit` (an exception, Ctrl-C, SIGTERM) removes
    everything staged.  The staging folders are hidden (``.<name>.flightrecon-tmp-<pid>-...``)
    in the target's own folder, so each publication step is a rename on one file system.
    """

    def __init__(self) -> None:
        self._stages: dict[Path, Path] = {}   # target folder -> staging folder
        self._moves: list[tuple[Path, Path, str]] = []
        self.committed = False

    def _stage_dir(self, folder: Path, name: str) -> Path:
        key = folder.resolve() if folder.exists() else folder.absolute()
        if key not in self._stages:
            check_writable_folder(folder, "output", folder / name)
            d = folder / f".{name}{TMP_TAG}{os.getpid()}-{secrets.token_hex(4)}"
            try:
                d.mkdir()
            except PermissionError as exc:
                raise OutputError(f"cannot write: {exc.strerror or exc}",
                                  file=str(folder / name)) from exc
            self._stages[key] = d
        return self._stages[key]

    def file(self, target: str | os.PathLike) -> Path:
        """Where to write ``target`` (same name, in a staging folder beside it)."""
        target = Path(target)
        staged = self._stage_dir(_folder_of(target), target.name) / target.name
        self._moves.append((staged, target, "file"))
        return staged

    def folder(self, target: str | os.PathLike) -> Path:
        """Where to write the files of the folder ``target`` (a fresh empty folder; its files
        are moved into ``target`` on commit, ``target`` and its parents created if needed)."""
        target = Path(target).absolute()
        base = target if target.is_dir() else _folder_of(target)
        try:
            base.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            raise OutputError(f"cannot create the folder: {exc.strerror or exc}",
                              file=str(base)) from exc
        staged = self._stage_dir(base, target.name or "folder") / f"folder-{len(self._moves)}"
        staged.mkdir()
        self._moves.append((staged, target, "folder"))
        return staged

    def commit(self, before: Callable[[], None] | None = None) -> None:
        """Publish every staged output; ``before`` (e.g. a store transaction) runs first, in
        the same signal-deferred block, so it is published with them or not at all."""
        with deferred_signals():
            if before is not None:
                before()
            for staged, _, kind in self._moves:
                if kind == "file" and not staged.exists():
                    raise OutputError("writer produced no file", file=str(staged))
            stages = list(self._stages.values())
            if stages:
                journal = stages[0] / JOURNAL
                doc = {"moves": [[str(s.absolute()), str(t.absolute()), k]
                                 for s, t, k in self._moves]}
                with open(journal, "w", encoding="utf-8") as fh:
                    fh.write(json.dumps(doc))
                    fh.flush()
                    os.fsync(fh.fileno())
            try:
                for staged, target, kind in self._moves:
                    _move_into_place(staged, target, kind)
            except PermissionError as exc:
                raise OutputError(f"cannot write: {exc.strerror or exc}",
                                  file=str(exc.filename or "")) from exc
            self.committed = True
            self._cleanup()

    def _cleanup(self) -> None:
        for d in self._stages.values():
            with contextlib.suppress(OSError):
                shutil.rmtree(d)
        self._stages.clear()

    def __enter__(self) -> Self:
        return self

    def __exit__(self, *exc) -> None:
        if not self.committed:
            with deferred_signals():
                self._cleanup()
