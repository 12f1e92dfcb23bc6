"""SQLite study files on disk: which file a ``--db`` names, whether an existing file can
be a study database, read-only connections, and creating a new file atomically.

:func:`study.data.storage.open_database` is the only user. A new study file is built
under a temporary name in the same folder (tables and schema version in one go) and
linked into place only when complete, so another process never sees a half-made study;
an existing file must be an SQLite database and is never written before it is known to
be ours. Read-only openings (``asa db check``, ``export``, ``report``, ``replay``) use
SQLite's ``mode=ro`` when a ``-wal`` file shows the database is in use, else
``immutable=1``, so they create no ``-wal``/``-shm`` files and work on a file or folder
the user cannot write (docs/decisions.md, "study/data/storage.py").
"""

from __future__ import annotations

import contextlib
import errno
import os
import re
import sqlite3
import uuid
from collections.abc import Callable
from pathlib import Path
from urllib.parse import quote

SQLITE_HEADER = b"SQLite format 3\x00"
_URL = re.compile(r"^[A-Za-z][A-Za-z0-9+.\-]*://")


def is_url(text: str) -> bool:
    """Whether ``text`` is a SQLAlchemy URL (``scheme://...``) rather than a file path."""
    return bool(_URL.match(text))


def sqlite_url_file(url: str) -> Path | None:
    """The file a ``sqlite://`` URL names (absolute), or None for an in-memory database
    or another backend. ``sqlite:///file:x.db?mode=ro&uri=true`` names ``x.db``."""
    from sqlalchemy.engine import make_url
    from sqlalchemy.exc import ArgumentError

    try:
        parsed = make_url(url)
    except ArgumentError:
        return None
    if parsed.get_backend_name() != "sqlite":
        return None
    name = parsed.database or ""
    if name.startswith("file:"):
        name = name[len("file:") :].split("?", 1)[0]
    if name in ("", ":memory:") or "mode=memory" in url:
        return None
    return Path(name).absolute()


def ro_uri(path: Path) -> str:
    """The SQLite URI that opens ``path`` without writing anything: ``mode=ro`` when a
    ``-wal`` file is beside it (a writer has the database open, or crashed and its
    committed transactions are in the WAL: read them, with SQLite's locking), else
    ``immutable=1`` (no locks, no ``-wal``/``-shm`` files)."""
    has_wal = path.with_name(path.name + "-wal").exists()
    quoted = quote(str(path.absolute()), safe="/")
    return f"file:{quoted}?mode=ro" if has_wal else f"file:{quoted}?immutable=1"


def ro_connect(path: Path) -> sqlite3.Connection:
    """A read-only connection to ``path`` (:func:`ro_uri`)."""
    return sqlite3.connect(ro_uri(path), uri=True, check_same_thread=False)


def check_existing(path: Path, db: str | Path) -> None:
    """Refuse (``ValueError``, one line naming ``db``) a path that is a folder, an empty
    file or a file that is not an SQLite database; reads at most 100 bytes."""
    if path.is_dir():
        raise ValueError(f"{db}: is a folder; give a study database file (SQLite)")
    try:
        with path.open("rb") as f:
            head = f.read(100)
    except OSError as error:
        raise ValueError(f"{db}: cannot be read ({error.strerror or error})") from None
    if not head:
        raise ValueError(
            f"{db}: is an empty file (0 bytes), not an asa-study database; give a study "
            "database or a name that does not exist yet for a new study"
        )
    if not head.startswith(SQLITE_HEADER) or len(head) < 100:
        raise ValueError(
            f"{db}: is not an SQLite file, so not an asa-study database; it was left as it is"
        )


def probe(path: Path) -> tuple[set[str], str | None]:
    """The table names of the SQLite file ``path`` and its ``meta.schema_version`` (None
    without one), read without writing anything (:func:`ro_connect`)."""
    conn = ro_connect(path)
    try:
        tables = {r[0] for r in conn.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
        version = None
        if "meta" in tables:
            row = conn.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
            version = None if row is None else str(row[0])
        return tables, version
    finally:
        conn.close()


def remove_sqlite(path: Path) -> None:
    """Delete ``path`` and its ``-wal``, ``-shm`` and ``-journal`` files, if present."""
    for suffix in ("", "-wal", "-shm", "-journal"):
        with contextlib.suppress(FileNotFoundError):
            path.with_name(path.name + suffix).unlink()


def create_atomically(path: Path, build: Callable[[Path], None]) -> bool:
    """Make the SQLite file ``path`` with ``build(temporary_path)`` and put it in place
    only if ``path`` still does not exist; True if this call made it, False if another
    process made it first (then the temporary file is dropped).

    ``build`` must leave a complete, closed database (tables and schema version). The
    file is linked into place (``os.link`` does not replace an existing file); where the
    file system has no hard links, it is copied into a file opened with ``O_EXCL``.
    """
    tmp = path.with_name(f".{path.name}.{os.getpid()}.{uuid.uuid4().hex[:8]}.creating")
    try:
        build(tmp)
        with tmp.open("rb+") as f:
            os.fsync(f.fileno())
        try:
            os.link(tmp, path)
        except FileExistsError:
            return False
        except OSError as error:
            if error.errno not in (errno.EPERM, errno.ENOTSUP, errno.EOPNOTSUPP, errno.EXDEV):
                raise
            return _copy_exclusive(tmp, path)
        _fsync_folder(path.parent)
        return True
    finally:
        remove_sqlite(tmp)


def _copy_exclusive(src: Path, dst: Path) -> bool:
    """Copy ``src`` into the new file ``dst`` (``O_EXCL``); False if ``dst`` exists."""
    try:
        fd = os.open(dst, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    except FileExistsError:
        return False
    with os.fdopen(fd, "wb") as out:
        out.write(src.read_bytes())
        out.flush()
        os.fsync(out.fileno())
    return True


def _fsync_folder(folder: Path) -> None:
    with contextlib.suppress(OSError):
        fd = os.open(folder, os.O_RDONLY)
        try:
            os.fsync(fd)
        finally:
            os.close(fd)


__all__ = [
    "SQLITE_HEADER",
    "check_existing",
    "create_atomically",
    "is_url",
    "probe",
    "remove_sqlite",
    "ro_connect",
    "ro_uri",
    "sqlite_url_file",
]
