"""The participants' part of ``asa db check`` (:func:`study.data.dbtools.check`): sessions
left running without a live process, questionnaires a completed session lacks, the sites
of a multi-site study, and the order ledger (every slot issued once, to the participant
whose order it gives; issues 20 and 24)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from study.data import locks, server_locks
from study.data.storage import (
    OrderSlot,
    Participant,
    Response,
    SessionRow,
    Trial,
    database_file,
    database_url,
    is_postgresql,
)


def check_people(s: Session, db: str | Path, protocol: Any, problems: list[str]) -> int:
    """Sessions left ``running`` (with or without a trial running) without a live process
    holding the session (interrupted: to be resumed), and completed sessions without the
    experience questionnaire the protocol asks; returns the sessions running live."""
    people = {p.id: p for p in s.scalars(select(Participant))}
    running_trials = {
        sid for (sid,) in s.execute(select(Trial.session_id).where(Trial.status == "running"))
    }
    answered = set(s.scalars(select(Response.participant_id).where(Response.trial_id.is_(None))
                             .where(Response.instrument == _experience(protocol))))  # fmt: skip
    live = 0
    for row in s.scalars(select(SessionRow).order_by(SessionRow.id)):
        person = people.get(row.participant_id)
        if person is None:
            continue  # an orphan, reported by _orphans
        if row.status == "running":  # a trial running elsewhere: see check()
            if _live(s, db, person.code):
                live += 1
                continue
            problems.append(
                f"participant {person.code}: session {row.id} is still running"
                + (" (a trial too)" if row.id in running_trials else "")
                + " but no process holds it: interrupted; resume with `asa run --protocol "
                f"<protocol> --participant {person.code} --db {db} --resume`"
            )
        elif row.status == "completed" and _experience(protocol) and person.id not in answered:
            problems.append(
                f"participant {person.code}: session {row.id} completed without the "
                f"'{_experience(protocol)}' questionnaire its protocol requires"
            )
    return live


def check_sites(s: Session, study: Any, problems: list[str]) -> None:
    """In a multi-site study every participant belongs to one of the study's sites, and
    every session ran at its participant's site (issue 24)."""
    sites = list(study.sites or []) if study is not None else []
    people = {p.id: p for p in s.scalars(select(Participant))}
    for person in people.values():
        if sites and person.site not in sites:
            problems.append(
                f"participant {person.code}: site {person.site or '(none)'} is not one of the "
                f"study's sites ({', '.join(sites)})"
            )
    for row in s.scalars(select(SessionRow).order_by(SessionRow.id)):
        person = people.get(row.participant_id)
        if person is not None and row.site is not None and row.site != person.site:
            problems.append(
                f"participant {person.code}: session {row.id} ran at site {row.site}, the "
                f"participant belongs to {person.site or '(none)'}"
            )


def _experience(protocol: Any) -> str:
    """The instrument of the protocol's experience phase, "" without one."""
    phase = protocol.phase("experience") if protocol is not None else None
    return phase.instrument if phase is not None else ""


def _live(s: Session, db: str | Path, code: str) -> bool:
    """True when a process holds participant ``code``'s session lock (a lock file beside
    an SQLite file, an advisory lock on PostgreSQL; never on other servers)."""
    if is_postgresql(db):
        return server_locks.is_held(s.connection(), server_locks.session_lock(code))
    if not database_url(db).startswith("sqlite:///"):
        return False
    return locks.is_held(locks.session_lock(database_file(db), code))


def _synth_live(s: Session, db: str | Path) -> bool:
    """True when a synthetic study is writing the database (its lock is held)."""
    if is_postgresql(db):
        return server_locks.is_held(s.connection(), server_locks.SYNTH)
    if not database_url(db).startswith("sqlite:///"):
        return False
    return locks.is_held(locks.synth_lock(database_file(db)))


def check_ledger(
    s: Session, db: str | Path, study: Any, protocol: Any, problems: list[str]
) -> None:
    """Every participant holds one order slot (or gave it up by exclusion), each slot is
    held by the participant of its code, and the slot gives the participant's stored row
    of the scheme; a slot reserved by a synthetic study that is no longer running."""
    from study.engine.counterbalance import SlotOrders

    rows = list(s.scalars(select(OrderSlot).order_by(OrderSlot.site, OrderSlot.slot)))
    people = {p.id: p for p in s.scalars(select(Participant))}
    if not rows:
        return  # a database made before the ledger: filled in on its next write
    per_site: dict[str, SlotOrders] = {}

    def row_of(site: str, slot: int) -> int | None:
        if protocol is None:
            return None
        if site not in per_site:
            per_site[site] = SlotOrders(
                protocol.modes, protocol.counterbalancing, study.seed, site or None
            )
        return per_site[site].row(slot)

    holders: dict[int, int] = {}
    released = {h.get("participant_id") for r in rows for h in r.released}
    synth_live = _synth_live(s, db)
    for r in rows:
        where = f"order slot {r.slot}" + (f" of site {r.site}" if r.site else "")
        if r.status == "reserved":
            if r.participant_id is None and not synth_live:
                problems.append(
                    f"{where}: reserved for {r.code} by a synthetic study that did not "
                    "finish; run the same `asa synth` again"
                )
            continue
        person = people.get(r.participant_id) if r.participant_id is not None else None
        if person is None or person.code != r.code:
            problems.append(f"{where}: held by {r.code}, who is not that participant")
            continue
        holders[person.id] = holders.get(person.id, 0) + 1
        if r.site != (person.site or ""):
            problems.append(f"{where}: {r.code} belongs to site {person.site or '(none)'}")
        expected = row_of(r.site, r.slot)
        if expected is not None and expected != person.order_index:
            problems.append(
                f"{where}: gives row {expected}, but {r.code} has row {person.order_index}"
            )
    for pid, person in people.items():
        if holders.get(pid, 0) > 1:
            problems.append(f"participant {person.code}: holds {holders[pid]} order slots")
        elif pid not in holders and pid not in released:
            problems.append(f"participant {person.code}: holds no order slot")
