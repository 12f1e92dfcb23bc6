"""Revision 0004: the lab's streams (Lab Streaming Layer, issue 38): the tables
``lsl_stream``, ``lsl_chunk``, ``lsl_offset`` and ``lsl_gap`` (:mod:`study.data.lsl_tables`)
and ``sample.lsl_clock_s`` (nullable: the ticks of a session without LSL have none).
``meta.schema_version`` becomes 4.

Revision ID: 0004
Revises: 0003
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None


def _id() -> sa.Column:
    return sa.Column("id", sa.Integer(), primary_key=True)


def _stream(name: str) -> sa.Column:
    return sa.Column(name, sa.Integer(), sa.ForeignKey("lsl_stream.id"), nullable=False)


def upgrade() -> None:
    op.add_column("sample", sa.Column("lsl_clock_s", sa.Float(), nullable=True))
    op.create_table(
        "lsl_stream",
        _id(),
        sa.Column("session_id", sa.Integer(), sa.ForeignKey("session.id"), nullable=False),
        sa.Column("origin", sa.String(16), nullable=False),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("type", sa.String(64), nullable=False),
        sa.Column("source_id", sa.String(200), nullable=False),
        sa.Column("hostname", sa.String(200), nullable=False),
        sa.Column("channel_count", sa.Integer(), nullable=False),
        sa.Column("nominal_srate", sa.Float(), nullable=False),
        sa.Column("channel_format", sa.String(16), nullable=False),
        sa.Column("dtype", sa.String(8), nullable=False),
        sa.Column("channels", sa.Text(), nullable=False),
        sa.Column("required", sa.Boolean(), nullable=True),
        sa.Column("info_xml", sa.Text(), nullable=False),
        sa.Column("clock_shift_s", sa.Float(), nullable=False),
        sa.Column("source", sa.Text(), nullable=False),
        sa.Column("created_at", sa.DateTime(timezone=True), nullable=False),
    )
    op.create_index("ix_lsl_stream_session", "lsl_stream", ["session_id"])
    op.create_table(
        "lsl_chunk",
        _id(),
        _stream("stream_id"),
        sa.Column("segment", sa.Integer(), nullable=False),
        sa.Column("n", sa.Integer(), nullable=False),
        sa.Column("first_ts", sa.Float(), nullable=False),
        sa.Column("last_ts", sa.Float(), nullable=False),
        sa.Column("received_clock_s", sa.Float(), nullable=False),
        sa.Column("timestamps", sa.LargeBinary(), nullable=False),
        sa.Column("data", sa.LargeBinary(), nullable=False),
    )
    op.create_index("ix_lsl_chunk_stream", "lsl_chunk", ["stream_id", "segment"])
    op.create_table(
        "lsl_offset",
        _id(),
        _stream("stream_id"),
        sa.Column("segment", sa.Integer(), nullable=False),
        sa.Column("clock_s", sa.Float(), nullable=False),
        sa.Column("offset_s", sa.Float(), nullable=False),
    )
    op.create_index("ix_lsl_offset_stream", "lsl_offset", ["stream_id", "segment"])
    op.create_table(
        "lsl_gap",
        _id(),
        _stream("stream_id"),
        sa.Column("segment", sa.Integer(), nullable=False),
        sa.Column("start_clock_s", sa.Float(), nullable=False),
        sa.Column("end_clock_s", sa.Float(), nullable=True),
        sa.Column("trial_id", sa.Integer(), sa.ForeignKey("trial.id"), nullable=True),
    )
    op.create_index("ix_lsl_gap_stream", "lsl_gap", ["stream_id"])
    op.execute("UPDATE meta SET value = '4' WHERE key = 'schema_version'")


def downgrade() -> None:
    raise NotImplementedError("asa-study offers no downgrade (docs/decisions.md)")
