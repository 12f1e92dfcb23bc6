"""Revision 0002: where a session ran and which sites a study has (multi-site studies,
issue 24): nullable ``session.site`` and ``session.machine``, and ``study.sites`` (a JSON
list, ``[]`` for the studies already there). ``meta.schema_version`` becomes 2.

Revision ID: 0002
Revises: 0001
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None


def upgrade() -> None:
    # ADD COLUMN on both backends (SQLite adds a nullable column, or one with a constant
    # default, in place); a batch operation would copy the table, and dropping the old
    # ``study`` breaks the foreign keys that SQLite enforces inside the transaction
    op.add_column(
        "study", sa.Column("sites", sa.JSON(), nullable=False, server_default=sa.text("'[]'"))
    )
    op.add_column("session", sa.Column("site", sa.String(64), nullable=True))
    op.add_column("session", sa.Column("machine", sa.String(128), nullable=True))
    op.execute("UPDATE meta SET value = '2' WHERE key = 'schema_version'")


def downgrade() -> None:
    raise NotImplementedError("asa-study offers no downgrade (docs/decisions.md)")
