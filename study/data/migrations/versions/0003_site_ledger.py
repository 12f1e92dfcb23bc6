"""Revision 0003: a participant's site, a counterbalancing ledger per site and a global key
for every session (multi-site studies, issue 24). ``participant.site`` (nullable: a study
without sites), ``order_slot.site`` (``''`` for a study without sites) with the slot unique
per study and site instead of per study, and ``session.uid`` (a UUID4 string, filled in for
the sessions already there), by which a pushed session is recognised in another database.
``meta.schema_version`` becomes 3.

Revision ID: 0003
Revises: 0002
"""

from __future__ import annotations

import uuid

import sqlalchemy as sa
from alembic import op

revision = "0003"
down_revision = "0002"
branch_labels = None
depends_on = None

_SLOT_COLUMNS = "id, study_id, slot, code, participant_id, status, released, created_at"


def _order_slot(name: str) -> None:
    """The ledger table as this revision has it (as in storage.OrderSlot)."""
    op.create_table(
        name,
        sa.Column("id", sa.Integer(), primary_key=True),
        sa.Column("study_id", sa.Integer(), sa.ForeignKey("study.id"), nullable=False),
        sa.Column("site", sa.String(64), nullable=False, server_default=sa.text("''")),
        sa.Column("slot", sa.Integer(), nullable=False),
        sa.Column("code", sa.String(64), nullable=False),
        sa.Column("participant_id", sa.Integer(), sa.ForeignKey("participant.id"), nullable=True),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("released", sa.JSON(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
        sa.UniqueConstraint("study_id", "site", "slot", name="uq_order_slot_site_slot"),
        sa.UniqueConstraint("study_id", "code", name="uq_order_slot_code"),
    )


def _session_uids() -> None:
    """``session.uid``, one UUID4 per existing session, unique."""
    op.add_column("session", sa.Column("uid", sa.String(36), nullable=True))
    conn = op.get_bind()
    ids = [row[0] for row in conn.execute(sa.text("SELECT id FROM session"))]
    for sid in ids:
        conn.execute(
            sa.text("UPDATE session SET uid = :uid WHERE id = :id"),
            {"uid": str(uuid.uuid4()), "id": sid},
        )
    op.create_index("ix_session_uid", "session", ["uid"], unique=True)


def upgrade() -> None:
    op.add_column("participant", sa.Column("site", sa.String(64), nullable=True))
    _session_uids()
    # the ledger's unique slot changes from (study, slot) to (study, site, slot): a new
    # table, the rows copied, the old one dropped (nothing refers to order_slot; SQLite
    # cannot drop a constraint in place)
    _order_slot("order_slot_0003")
    op.execute(
        f"INSERT INTO order_slot_0003 ({_SLOT_COLUMNS}, site) "
        f"SELECT {_SLOT_COLUMNS}, '' FROM order_slot"
    )
    op.drop_table("order_slot")
    op.rename_table("order_slot_0003", "order_slot")
    if op.get_bind().dialect.name == "postgresql":  # the id sequence keeps counting
        op.execute(
            "SELECT setval(pg_get_serial_sequence('order_slot', 'id'), "
            "COALESCE((SELECT MAX(id) FROM order_slot), 0) + 1, false)"
        )
    op.execute("UPDATE meta SET value = '3' WHERE key = 'schema_version'")


def downgrade() -> None:
    raise NotImplementedError("asa-study offers no downgrade (docs/decisions.md)")
