"""One participant's session of a protocol: open (or resume) it in the database, then run
its phases (:mod:`study.engine.runner`). Thesis Sec. 7.6.1.3 ("Test procedure"); the
active mode is never shown to the participant."""

from __future__ import annotations

import hashlib
import re
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from sqlalchemy import select
from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session

from study import __version__
from study.data.storage import (
    Event,
    Participant,
    SessionRow,
    Study,
    Trial,
    get_study,
    open_database,
    utc_now,
)
from study.engine.counterbalance import assign_indexed, cycle_length
from study.engine.protocol import Protocol
from study.engine.resume import resume_plan, session_state
from study.engine.runner import SessionRunner, TrialSummary, derive_seed
from study.engine.trial import ExperimenterControl, FreeClock, TrialWriter, WallClock
from study.participants.base import Participant as SessionParticipant

__all__ = [
    "SessionSummary",
    "TrialSummary",
    "check_code",
    "default_seed",
    "derive_seed",
    "run_session",
]

CODE_PATTERN = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_-]{0,63}$")
MAX_RANDOM_INDEX = 100_000  # participant numbers the random scheme serves


@dataclass(frozen=True, slots=True)
class SessionSummary:
    """What :func:`run_session` did."""

    participant: str  # code
    participant_id: int
    session_id: int
    status: str  # "completed" or "aborted"
    mode_order: tuple[str, ...]
    trials: tuple[TrialSummary, ...]  # run by this call, in order
    resumed: bool
    forced: bool
    note: str


@dataclass(frozen=True, slots=True)
class _Opened:
    """A session row ready to run: its participant (detached from the database) and id."""

    person: Participant
    session_id: int
    resumed: bool
    forced: bool
    note: str


def check_code(code: str) -> str:
    """A participant code: letters, digits, ``_`` and ``-``, at most 64, starting with a
    letter or digit. Raises ``ValueError`` naming the field otherwise."""
    if not isinstance(code, str) or not CODE_PATTERN.match(code):
        raise ValueError(
            f"participant code: must be 1-64 letters, digits, '_' or '-' starting with a "
            f"letter or digit, got {code!r}"
        )
    return code


def default_seed(study_seed: int, code: str) -> int:
    """A participant's seed when none is given: a 31-bit hash of the study seed and code."""
    digest = hashlib.sha256(f"{study_seed}:{code}".encode()).digest()
    return int.from_bytes(digest[:4], "little") >> 1


def _order_index(s: Session, study: Study, code: str) -> int:
    m = re.search(r"(\d+)$", code)
    if m and int(m[1]) >= 1:
        return int(m[1]) - 1
    used = set(s.scalars(select(Participant.order_index).where(Participant.study_id == study.id)))
    index = 0
    while index in used:
        index += 1
    return index


# ---------------------------------------------------------------------- opening


def _study(s: Session, protocol: Protocol, db: str | Path, force: bool, notes: list[str]) -> Study:
    """The database's study row (made on first use); another protocol needs ``force``."""
    study = get_study(s)
    if study is None:
        study = Study(
            name=protocol.name,
            protocol_text=protocol.text,
            protocol_sha256=protocol.sha256,
            platform_version=__version__,
            seed=protocol.study.seed,
        )
        s.add(study)
        s.flush()
    elif study.protocol_sha256 != protocol.sha256:
        message = (
            f"{db}: field 'study.protocol_sha256': the database was made with protocol "
            f"'{study.name}' (SHA-256 {study.protocol_sha256[:12]}...), not with "
            f"{protocol.source} ({protocol.sha256[:12]}...)"
        )
        if not force:
            raise ValueError(message + "; use force=True to run it anyway")
        notes.append(f"forced: protocol {protocol.sha256[:12]} differs from the study's")
    return study


