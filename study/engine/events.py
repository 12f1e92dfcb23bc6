"""Where a trial's rows and events go: :class:`TrialWriter` buffers the rows and writes
them in few transactions (DESIGN.md, "Data"); :class:`EventSink` writes one event to both
the database and the trial's recording."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np
from sqlalchemy.engine import Connection, Engine
from sqlalchemy.orm import Session

from sim.types import Contact
from study.data.recording import TrialRecorder
from study.data.storage import Event, Question, Sample, Trial, utc_now
from tasks.secondary import SecondaryEvent

# Core inserts of the buffered rows (plain executemany, column defaults applied)
_INSERT_SAMPLE = Sample.__table__.insert()
_INSERT_EVENT = Event.__table__.insert()
_INSERT_QUESTION = Question.__table__.insert()


def jsonable(value: Any) -> Any:
    """NaN and infinities as None, tuples as lists, recursively (for JSON columns)."""
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, dict):
        return {str(k): jsonable(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [jsonable(v) for v in value]
    if isinstance(value, np.generic):
        return jsonable(value.item())
    return value


class TrialWriter:
    """Buffers a trial's rows and writes them in few transactions.

    ``commits`` lists ``(tick, kind)`` of every transaction ("start", "flush", "end"),
    for tests and diagnostics.
    """

    def __init__(
        self,
        engine: Engine,
        session_id: int,
        listener: Callable[[float, str, dict[str, Any]], None] | None = None,
    ) -> None:
        self.engine = engine
        self.session_id = session_id
        # told of every event buffered, ``(t, kind, detail)`` (the session's LSL markers)
        self.listener = listener
        self.trial_id = -1
        self.recording_path = ""
        self.samples: list[dict[str, Any]] = []
        self.events: list[dict[str, Any]] = []
        self.questions: list[dict[str, Any]] = []
        self.commits: list[tuple[int, str]] = []

    def start(self, values: dict[str, Any], recording: Callable[[int], str]) -> int:
        """Insert the trial row (status running) and its start event; returns its id."""
        with Session(self.engine) as s, s.begin():
            row = Trial(**values, status="running", started_at=utc_now())
            s.add(row)
            s.flush()
            row.recording_path = self.recording_path = recording(row.id)
            s.add(
                Event(
                    session_id=self.session_id,
                    trial_id=row.id,
                    t=0.0,
                    kind="trial_started",
                    detail=jsonable(
                        {k: values[k] for k in ("phase", "ordinal", "attempt", "scenario")}
                    ),
                )
            )
            self.trial_id = row.id
        self.commits.append((0, "start"))
        return self.trial_id

    def event(self, t: float, kind: str, **detail: Any) -> None:
        if self.listener is not None:
            self.listener(t, kind, detail)
        self.events.append(
            {
                "session_id": self.session_id,
                "trial_id": self.trial_id,
                "t": float(t),
                "kind": kind,
                "detail": jsonable(detail),
                "created_at": utc_now(),
            }
        )

    def _write(self, s: Session | Connection) -> None:
        if self.samples:
            s.execute(_INSERT_SAMPLE, self.samples)
        if self.events:
            s.execute(_INSERT_EVENT, self.events)
        if self.questions:
            s.execute(_INSERT_QUESTION, self.questions)

    def _clear(self) -> None:
        """Forget the buffered rows: only once their transaction has committed."""
        self.samples, self.events, self.questions = [], [], []

    def flush(self, tick: int) -> None:
        """Write what is buffered in one transaction (kept for a retry if it fails)."""
        # a Core connection: the same rows and transaction as an ORM session, cheaper
        # (no unit of work for plain executemany inserts; docs/results.md)
        with self.engine.begin() as conn:
            self._write(conn)
        self._clear()
        self.commits.append((tick, "flush"))

    def abort(self, tick: int, t: float, reason: str) -> None:
        """After an exception in the loop: store what is buffered and mark the trial
        ``aborted`` with ``reason`` in one transaction (best effort: a database that
        fails here leaves the trial ``running`` for a resumed session to abort)."""
        self.event(t, "trial_ended", status="aborted", reason=reason)
        with Session(self.engine) as s, s.begin():
            self._write(s)
            row = s.get(Trial, self.trial_id)
            if row is not None:
                row.status = "aborted"
                row.outcome = {"ticks": tick, "duration_s": t, "aborted_reason": reason}
                row.ended_at = utc_now()
        self._clear()
        self.commits.append((tick, "abort"))

    def finish(self, tick: int, values: dict[str, Any]) -> None:
        """The last rows and the trial's outcome, status and end time: one transaction."""
        with Session(self.engine) as s, s.begin():
            self._write(s)
            row = s.get(Trial, self.trial_id)
            assert row is not None  # written by start()
            for key, value in values.items():
                setattr(row, key, value)
            row.ended_at = utc_now()
        self._clear()


