"""Checking and exporting a study database (``asa db check``, ``asa export``), and finding
a trial's recording (``asa replay``).

:func:`check` looks for what the session engine promises (DESIGN.md "Data"; issue 4):
every finished trial (completed or timed out) has its samples (one per tick at 20 Hz,
contiguous, as many as its duration asks, within two ticks), its start and end events,
its outcome fields, its NASA-TLX answers where the protocol asks for them, and its
recording (unless it was run without one: an empty path), which passes
``rerun rrd verify`` (:func:`study.data.rrd.verify_many`); a timed-out trial's task is
not completed; no orphan rows; no trial left ``running`` outside a ``running`` session;
no session or trial ``running`` without a live process
holding it (:mod:`study.data.locks`; else it was interrupted and is to be resumed); the
questionnaires the stored protocol requires of a completed session; the order ledger
consistent with the participants, every slot issued once (issue 20;
:mod:`study.data.check_people`). :func:`export` writes one CSV per table:
columns in the table's order, JSON columns as JSON text, times in ISO 8601, NULL empty.
"""

from __future__ import annotations

import base64
import contextlib
import csv
import datetime as dt
import json
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sqlalchemy import JSON, func, inspect, select
from sqlalchemy.orm import Session

from questionnaires import nasa_tlx
from study.data.check_people import check_ledger, check_people, check_sites
from study.data.rrd import verify_many
from study.data.storage import (
    TRIAL_FINISHED,
    Base,
    Event,
    Participant,
    Question,
    Response,
    Sample,
    SessionRow,
    Trial,
    database_file,
    database_url,
    get_study,
    open_database,
)

DT = 0.05  # [s] control tick
TICK_TOLERANCE = 2  # ticks


@dataclass(frozen=True, slots=True)
class CheckReport:
    """What :func:`check` found."""

    database: str
    problems: tuple[str, ...]
    counts: dict[str, int] = field(default_factory=dict)  # rows per table, checked trials
    recordings: str = ""  # where the recordings were looked for

    @property
    def clean(self) -> bool:
        return not self.problems

    def as_dict(self) -> dict[str, Any]:
        return {
            "database": self.database,
            "clean": self.clean,
            "problems": list(self.problems),
            "counts": dict(self.counts),
            "recordings": self.recordings,
        }

    def text(self) -> str:
        lines = [
            f"{self.database}: " + ("clean" if self.clean else f"{len(self.problems)} problems")
        ]
        if self.recordings:
            lines.append(f"recordings: looked in {self.recordings}")
        lines.append("  " + ", ".join(f"{k} {v}" for k, v in self.counts.items()))
        lines += [f"  - {p}" for p in self.problems]
        return "\n".join(lines)


def _stored_protocol(protocol_text: str) -> Any:
    """The study's protocol read back from its stored text, None if it no longer parses."""
    from study.engine.protocol import parse_protocol

    try:
        return parse_protocol(protocol_text, "<stored protocol>")
    except ValueError:
        return None


def _after_trial(protocol: Any) -> tuple[bool, str] | None:
    """(questionnaire after main trials?, weights) of a stored protocol, None if unreadable."""
    if protocol is None:
        return None
    after = protocol.main.after_trial
    return (after is not None, after.weights if after is not None else "raw")


def _orphans(s: Session, problems: list[str]) -> None:
    def missing(child: Any, column: Any, parent: Any, label: str) -> None:
        rows = s.execute(
            select(child.id, column)
            .outerjoin(parent, column == parent.id)
            .where(column.is_not(None), parent.id.is_(None))
            .limit(5)
        ).all()
        for row_id, ref in rows:
            problems.append(f"{label} {row_id}: refers to a missing row {ref}")

    missing(Sample, Sample.trial_id, Trial, "sample")
    missing(Event, Event.trial_id, Trial, "event")
    missing(Event, Event.session_id, SessionRow, "event")
    missing(Question, Question.trial_id, Trial, "question")
    missing(Response, Response.trial_id, Trial, "response")
    missing(Response, Response.participant_id, Participant, "response")
    missing(Trial, Trial.session_id, SessionRow, "trial")
    missing(Trial, Trial.participant_id, Participant, "trial")
    missing(SessionRow, SessionRow.participant_id, Participant, "session")


