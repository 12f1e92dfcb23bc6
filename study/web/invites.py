"""Invitations: the links that open a participant's session in the browser (issue 37).

A token is 128 random bits, URL-safe (``secrets.token_urlsafe(16)``); the database keeps
only its SHA-256 (:class:`study.data.storage.Invite`), so a copy of the database opens no
session. A link is ``<base>/s/<token>``; a Prolific link (``/join?PROLIFIC_PID=...``) makes
an invite of its own for the PROLIFIC_PID's code each time (docs/decisions.md).
"""

from __future__ import annotations

import hashlib
import re
import secrets
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session

from study.data.storage import Invite, Participant
from study.engine.session import check_code

TOKEN_PATTERN = re.compile(r"^[A-Za-z0-9_-]{16,64}$")
PROLIFIC_FIELDS = ("PROLIFIC_PID", "STUDY_ID", "SESSION_ID")
PROLIFIC_PATTERN = re.compile(r"^[A-Za-z0-9]{1,64}$")
MAX_INVITES = 10_000  # invites made at once


@dataclass(frozen=True, slots=True)
class InviteInfo:
    """What the server needs of an invite."""

    token_sha256: str
    code: str
    prolific: dict[str, str]
    status: str


def token_hash(token: str) -> str:
    """The stored form of ``token``: its SHA-256 in hex."""
    return hashlib.sha256(token.encode("ascii", "replace")).hexdigest()


def new_token() -> str:
    """An unguessable token (128 random bits)."""
    return secrets.token_urlsafe(16)


def link(base_url: str, token: str) -> str:
    """The participant's link."""
    return f"{base_url.rstrip('/')}/s/{token}"


def make_invites(
    engine: Engine, codes: Sequence[str], *, prolific: dict[str, str] | None = None
) -> list[tuple[str, str]]:
    """One invite per code (checked: :func:`study.engine.session.check_code`), in one
    transaction; returns (code, token) pairs, the only time a token is seen."""
    for code in codes:
        check_code(code)
    out = []
    with Session(engine) as s, s.begin():
        for code in codes:
            token = new_token()
            s.add(Invite(token_sha256=token_hash(token), code=code, prolific=prolific or {}))
            out.append((code, token))
    return out


def free_codes(engine: Engine, count: int, prefix: str = "W") -> list[str]:
    """``count`` codes ``W001``, ``W002``, ... that no participant or invite has yet."""
    if not 1 <= count <= MAX_INVITES:
        raise ValueError(f"count: must be 1-{MAX_INVITES}, got {count}")
    with Session(engine) as s:
        taken = set(s.scalars(select(Invite.code))) | set(s.scalars(select(Participant.code)))
    out, n = [], 0
    while len(out) < count:
        n += 1
        code = f"{prefix}{n:03d}"
        if code not in taken:
            out.append(code)
    return out


def find(engine: Engine, token: str) -> InviteInfo | None:
    """The invite of ``token``; None for a token of no invite (or not a token at all)."""
    if not TOKEN_PATTERN.match(token):
        return None
    with Session(engine) as s:
        row = s.scalars(select(Invite).where(Invite.token_sha256 == token_hash(token))).first()
        if row is None:
            return None
        return InviteInfo(row.token_sha256, row.code, dict(row.prolific), row.status)


def prolific_ids(query: dict[str, str]) -> dict[str, str] | None:
    """Prolific's ids from a link's query (all three, each 1-64 letters or digits); None
    when any is missing or malformed."""
    ids = {k: query.get(k, "") for k in PROLIFIC_FIELDS}
    if not all(PROLIFIC_PATTERN.match(v) for v in ids.values()):
        return None
    return ids


def update(engine: Engine, token_sha256: str, *, status: str = "", check: Any = None) -> None:
    """Set the invite's ``status`` and/or append a browser ``check``'s result."""
    with Session(engine) as s, s.begin():
        row = s.scalars(select(Invite).where(Invite.token_sha256 == token_sha256)).first()
        if row is None:
            return
        if status:
            row.status = status
        if check is not None:
            row.checks = [*row.checks, check]


def write_links(path: Path, pairs: Sequence[tuple[str, str]], base_url: str) -> None:
    """``code<TAB>link`` per line into ``path`` (made readable by its owner only)."""
    path.write_text("".join(f"{c}\t{link(base_url, t)}\n" for c, t in pairs), encoding="utf-8")
    path.chmod(0o600)
