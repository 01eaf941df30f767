"""The SQLite file of the coefficient store: location, identity checks, opening and locking.

One SQLite file (stdlib :mod:`sqlite3`) holds every aircraft's fits.  It is marked as ours by
``PRAGMA application_id`` (:data:`APPLICATION_ID`, the bytes ``FRCS``) and by a ``store_meta``
table; its schema version is ``PRAGMA user_version`` (:data:`SCHEMA_VERSION`).

Safety rules implemented here (docs/store.md explains them for users):

* An existing file is checked *before* it is opened for writing: the 16-byte SQLite magic and the
  ``application_id`` are read from the raw 100-byte header, then (only for a file that claims to
  be ours) a read-only connection (``mode=ro``) reads ``user_version`` and the ``store_meta``
  marker.  A non-SQLite file or a foreign SQLite database
  raises :class:`~flightrecon.errors.StoreError` and is left byte-identical: no table is ever
  created in a database that is not ours.
* Every change runs inside ``BEGIN IMMEDIATE ... COMMIT`` (the write lock is taken at BEGIN, so
  concurrent writers queue on the busy timeout instead of failing at COMMIT); an exception,
  KeyboardInterrupt included, rolls it back.  A killed process leaves a hot journal / WAL that
  SQLite rolls back on the next open.
* Journal mode WAL where the file system supports it (readers never block the writer), else the
  rollback journal (DELETE) with a note.  WAL needs shared memory between the processes, which
  network file systems (NFS, SMB) do not provide: keep the store on a local disk.
"""

from __future__ import annotations

import contextlib
import os
import sqlite3
import sys
from collections.abc import Iterator
from pathlib import Path

from flightrecon import __version__
from flightrecon.errors import StoreError
from flightrecon.store.schema import (
    APPLICATION_ID,
    APPLICATION_NAME,
    MIGRATIONS,
    SCHEMA_V4_DDL,
    SCHEMA_VERSION,
    create_schema,
)

#: environment variable that overrides the default location
ENV_VAR = "FLIGHTRECON_STORE"
#: seconds a connection waits for another process's lock before giving up
DEFAULT_BUSY_TIMEOUT_S = 30.0

SQLITE_MAGIC = b"SQLite format 3\x00"
SQLITE_HEADER_BYTES = 100