def check(
    db: str | Path, *, verify_recordings: bool = True, recordings: str | Path | None = None
) -> CheckReport:
    """Integrity and consistency of a study database (see the module docstring).

    ``recordings``: the folder the recordings were written to (``--recordings``), where
    each trial's file is looked for as ``<code>/<file name>``; default: its stored path,
    relative to the database's folder.

    Raises
    ------
    ValueError
        When the database is not an asa-study database (names it).
    FileNotFoundError
        When the SQLite file does not exist.
    """
    engine = open_database(db, create=False)
    problems: list[str] = []
    to_verify: list[tuple[Path, str]] = []  # recordings, checked together at the end
    counts: dict[str, int] = {}
    folder = database_file(db).parent
    looked = Path(recordings) if recordings is not None else folder
    try:
        present = set(inspect(engine).get_table_names())
        with Session(engine) as s:
            counts.update(_table_counts(s, present))
            study = get_study(s)
            if study is None:
                problems.append("study: no study row (an empty database)")
                return CheckReport(str(db), tuple(problems), counts, str(looked.resolve()))
            protocol = _stored_protocol(study.protocol_text)
            after = _after_trial(protocol)
            _orphans(s, problems)
            sessions = {r.id: r for r in s.scalars(select(SessionRow))}
            stats = _sample_stats(s)
            kinds = _event_kinds(s)
            main_trials: dict[int, list[Trial]] = {}
            checked = 0
            for trial in s.scalars(select(Trial).order_by(Trial.id)):
                where = f"trial {trial.id} ({trial.phase} #{trial.ordinal})"
                session = sessions.get(trial.session_id)
                if (
                    trial.status == "running"
                    and session is not None
                    and session.status != "running"
                ):
                    problems.append(f"{where}: still running in a session that is {session.status}")
                if trial.status not in TRIAL_FINISHED:
                    continue
                checked += 1
                if trial.phase == "main":
                    main_trials.setdefault(trial.session_id, []).append(trial)
                _check_samples(trial, stats.get(trial.id, (0, None, None, None)), where, problems)
                _check_completed(trial, kinds.get(trial.id, set()), where, problems)
                path = recording_file(trial.recording_path, folder, recordings)
                _check_recording(trial, path, verify_recordings, problems, where, to_verify)
            if after is not None and after[0]:
                _check_questionnaires(s, main_trials, sessions, after[1], problems)
            counts["live_sessions"] = check_people(s, db, protocol, problems)
            check_sites(s, study, problems)
            if "order_slot" in present:
                check_ledger(s, db, study, protocol, problems)
            counts["trials_checked"] = checked
    finally:
        engine.dispose()
    if to_verify:  # one rerun process for all recordings
        failures = verify_many([path for path, _ in to_verify])
        for path, where in to_verify:
            if path in failures:
                problems.append(f"{where}: {failures[path]}")
    return CheckReport(str(db), tuple(problems), counts, str(looked.resolve()))


def recording_file(stored: str, folder: Path, recordings: str | Path | None = None) -> Path:
    """Where a trial's recording is: its stored path against the database's ``folder``,
    or with ``recordings`` given, ``<recordings>/<code>/<file name>`` (the layout every
    session writes, so a recordings folder copied elsewhere is found)."""
    path = Path(stored)
    if recordings is not None:
        return Path(recordings) / path.parent.name / path.name
    return path if path.is_absolute() else folder / path


def _table_counts(s: Session, present: set[str]) -> dict[str, int]:
    """Rows per table of the schema that the database has (``order_slot`` is missing in
    databases made before issue 20)."""
    return {
        table.name: int(s.scalar(select(func.count()).select_from(table)) or 0)
        for table in Base.metadata.sorted_tables
        if table.name in present
    }


def _event_kinds(s: Session) -> dict[int, set[str]]:
    """Trial id -> the kinds of its events."""
    kinds: dict[int, set[str]] = {}
    for tid, kind in s.execute(
        select(Event.trial_id, Event.kind).where(Event.trial_id.is_not(None)).distinct()
    ):
        kinds.setdefault(tid, set()).add(kind)
    return kinds


def _sample_stats(s: Session) -> dict[int, tuple[int, int, int, float]]:
    """Trial id -> (samples, first tick, last tick, last sample time [s])."""
    return {
        tid: (n, lo, hi, tmax)
        for tid, n, lo, hi, tmax in s.execute(
            select(
                Sample.trial_id,
                func.count(),
                func.min(Sample.tick),
                func.max(Sample.tick),
                func.max(Sample.t),
            ).group_by(Sample.trial_id)
        )
    }


