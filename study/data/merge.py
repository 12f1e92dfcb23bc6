"""Merging a one-participant study database into a study database, with fresh row ids
(the synthetic study's workers write one temporary database each; thesis section 7.6)."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.engine import Connection, Engine

from study.data.storage import Base, open_database

_CHUNK = 5000  # rows per executemany when copying samples


def table_rows(conn: Connection, table: str, where: Any = None) -> list[dict[str, Any]]:
    """The rows of ``table`` in id order as dictionaries (``where(t)`` filters them)."""
    t = Base.metadata.tables[table]
    query = select(t).order_by(t.c.id)
    if where is not None:
        query = query.where(where(t))
    return [dict(r._mapping) for r in conn.execute(query)]


def _insert(conn: Connection, table: str, row: dict[str, Any]) -> int:
    t = Base.metadata.tables[table]
    values = {k: v for k, v in row.items() if k != "id"}
    return int(conn.execute(t.insert().values(**values)).inserted_primary_key[0])


def _bulk(conn: Connection, table: str, rows: list[dict[str, Any]]) -> None:
    t = Base.metadata.tables[table]
    for i in range(0, len(rows), _CHUNK):
        chunk = [{k: v for k, v in r.items() if k != "id"} for r in rows[i : i + _CHUNK]]
        if chunk:
            conn.execute(t.insert(), chunk)


def _sample_columns() -> list[str]:
    return [c.name for c in Base.metadata.tables["sample"].columns if c.name != "id"]


def _sample_tuples(conn: Connection) -> list[tuple[Any, ...]]:
    """Every sample row (without ``id``, in id order) as the driver's plain tuples: the
    bulk of a participant (some 16,000 rows), copied without per-row dictionaries."""
    columns = ", ".join(f'"{c}"' for c in _sample_columns())
    return list(conn.exec_driver_sql(f"SELECT {columns} FROM sample ORDER BY id"))


def _copy_samples(
    conn: Connection, samples: list[tuple[Any, ...]], trial_ids: dict[int, int]
) -> None:
    """Insert ``samples`` (from :func:`_sample_tuples`) with their trial ids remapped; the
    stored values are those of the source rows (SQLite's own types, unconverted)."""
    names = _sample_columns()
    at = names.index("trial_id")
    columns = ", ".join(f'"{c}"' for c in names)
    marks = ", ".join("?" * len(names))
    sql = f"INSERT INTO sample ({columns}) VALUES ({marks})"
    for i in range(0, len(samples), _CHUNK):
        chunk = [(*r[:at], trial_ids[r[at]], *r[at + 1 :]) for r in samples[i : i + _CHUNK]]
        if chunk:
            conn.exec_driver_sql(sql, chunk)


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


def _read_source(src: Path) -> _SourceRows:
    source = open_database(src, create=False)
    try:
        with source.connect() as sc:
            return _SourceRows(
                study=table_rows(sc, "study"),
                people=table_rows(sc, "participant"),
                sessions=table_rows(sc, "session"),
                trials=table_rows(sc, "trial"),
                samples=_sample_tuples(sc),
                events=table_rows(sc, "event"),
                questions=table_rows(sc, "question"),
                responses=table_rows(sc, "response"),
            )
    finally:
        source.dispose()


def _study_id(conn: Connection, study: dict[str, Any]) -> int:
    """The id of the study row in the destination, copied from ``study`` if there is none."""
    have = table_rows(conn, "study")
    if not have:
        return _insert(conn, "study", study)
    if have[0]["protocol_sha256"] != study["protocol_sha256"]:
        raise ValueError(
            f"field 'study.protocol_sha256': the database holds study "
            f"{have[0]['name']!r} of another protocol; use a new database file"
        )
    return int(have[0]["id"])


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
        trial_ids[t["id"]] = _insert(
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


def merge_participant(src: Path, dst: Engine, *, src_folder: Path, dst_folder: Path) -> str:
    """Copy the one participant of the database ``src`` into ``dst`` in one transaction.

    Row ids are assigned afresh in ``dst`` and every reference is remapped; the study row
    is copied if ``dst`` has none; ``trial.recording_path`` is rewritten from relative to
    ``src_folder`` to relative to ``dst_folder``. JSON details of events are copied as they
    are (a fresh session has no event whose detail holds row ids).

    Returns
    -------
    str
        The participant's code.

    Raises
    ------
    ValueError
        ``dst`` holds a study of another protocol, or ``src`` does not hold exactly one
        participant, or the participant is already in ``dst``.
    """
    rows = _read_source(src)
    if len(rows.study) != 1 or len(rows.people) != 1:
        raise ValueError(f"{src}: expected one study and one participant to merge")
    person = rows.people[0]
    with dst.begin() as conn:
        study_id = _study_id(conn, rows.study[0])
        pt = Base.metadata.tables["participant"]
        if conn.execute(
            select(pt.c.id).where(pt.c.study_id == study_id, pt.c.code == person["code"])
        ).first():
            raise ValueError(f"participant {person['code']} is already in the database")
        pid = _insert(conn, "participant", {**person, "study_id": study_id})
        session_ids = {
            s["id"]: _insert(conn, "session", {**s, "participant_id": pid}) for s in rows.sessions
        }
        trial_ids = _insert_trials(conn, rows.trials, pid, session_ids, src_folder, dst_folder)

        def tid(value: int | None) -> int | None:
            return None if value is None else trial_ids[value]

        _copy_samples(conn, rows.samples, trial_ids)
        events = [
            {**r, "session_id": session_ids[r["session_id"]], "trial_id": tid(r["trial_id"])}
            for r in rows.events
        ]
        _bulk(conn, "event", events)
        questions = [{**r, "trial_id": trial_ids[r["trial_id"]]} for r in rows.questions]
        _bulk(conn, "question", questions)
        responses = [
            {**r, "participant_id": pid, "trial_id": tid(r["trial_id"])} for r in rows.responses
        ]
        _bulk(conn, "response", responses)
    return str(person["code"])


def merged_codes(db: Path) -> tuple[set[str], str | None]:
    """The participant codes in the database ``db`` and its protocol's SHA-256 (empty and
    ``None`` when there is no file or no study yet)."""
    if not db.exists():
        return set(), None
    engine = open_database(db, create=False)
    try:
        with engine.connect() as conn:
            names = {r["code"] for r in table_rows(conn, "participant")}
            study = table_rows(conn, "study")
    finally:
        engine.dispose()
    return names, (study[0]["protocol_sha256"] if study else None)
