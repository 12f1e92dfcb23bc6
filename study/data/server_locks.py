"""Which process writes a server study database now (issue 24): PostgreSQL session-level
advisory locks, the server's counterpart of the lock files of :mod:`study.data.locks`
(which only the processes of one machine see).

A lock is held by a connection of its own for as long as the process works and is
released by the server when that connection ends, also when the process dies (no stale
locks). Names are those of the lock files: ``synth`` (the one synthetic study writing the
database) and ``session-<code>`` (a participant's session running). The holder is named
by its connection's ``application_name`` (``asa-study <pid> on <host>``). Keys are two
32-bit integers: :data:`NAMESPACE` and the first 31 bits of the name's SHA-256.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import socket
import time
from collections.abc import Callable, Iterator

from sqlalchemy import create_engine, text
from sqlalchemy.engine import Connection
from sqlalchemy.pool import NullPool

from study.data.locks import WAIT_POLL_S, LockHeld

NAMESPACE = 0x41534121  # "ASA!": the first key of every asa-study advisory lock
_HOLDER = text(
    "SELECT a.application_name FROM pg_locks l JOIN pg_stat_activity a ON a.pid = l.pid "
    "WHERE l.locktype = 'advisory' AND l.granted AND l.classid::bigint = :k1 "
    "AND l.objid::bigint = :k2 AND l.objsubid = 2 LIMIT 1"
)


def session_lock(code: str) -> str:
    """The lock name of participant ``code``'s session."""
    return f"session-{code}"


SYNTH = "synth"  # the lock name of the synthetic study writing the database


def lock_keys(name: str) -> tuple[int, int]:
    """The two advisory-lock keys of lock ``name``."""
    digest = hashlib.sha256(f"asa-study:{name}".encode()).digest()
    return NAMESPACE, int.from_bytes(digest[:4], "big") & 0x7FFF_FFFF


def _me() -> str:
    return f"asa-study {os.getpid()} on {socket.gethostname()}"[:63]


def holder(conn: Connection, name: str) -> str:
    """Who holds lock ``name`` (``<pid> on <host>``), or "?"."""
    k1, k2 = lock_keys(name)
    found = conn.execute(_HOLDER, {"k1": k1, "k2": k2}).scalar()
    if not found:
        return "?"
    return str(found).removeprefix("asa-study ")


def is_held(conn: Connection, name: str) -> bool:
    """True when a live connection holds lock ``name`` (this one's own included)."""
    k1, k2 = lock_keys(name)
    return conn.execute(_HOLDER, {"k1": k1, "k2": k2}).first() is not None


@contextlib.contextmanager
def held(
    url: str, name: str, *, wait: bool, on_wait: Callable[[str], None] | None = None
) -> Iterator[None]:
    """Hold lock ``name`` of the server database ``url`` for the block, on a connection
    of its own. Taken by another process: with ``wait``, ``on_wait(holder)`` is called
    once and the lock is awaited; else :class:`study.data.locks.LockHeld`."""
    engine = create_engine(
        url, poolclass=NullPool, connect_args={"application_name": _me()}
    ).execution_options(isolation_level="AUTOCOMMIT")
    k1, k2 = lock_keys(name)
    take = text("SELECT pg_try_advisory_lock(:k1, :k2)")
    try:
        with engine.connect() as conn:
            if not conn.execute(take, {"k1": k1, "k2": k2}).scalar():
                if not wait:
                    raise LockHeld(name, holder(conn, name))
                if on_wait is not None:
                    on_wait(holder(conn, name))
                while not conn.execute(take, {"k1": k1, "k2": k2}).scalar():
                    time.sleep(WAIT_POLL_S)
            yield  # closing the connection releases the lock
    finally:
        engine.dispose()
