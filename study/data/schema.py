"""The study database's schema revision: Alembic, configured in code.

The migrations ship in the package (``study/data/migrations``: ``env.py`` and
``versions/``); no ``alembic.ini`` is read. Every command runs on a connection the caller
opened and holds in a transaction (``config.attributes["connection"]``), so making a
study or upgrading one commits whole or not at all. A database's revision is its
``alembic_version``; one made before the migrations (``meta.schema_version = 1``, no
``alembic_version``) is revision 0001. ``meta.schema_version`` is kept in step by every
revision: it is what older platform versions read (docs/decisions.md, "Schema
migrations").
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

from sqlalchemy import inspect, text
from sqlalchemy.engine import Connection
from sqlalchemy.schema import MetaData

if TYPE_CHECKING:
    from alembic.config import Config

MIGRATIONS = Path(__file__).with_name("migrations")
# the revisions in migrations/versions, oldest first (a test checks them against Alembic's
# script directory): every opening reads them, and importing Alembic takes longer than
# opening a study, so Alembic is imported only to stamp a new database or to upgrade one
REVISIONS = ("0001", "0002", "0003", "0004", "0005")
LEGACY_REVISION = "0001"  # a database with meta.schema_version 1 and no alembic_version


def alembic_config(connection: Connection | None = None) -> Config:
    """Alembic's configuration, built in code, with ``connection`` for ``env.py``."""
    from alembic.config import Config

    config = Config()
    config.set_main_option("script_location", str(MIGRATIONS))
    config.attributes["connection"] = connection
    return config


def head() -> str:
    """The newest revision this platform knows."""
    return REVISIONS[-1]


def revisions() -> list[str]:
    """Every revision this platform knows, oldest first."""
    return list(REVISIONS)


def _stored(conn: Connection) -> list[str]:
    """The revisions in the database's ``alembic_version`` (none without the table)."""
    if "alembic_version" not in inspect(conn).get_table_names():
        return []
    return [str(v) for v in conn.execute(text("SELECT version_num FROM alembic_version")).scalars()]


def database_revision(conn: Connection) -> str | None:
    """The revision of the database on ``conn``: its ``alembic_version`` (several, as
    Alembic's branches would leave, joined with ``+``: none this platform knows), else
    :data:`LEGACY_REVISION` when ``meta.schema_version`` is 1, else None. Writes
    nothing."""
    stored = _stored(conn)
    if stored:
        return "+".join(sorted(stored))
    if "meta" not in inspect(conn).get_table_names():
        return None
    row = conn.execute(text("SELECT value FROM meta WHERE key = 'schema_version'")).first()
    return LEGACY_REVISION if row is not None and str(row[0]) == "1" else None


def is_stamped(conn: Connection) -> bool:
    """Whether the database on ``conn`` records its revision (``alembic_version``)."""
    return bool(_stored(conn))


def stamp_head(conn: Connection) -> None:
    """Record the head revision on a database whose tables were made by ``create_all``."""
    from alembic import command

    command.stamp(alembic_config(conn), "head")


def upgrade_to(conn: Connection, target: str) -> None:
    """Run the migrations from the database's revision to ``target`` on ``conn``, in the
    caller's transaction."""
    from alembic import command

    command.upgrade(alembic_config(conn), target)


def upgrade_line(db: object) -> str:
    """What a user must run to bring ``db`` to this platform's revision."""
    return f"run `asa db upgrade --db {db}` first (back it up before)"


def unknown_line(db: object, current: str | None) -> str:
    """The refusal of a database at a revision this platform does not know."""
    return (
        f"{db}: schema revision {current or 'none'} is not one this platform knows (it "
        f"reads up to {head()}); a newer asa-study made it: upgrade asa-study"
    )


def check_revision(db: object, conn: Connection, metadata: MetaData, *, write: bool) -> None:
    """Refuse (``ValueError``, one line naming ``db``) a database whose revision this
    platform does not know (a newer platform made it), or an older one opened for
    writing, or opened for reading with a table that lacks a column of ``metadata``."""
    current = database_revision(conn)
    newest = head()
    if current == newest:
        return
    if current not in revisions():
        raise ValueError(unknown_line(db, current))
    older = f"{db}: schema revision {current} is older than this platform's {newest}; "
    if write or not _readable(conn, metadata):
        raise ValueError(older + upgrade_line(db))


def _readable(conn: Connection, metadata: MetaData) -> bool:
    """Whether every table of the database that ``metadata`` maps has all its columns."""
    inspector = inspect(conn)
    present = set(inspector.get_table_names())
    for name, table in metadata.tables.items():
        if name in present:
            columns = {c["name"] for c in inspector.get_columns(name)}
            if not set(table.columns.keys()) <= columns:
                return False
    return True