def _check_samples(trial: Trial, stats: tuple[Any, ...], where: str, problems: list[str]) -> None:
    """One sample per tick at 20 Hz, contiguous, as many as the trial's duration asks."""
    n, lo, hi, tmax = stats
    if n == 0:
        problems.append(f"{where}: {trial.status} but has no samples")
        return
    if hi - lo + 1 != n:
        problems.append(f"{where}: sample ticks {lo}..{hi} are not contiguous ({n})")
    expected = round(tmax / DT)
    if abs(n - expected) > TICK_TOLERANCE:
        problems.append(f"{where}: {n} samples for {tmax:.2f} s (expected ~{expected} at 20 Hz)")
    if trial.completion_time_s is not None and trial.phase != "baseline":
        if n < round(trial.completion_time_s / DT) - TICK_TOLERANCE:
            problems.append(
                f"{where}: {n} samples for a completion time of {trial.completion_time_s:.2f} s"
            )


def _check_completed(trial: Trial, kinds: set[str], where: str, problems: list[str]) -> None:
    """A finished trial's start and end events, ``ended_at`` and outcome fields."""
    missing_events = {"trial_started", "trial_ended"} - kinds
    if missing_events:
        problems.append(f"{where}: missing events {', '.join(sorted(missing_events))}")
    if trial.ended_at is None:
        problems.append(f"{where}: {trial.status} without ended_at")
    if trial.status == "timed_out" and trial.completed_task:
        problems.append(f"{where}: timed out, yet its task is stored as completed")
    if trial.phase != "baseline" and (
        trial.completed_task is None
        or trial.completion_time_s is None
        or trial.collisions is None
        or trial.score is None
    ):
        problems.append(f"{where}: {trial.status} without its outcome fields")


def _check_questionnaires(
    s: Session,
    main_trials: dict[int, list[Trial]],
    sessions: dict[int, SessionRow],
    weights: str,
    problems: list[str],
) -> None:
    """NASA-TLX ratings (and pairwise choices as ``weights`` asks) after every main trial
    of a completed session."""
    tlx: dict[int, set[str]] = {}
    for tid, item in s.execute(
        select(Response.trial_id, Response.item).where(
            Response.instrument == nasa_tlx.INSTRUMENT_ID, Response.trial_id.is_not(None)
        )
    ):
        tlx.setdefault(tid, set()).add(item)
    for session_id, trials in main_trials.items():
        session = sessions.get(session_id)
        if session is None or session.status != "completed":
            continue
        last = max(t.ordinal for t in trials)
        for trial in trials:
            items = tlx.get(trial.id, set())
            where = f"trial {trial.id} (main #{trial.ordinal})"
            if not set(nasa_tlx.SUBSCALE_IDS) <= items:
                problems.append(f"{where}: NASA-TLX ratings missing")
            pairs = {i for i in items if i.startswith("pair:")}
            want_pairs = weights == "per_trial" or (weights == "once" and trial.ordinal == last)
            if want_pairs and len(pairs) != nasa_tlx.N_PAIRS:
                problems.append(
                    f"{where}: {len(pairs)} NASA-TLX pairwise choices, expected {nasa_tlx.N_PAIRS}"
                )


def _check_recording(
    trial: Trial,
    path: Path,
    verify_recordings: bool,
    problems: list[str],
    where: str,
    to_verify: list[tuple[Path, str]],
) -> None:
    if not trial.recording_path:  # run without recordings (asa synth --no-recordings)
        return
    if not path.is_file():
        problems.append(f"{where}: recording {trial.recording_path} is missing (looked at {path})")
        return
    if verify_recordings:
        to_verify.append((path, where))


# ------------------------------------------------------------------------- replay


def find_recording(
    db: str | Path, participant: str, trial: int, *, recordings: str | Path | None = None
) -> Path:
    """The ``.rrd`` file of trial ``trial`` (row id) of participant ``participant``
    (``recordings``: the recordings' folder, as :func:`check`).

    Raises
    ------
    ValueError
        Naming the database and the field (``participant.code``, ``trial.id``,
        ``trial.recording_path``) when the participant or trial is unknown, or the
        trial has no recording or its file is missing.
    """
    engine = open_database(db, create=False)
    try:
        with Session(engine) as s:
            person = s.scalars(select(Participant).where(Participant.code == participant)).first()
            if person is None:
                codes = s.scalars(select(Participant.code).order_by(Participant.code)).all()
                known = ", ".join(codes[:20]) + (" ..." if len(codes) > 20 else "")
                raise ValueError(
                    f"{db}: field 'participant.code': no participant {participant!r} "
                    f"(known: {known or 'none'})"
                )
            row = s.get(Trial, trial)
            if row is None or row.participant_id != person.id:
                trials = s.scalars(
                    select(Trial).where(Trial.participant_id == person.id).order_by(Trial.id)
                ).all()
                listed = "; ".join(
                    f"{t.id} ({t.phase} {t.ordinal}"
                    + (f" attempt {t.attempt}" if t.attempt else "")
                    + (f", {t.mode}" if t.mode else "")
                    + ")"
                    for t in trials
                )
                raise ValueError(
                    f"{db}: field 'trial.id': participant {participant} has no trial {trial} "
                    f"(trial ids: {listed or 'none'})"
                )
            stored = row.recording_path
    finally:
        engine.dispose()
    if not stored:
        raise ValueError(
            f"{db}: field 'trial.recording_path': trial {trial} of {participant} has no recording"
        )
    url = database_url(db)
    base = Path(url[len("sqlite:///") :]).parent if url.startswith("sqlite:///") else Path()
    path = recording_file(stored, base, recordings)
    if not path.is_file():
        raise ValueError(
            f"{db}: field 'trial.recording_path': the recording of trial {trial} of "
            f"{participant} is missing ({path})"
        )
    return path


