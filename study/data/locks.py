"""Which process writes a study database now (issue 20): advisory lock files in
``<db stem>_locks/`` beside an SQLite study database, held with ``flock`` for as long as
the process works and released by the operating system when it dies (no stale locks).

- ``synth.lock``: the one synthetic study (``asa synth``) writing the database; it owns the
  scratch folder ``<db stem>_work/``.
- ``session-<code>.lock``: a participant's session running (``asa run``), so ``asa db check``
  tells a live session from one cut short by a crash.

Each file holds the holder's pid (for the messages). The files are never deleted (deleting
a lock file that another process is about to lock would let two processes hold it).
Without ``fcntl`` (Windows) the locks are no-ops and every session counts as not live.
"""

from __future__ import annotations

import contextlib
import os
import time
from collections.abc import Callable, Iterator
from pathlib import Path

try:
    import fcntl
except ImportError:  # pragma: no cover - Windows
    fcntl = None  # type: ignore[assignment]

WAIT_POLL_S = 0.2  # [s] between attempts while waiting for a lock


class LockHeld(BlockingIOError):
    """The lock (a file, or a server lock's name) is held by another process (its pid in
    ``pid``)."""

    def __init__(self, path: Path | str, pid: str) -> None:
        super().__init__(f"{path} is held by pid {pid}")
        self.path, self.pid = path, pid


def locks_folder(db_file: Path) -> Path:
    """``<db stem>_locks/`` beside the database file."""
    return db_file.parent / f"{db_file.stem}_locks"


def session_lock(db_file: Path, code: str) -> Path:
    """The lock file of participant ``code``'s session (``code`` is a checked code)."""
    return locks_folder(db_file) / f"session-{code}.lock"


def synth_lock(db_file: Path) -> Path:
    """The lock file of the synthetic study writing ``db_file``."""
    return locks_folder(db_file) / "synth.lock"


def holder(path: Path) -> str:
    """The pid written in a lock file, or "?"."""
    try:
        return path.read_text().strip() or "?"
    except OSError:
        return "?"


def _try(fd: int) -> bool:
    if fcntl is None:
        return True
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return False
    return True


@contextlib.contextmanager
def held(path: Path, *, wait: bool, on_wait: Callable[[str], None] | None = None) -> Iterator[None]:
    """Hold the lock ``path`` for the block. Taken by another process: with ``wait``,
    ``on_wait(pid)`` is called once and the lock is awaited; else :class:`LockHeld`.
    ``OSError`` when the file cannot be made (a read-only folder)."""
    path.parent.mkdir(exist_ok=True)
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        if not _try(fd):
            if not wait:
                raise LockHeld(path, holder(path))
            if on_wait is not None:
                on_wait(holder(path))
            while not _try(fd):
                time.sleep(WAIT_POLL_S)
        os.ftruncate(fd, 0)
        os.write(fd, f"{os.getpid()}\n".encode())
        yield
    finally:
        os.close(fd)  # releases the flock


def is_held(path: Path) -> bool:
    """True when a live process holds the lock ``path`` (never creates the file)."""
    if fcntl is None or not path.is_file():
        return False
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return False
    try:
        if _try(fd):
            fcntl.flock(fd, fcntl.LOCK_UN)
            return False
        return True
    finally:
        os.close(fd)