def default_store_path() -> Path:
    """Where the store lives when no ``--store`` is given.

    ``$FLIGHTRECON_STORE`` if set; otherwise the platform's per-user data folder:
    ``$XDG_DATA_HOME/flightrecon`` (default ``~/.local/share/flightrecon``) on Linux and other
    Unix, ``~/Library/Application Support/flightrecon`` on macOS,
    ``%LOCALAPPDATA%\\flightrecon`` on Windows; file name ``coefficients.sqlite``.
    """
    env = os.environ.get(ENV_VAR)
    if env:
        return Path(env).expanduser()
    if sys.platform == "win32":
        base = Path(os.environ.get("LOCALAPPDATA") or Path.home() / "AppData" / "Local")
    elif sys.platform == "darwin":
        base = Path.home() / "Library" / "Application Support"
    else:
        base = Path(os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share")
    return base / "flightrecon" / "coefficients.sqlite"


def _ro_uri(path: Path) -> str:
    return "file:" + path.resolve().as_posix().replace("?", "%3f").replace("#", "%23") + "?mode=ro"


def inspect_existing(path: Path, busy_timeout_s: float = DEFAULT_BUSY_TIMEOUT_S) -> int:
    """Check, without writing, that the existing non-empty ``path`` is a coefficient store.

    Returns
    -------
    int
        Its schema version (``PRAGMA user_version``).

    Raises
    ------
    StoreError
        Not a SQLite file, a SQLite database of another application, a store written by a newer
        flightrecon, or unreadable.  The file is not modified in any case.
    """
    try:
        with open(path, "rb") as fh:
            head = fh.read(SQLITE_HEADER_BYTES)
    except OSError as exc:
        raise StoreError(f"cannot read the coefficient store: {exc.strerror}",
                         file=str(path)) from exc
    if len(head) < SQLITE_HEADER_BYTES or head[:len(SQLITE_MAGIC)] != SQLITE_MAGIC:
        raise StoreError("not a flightrecon coefficient store: the file is not a SQLite database "
                         "(left unchanged; give another --store path)", file=str(path))
    # application_id lives at bytes 68-71 of the header, big-endian (SQLite file format, 1.3).
    # Refusing a foreign database on the raw header means SQLite never opens it: not even the
    # -wal/-shm side files a read-only open of a WAL database would leave beside it.
    raw_app_id = int.from_bytes(head[68:72], "big")
    if raw_app_id != APPLICATION_ID:
        _check_identity(path, raw_app_id, None, SCHEMA_VERSION)
    try:
        con = sqlite3.connect(_ro_uri(path), uri=True, timeout=busy_timeout_s,
                              isolation_level=None)
    except sqlite3.Error as exc:
        raise StoreError(f"cannot open the coefficient store read-only: {exc}",
                         file=str(path)) from exc
    try:
        app_id = con.execute("PRAGMA application_id").fetchone()[0]
        version = con.execute("PRAGMA user_version").fetchone()[0]
        marker = None
        if app_id == APPLICATION_ID:
            has_meta = con.execute("SELECT count(*) FROM sqlite_master WHERE type = 'table' "
                                   "AND name = 'store_meta'").fetchone()[0]
            if has_meta:
                row = con.execute("SELECT value FROM store_meta WHERE key = 'application'"
                                  ).fetchone()
                marker = None if row is None else row[0]
    except sqlite3.OperationalError as exc:  # locked past the timeout, unreadable, I/O error
        raise StoreError(f"cannot read the coefficient store: {exc}", file=str(path)) from exc
    except sqlite3.DatabaseError as exc:
        raise StoreError(f"not a usable coefficient store: the SQLite file is corrupt ({exc}); "
                         "left unchanged", file=str(path)) from exc
    finally:
        con.close()
    _check_identity(path, app_id, marker, version)
    return int(version)


def _check_identity(path: Path, app_id: int, marker: str | None, version: int) -> None:
    if app_id != APPLICATION_ID or marker != APPLICATION_NAME:
        raise StoreError(
            "not a flightrecon coefficient store: a SQLite database of another application "
            f"(application_id {app_id:#010x}, expected {APPLICATION_ID:#010x}); left unchanged",
            file=str(path))
    if version > SCHEMA_VERSION:
        raise StoreError(f"the coefficient store has schema version {version}, newer than this "
                         f"flightrecon ({__version__}) understands ({SCHEMA_VERSION}); upgrade "
                         "flightrecon", file=str(path))
    if version < 1:
        raise StoreError(f"the coefficient store has an invalid schema version {version}",
                         file=str(path))


@contextlib.contextmanager
def write_transaction(con: sqlite3.Connection) -> Iterator[sqlite3.Connection]:
    """``BEGIN IMMEDIATE`` ... ``COMMIT``; any exception (KeyboardInterrupt too) rolls back.

    ``con`` must be in autocommit mode (``isolation_level=None``) so that the module does not
    open transactions behind our back.
    """
    con.execute("BEGIN IMMEDIATE")
    try:
        yield con
    except BaseException:
        with contextlib.suppress(sqlite3.Error):
            con.execute("ROLLBACK")
        raise
    con.execute("COMMIT")


def check_store_path(path: str | os.PathLike, *, write: bool = True) -> None:
    """Refuse, before any work, a coefficient store that this run could not use (exit code 10).

    Nothing is created or modified: the checks only look at the file system and, for an
    existing file, at its header through :func:`inspect_existing`.

    Parameters
    ----------
    path : the store file (``--store``)
    write : the run records into the store (``False``: it only reads it, e.g. fleet
        coefficients; a missing store is then left to the reader's own message)

    Raises
    ------
    StoreError
        Naming the store file: the path is a folder; the file exists but is not a flightrecon
        store (not SQLite, another application's database, a newer schema) or cannot be read;
        and for a run that writes: its folder does not exist or cannot be written (SQLite
        creates its journal beside the store), or the file itself is read-only.
    """
    path = Path(path)
    folder = path.parent if str(path.parent) else Path(".")
    if path.is_dir():
        raise StoreError("the coefficient store path is a folder; give a file", file=str(path))
    if path.exists() and path.stat().st_size > 0:
        inspect_existing(path)
    if not write:
        return
    if not folder.is_dir():
        what = "is not a folder" if folder.exists() else "does not exist"
        raise StoreError(f"the folder of the coefficient store {what}: {folder}",
                         file=str(path))
    if not os.access(folder, os.W_OK | os.X_OK):
        raise StoreError(f"the folder of the coefficient store is not writable: {folder} "
                         "(SQLite writes its journal beside the store; give a --store in a "
                         "folder you can write)", file=str(path))
    if path.exists() and not os.access(path, os.R_OK | os.W_OK):
        raise StoreError("the coefficient store is read-only (no write permission on the "
                         "file): this run records the flight in it; make it writable or give "
                         "another --store", file=str(path))


def connect(path: str | os.PathLike | None = None, *,
            busy_timeout_s: float = DEFAULT_BUSY_TIMEOUT_S,
            create: bool = True) -> tuple[sqlite3.Connection, Path, str]:
    """Open (creating or upgrading as needed) the store at ``path``.

    Parameters
    ----------
    path : store file; ``None`` for :func:`default_store_path` (whose folder is created)
    busy_timeout_s : how long to wait for another process's lock [s]
    create : create a missing store; if False a missing store raises StoreError

    Returns
    -------
    con, path, journal_mode
        An autocommit connection, the store path, and the journal mode in effect
        (``"wal"``, or ``"delete"`` where the file system does not support WAL).
    """
    if path is None:
        path = default_store_path()
        if create:
            try:
                path.parent.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                raise StoreError(f"cannot create the store folder: {exc.strerror}",
                                 file=str(path.parent)) from exc
    path = Path(path)
    if path.is_dir():
        raise StoreError("the coefficient store path is a folder; give a file", file=str(path))
    existed = path.exists() and path.stat().st_size > 0
    if existed:
        inspect_existing(path, busy_timeout_s)
    else:
        if not create:
            raise StoreError("no coefficient store here (it is created when the first flight "
                             "is recorded)", file=str(path))
        if not path.parent.is_dir():
            raise StoreError("the folder of the coefficient store does not exist",
                             file=str(path.parent))
    try:
        con = sqlite3.connect(str(path), timeout=busy_timeout_s, isolation_level=None)
    except sqlite3.Error as exc:
        raise StoreError(f"cannot open the coefficient store: {exc}", file=str(path)) from exc
    try:
        con.execute(f"PRAGMA busy_timeout = {int(busy_timeout_s * 1000):d}")
        _initialise(con, path)
        mode = _set_journal_mode(con)
        con.execute("PRAGMA foreign_keys = ON")
    except sqlite3.Error as exc:
        con.close()
        raise StoreError(f"cannot use the coefficient store: {exc}", file=str(path)) from exc
    except BaseException:
        con.close()
        raise
    return con, path, mode


def _initialise(con: sqlite3.Connection, path: Path) -> None:
    """Create the schema in an empty file, or upgrade an older one, under the write lock.

    An up-to-date store is only read (no write lock: a store on read-only media can still be
    listed).  Otherwise the identity is checked again under the write lock: another process may
    have created or upgraded the file between our first look and now.
    """
    app_id = con.execute("PRAGMA application_id").fetchone()[0]
    version = con.execute("PRAGMA user_version").fetchone()[0]
    if app_id == APPLICATION_ID and version == SCHEMA_VERSION:
        row = con.execute("SELECT value FROM store_meta WHERE key = 'application'").fetchone()
        _check_identity(path, app_id, None if row is None else row[0], version)
        return
    with write_transaction(con):
        n_objects = con.execute("SELECT count(*) FROM sqlite_master").fetchone()[0]
        app_id = con.execute("PRAGMA application_id").fetchone()[0]
        version = con.execute("PRAGMA user_version").fetchone()[0]
        if n_objects == 0 and app_id == 0 and version == 0:
            create_schema(con, SCHEMA_V4_DDL, SCHEMA_VERSION)
            return
        marker = None
        if app_id == APPLICATION_ID and con.execute(
                "SELECT count(*) FROM sqlite_master WHERE name = 'store_meta'").fetchone()[0]:
            row = con.execute("SELECT value FROM store_meta WHERE key = 'application'").fetchone()
            marker = None if row is None else row[0]
        _check_identity(path, app_id, marker, version)
        while version < SCHEMA_VERSION:
            MIGRATIONS[version](con)
            version = con.execute("PRAGMA user_version").fetchone()[0]


def _set_journal_mode(con: sqlite3.Connection) -> str:
    """Switch to WAL if the file system allows it; return the mode in effect."""
    try:
        mode = con.execute("PRAGMA journal_mode = WAL").fetchone()[0]
    except sqlite3.OperationalError:
        # another process holds the database; the mode is persistent, so read what it is
        mode = con.execute("PRAGMA journal_mode").fetchone()[0]
    return str(mode).lower()
