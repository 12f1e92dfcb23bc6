"""One participant's session of a protocol: open (or resume) it in the database, then run
its phases (:mod:`study.engine.runner`). Thesis Sec. 7.6.1.3 ("Test procedure"); the
active mode is never shown to the participant."""

from __future__ import annotations

import contextlib
import dataclasses
import hashlib
import re
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

from sqlalchemy import select
from sqlalchemy.engine import Engine
from sqlalchemy.exc import ArgumentError, DBAPIError
from sqlalchemy.orm import Session

from study import __version__
from study.data import identity, ledger, locks, server_locks
from study.data.storage import (
    Event,
    OrderSlot,
    Participant,
    SessionRow,
    Study,
    Trial,
    database_file,
    database_url,
    get_study,
    is_postgresql,
    open_database,
    utc_now,
)
from study.engine.counterbalance import SlotOrders, cycle_length
from study.engine.protocol import Protocol
from study.engine.resume import resume_plan, session_state
from study.engine.runner import SessionRunner, TrialSummary, derive_seed
from study.engine.sites import Place, check_participant_site, check_site
from study.engine.trial import ExperimenterControl, FreeClock, TrialWriter, WallClock
from study.lsl.session import LslPlan
from study.participants.base import Participant as SessionParticipant

__all__ = [
    "SessionSummary",
    "TrialSummary",
    "check_code",
    "default_seed",
    "derive_seed",
    "reserve_slots",
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
class _RunOptions:
    """How a session runs, with :func:`run_session`'s defaults applied (the keyword
    arguments of :class:`SessionRunner`)."""

    progress: Callable[[str], None]
    control: ExperimenterControl
    clock: FreeClock | WallClock
    camera_hz: float
    on_tick: Callable[[int, TrialWriter], None] | None
    recordings: Path | None
    record: bool


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


# ---------------------------------------------------------------------- opening


def _study(s: Session, protocol: Protocol, db: str | Path, force: bool, notes: list[str]) -> Study:
    """The database's study row (made on first use), under the database's write lock.
    Another protocol, study seed or platform version is refused unless ``force`` (then
    noted in ``notes``)."""
    ledger.lock_study(s)
    study = get_study(s)
    if study is None:
        study = Study(
            name=protocol.name,
            protocol_text=protocol.text,
            protocol_sha256=protocol.sha256,
            platform_version=__version__,
            seed=protocol.study.seed,
            sites=list(protocol.study.sites),
        )
        s.add(study)
        s.flush()
        return study
    stored = {
        "protocol_sha256": study.protocol_sha256,
        "seed": study.seed,
        "platform_version": study.platform_version,
    }
    wanted = {
        "protocol_sha256": protocol.sha256,
        "seed": protocol.study.seed,
        "platform_version": __version__,
    }
    found = identity.mismatches(stored, wanted)
    if found and found[0].field == "study.protocol_sha256" and not force:
        raise ValueError(
            f"{db}: field 'study.protocol_sha256': the database was made with protocol "
            f"'{study.name}' (SHA-256 {study.protocol_sha256[:12]}...), not with "
            f"{protocol.source} ({protocol.sha256[:12]}...); use force=True to run it anyway"
        )
    notes.extend(identity.check(db, found, force))
    return study


def _resume(
    s: Session,
    person: Participant | None,
    sessions: Sequence[SessionRow],
    code: str,
    db: str | Path,
    notes: list[str],
    machine: str,
) -> SessionRow:
    """Reopen the participant's last session (on ``machine``, recorded in the event):
    trials left ``running`` become ``aborted``."""
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
            detail={"aborted_trials": [t.id for t in stale], "machine": machine},
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
    slot: int | None,
    site: str | None,
) -> Participant:
    """The participant row with its order slot from the ledger of its ``site`` (``slot``
    when the caller reserved one) and the mode order of that slot."""
    person = Participant(
        study_id=study.id,
        code=code,
        site=site,
        kind=participant.kind,
        parameters=dict(participant.parameters),
        order_index=0,
        mode_order=[],
        seed=int(seed) if seed is not None else default_seed(study.seed, code),
    )
    s.add(person)
    s.flush()
    orders = _slot_orders(protocol, study, site)
    if slot is None:
        slot = ledger.allocate(s, study.id, code, person.id, orders.row, site)
    else:
        s.add(
            OrderSlot(
                study_id=study.id, site=site or "", slot=slot, code=code, participant_id=person.id
            )
        )
    index, order = orders(_check_slot(slot, protocol, code))
    person.order_index, person.mode_order = index, list(order)
    s.flush()
    return person


