"""Writing one participant's push plan (:mod:`study.data.pushplan`) into the destination,
inside the push's transaction: rows inserted with fresh ids and every reference remapped,
a replaced session's earlier rows deleted first, the order slot inserted or taken over."""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

from sqlalchemy import delete, select
from sqlalchemy.engine import Connection

from study.data.pushplan import Plan
from study.data.rows import bulk_insert, copy_samples, insert_row
from study.data.storage import Base

Folders = tuple[Path, Path] | None  # (source folder, destination folder); None: a server


def write_plan(conn: Connection, study_id: int | None, plan: Plan, folders: Folders) -> None:
    """Write ``plan`` on ``conn`` (in the caller's transaction, under its write lock)."""
    if plan.action not in ("pushed", "updated"):
        return
    assert study_id is not None  # a push that writes has a destination study
    pid = plan.person_id
    if pid is None:
        pid = insert_row(conn, "participant", {**plan.rows.person, "study_id": study_id})
        _write_slot(conn, study_id, plan, pid)
    for session_id in plan.replace:
        _delete_session(conn, session_id)
    trial_ids = _write_sessions(conn, pid, plan, folders)
    # the responses of the written trials and those outside trials added since the
    # destination's, in the source's order (a first push keeps the source's row order)
    loose = {r["id"] for r in plan.responses}
    responses = [
        {**r, "participant_id": pid, "trial_id": trial_ids.get(r["trial_id"])}
        for r in plan.rows.responses
        if r["id"] in loose or r["trial_id"] in trial_ids
    ]
    bulk_insert(conn, "response", responses)


def _write_sessions(conn: Connection, pid: int, plan: Plan, folders: Folders) -> dict[int, int]:
    """Insert the plan's sessions with their trials, samples, events and questions;
    returns source trial id -> destination trial id."""
    rows = plan.rows
    session_ids = {
        s["id"]: insert_row(conn, "session", {**s, "participant_id": pid}) for s in plan.sessions
    }
    trial_ids: dict[int, int] = {}
    for t in rows.trials:
        if t["session_id"] in session_ids:
            row = {**t, "participant_id": pid, "session_id": session_ids[t["session_id"]],
                   "recording_path": _recording(t["recording_path"], folders)}  # fmt: skip
            trial_ids[t["id"]] = insert_row(conn, "trial", row)
    samples = [r for t in trial_ids for r in rows.samples.get(t, [])]
    copy_samples(conn, samples, trial_ids)

    def tid(value: int | None) -> int | None:
        return None if value is None else trial_ids[value]

    events = [
        {**e, "session_id": session_ids[e["session_id"]], "trial_id": tid(e["trial_id"]),
         "detail": _detail(e["detail"], trial_ids)}
        for e in rows.events
        if e["session_id"] in session_ids
    ]  # fmt: skip
    bulk_insert(conn, "event", events)
    questions = [{**q, "trial_id": trial_ids[q["trial_id"]]}
                 for q in rows.questions if q["trial_id"] in trial_ids]  # fmt: skip
    bulk_insert(conn, "question", questions)
    _write_lsl(conn, rows.lsl, session_ids, trial_ids)
    return trial_ids


def _write_lsl(
    conn: Connection,
    lsl: dict[str, list[dict[str, Any]]],
    session_ids: dict[int, int],
    trial_ids: dict[int, int],
) -> None:
    """The lab's streams of the written sessions, with their chunks, offsets and gaps."""
    stream_ids = {
        r["id"]: insert_row(conn, "lsl_stream", {**r, "session_id": session_ids[r["session_id"]]})
        for r in lsl.get("lsl_stream", [])
        if r["session_id"] in session_ids
    }
    for name in ("lsl_chunk", "lsl_offset", "lsl_gap"):
        rows = [{**r, "stream_id": stream_ids[r["stream_id"]]}
                for r in lsl.get(name, []) if r["stream_id"] in stream_ids]  # fmt: skip
        if name == "lsl_gap":
            rows = [{**r, "trial_id": trial_ids.get(r["trial_id"])} for r in rows]
        bulk_insert(conn, name, rows)


def _recording(path: str, folders: Folders) -> str:
    """A recording path relative to the destination's folder (kept for a server)."""
    if not path or folders is None:
        return path
    src_folder, dst_folder = folders
    return os.path.relpath((src_folder / path).resolve(), dst_folder.resolve())


def _detail(detail: Any, trial_ids: dict[int, int]) -> Any:
    """An event's detail with the trial ids it names (``aborted_trials``) remapped."""
    if isinstance(detail, dict) and isinstance(detail.get("aborted_trials"), list):
        ids = [trial_ids.get(i, i) for i in detail["aborted_trials"]]
        return {**detail, "aborted_trials": ids}
    return detail


def _delete_session(conn: Connection, session_id: int) -> None:
    """Delete a destination session and every row of it (a resumed session's earlier
    push, about to be replaced by its newer state)."""
    t = Base.metadata.tables
    tids = list(
        conn.execute(select(t["trial"].c.id).where(t["trial"].c.session_id == session_id))
        .scalars()
    )  # fmt: skip
    streams = select(t["lsl_stream"].c.id).where(t["lsl_stream"].c.session_id == session_id)
    for name in ("lsl_chunk", "lsl_offset", "lsl_gap"):
        conn.execute(delete(t[name]).where(t[name].c.stream_id.in_(streams)))
    conn.execute(delete(t["lsl_stream"]).where(t["lsl_stream"].c.session_id == session_id))
    for name in ("sample", "question", "response"):
        conn.execute(delete(t[name]).where(t[name].c.trial_id.in_(tids)))
    conn.execute(delete(t["event"]).where(t["event"].c.session_id == session_id))
    conn.execute(delete(t["trial"]).where(t["trial"].c.session_id == session_id))
    conn.execute(delete(t["session"]).where(t["session"].c.id == session_id))


def _write_slot(conn: Connection, study_id: int, plan: Plan, pid: int) -> None:
    """The new participant's order slot: the source's row inserted, or the destination's
    row taken over; earlier holders' participant ids remapped by code."""
    slot = plan.rows.slot
    if plan.slot == "none" or slot is None:
        return
    people = Base.metadata.tables["participant"]
    released = []
    for h in slot["released"] or []:
        found = conn.execute(select(people.c.id).where(people.c.code == h.get("code"))).first()
        released.append({**h, "participant_id": None if found is None else int(found.id)})
    values = {**slot, "study_id": study_id, "participant_id": pid, "released": released}
    if plan.slot == "insert":
        insert_row(conn, "order_slot", values)
        return
    t = Base.metadata.tables["order_slot"]
    values = {k: v for k, v in values.items() if k != "id"}
    conn.execute(t.update().where(t.c.id == plan.slot_id).values(**values))