def remove_recordings_of(db: str | Path) -> list[Path]:
    """Delete the recording files the SQLite database ``db`` refers to, and their
    participant folders when that leaves them empty; returns the files deleted.

    For a scratch database about to be thrown away (a synthetic participant run again
    after a crash): only its own files go, never the rest of a shared recordings folder.
    A missing or unreadable database deletes nothing.
    """
    try:
        engine = open_database(db, create=False)
    except (ValueError, FileNotFoundError):
        return []
    try:
        with Session(engine) as s:
            stored = [p for p in s.scalars(select(Trial.recording_path)) if p]
    finally:
        engine.dispose()
    folder = database_file(db).parent
    removed = []
    for rel in stored:
        path = Path(rel) if Path(rel).is_absolute() else folder / rel
        if path.is_file():
            path.unlink()
            removed.append(path)
            with contextlib.suppress(OSError):
                path.parent.rmdir()  # only when empty
    return removed


# ------------------------------------------------------------------------- export


def _has_rows(conn: Any, table: Any) -> bool:
    return conn.execute(select(table.c.id).limit(1)).first() is not None


def _cell(value: Any, is_json: bool) -> str:
    if value is None:
        return ""
    if is_json:
        return json.dumps(value, sort_keys=True)
    if isinstance(value, dt.datetime):
        return value.isoformat()
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else ""
    if isinstance(value, bytes):  # the lab's samples (lsl_chunk): base64 text
        return base64.b64encode(value).decode("ascii")
    return str(value)


# the server's bookkeeping, not study data: the invites' token hashes (issue 37)
NOT_EXPORTED = frozenset({"invite"})


def export(db: str | Path, out: str | Path, *, force: bool = False) -> dict[str, int]:
    """Write one CSV per table of the study database into folder ``out`` (the database is
    opened read-only; not the tables of :data:`NOT_EXPORTED`).

    Returns
    -------
    dict
        Table name -> rows written.

    Raises
    ------
    ValueError
        ``out`` is a file, or a CSV file of the export exists already and ``force`` is
        false (naming it; nothing is written); see :func:`open_database` for the database.
    """
    from study.data.paths import refuse_existing

    folder = Path(out)
    if folder.exists() and not folder.is_dir():
        raise ValueError(f"out: {out} must be a folder, and this is a file")
    targets = [
        folder / f"{table.name}.csv"
        for table in Base.metadata.sorted_tables
        if table.name not in NOT_EXPORTED
    ]
    refuse_existing(targets, force=force)
    engine = open_database(db, create=False)
    folder.mkdir(parents=True, exist_ok=True)
    written: dict[str, int] = {}
    try:
        present = set(inspect(engine).get_table_names())
        with engine.connect() as conn:
            for table in Base.metadata.sorted_tables:
                if table.name not in present or table.name in NOT_EXPORTED:
                    continue  # order_slot in a database made before issue 20
                if table.name.startswith("lsl_") and not _has_rows(conn, table):
                    continue  # the lab's streams: only in a study that recorded some
                columns = list(table.columns)
                json_cols = [isinstance(c.type, JSON) for c in columns]
                n = 0
                with open(folder / f"{table.name}.csv", "w", newline="", encoding="utf-8") as f:
                    writer = csv.writer(f)
                    writer.writerow([c.name for c in columns])
                    result = conn.execution_options(stream_results=True).execute(
                        select(table).order_by(*table.primary_key.columns)
                    )
                    for row in result:
                        writer.writerow([_cell(v, j) for v, j in zip(row, json_cols, strict=True)])
                        n += 1
                written[table.name] = n
    finally:
        engine.dispose()
    return written