def _not_reserved_elsewhere(
    s: Session, study: Study, code: str, db: str | Path, slot: int | None
) -> None:
    """Refuse a code whose slot a running synthetic study has reserved (it will merge that
    participant); an interrupted study's reservation is taken up instead."""
    if slot is not None or not (is_postgresql(db) or database_url(db).startswith("sqlite:///")):
        return
    reserved = s.scalars(
        select(OrderSlot).where(
            OrderSlot.study_id == study.id, OrderSlot.code == code, OrderSlot.status == "reserved"
        )
    ).first()
    if reserved is None:
        return
    if is_postgresql(db):
        conn = s.connection()
        live = server_locks.is_held(conn, server_locks.SYNTH)
        pid = server_locks.holder(conn, server_locks.SYNTH) if live else ""
    else:
        lock = locks.synth_lock(database_file(db))
        live, pid = locks.is_held(lock), locks.holder(lock)
    if live:
        raise ValueError(
            f"{db}: field 'participant.code': {code} is a participant of the synthetic study "
            f"running on this database (pid {pid}); choose another code"
        )


def _slot_orders(protocol: Protocol, study: Study, site: str | None) -> SlotOrders:
    """Slot -> (row, mode order) of ``site``'s ledger under ``protocol``'s scheme (random
    draws seeded with the study seed and the site)."""
    return SlotOrders(protocol.modes, protocol.counterbalancing, study.seed, site)


def _check_slot(slot: int, protocol: Protocol, code: str) -> int:
    cycle = cycle_length(len(protocol.modes), protocol.counterbalancing)
    if cycle is None and slot >= MAX_RANDOM_INDEX:
        raise ValueError(
            f"participant code: {code!r} would take order slot {slot + 1}; the random scheme "
            f"draws orders in sequence up to {MAX_RANDOM_INDEX}"
        )
    return slot


