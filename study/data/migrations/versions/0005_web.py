"""Revision 0005: participants in a browser (issue 37): ``sample.input_age_ticks`` and
``sample.rtt_ms`` (nullable: only a browser participant's ticks have them) and the table
``invite`` (:mod:`study.data.web_tables`). ``meta.schema_version`` becomes 5.

Revision ID: 0005
Revises: 0004
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column("sample", sa.Column("input_age_ticks", sa.Integer(), nullable=True))
    op.add_column("sample", sa.Column("rtt_ms", sa.Float(), nullable=True))
    op.create_table(
        "invite",
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("token_sha256", sa.String(64), nullable=False),
        sa.Column("code", sa.String(64), nullable=False),
        sa.Column("prolific", sa.JSON(), nullable=False),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("checks", sa.JSON(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
    )
    op.create_index("ix_invite_token", "invite", ["token_sha256"], unique=True)
    op.execute("UPDATE meta SET value = '5' WHERE key = 'schema_version'")


def downgrade() -> None:
    raise NotImplementedError("asa-study offers no downgrade (docs/decisions.md)")