def _resume(
    s: Session,
    person: Participant | None,
    sessions: Sequence[SessionRow],
    code: str,
    db: str | Path,
    notes: list[str],
) -> SessionRow:
    """Reopen the participant's last session: trials left ``running`` become ``aborted``."""
    if person is None or not sessions:
        raise ValueError(
            f"{db}: field 'participant.code': participant {code} has no session "
            "to resume; run with resume=False"
        )
    row = sessions[-1]
    if row.status == "completed":
        raise ValueError(
            f"{db}: field 'session.status': the session of participant {code} "
            "is completed; nothing to resume"
        )
    row.resumed = True
    row.status = "running"
    row.ended_at = None
    stale = s.scalars(
        select(Trial).where(Trial.participant_id == person.id, Trial.status == "running")
    ).all()
    for trial in stale:
        trial.status = "aborted"
        trial.ended_at = utc_now()
        trial.outcome = {**trial.outcome, "aborted_reason": "resumed after a crash"}
    s.add(
        Event(
            session_id=row.id,
            trial_id=None,
            t=0.0,
            kind="session_resumed",
            detail={"aborted_trials": [t.id for t in stale]},
        )
    )
    if notes:
        row.forced = True
        row.note = "; ".join(filter(None, [row.note, *notes]))
    return row


def _new_person(
    s: Session,
    study: Study,
    protocol: Protocol,
    code: str,
    participant: SessionParticipant,
    seed: int | None,
) -> Participant:
    """The participant row: order index from the code, mode order from counterbalancing."""
    index = _order_index(s, study, code)
    cycle = cycle_length(len(protocol.modes), protocol.counterbalancing)
    if cycle is None and index >= MAX_RANDOM_INDEX:
        raise ValueError(
            f"participant code: {code!r} asks for participant number "
            f"{index + 1}; the random scheme draws orders in sequence up to "
            f"{MAX_RANDOM_INDEX}, use a smaller number"
        )
    # deterministic schemes repeat with their cycle: only compute one cycle
    rows = assign_indexed(
        protocol.modes,
        (index % cycle if cycle else index) + 1,
        protocol.counterbalancing,
        rng=np.random.default_rng(study.seed),
    )
    person = Participant(
        study_id=study.id,
        code=code,
        kind=participant.kind,
        parameters=dict(participant.parameters),
        order_index=rows[-1][0],
        mode_order=list(rows[-1][1]),
        seed=int(seed) if seed is not None else default_seed(study.seed, code),
    )
    s.add(person)
    s.flush()
    return person


def _open(
    engine: Engine,
    protocol: Protocol,
    code: str,
    db: str | Path,
    participant: SessionParticipant,
    *,
    seed: int | None,
    resume: bool,
    force: bool,
) -> _Opened:
    """Resume the participant's session or start a new one, in one transaction."""
    notes: list[str] = []
    with Session(engine) as s, s.begin():
        study = _study(s, protocol, db, force, notes)
        person = s.scalars(
            select(Participant).where(Participant.study_id == study.id, Participant.code == code)
        ).first()
        sessions = []
        if person is not None:
            sessions = list(
                s.scalars(
                    select(SessionRow)
                    .where(SessionRow.participant_id == person.id)
                    .order_by(SessionRow.id)
                )
            )
        if resume:
            row = _resume(s, person, sessions, code, db, notes)
        else:
            if sessions:
                if not force:
                    raise ValueError(
                        f"{db}: field 'participant.code': participant {code} already has "
                        f"a session (id {sessions[-1].id}, {sessions[-1].status}); use "
                        "resume=True to continue it or force=True to start a new one"
                    )
                notes.append(
                    f"forced: a new session although participant {code} has "
                    f"{len(sessions)} (last id {sessions[-1].id}); nothing was deleted"
                )
            if person is None:
                person = _new_person(s, study, protocol, code, participant, seed)
            row = SessionRow(
                participant_id=person.id,
                status="running",
                forced=bool(notes),
                note="; ".join(notes),
            )
            s.add(row)
            s.flush()
        assert person is not None  # _resume refuses a missing participant
        opened = _Opened(person, row.id, row.resumed, row.forced, row.note)
        s.expunge(person)
    return opened


# ---------------------------------------------------------------------- the session


