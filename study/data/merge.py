"""Merging a one-participant study database into a study database, with fresh row ids
(the synthetic study's workers write one temporary database each; thesis section 7.6).

Only a finished participant is taken (its sessions ended, no trial running), under the
study database's write lock, into the order slot reserved for it in the study's ledger
(:func:`study.engine.session.reserve_slots`); the study's identity (protocol, seed,
platform version) must match unless the merge is forced with a note (issue 20)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.engine import Connection, Engine
from sqlalchemy.orm import Session

from study.data import identity
from study.data.ledger import lock_study
from study.data.rows import bulk_insert, copy_samples, insert_row, sample_tuples, table_rows
from study.data.storage import Base, open_database


@dataclass(frozen=True, slots=True)
class _SourceRows:
    """Every row of a one-participant database, read before the merge."""

    study: list[dict[str, Any]]
    people: list[dict[str, Any]]
    sessions: list[dict[str, Any]]
    trials: list[dict[str, Any]]
    samples: list[tuple[Any, ...]]  # without id, as the driver's tuples
    events: list[dict[str, Any]]
    questions: list[dict[str, Any]]
    responses: list[dict[str, Any]]
    slots: list[dict[str, Any]]


def _read_source(src: Path) -> _SourceRows:
    source = open_database(src, create=False)
    try:
        with source.connect() as sc:
            return _SourceRows(
                study=table_rows(sc, "study"),
                people=table_rows(sc, "participant"),
                sessions=table_rows(sc, "session"),
                trials=table_rows(sc, "trial"),
                samples=sample_tuples(sc),
                events=table_rows(sc, "event"),
                questions=table_rows(sc, "question"),
                responses=table_rows(sc, "response"),
                slots=table_rows(sc, "order_slot"),
            )
    finally:
        source.dispose()


_IDENTITY = ("protocol_sha256", "seed", "platform_version")


def _study_id(conn: Connection, study: dict[str, Any], note: str) -> int:
    """The id of the study row in the destination, copied from ``study`` if there is none;
    another identity is refused unless ``note`` (a forced run's) is given."""
    have = table_rows(conn, "study")
    if not have:
        return insert_row(conn, "study", study)
    found = identity.mismatches(
        {k: have[0][k] for k in _IDENTITY}, {k: study[k] for k in _IDENTITY}
    )
    if found and not note:
        raise ValueError(
            f"study {have[0]['name']!r}: "
            + "; ".join(m.words() for m in found)
            + "; use a new database file"
        )
    return int(have[0]["id"])


def _finished(src: Path, rows: _SourceRows) -> None:
    """Refuse a participant whose session or trials are still running (a scratch copy
    another process is writing, or one cut off by a crash)."""
    running = [s["id"] for s in rows.sessions if s["status"] == "running"]
    running += [t["id"] for t in rows.trials if t["status"] == "running"]
    if running or not rows.sessions:
        raise ValueError(
            f"{src}: participant {rows.people[0]['code']} is not finished (a session or "
            "trial is still running); only finished participants are merged"
        )


def _take_slot(conn: Connection, study_id: int, code: str, pid: int, slots: list[Any]) -> None:
    """Give participant ``pid`` the slot reserved for ``code`` in the destination's ledger
    (the slot it ran with, per the source's ledger)."""
    t = Base.metadata.tables["order_slot"]
    row = conn.execute(select(t).where(t.c.study_id == study_id, t.c.code == code)).first()
    ran = next((r["slot"] for r in slots if r["code"] == code), None)
    if row is None or row.status != "reserved" or (ran is not None and ran != row.slot):
        raise ValueError(
            f"field 'order_slot': participant {code} ran with order slot {ran}, which is not "
            "reserved for it in the study database; run the participant again"
        )
    conn.execute(t.update().where(t.c.id == row.id).values(participant_id=pid, status="issued"))


def _insert_trials(
    conn: Connection,
    trials: list[dict[str, Any]],
    pid: int,
    session_ids: dict[int, int],
    src_folder: Path,
    dst_folder: Path,
) -> dict[int, int]:
    """Insert ``trials`` for participant ``pid``; source trial id -> new trial id."""
    trial_ids: dict[int, int] = {}
    for t in trials:
        path = t["recording_path"]
        if path:
            path = os.path.relpath((src_folder / path).resolve(), dst_folder.resolve())
        trial_ids[t["id"]] = insert_row(
            conn,
            "trial",
            {
                **t,
                "participant_id": pid,
                "session_id": session_ids[t["session_id"]],
                "recording_path": path,
            },
        )
    return trial_ids


def merge_participant(
    src: Path, dst: Engine, *, src_folder: Path, dst_folder: Path, note: str = ""
) -> str:
    """Copy the one participant of the database ``src`` into ``dst`` in one transaction.

    Row ids are assigned afresh in ``dst`` and every reference is remapped; the study row
    is copied if ``dst`` has none; ``trial.recording_path`` is rewritten from relative to
    ``src_folder`` to relative to ``dst_folder``. JSON details of events are copied as they
    are (a fresh session has no event whose detail holds row ids). The participant takes
    the order slot reserved for its code in ``dst``'s ledger. A ``note`` (a forced run's:
    the study identity it overrode) allows another identity and is appended to each
    copied session's ``note``, which is marked ``forced``.

    Returns
    -------
    str
        The participant's code.

    Raises
    ------
    ValueError
        ``dst`` holds a study of another protocol, seed or platform version (without
        ``note``), or ``src`` does not hold exactly one finished participant, or the
        participant is already in ``dst``, or no order slot is reserved for it.
    """
    rows = _read_source(src)
    if len(rows.study) != 1 or len(rows.people) != 1:
        raise ValueError(f"{src}: expected one study and one participant to merge")
    _finished(src, rows)
    person = rows.people[0]
    with Session(dst) as s, s.begin():
        lock_study(s)
        conn = s.connection()
        study_id = _study_id(conn, rows.study[0], note)
        pt = Base.metadata.tables["participant"]
        if conn.execute(
            select(pt.c.id).where(pt.c.study_id == study_id, pt.c.code == person["code"])
        ).first():
            raise ValueError(f"participant {person['code']} is already in the database")
        pid = insert_row(conn, "participant", {**person, "study_id": study_id})
        _take_slot(conn, study_id, person["code"], pid, rows.slots)
        session_ids = {
            r["id"]: insert_row(conn, "session", _session(r, pid, note)) for r in rows.sessions
        }
        trial_ids = _insert_trials(conn, rows.trials, pid, session_ids, src_folder, dst_folder)

        def tid(value: int | None) -> int | None:
            return None if value is None else trial_ids[value]

        copy_samples(conn, rows.samples, trial_ids)
        events = [
            {**r, "session_id": session_ids[r["session_id"]], "trial_id": tid(r["trial_id"])}
            for r in rows.events
        ]
        bulk_insert(conn, "event", events)
        questions = [{**r, "trial_id": trial_ids[r["trial_id"]]} for r in rows.questions]
        bulk_insert(conn, "question", questions)
        responses = [
            {**r, "participant_id": pid, "trial_id": tid(r["trial_id"])} for r in rows.responses
        ]
        bulk_insert(conn, "response", responses)
    return str(person["code"])


def _session(row: dict[str, Any], pid: int, note: str) -> dict[str, Any]:
    """A source session row for participant ``pid``, a forced run's ``note`` recorded."""
    if not note:
        return {**row, "participant_id": pid}
    text = "; ".join(filter(None, [row["note"], note]))
    return {**row, "participant_id": pid, "forced": True, "note": text}
