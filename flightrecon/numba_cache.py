"""Where numba keeps the compiled kernels: a location that works on any installation.

numba caches compiled kernels (``cache=True``) next to the source files, in ``__pycache__``.
On a read-only or system-wide installation that fails over to numba's per-user cache in the
home folder, and with an unwritable home too every import of a kernel module raised
``RuntimeError: cannot cache function ... no locator available`` (exit 1 on every run).
:func:`configure` is run once when :mod:`flightrecon` is imported, before any kernel is
compiled, and picks the first of:

1. ``NUMBA_CACHE_DIR`` when the user set it (numba honours it; nothing is changed);
2. the installation's own folders when they are writable (numba's default);
3. ``<user cache dir>/flightrecon/numba`` (``$XDG_CACHE_HOME`` or ``~/.cache`` on Linux and
   other Unix, ``~/Library/Caches`` on macOS, ``%LOCALAPPDATA%`` on Windows);
4. a private folder in the system's temporary folder (``flightrecon-numba-<user id>``, mode
   0700, used only when it is ours; a fresh one otherwise);
5. no cache at all: the kernels are compiled in each process (a minute on the first
   reconstruction instead of seconds), with a notice on stderr saying so.

Steps 3-5 set ``NUMBA_CACHE_DIR`` (or numba's configuration when numba is already
imported), so child processes use the same cache.

Stale kernels: numba keys a cached kernel on its own source file's time stamp and size, not on
the functions it calls in other files, so after a change to a called function (an upgrade
whose unchanged files keep their stamps, a branch switch) it would load the old compiled code,
silently.  :func:`drop_stale_kernels` keeps a digest of the package's sources beside the
cache and, when it differs, deletes the package's cached kernels: the next run compiles them
again (and says so).
"""

from __future__ import annotations

import hashlib
import os
import sys
import tempfile
from pathlib import Path

#: what :func:`configure` chose, for ``flightrecon info`` and the tests
CHOICE: dict[str, str | None] = {"how": None, "path": None}

#: sub-packages whose modules hold cached kernels (numba writes ``<dir>/__pycache__``)
_KERNEL_DIRS = ("methods", "cleaning", "geo", "sim", "estimation")


def user_cache_dir() -> Path:
    """The platform's per-user cache folder (not created)."""
    if sys.platform == "win32":
        base = os.environ.get("LOCALAPPDATA") or str(Path.home() / "AppData" / "Local")
        return Path(base)
    if sys.platform == "darwin":
        return Path.home() / "Library" / "Caches"
    xdg = os.environ.get("XDG_CACHE_HOME")
    return Path(xdg) if xdg and os.path.isabs(xdg) else Path.home() / ".cache"


def _writable_dir(path: Path) -> bool:
    """True when files can be created in ``path`` (creating it and its parents if needed)."""
    try:
        path.mkdir(parents=True, exist_ok=True)
    except OSError:
        return False
    if not path.is_dir() or not os.access(path, os.W_OK | os.X_OK):
        return False
    try:
        fd, name = tempfile.mkstemp(dir=path, prefix=".flightrecon-probe-")
    except OSError:
        return False
    os.close(fd)
    try:
        os.unlink(name)
    except OSError:
        pass
    return True


def _tree_writable(pkg: Path) -> bool:
    """True when numba can cache next to the sources: it writes ``<dir>/__pycache__`` beside
    each module with a cached kernel; probed by creating a file there, as numba itself does,
    in every package folder under the kernel folders."""
    for sub in _KERNEL_DIRS:
        top = pkg / sub
        if not top.is_dir():
            continue
        for d in [top, *sorted(p for p in top.rglob("*") if p.is_dir()
                               and p.name != "__pycache__" and (p / "__init__.py").exists())]:
            if not _writable_dir(d / "__pycache__"):
                return False
    return True


def _private_temp() -> Path | None:
    uid = os.getuid() if hasattr(os, "getuid") else os.getpid()
    p = Path(tempfile.gettempdir()) / f"flightrecon-numba-{uid}"
    try:
        p.mkdir(mode=0o700, exist_ok=True)
        st = os.lstat(p)
        ours = not p.is_symlink() and (not hasattr(os, "getuid") or st.st_uid == os.getuid())
        if ours and _writable_dir(p):
            return p
    except OSError:
        pass
    try:
        return Path(tempfile.mkdtemp(prefix="flightrecon-numba-"))
    except OSError:
        return None


def _set_cache_dir(path: Path) -> None:
    os.environ["NUMBA_CACHE_DIR"] = str(path)
    if "numba" in sys.modules:  # numba read its configuration already
        from numba.core import config

        setattr(config, "CACHE_DIR", str(path))  # noqa: B010 - numba's config module


