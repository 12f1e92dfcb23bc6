"""``asa db upgrade``: bring a study database to this platform's schema revision.

The migrations (:mod:`study.data.schema`) run on one connection in one transaction
under the database's write lock (SQLite ``BEGIN IMMEDIATE``, PostgreSQL the study's
advisory lock; both backends roll DDL back), so an upgrade that fails leaves the
database as it was. A database from before the migrations is revision 0001 and is
stamped on the way. There is no downgrade (docs/decisions.md, "Schema migrations").
"""

from __future__ import annotations

from pathlib import Path

from sqlalchemy import create_engine, inspect, select, text
from sqlalchemy.engine import Connection, Engine
from sqlalchemy.exc import ArgumentError, DBAPIError, NoSuchModuleError

from study.data import locks, schema, server_locks
from study.data.dbfile import check_existing, is_url, probe
from study.data.storage import (
    PG_STUDY_LOCK,
    Meta,
    _check_schema,
    _sqlite_engine,
    database_file,
    database_url,
    is_server,
)


def upgrade(db: str | Path, *, to: str = "head") -> tuple[str, str]:
    """Upgrade the study database ``db`` (a path or a SQLAlchemy URL) to revision ``to``
    (``"head"``: the newest); returns (revision before, revision after).

    Raises ``ValueError`` (one line naming ``db``) for a database that does not exist, is
    not an asa-study database, cannot be reached, is at a revision this platform does not
    know, or is past ``to`` (no downgrade); and for an unknown ``to``.
    """
    try:
        engine = _server_engine(db) if is_server(db) else _sqlite_file_engine(db)
    except (NoSuchModuleError, ArgumentError, ImportError) as error:
        raise ValueError(f"{db}: not a database URL this platform can open ({error})") from None
    try:
        return _upgrade(db, engine, to)
    except DBAPIError as error:
        reason = " ".join(str(error.orig or error).split())
        raise ValueError(f"{db}: cannot be upgraded ({reason})") from error
    finally:
        engine.dispose()


def _sqlite_file_engine(db: str | Path) -> Engine:
    path = database_file(db)
    if not path.exists():
        raise ValueError(f"{db}: no such file; give an existing study database")
    check_existing(path, db)
    tables, version = probe(path)
    _check_schema(db, tables, version)
    return _sqlite_engine(path, str(db) if is_url(str(db)) else None, durable=True, readonly=False)


def _server_engine(db: str | Path) -> Engine:
    engine = create_engine(database_url(db), pool_pre_ping=True)
    try:
        tables = set(inspect(engine).get_table_names())
        version = None
        if "meta" in tables:
            with engine.connect() as conn:
                version = conn.execute(
                    select(Meta.value).where(Meta.key == "schema_version")
                ).scalar()
        _check_schema(db, tables, version)
    except DBAPIError as error:
        engine.dispose()
        reason = " ".join(str(error.orig or error).split())
        raise ValueError(f"{db}: cannot be reached ({reason}); check the URL") from None
    except BaseException:
        engine.dispose()
        raise
    return engine


def _lock(conn: Connection) -> None:
    """Take the database's write lock for the rest of the transaction."""
    if conn.dialect.name == "sqlite":
        conn.exec_driver_sql("BEGIN IMMEDIATE")
    elif conn.dialect.name == "postgresql":
        conn.execute(text("SELECT pg_advisory_xact_lock(:key)"), {"key": PG_STUDY_LOCK})


def _live_writers(db: str | Path, conn: Connection) -> list[str]:
    """The participants whose session a live process holds (a running ``asa run``), and
    ``synth`` when a synthetic study is writing: read with plain SQL, whatever the
    revision."""
    codes = conn.execute(
        text(
            "SELECT DISTINCT p.code FROM session s JOIN participant p ON p.id = s.participant_id "
            "WHERE s.status = 'running' ORDER BY p.code"
        )
    ).scalars()
    if conn.dialect.name == "postgresql":
        live = [c for c in codes if server_locks.is_held(conn, server_locks.session_lock(c))]
        return live + (["synth"] if server_locks.is_held(conn, server_locks.SYNTH) else [])
    path = database_file(db)
    live = [c for c in codes if locks.is_held(locks.session_lock(path, c))]
    return live + (["synth"] if locks.is_held(locks.synth_lock(path)) else [])


def _refuse_live(db: str | Path, conn: Connection) -> None:
    """Refuse to migrate under running sessions: the platform that runs them writes the
    schema it knows (docs/decisions.md, "Schema migrations")."""
    live = _live_writers(db, conn)
    if live:
        who = ", ".join("a synthetic study" if c == "synth" else c for c in live)
        raise ValueError(
            f"{db}: {len(live)} session(s) are running ({who}); upgrade when they have "
            "ended (a running platform writes the schema it knows)"
        )


def _upgrade(db: str | Path, engine: Engine, to: str) -> tuple[str, str]:
    known = schema.revisions()
    target = schema.head() if to == "head" else to
    if target not in known:
        raise ValueError(f"{db}: no schema revision {to!r} (this platform has {', '.join(known)})")
    with engine.connect() as conn:
        _lock(conn)
        current = schema.database_revision(conn)
        if current not in known:
            raise ValueError(schema.unknown_line(db, current))
        if known.index(target) < known.index(current):
            raise ValueError(
                f"{db}: is at schema revision {current}, past {target}; asa-study offers "
                "no downgrade (restore a backup instead)"
            )
        if target != current or not schema.is_stamped(conn):
            _refuse_live(db, conn)
            schema.upgrade_to(conn, target)
        conn.commit()
    return current, target
