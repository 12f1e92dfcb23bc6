"""One browser participant's session in a process of its own (issue 37; pybullet keeps one
client per process): the browser check, then :func:`study.engine.session.run_session`
exactly as ``asa run`` calls it (the ledger, crash-safe storage, recordings, ``resume``
after an aborted session) with a :class:`study.web.participant.WebParticipant`, then the
end page, sent only once the session's last transaction has been committed.

:func:`session_main` is the process's entry (``multiprocessing`` spawn); ``job`` is a
:class:`SessionJob`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Any

from sqlalchemy import select
from sqlalchemy.orm import Session

from study.data.storage import Participant, SessionRow, open_database, utc_now
from study.engine.clocks import ExperimenterControl
from study.engine.protocol import Protocol, load_protocol
from study.engine.session import run_session
from study.engine.sites import Place
from study.ui.sticks import GamepadMapping
from study.web import invites
from study.web import messages as wire
from study.web.check import CheckAbandoned, browser_check
from study.web.link import Link
from study.web.participant import SessionStopped, WebParticipant


@dataclass(frozen=True, slots=True)
class SessionJob:
    """What a session process runs."""

    protocol: str  # shipped name or TOML file
    db: str  # SQLite file or URL
    code: str  # the participant's code
    token_sha256: str  # the invite's
    prolific: dict[str, str] = field(default_factory=dict)
    recordings: str | None = None  # folder of the recordings, default beside the database
    site: str | None = None
    camera: bool = True  # False: no camera on the page (tests, benchmarks)


def session_main(conn: Any, job: SessionJob) -> None:
    """Process entry: run ``job``'s session over the pipe ``conn``."""
    os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
    from study._blas import limit_blas_threads

    limit_blas_threads()
    protocol = load_protocol(job.protocol)
    hello = wire.server_json("hello", keys=dict(protocol.input.keys))
    link = Link(conn, GamepadMapping.from_settings(protocol.input), hello=hello)
    try:
        _run(link, protocol, job)
    except (SessionStopped, CheckAbandoned) as stop:
        link.send(wire.server_json("aborted", reason=str(stop)))
    finally:
        link.status({"ended": True})
        conn.close()


def _last(db: str, code: str) -> tuple[str, str] | None:
    """The status and note of participant ``code``'s last session; None without one."""
    engine = open_database(db)
    try:
        with Session(engine) as s:
            row = s.execute(
                select(SessionRow.status, SessionRow.note)
                .join(Participant, Participant.id == SessionRow.participant_id)
                .where(Participant.code == code)
                .order_by(SessionRow.id.desc())
            ).first()
            return None if row is None else (row[0], row[1] or "")
    finally:
        engine.dispose()


def _run(link: Link, protocol: Protocol, job: SessionJob) -> None:
    last = _last(job.db, job.code)
    if last is not None and (last[0] == "completed" or "excluded" in last[1]):
        _end(link, protocol, last[0] if last[0] == "completed" else "excluded")
        return
    engine = open_database(job.db)
    try:
        check = browser_check(link, protocol.web, protocol.web.grace_s)
        invites.update(engine, job.token_sha256, check=check,
                       status="running" if check["passed"] else "refused")  # fmt: skip
        if not check["passed"]:
            link.send(wire.server_json("refused", reasons=check["reasons"]))
            return
        status = _session(link, protocol, job, check, resume=last is not None)
        invites.update(engine, job.token_sha256, status=status)
    finally:
        engine.dispose()


def _session(
    link: Link, protocol: Protocol, job: SessionJob, check: dict[str, Any], *, resume: bool
) -> str:
    """The session itself; its final status ("completed" or "aborted")."""
    from study.ui.camera import CameraFeed

    control = ExperimenterControl()
    params = {"check": {k: check[k] for k in ("rtt_median_ms", "window", "gamepad", "agent")}}
    if job.prolific:
        params["prolific"] = dict(job.prolific)
    camera = CameraFeed() if job.camera and protocol.web.camera_hz > 0 else None
    person = WebParticipant(
        protocol.ui, protocol.input, protocol.web, link, parameters=params, camera=camera,
        control=control,
    )  # fmt: skip
    try:
        summary = run_session(
            protocol, job.code, job.db, participant=person, resume=resume, control=control,
            recordings=job.recordings, place=Place(site=job.site),
        )  # fmt: skip
    except SessionStopped as stop:
        _abort(job.db, job.code, f"aborted: {stop}")
        link.send(wire.server_json("aborted", reason=str(stop)))
        return "aborted"
    finally:
        person.close()
    if summary.status == "completed":
        _end(link, protocol, "completed")
    else:
        link.send(wire.server_json("aborted", reason=control.reason or "the session ended"))
    return summary.status


def _abort(db: str, code: str, note: str) -> None:
    """Mark participant ``code``'s running session aborted with ``note`` (resumable)."""
    engine = open_database(db)
    try:
        with Session(engine) as s, s.begin():
            row = s.scalars(
                select(SessionRow)
                .join(Participant, Participant.id == SessionRow.participant_id)
                .where(Participant.code == code, SessionRow.status == "running")
                .order_by(SessionRow.id.desc())
            ).first()
            if row is not None:
                row.status, row.ended_at = "aborted", utc_now()
                row.note = f"{row.note}; {note}" if row.note else note
    finally:
        engine.dispose()


def _end(link: Link, protocol: Protocol, status: str) -> None:
    """The end page: the completion code and address once the session is stored."""
    web = protocol.web
    done = status == "completed"
    link.send(
        wire.server_json(
            "end",
            status=status,
            code=web.completion_code if done else "",
            url=web.completion_url if done else "",
        )
    )