def _disable_cache() -> None:
    """Compile without caching: numba's dispatchers keep their null cache."""
    from numba.core import dispatcher

    dispatcher.Dispatcher.enable_caching = lambda self: None  # type: ignore[method-assign]


def configure(pkg_dir: Path | None = None) -> dict[str, str | None]:
    """Choose the kernel cache (module docstring); returns ``{"how", "path"}``."""
    pkg = Path(pkg_dir) if pkg_dir is not None else Path(__file__).resolve().parent
    if os.environ.get("NUMBA_CACHE_DIR"):
        CHOICE.update(how="NUMBA_CACHE_DIR", path=os.environ["NUMBA_CACHE_DIR"])
    elif _tree_writable(pkg):
        CHOICE.update(how="installation", path=str(pkg))
    else:
        user = user_cache_dir() / "flightrecon" / "numba"
        if _writable_dir(user):
            _set_cache_dir(user)
            CHOICE.update(how="user cache", path=str(user))
        else:
            tmp = _private_temp()
            if tmp is not None:
                _set_cache_dir(tmp)
                CHOICE.update(how="temporary", path=str(tmp))
            else:
                _disable_cache()
                CHOICE.update(how="none", path=None)
                print("flightrecon: notice: no writable folder for the compiled-kernel cache "
                      "(installation, user cache and temporary folder are read-only): kernels "
                      "are compiled in every run; set NUMBA_CACHE_DIR to a writable folder",
                      file=sys.stderr)
    if CHOICE["how"] != "none":
        drop_stale_kernels(pkg, os.environ.get("NUMBA_CACHE_DIR") or None)
    return dict(CHOICE)


#: package folders that hold no compiled kernel and that no kernel calls into: their sources
#: do not enter the digest (tests/testnumba_cache.py checks that they hold no kernel)
NO_KERNEL_DIRS = ("cli", "report", "export", "batch", "store", "ingest")

#: the digest's file, in the cache folder of the package's top level
DIGEST_FILE = "flightrecon-kernel-sources.sha1"


def sources_digest(pkg: Path) -> str:
    """SHA-1 of the package's Python sources (relative paths and contents, sorted), except
    :data:`NO_KERNEL_DIRS`."""
    h = hashlib.sha1()
    for f in sorted(pkg.rglob("*.py")):
        rel = f.relative_to(pkg)
        if rel.parts[0] in NO_KERNEL_DIRS or "__pycache__" in rel.parts:
            continue
        h.update(str(rel.as_posix()).encode())
        h.update(b"\0")
        h.update(f.read_bytes())
        h.update(b"\0")
    return h.hexdigest()


def kernel_cache_dirs(pkg: Path, cache_dir: str | None) -> list[Path]:
    """Where numba keeps the cached kernels of each of the package's folders: ``__pycache__``
    beside the sources, or with ``NUMBA_CACHE_DIR`` its ``<folder>_<sha1 of the folder's
    path>`` subfolder (numba's ``UserProvidedCacheLocator``).  The top level first."""
    dirs = [pkg, *sorted(p for p in pkg.rglob("*") if p.is_dir() and p.name != "__pycache__"
                         and "__pycache__" not in p.parts and (p / "__init__.py").exists())]
    if cache_dir is None:
        return [d / "__pycache__" for d in dirs]
    out = []
    for d in dirs:
        path = os.path.abspath(d)
        out.append(Path(cache_dir) / f"{os.path.split(path)[-1]}_"
                   f"{hashlib.sha1(path.encode()).hexdigest()}")
    return out


def drop_stale_kernels(pkg: Path, cache_dir: str | None) -> bool:
    """Delete the package's cached kernels (``*.nbi``, ``*.nbc``) when its sources differ from
    those they were compiled from (module docstring); returns True when it deleted any.

    The digest is written after the deletion, atomically; any file-system error leaves the
    cache as it is (numba's own per-file check still applies).
    """
    try:
        dirs = kernel_cache_dirs(pkg, cache_dir)
        digest = sources_digest(pkg)
        marker = dirs[0] / DIGEST_FILE
        if marker.is_file() and marker.read_text().strip() == digest:
            return False
        dropped = False
        for d in dirs:
            if not d.is_dir():
                continue
            for f in [*d.glob("*.nbi"), *d.glob("*.nbc")]:
                try:
                    f.unlink()
                    dropped = True
                except FileNotFoundError:  # another process dropped it first
                    pass
        dirs[0].mkdir(parents=True, exist_ok=True)
        tmp = dirs[0] / f".{DIGEST_FILE}.{os.getpid()}"
        tmp.write_text(digest + "\n")
        os.replace(tmp, marker)
        return dropped
    except OSError:
        return False
