"""Alembic's environment for the study database's migrations (:mod:`study.data.schema`).

Run only from :mod:`study.data.schema`, which builds the configuration in code and passes
an open connection in ``config.attributes["connection"]`` (Alembic's cookbook, "Sharing a
Connection across one or more programmatic migration commands"): the caller owns the
transaction and its lock, so every step of an upgrade commits together or not at all.
Batch mode (``render_as_batch``) lets a revision alter a SQLite table by copying it.
"""

from __future__ import annotations

from alembic import context

connection = context.config.attributes.get("connection")
if connection is None:
    raise RuntimeError(
        "the asa-study migrations run through study.data.schema (asa db upgrade), "
        "which passes a connection; there is no alembic.ini"
    )
context.configure(connection=connection, render_as_batch=True)
with context.begin_transaction():
    context.run_migrations()