def run_session(
    protocol: Protocol,
    participant_code: str,
    db: str | Path,
    *,
    participant: SessionParticipant,
    seed: int | None = None,
    resume: bool = False,
    force: bool = False,
    progress: Callable[[str], None] | None = None,
    control: ExperimenterControl | None = None,
    clock: FreeClock | WallClock | None = None,
    camera_hz: float | None = None,
    on_tick: Callable[[int, TrialWriter], None] | None = None,
    recordings: str | Path | None = None,
    durable: bool = True,
) -> SessionSummary:
    """Run (or resume) one participant's session of ``protocol`` and store everything.

    Parameters
    ----------
    protocol : Protocol
        The validated protocol (:func:`study.engine.protocol.load_protocol`).
    participant_code : str
        Pseudonymous code (:func:`check_code`).
    db : str or Path
        SQLite file or SQLAlchemy URL (created if missing).
    participant : Participant
        Who takes part (``study.participants.base.Participant``).
    seed : int, optional
        The participant's seed; default derived from the study seed and the code.
    resume, force : bool
        ``resume`` continues the participant's last session after a crash; ``force`` runs
        although the database was made with another protocol, or the participant already
        has a session (a new session row, ``forced``, with a note).
    progress, control : optional
        Receives one experimenter line per phase and trial; the experimenter's pause and
        abort (:class:`study.engine.clocks.ExperimenterControl`).
    clock, camera_hz : optional
        Default for human participants a wall-clock pace, else free-running; camera
        frames per second in the recordings, default the protocol's
        ``[recording] camera_hz``.
    on_tick : callable, optional
        Passed to :func:`study.engine.trial.run_trial`.
    recordings : str or Path, optional
        Folder for the rerun recordings (``<code>/...rrd`` inside it); default
        ``<db stem>_recordings`` beside the database; paths stored relative to its folder.
    durable : bool
        False only for a scratch database thrown away after a crash (no fsync on commit,
        :func:`study.data.storage.open_database`): a synthetic study's per-participant file.

    Returns
    -------
    SessionSummary

    Raises
    ------
    ValueError
        A bad participant code, a database not ours or made with another protocol, a
        second session without ``force``, nothing to resume.
    """
    code = check_code(participant_code)
    engine = open_database(db, durable=durable)
    try:
        opened = _open(
            engine, protocol, code, db, participant, seed=seed, resume=resume, force=force
        )
        runner = _runner(
            protocol, engine, db, participant, opened,
            progress, control, clock, camera_hz, on_tick, recordings,
        )  # fmt: skip
        return _run(runner, code, opened)
    finally:
        engine.dispose()


def _runner(
    protocol: Protocol,
    engine: Engine,
    db: str | Path,
    participant: SessionParticipant,
    opened: _Opened,
    progress: Callable[[str], None] | None,
    control: ExperimenterControl | None,
    clock: FreeClock | WallClock | None,
    camera_hz: float | None,
    on_tick: Callable[[int, TrialWriter], None] | None,
    recordings: str | Path | None,
) -> SessionRunner:
    """The runner of the opened session, with :func:`run_session`'s defaults."""
    human = participant.kind == "human"
    return SessionRunner(
        protocol,
        engine,
        db,
        participant,
        _checked(opened, protocol, db),
        opened.session_id,
        progress=progress if progress is not None else (lambda line: None),
        control=control if control is not None else ExperimenterControl(),
        clock=clock if clock is not None else (WallClock() if human else FreeClock()),
        camera_hz=camera_hz if camera_hz is not None else protocol.recording.camera_hz,
        on_tick=on_tick,
        recordings=Path(recordings).resolve() if recordings is not None else None,
    )


def _run(runner: SessionRunner, code: str, opened: _Opened) -> SessionSummary:
    """Every phase of the opened session; what was done."""
    runner.progress(
        f"{code} session {opened.session_id}"
        + (" resumed" if opened.resumed else "")
        + (" (forced)" if opened.forced else "")
        + f", order index {opened.person.order_index}"
        + (
            f": {resume_plan(session_state(runner.engine, opened.session_id))}"
            if opened.resumed
            else ""
        )
    )
    try:
        status = runner.run()
    finally:
        runner.scenes.close()
    return SessionSummary(
        participant=code,
        participant_id=opened.person.id,
        session_id=opened.session_id,
        status=status,
        mode_order=tuple(opened.person.mode_order),
        trials=tuple(runner.trials),
        resumed=opened.resumed,
        forced=opened.forced,
        note=opened.note,
    )


def _checked(opened: _Opened, protocol: Protocol, db: str | Path) -> Participant:
    """The participant row, its mode order checked against ``protocol``'s modes."""
    unknown = [m for m in opened.person.mode_order if m not in protocol.modes]
    if unknown:
        raise ValueError(
            f"{db}: field 'participant.mode_order': {unknown[0]!r} is not a mode of "
            f"{protocol.source}"
        )
    return opened.person
