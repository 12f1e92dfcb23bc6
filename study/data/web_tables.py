"""Invitations of browser participants (revision 0005; DESIGN.md, "Participants in a
browser"): one row per link handed out by ``asa invite`` or made from Prolific's ids by
``asa serve --prolific``. Only the token's SHA-256 is stored, never the token; the row
carries the participant's code, Prolific's ids when the link had them, and the results of
every browser check the participant took. Imported by :mod:`study.data.storage`, which
re-exports the model. Timestamps are UTC.
"""

from __future__ import annotations

import datetime as dt
from typing import Any

from sqlalchemy import Index, String
from sqlalchemy.orm import Mapped, mapped_column

from study.data.storage import Base, UTCDateTime, utc_now

INVITE_STATUSES = ("issued", "checked", "refused", "running", "aborted", "completed")


class Invite(Base):
    __tablename__ = "invite"
    __table_args__ = (Index("ix_invite_token", "token_sha256", unique=True),)
    id: Mapped[int] = mapped_column(primary_key=True)
    token_sha256: Mapped[str] = mapped_column(String(64))  # hex SHA-256 of the token
    code: Mapped[str] = mapped_column(String(64))  # the participant's code
    prolific: Mapped[dict[str, Any]] = mapped_column(default=dict)  # PROLIFIC_PID, ...
    status: Mapped[str] = mapped_column(String(16), default="issued")  # INVITE_STATUSES
    checks: Mapped[list[Any]] = mapped_column(default=list)  # every browser check's result
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utc_now)
