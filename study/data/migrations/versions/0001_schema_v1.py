"""Revision 0001: the schema of ``meta.schema_version = 1``, as ``create_all`` made it
before the migrations (every table of study/data/storage.py then, written out).

A database from before the migrations has these tables and no ``alembic_version``;
upgrading it runs this revision, which makes only the tables it lacks (a study from
before ``question`` or ``order_slot`` existed gets them, as opening it for writing used
to add them), then stamps it.

Revision ID: 0001
Revises: none
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0001"
down_revision = None
branch_labels = None
depends_on = None

# timestamps are UTC-aware: timestamptz on PostgreSQL, DATETIME text on SQLite
_STAMP = sa.DateTime(timezone=True)


def _id() -> sa.Column:
    return sa.Column("id", sa.Integer(), primary_key=True)


def _created_at() -> sa.Column:
    return sa.Column("created_at", _STAMP, nullable=False)


def _meta() -> None:
    op.create_table(
        "meta",
        sa.Column("key", sa.String(64), primary_key=True),
        sa.Column("value", sa.Text(), nullable=False),
    )


def _study() -> None:
    op.create_table(
        "study",
        _id(),
        sa.Column("name", sa.String(200), nullable=False),
        sa.Column("protocol_text", sa.Text(), nullable=False),
        sa.Column("protocol_sha256", sa.String(64), nullable=False),
        sa.Column("platform_version", sa.String(64), nullable=False),
        sa.Column("seed", sa.Integer(), nullable=False),
        _created_at(),
    )


def _participant() -> None:
    op.create_table(
        "participant",
        _id(),
        sa.Column("study_id", sa.Integer(), sa.ForeignKey("study.id"), nullable=False),
        sa.Column("code", sa.String(64), nullable=False),
        sa.Column("kind", sa.String(16), nullable=False),
        sa.Column("parameters", sa.JSON(), nullable=False),
        sa.Column("order_index", sa.Integer(), nullable=False),
        sa.Column("mode_order", sa.JSON(), nullable=False),
        sa.Column("seed", sa.Integer(), nullable=False),
        _created_at(),
        sa.UniqueConstraint("study_id", "code"),
    )


def _session() -> None:
    op.create_table(
        "session",
        _id(),
        sa.Column("participant_id", sa.Integer(), sa.ForeignKey("participant.id"), nullable=False),
        sa.Column("started_at", _STAMP, nullable=False),
        sa.Column("ended_at", _STAMP, nullable=True),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("resumed", sa.Boolean(), nullable=False),
        sa.Column("forced", sa.Boolean(), nullable=False),
        sa.Column("note", sa.Text(), nullable=False),
    )


def _order_slot() -> None:
    op.create_table(
        "order_slot",
        _id(),
        sa.Column("study_id", sa.Integer(), sa.ForeignKey("study.id"), nullable=False),
        sa.Column("slot", sa.Integer(), nullable=False),
        sa.Column("code", sa.String(64), nullable=False),
        sa.Column("participant_id", sa.Integer(), sa.ForeignKey("participant.id"), nullable=True),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("released", sa.JSON(), nullable=False),
        _created_at(),
        sa.UniqueConstraint("study_id", "slot"),
        sa.UniqueConstraint("study_id", "code"),
    )


def _trial() -> None:
    floats = ("completion_time_s", "collisions", "score", "path_length_m")
    floats += ("clearance_mean_m", "clearance_min_m", "tick_jitter_ms")
    op.create_table(
        "trial",
        _id(),
        sa.Column("participant_id", sa.Integer(), sa.ForeignKey("participant.id"), nullable=False),
        sa.Column("session_id", sa.Integer(), sa.ForeignKey("session.id"), nullable=False),
        sa.Column("phase", sa.String(16), nullable=False),
        sa.Column("mode", sa.String(32), nullable=False),
        sa.Column("ordinal", sa.Integer(), nullable=False),
        sa.Column("attempt", sa.Integer(), nullable=False),
        sa.Column("scenario", sa.String(200), nullable=False),
        sa.Column("seed", sa.Integer(), nullable=False),
        sa.Column("status", sa.String(16), nullable=False),
        sa.Column("started_at", _STAMP, nullable=False),
        sa.Column("ended_at", _STAMP, nullable=True),
        sa.Column("completed_task", sa.Boolean(), nullable=True),
        *(
            sa.Column(name, sa.Integer() if name == "collisions" else sa.Float(), nullable=True)
            for name in floats
        ),
        sa.Column("recording_path", sa.Text(), nullable=False),
        sa.Column("outcome", sa.JSON(), nullable=False),
    )
    op.create_index("ix_trial_participant", "trial", ["participant_id", "phase", "ordinal"])


def _sample() -> None:
    floats = ("t", "x", "y", "yaw", "u_x", "u_y", "u_w", "v_x", "v_y", "v_w", "beta")
    op.create_table(
        "sample",
        _id(),
        sa.Column("trial_id", sa.Integer(), sa.ForeignKey("trial.id"), nullable=False),
        sa.Column("tick", sa.Integer(), nullable=False),
        *(sa.Column(name, sa.Float(), nullable=False) for name in floats),
        sa.Column("label", sa.String(32), nullable=False),
        sa.Column("target", sa.String(64), nullable=False),
        sa.Column("min_clearance_m", sa.Float(), nullable=False),
        sa.Column("in_region", sa.Boolean(), nullable=False),
        sa.Column("true_task", sa.String(32), nullable=False),
        sa.Column("true_target", sa.String(64), nullable=False),
    )
    op.create_index("ix_sample_trial_tick", "sample", ["trial_id", "tick"])


def _event() -> None:
    op.create_table(
        "event",
        _id(),
        sa.Column("session_id", sa.Integer(), sa.ForeignKey("session.id"), nullable=False),
        sa.Column("trial_id", sa.Integer(), sa.ForeignKey("trial.id"), nullable=True),
        sa.Column("t", sa.Float(), nullable=False),
        sa.Column("kind", sa.String(32), nullable=False),
        sa.Column("detail", sa.JSON(), nullable=False),
        _created_at(),
    )
    op.create_index("ix_event_trial", "event", ["trial_id", "t"])


def _question() -> None:
    op.create_table(
        "question",
        _id(),
        sa.Column("trial_id", sa.Integer(), sa.ForeignKey("trial.id"), nullable=False),
        sa.Column("block", sa.Integer(), nullable=False),
        sa.Column("index", sa.Integer(), nullable=False),
        sa.Column("text", sa.String(64), nullable=False),
        sa.Column("shown_is_correct", sa.Boolean(), nullable=False),
        sa.Column("shown_t", sa.Float(), nullable=False),
        sa.Column("answered_t", sa.Float(), nullable=True),
        sa.Column("response", sa.Boolean(), nullable=True),
        sa.Column("correct", sa.Boolean(), nullable=False),
        sa.Column("answer_time_s", sa.Float(), nullable=True),
    )
    op.create_index("ix_question_trial", "question", ["trial_id"])


def _response() -> None:
    op.create_table(
        "response",
        _id(),
        sa.Column("participant_id", sa.Integer(), sa.ForeignKey("participant.id"), nullable=False),
        sa.Column("trial_id", sa.Integer(), sa.ForeignKey("trial.id"), nullable=True),
        sa.Column("instrument", sa.String(32), nullable=False),
        sa.Column("item", sa.String(64), nullable=False),
        sa.Column("value", sa.Float(), nullable=True),
        sa.Column("text", sa.Text(), nullable=False),
        _created_at(),
    )
    op.create_index("ix_response_participant", "response", ["participant_id", "instrument"])


# in create_all's order (a table after those it refers to)
TABLES = {
    "meta": _meta,
    "study": _study,
    "participant": _participant,
    "session": _session,
    "order_slot": _order_slot,
    "trial": _trial,
    "sample": _sample,
    "event": _event,
    "question": _question,
    "response": _response,
}


def upgrade() -> None:
    bind = op.get_bind()
    present = set(sa.inspect(bind).get_table_names())
    for name, make in TABLES.items():
        if name not in present:
            make()
    meta = sa.table("meta", sa.column("key", sa.String), sa.column("value", sa.Text))
    version = bind.execute(sa.select(meta.c.value).where(meta.c.key == "schema_version"))
    if version.first() is None:
        op.bulk_insert(meta, [{"key": "schema_version", "value": "1"}])


def downgrade() -> None:
    raise NotImplementedError("asa-study offers no downgrade (docs/decisions.md)")
