"""The counterbalancing ledger: every order slot a study has issued (table ``order_slot``,
issue 20; DESIGN.md "Data": slots are allocated from a ledger in one locking transaction).

A new participant's slot is taken in the transaction that creates the participant, under
the study database's write lock (:func:`lock_study`), so concurrent sessions never receive
the same slot. Which slot (docs/decisions.md): a slot released by an excluded participant
is reissued first (the lowest such), else the lowest slot never issued; the form of the
participant code plays no part. Slot ``k`` maps to a row of the counterbalancing scheme
through ``row_of`` (:class:`study.engine.counterbalance.SlotOrders`); this module knows
nothing of schemes.

A multi-site study keeps one ledger per site (``order_slot.site``; docs/decisions.md
"Counterbalancing across sites"): a site's participants take that site's slots 0, 1, ...,
so every site is balanced on its own and an offline site allocates from its own file
without colliding with another site's slots; a study without sites has the one ledger
``site = ""``. A participant code is unique in the study whatever its site.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import dataclass

from sqlalchemy import select, text
from sqlalchemy.orm import Session

from study.data.storage import (
    PG_STUDY_LOCK,
    OrderSlot,
    Participant,
    SessionRow,
    Study,
    utc_now,
)

# the rule of the ledger, as `asa plan --db` states it (docs/decisions.md)
RULE = (
    "each site has its own slots 0, 1, ... (one ledger without sites); a new participant "
    "takes its site's lowest slot released by an excluded participant, else its lowest slot "
    "never issued; an aborted session keeps its slot (resume it), an excluded one's is "
    "reissued"
)
RowOf = Callable[[int], int]  # slot -> counterbalancing row (participant.order_index)
_SEARCH = 1000  # slots searched beyond the last issued one when backfilling a row


def lock_study(s: Session) -> None:
    """Take the study database's write lock for the transaction begun on ``s``; call it
    first in the transaction. SQLite: ``BEGIN IMMEDIATE`` (other writers wait, up to the
    busy timeout, instead of failing when they upgrade a read). PostgreSQL: a
    transaction-level advisory lock (:data:`PG_STUDY_LOCK`, released at commit or
    rollback), which also serialises the first writers of an empty database, where a
    ``SELECT ... FOR UPDATE`` of the study row would lock nothing. Other databases: the
    study row ``SELECT ... FOR UPDATE``."""
    conn = s.connection()
    if conn.dialect.name == "sqlite":
        conn.exec_driver_sql("BEGIN IMMEDIATE")
    elif conn.dialect.name == "postgresql":
        s.execute(text("SELECT pg_advisory_xact_lock(:key)"), {"key": PG_STUDY_LOCK})
    else:
        s.execute(select(Study.id).with_for_update())


def excluded_ids(s: Session) -> set[int]:
    """Participant ids whose last session ended in exclusion (aborted, noted ``excluded``)."""
    last: dict[int, SessionRow] = {}
    for row in s.scalars(select(SessionRow).order_by(SessionRow.id)):
        last[row.participant_id] = row
    return {
        pid for pid, r in last.items() if r.status == "aborted" and "excluded" in (r.note or "")
    }


def _slots(s: Session, study_id: int, site: str | None = None) -> list[OrderSlot]:
    """The ledger rows of ``site`` ("" without sites) in slot order; every site's (in site
    and slot order) when ``site`` is None."""
    query = select(OrderSlot).where(OrderSlot.study_id == study_id)
    if site is not None:
        query = query.where(OrderSlot.site == site)
    return list(s.scalars(query.order_by(OrderSlot.site, OrderSlot.slot)))


def _lowest_free(used: set[int]) -> int:
    k = 0
    while k in used:
        k += 1
    return k


def _backfill_slot(person: Participant, used: set[int], row_of: RowOf) -> int:
    """A slot for a participant stored before the ledger: its code's number if that slot
    is free and gives its stored row, else the lowest free slot giving that row."""
    m = re.search(r"(\d+)$", person.code)
    if m and 1 <= int(m[1]) <= len(used) + _SEARCH + 1:
        k = int(m[1]) - 1
        if k not in used and row_of(k) == person.order_index:
            return k
    top = max(used, default=-1) + _SEARCH
    for k in range(top + 1):
        if k not in used and row_of(k) == person.order_index:
            return k
    return _lowest_free(used)  # a row the scheme never gives here: recorded as it is


def backfill(s: Session, study_id: int, row_of: RowOf, skip: int | None = None) -> int:
    """Ledger rows for participants stored without one (databases made before issue 20,
    which had no sites), in participant order, except participant id ``skip`` (the one
    being given a slot); returns how many were added. Call under :func:`lock_study`."""
    everywhere = _slots(s, study_id)
    known = {r.participant_id for r in everywhere} | {skip}
    known |= {h.get("participant_id") for r in everywhere for h in r.released}
    people = s.scalars(
        select(Participant)
        .where(Participant.study_id == study_id, Participant.site.is_(None))
        .order_by(Participant.id)
    ).all()
    used = {r.slot for r in everywhere if r.site == ""}
    added = 0
    for person in people:
        if person.id in known:
            continue
        k = _backfill_slot(person, used, row_of)
        used.add(k)
        s.add(
            OrderSlot(
                study_id=study_id,
                slot=k,
                code=person.code,
                participant_id=person.id,
                status="issued",
                created_at=person.created_at,
            )
        )
        added += 1
    if added:
        s.flush()
    return added


def _release_excluded(s: Session, rows: list[OrderSlot]) -> None:
    """Mark the slots of excluded participants released (they keep their rows until the
    slot is reissued)."""
    out = excluded_ids(s)
    for r in rows:
        if r.status == "issued" and r.participant_id in out:
            r.status = "released"


def allocate(
    s: Session,
    study_id: int,
    code: str,
    participant_id: int | None,
    row_of: RowOf,
    site: str | None = None,
) -> int:
    """The slot for participant ``code`` in the ledger of ``site`` (None: a study without
    sites), recorded; call under :func:`lock_study`, in the transaction that creates the
    participant.

    A slot already reserved for ``code`` is taken up (``participant_id`` None keeps it
    reserved); else the site's lowest slot released by an excluded participant is reissued
    (its earlier holder kept in ``released``); else the site's lowest slot never issued.
    """
    backfill(s, study_id, row_of, participant_id)
    mine = next((r for r in _slots(s, study_id) if r.code == code), None)
    rows = _slots(s, study_id, site or "")
    if mine is not None:
        if mine.status != "reserved" or mine.site != (site or ""):
            raise RuntimeError(f"participant {code} already holds order slot {mine.slot}")
        if participant_id is not None:
            mine.participant_id, mine.status = participant_id, "issued"
            s.flush()
        return mine.slot
    _release_excluded(s, rows)
    free = [r for r in rows if r.status == "released"]
    status = "issued" if participant_id is not None else "reserved"
    if free:
        r = free[0]
        r.released = [
            *r.released,
            {"code": r.code, "participant_id": r.participant_id, "released_at": str(utc_now())},
        ]
        r.code, r.participant_id, r.status, r.created_at = code, participant_id, status, utc_now()
        s.flush()
        return r.slot
    k = _lowest_free({r.slot for r in rows})
    s.add(OrderSlot(study_id=study_id, site=site or "", slot=k, code=code,
                    participant_id=participant_id, status=status))  # fmt: skip
    s.flush()
    return k


@dataclass(frozen=True, slots=True)
class LedgerEntry:
    """One slot as the experimenter reads it."""

    site: str  # "" in a study without sites
    slot: int
    code: str
    status: str  # reserved, running, completed, aborted, excluded, released, no session
    order_index: int | None  # the holder's stored row (None while reserved)
    mode_order: tuple[str, ...]
    released: tuple[str, ...]  # codes of earlier holders (excluded)


def entries(s: Session, study_id: int) -> list[LedgerEntry]:
    """The ledger in site and slot order, each slot's holder and the state of its last
    session."""
    people = {p.id: p for p in s.scalars(select(Participant))}
    last: dict[int, SessionRow] = {}
    for row in s.scalars(select(SessionRow).order_by(SessionRow.id)):
        last[row.participant_id] = row
    out = []
    for r in _slots(s, study_id):
        person = people.get(r.participant_id) if r.participant_id is not None else None
        status = r.status
        if r.status == "issued":
            session = last.get(r.participant_id) if r.participant_id is not None else None
            status = "no session" if session is None else session.status
            if session is not None and session.status == "aborted" and "excluded" in session.note:
                status = "excluded"
        out.append(
            LedgerEntry(
                site=r.site,
                slot=r.slot,
                code=r.code,
                status=status,
                order_index=person.order_index if person is not None else None,
                mode_order=tuple(person.mode_order) if person is not None else (),
                released=tuple(str(h.get("code")) for h in r.released),
            )
        )
    return out
