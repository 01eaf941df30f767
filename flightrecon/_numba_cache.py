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
"""

from __future__ import annotations

import os
import sys
import tempfile
from pathlib import Path

#: what :func:`configure` chose, for ``flightrecon info`` and the tests
CHOICE: dict[str, str | None] = {"how": None, "path": None}

#: sub-packages whose modules hold cached kernels (numba writes ``<dir>/__pycache__``)
_KERNEL_DIRS = ("filters", "smoothing", "fusion", "geo", "sim", "estimation")


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
    return dict(CHOICE)