def _question_row(trial_id: int, ev: SecondaryEvent) -> dict[str, Any]:
    q = ev.question
    assert q is not None  # question events carry their question
    return {
        "trial_id": trial_id,
        "block": ev.block_index,
        "index": ev.question_index,
        "text": q.text,
        "shown_is_correct": q.shown_is_correct,
        "shown_t": float(ev.t),
        "answered_t": None,
        "response": None,
        "correct": False,
        "answer_time_s": None,
    }


class EventSink:
    """One event of a trial, written to the database (a buffered row) and the recording.

    Also keeps the questions shown and not yet resolved: their rows are written when
    answered or timed out, or (still open) at the end of the trial.
    """

    __slots__ = ("open_questions", "recorder", "writer")

    def __init__(self, writer: TrialWriter, recorder: TrialRecorder) -> None:
        self.writer = writer
        self.recorder = recorder
        self.open_questions: dict[tuple[int, int], dict[str, Any]] = {}

    def __call__(self, t: float, kind: str, note: str = "", /, **detail: Any) -> None:
        """An event row ``kind`` at ``t`` [s] with ``detail``; in the recording ``kind: note``."""
        self.writer.event(t, kind, **detail)
        self.recorder.event(t, kind, note)

    def collision(self, contact: Contact, t: float) -> None:
        """A collision's start: stored at its own start time, recorded at the tick's ``t``."""
        self.writer.event(
            contact.t_start,
            "collision",
            element=contact.obstacle,
            x=float(contact.position[0]),
            y=float(contact.position[1]),
            index=contact.index,
        )
        self.recorder.event(t, "collision", contact.obstacle)

    def secondary(self, ev: SecondaryEvent) -> None:
        """An event of the secondary task: question rows, event rows, the recording."""
        writer, recorder = self.writer, self.recorder
        key = (ev.block_index, ev.question_index if ev.question_index is not None else -1)
        if ev.kind == "question_shown":
            self.open_questions[key] = _question_row(writer.trial_id, ev)
            text = ev.question.text if ev.question is not None else ""
            writer.event(
                ev.t, "question_shown", block=ev.block_index, index=ev.question_index, text=text
            )
            recorder.question(ev.t, text)
        elif ev.kind in ("answer_given", "question_timeout"):
            row = self.open_questions.pop(key, None)
            if ev.kind == "answer_given":
                if row is not None:
                    row.update(
                        answered_t=float(ev.t),
                        response=ev.response,
                        correct=bool(ev.correct),
                        answer_time_s=ev.answer_time_s,
                    )
                writer.event(
                    ev.t,
                    "answer_given",
                    block=ev.block_index,
                    index=ev.question_index,
                    response=ev.response,
                    correct=ev.correct,
                    answer_time_s=ev.answer_time_s,
                )
                recorder.question(ev.t, f"answer: {'yes' if ev.response else 'no'}")
            else:
                writer.event(
                    ev.t, "question_timeout", block=ev.block_index, index=ev.question_index
                )
                recorder.event(ev.t, "timeout", "question")
            if row is not None:
                writer.questions.append(row)
        else:
            writer.event(ev.t, ev.kind, block=ev.block_index)

    def close_questions(self) -> None:
        """Buffer the rows of the questions shown and never resolved."""
        self.writer.questions.extend(self.open_questions.values())
        self.open_questions.clear()