def reserve_slots(
    engine: Engine,
    protocol: Protocol,
    db: str | Path,
    codes: Sequence[str],
    *,
    force: bool,
    place: Place | None = None,
) -> tuple[dict[str, int], list[str]]:
    """Order slots reserved in the study database for participants ``codes`` that run
    elsewhere first (a synthetic study's scratch files) at ``place``'s site, in one locked
    transaction; the study row is made if missing and its identity checked as
    :func:`run_session` does. Returns code -> slot (a code reserved before keeps its slot)
    and the notes of a forced identity mismatch."""
    notes: list[str] = []
    place = place if place is not None else Place()
    with Session(engine) as s, s.begin():
        study = _study(s, protocol, db, force, notes)
        check_site(db, place, study.sites or [], study.name)
        orders = _slot_orders(protocol, study, place.site)
        out = {
            code: ledger.allocate(s, study.id, code, None, orders.row, place.site) for code in codes
        }
        for code, slot in out.items():
            _check_slot(slot, protocol, code)
    return out, notes


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
    slot: int | None = None,
    place: Place | None = None,
) -> _Opened:
    """Resume the participant's session or start a new one at ``place`` (default no site,
    this host), in one transaction."""
    notes: list[str] = []
    place = place if place is not None else Place()
    with Session(engine) as s, s.begin():
        study = _study(s, protocol, db, force, notes)
        check_site(db, place, study.sites or [], study.name)
        person = s.scalars(
            select(Participant).where(Participant.study_id == study.id, Participant.code == code)
        ).first()
        sessions = []
        if person is not None:
            check_participant_site(db, code, person.site, place)
            sessions = list(
                s.scalars(
                    select(SessionRow)
                    .where(SessionRow.participant_id == person.id)
                    .order_by(SessionRow.id)
                )
            )
        if resume:
            row = _resume(s, person, sessions, code, db, notes, place.machine)
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
                _not_reserved_elsewhere(s, study, code, db, slot)
                person = _new_person(s, study, protocol, code, participant, seed, slot, place.site)
            row = SessionRow(
                participant_id=person.id,
                site=place.site,
                machine=place.machine,
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
    record: bool = True,
    durable: bool = True,
    slot: int | None = None,
    lock: bool = True,
    place: Place | None = None,
    lsl: bool | None = None,
    lsl_record: bool = True,
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
        ``[recording] camera_hz`` for a participant with a screen (``shows_camera``),
        none for one without (nobody looks: synthetic and headless scripted drivers).
    on_tick : callable, optional
        Passed to :func:`study.engine.trial.run_trial`.
    recordings : str or Path, optional
        Folder for the rerun recordings (``<code>/...rrd`` inside it); default
        ``<db stem>_recordings`` beside the database; paths stored relative to its folder.
    record : bool
        False: no trial is recorded (``asa synth --no-recordings``): every trial's
        ``recording_path`` is empty, every other row as with recordings.
    durable : bool
        False only for a scratch database thrown away after a crash (no fsync on commit,
        :func:`study.data.storage.open_database`): a synthetic study's per-participant file.
    slot : int, optional
        The order slot reserved for a new participant (:func:`reserve_slots`; a synthetic
        study's scratch file); default the next slot of the study's ledger.
    lock : bool
        Hold the session's lock file (``<db stem>_locks/session-<code>.lock``, SQLite only)
        while it runs, so ``asa db check`` knows it is live and a second process cannot
        run the same participant; False for scratch files.
    place : Place, optional
        Where the session runs: the site (required, and one of the study's, in a study
        with sites; the participant's site for all its sessions) and the machine; default
        no site and this host's name.
    lsl : bool, optional
        Lab Streaming Layer (:mod:`study.lsl`): None follows the protocol's ``[lsl]``; True
        opens the event and state outlets even without one; False none.
    lsl_record : bool
        False: the protocol's ``[[lsl.record]]`` streams are not recorded (outlets only).

    Returns
    -------
    SessionSummary

    Raises
    ------
    ValueError
        A bad participant code, a database not ours or made with another protocol, study
        seed or platform version, a second session without ``force``, nothing to resume,
        the participant's session running in another process, a missing or unknown site
        or another site than the participant's; LSL asked for without pylsl or liblsl, or
        a required stream of the lab's not on the network (before anything is started).
    """
    code = check_code(participant_code)
    human = participant.kind == "human"
    options = _RunOptions(
        progress=progress if progress is not None else (lambda line: None),
        control=control if control is not None else ExperimenterControl(),
        clock=clock if clock is not None else (WallClock() if human else FreeClock()),
        camera_hz=camera_hz if camera_hz is not None else _camera_hz(protocol, participant),
        on_tick=on_tick,
        recordings=Path(recordings).resolve() if recordings is not None else None,
        record=record,
    )
    where = place if place is not None else Place()
    plan = LslPlan.of(protocol.lsl, enable=lsl, record=lsl_record)
    found = plan.check() if plan is not None else []  # before anything is started
    with _session_lock(db, code, lock):
        return _run_locked(
            protocol, code, db, participant, seed, resume, force, durable, slot, where, options,
            (plan, found),
        )  # fmt: skip


def _camera_hz(protocol: Protocol, participant: SessionParticipant) -> float:
    """Camera frames per second in the recordings: what a participant with a screen saw,
    at the protocol's rate; none for a participant without one (docs/decisions.md)."""
    return protocol.recording.camera_hz if participant.shows_camera else 0.0


@contextlib.contextmanager
def _session_lock(db: str | Path, code: str, lock: bool) -> Iterator[None]:
    """Hold participant ``code``'s session lock: a lock file beside an SQLite file
    (:mod:`study.data.locks`), an advisory lock on a server database
    (:mod:`study.data.server_locks`); another process holding it is refused with one
    line. Where no lock can be taken (no folder, read-only, a server that cannot be
    reached) the session runs without one, and opening the database says what is wrong."""
    stack = contextlib.ExitStack()
    if lock:
        try:
            _take_session_lock(stack, db, code)
        except locks.LockHeld as held:
            raise ValueError(
                f"{db}: field 'participant.code': the session of participant {code} is "
                f"running in another process (pid {held.pid}); wait for it to end or stop it"
            ) from None
        except (OSError, DBAPIError, ArgumentError, ImportError):
            pass
    with stack:
        yield


def _take_session_lock(stack: contextlib.ExitStack, db: str | Path, code: str) -> None:
    if is_postgresql(db):
        name = server_locks.session_lock(code)
        stack.enter_context(server_locks.held(database_url(db), name, wait=False))
        return
    path = locks.session_lock(database_file(db), code)
    if database_url(db).startswith("sqlite:///") and path.parent.parent.is_dir():
        stack.enter_context(locks.held(path, wait=False))


def _run_locked(
    protocol: Protocol,
    code: str,
    db: str | Path,
    participant: SessionParticipant,
    seed: int | None,
    resume: bool,
    force: bool,
    durable: bool,
    slot: int | None,
    place: Place,
    options: _RunOptions,
    lsl: tuple[LslPlan | None, list],
) -> SessionSummary:
    """:func:`run_session` once the session's lock is held."""
    engine = open_database(db, durable=durable)
    try:
        opened = _open(
            engine, protocol, code, db, participant,
            seed=seed, resume=resume, force=force, slot=slot, place=place,
        )  # fmt: skip
        person = _checked(opened, protocol, db)
        plan, found = lsl
        with contextlib.ExitStack() as stack:
            link = None
            if plan is not None:
                link = stack.enter_context(
                    plan.started(engine, opened.session_id, code, place.machine, found)
                )
            runner = SessionRunner(
                protocol,
                engine,
                db,
                participant,
                person,
                opened.session_id,
                lsl=link,
                **{f.name: getattr(options, f.name) for f in dataclasses.fields(options)},
            )
            return _run(runner, code, opened)
    finally:
        engine.dispose()


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
