"""Where a participant's session stands after an interruption, for the experimenter: the
trial that was cut short and what a resumed session runs again (``asa run`` and its
``--resume``; DESIGN.md "Data": a resumed session runs its aborted trial again)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from sqlalchemy import select
from sqlalchemy.engine import Engine
from sqlalchemy.orm import Session

from study.data.storage import (
    TRIAL_FINISHED,
    Participant,
    SessionRow,
    Trial,
    get_study,
    open_database,
)


@dataclass(frozen=True, slots=True)
class TrialRef:
    """One trial as the experimenter names it."""

    trial_id: int
    phase: str
    ordinal: int
    attempt: int
    mode: str
    status: str
    duration_s: float | None  # [s] simulated, when it ended
    reason: str  # why it was aborted; "" otherwise

    def name(self) -> str:
        """``main #1 (mode reactive_bn, trial 12)``."""
        mode = f"mode {self.mode}, " if self.mode else ""
        attempt = f" attempt {self.attempt}" if self.attempt else ""
        return f"{self.phase} #{self.ordinal}{attempt} ({mode}trial {self.trial_id})"


@dataclass(frozen=True, slots=True)
class SessionState:
    """A participant's last session: its status, the trials that run again on resume
    (aborted and not finished since) and the last finished one."""

    session_id: int
    status: str  # "running" (cut off), "aborted", "completed"
    again: tuple[TrialRef, ...]  # the last attempt of its (phase, ordinal), cut short
    last_finished: TrialRef | None
    finished: int  # trials that ran to their end (kept)


def _ref(t: Trial) -> TrialRef:
    outcome = t.outcome or {}
    return TrialRef(
        trial_id=t.id,
        phase=t.phase,
        ordinal=t.ordinal,
        attempt=t.attempt,
        mode=t.mode,
        status=t.status,
        duration_s=outcome.get("duration_s"),
        reason=str(outcome.get("aborted_reason", "")) if t.status == "aborted" else "",
    )


def session_state(engine: Engine, session_id: int) -> SessionState:
    """The state of session ``session_id`` (see :class:`SessionState`)."""
    with Session(engine) as s:
        row = s.get(SessionRow, session_id)
        if row is None:
            raise ValueError(f"session_id: no session {session_id} in the database")
        trials = list(s.scalars(select(Trial).where(Trial.session_id == session_id)))
        trials.sort(key=lambda t: t.id)
        status = row.status
    last: dict[tuple[str, int], Trial] = {}
    for t in trials:
        last[(t.phase, t.ordinal)] = t
    # cut short and not run again since: the session runs it again
    again = [_ref(t) for t in last.values() if t.status in ("aborted", "running")]
    again.sort(key=lambda ref: ref.trial_id)
    finished = [t for t in trials if t.status in TRIAL_FINISHED]
    return SessionState(
        session_id=session_id,
        status=status,
        again=tuple(again),
        last_finished=_ref(finished[-1]) if finished else None,
        finished=len(finished),
    )


def last_session(db: str | Path, code: str) -> SessionState | None:
    """The state of participant ``code``'s last session in ``db``; None without one (or
    without a database)."""
    try:
        engine = open_database(db, create=False)
    except (ValueError, FileNotFoundError):
        return None
    try:
        with Session(engine) as s:
            study = get_study(s)
            person = (
                s.scalars(
                    select(Participant).where(
                        Participant.study_id == study.id, Participant.code == code
                    )
                ).first()
                if study is not None
                else None
            )
            session_id = (
                s.scalars(
                    select(SessionRow.id)
                    .where(SessionRow.participant_id == person.id)
                    .order_by(SessionRow.id.desc())
                ).first()
                if person is not None
                else None
            )
        return session_state(engine, session_id) if session_id is not None else None
    finally:
        engine.dispose()


def resume_plan(state: SessionState) -> str:
    """What a resumed session does first, in words (the line after "session N resumed")."""
    kept = f"{state.finished} finished trial{'s' if state.finished != 1 else ''} kept"
    if state.again:
        runs = "; ".join(
            f"{t.phase} #{t.ordinal}" + (f" mode {t.mode}" if t.mode else "")
            + f" runs again as attempt {t.attempt + 1} (trial {t.trial_id} was aborted"
            + (f": {t.reason})" if t.reason else ")")
            for t in state.again
        )  # fmt: skip
        return f"{runs}; {kept}"
    if state.last_finished is None:
        return f"no trial was run yet; it starts after what is done ({kept})"
    return f"no trial was cut short; it continues after {state.last_finished.name()}; {kept}"
