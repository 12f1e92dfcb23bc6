"""Pushing a site's study database into the study's shared database (issue 24; DESIGN.md
"Data": an offline site writes SQLite and pushes to the server later, idempotently).

The source (an SQLite file or a URL) is read whole; the destination (likewise; an empty
one gets the schema and the source's study row) is written in one transaction under its
write lock (:func:`study.data.ledger.lock_study`), so a push adds everything or nothing.
Rows are matched by global keys (:mod:`study.data.pushdata`), never by ids, which are
assigned afresh. The rules (docs/decisions.md, "Pushing a site's database"):

- a participant not in the destination is copied with its order slot; a slot that
  another code holds there is a conflict (unless that code was excluded and the slot
  reissued to this one at the site);
- a participant in the destination must have the same fields and slot; its sessions
  there must be the same here, except that one held ``aborted`` there may be replaced by
  its newer state here when what is there is the start of it (a resumed session); its
  sessions not there are added;
- participants with a session still running here are held back, to a later push;
- any other difference is a conflict: ``ValueError`` naming the participant and the
  field, and nothing is written.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sqlalchemy import create_engine, inspect
from sqlalchemy.engine import Connection, Engine
from sqlalchemy.exc import DBAPIError
from sqlalchemy.orm import Session

from study.data import identity, schema
from study.data.dbfile import is_url
from study.data.ledger import lock_study
from study.data.pushdata import PersonRows, read_people
from study.data.pushplan import Plan, plan_person
from study.data.pushwrite import write_plan
from study.data.rows import insert_row, table_rows
from study.data.storage import database_file, database_url, is_server, open_database

_IDENTITY = ("protocol_sha256", "seed")


@dataclass(frozen=True, slots=True)
class PersonResult:
    """What a push did (or, dry, would do) with one participant of the source."""

    code: str
    site: str | None
    action: str  # "pushed", "updated", "already there", "held back"
    sessions: int  # sessions written (added or replaced)
    trials: int
    samples: int
    detail: str  # what was added or replaced, or why it was held back


@dataclass(frozen=True, slots=True)
class PushReport:
    """A push's outcome: per participant, the totals written, and notes for the user."""

    source: str
    destination: str
    dry_run: bool
    study_created: bool  # the destination had no study: the source's was copied
    people: tuple[PersonResult, ...]
    recordings: str  # where the recordings are after the push
    notes: tuple[str, ...] = field(default_factory=tuple)

    def totals(self) -> dict[str, int]:
        """Participants, sessions, trials and samples written; participants held back."""
        written = [p for p in self.people if p.action in ("pushed", "updated")]
        return {
            "participants": sum(p.action == "pushed" for p in self.people),
            "participants_updated": sum(p.action == "updated" for p in self.people),
            "participants_already_there": sum(p.action == "already there" for p in self.people),
            "participants_held_back": sum(p.action == "held back" for p in self.people),
            "sessions": sum(p.sessions for p in written),
            "trials": sum(p.trials for p in written),
            "samples": sum(p.samples for p in written),
        }

    @property
    def changed(self) -> bool:
        """Whether the push wrote (or, dry, would write) anything."""
        return self.study_created or any(p.action in ("pushed", "updated") for p in self.people)

    def as_dict(self) -> dict[str, Any]:
        return {
            "source": self.source,
            "destination": self.destination,
            "dry_run": self.dry_run,
            "study_created": self.study_created,
            "changed": self.changed,
            "totals": self.totals(),
            "participants": [
                {
                    "code": p.code, "site": p.site, "action": p.action, "sessions": p.sessions,
                    "trials": p.trials, "samples": p.samples, "detail": p.detail,
                }
                for p in self.people
            ],
            "recordings": self.recordings,
            "notes": list(self.notes),
        }  # fmt: skip

    def text(self) -> str:
        n = self.totals()
        verb = "would push" if self.dry_run else "pushed"
        lines = [f"{self.source} -> {self.destination}" + (" (dry run: nothing written)"
                                                           if self.dry_run else "")]  # fmt: skip
        for p in self.people:
            site = f" ({p.site})" if p.site else ""
            lines.append(f"  {p.code}{site}: {p.action}" + (f": {p.detail}" if p.detail else ""))
        if not self.changed:
            lines.append("everything was already there; nothing to do")
        else:
            lines.append(
                f"{verb} {count(n['participants'], 'new participant')}, "
                f"{n['participants_updated']} updated; {count(n['sessions'], 'session')}, "
                f"{count(n['trials'], 'trial')}, {count(n['samples'], 'sample')}; "
                f"{n['participants_already_there']} already there"
            )
        if n["participants_held_back"]:
            lines.append(
                f"{count(n['participants_held_back'], 'participant')} held back (a session "
                "still running); a later push takes them once their sessions have ended"
            )
        lines += [*self.notes, self.recordings]
        return "\n".join(lines)


def count(n: int, noun: str) -> str:
    """``1 trial``, ``3 trials``."""
    return f"{n} {noun}" + ("" if n == 1 else "s")


def push(src: str | Path, dst: str | Path, *, dry_run: bool = False) -> PushReport:
    """Copy the study data of the database ``src`` into the study database ``dst``.

    Parameters
    ----------
    src, dst : str or Path
        SQLite files or SQLAlchemy URLs. ``dst`` may be a new file or an empty server
        database (it gets the schema and the source's study row).
    dry_run : bool
        Write nothing (not even a new destination's schema); report what a push would do.

    Returns
    -------
    PushReport

    Raises
    ------
    ValueError
        One line: ``src`` missing or not a study database, or at an older schema revision;
        ``dst`` not a study database, at an older revision, of another study (protocol
        SHA-256 or seed), or the same database as ``src``; a participant in both with
        other data, or an order slot held by another code there (then nothing is written).
    """
    _check_distinct(src, dst)
    study, people = _read_source(src)
    engine = _open_destination(dst, dry_run)
    try:
        if engine is None:  # dry run into a destination without a study yet
            plans = [plan_person(None, None, rows, src, dst) for rows in people.values()]
            return _report(src, dst, dry_run, True, plans, ())
        with Session(engine) as s, s.begin():
            if not dry_run:
                lock_study(s)
            conn = s.connection()
            study_id, created, notes = _destination_study(conn, study, src, dst, dry_run)
            there = read_people(conn, list(people)) if study_id is not None else {}
            plans = [plan_person(conn, there.get(c), rows, src, dst) for c, rows in people.items()]
            if not dry_run:
                for plan in plans:
                    write_plan(conn, study_id, plan, _folders(src, dst))
        return _report(src, dst, dry_run, created, plans, notes)
    finally:
        if engine is not None:
            engine.dispose()


def _check_distinct(src: str | Path, dst: str | Path) -> None:
    """Refuse pushing a database into itself."""
    same = database_url(src) == database_url(dst)
    if not same and not is_server(src) and not is_server(dst):
        a, b = database_file(src), database_file(dst)
        same = a.exists() and b.exists() and os.path.samefile(a, b)
    if same:
        raise ValueError(f"{dst}: is the database being pushed ({src}); give another destination")


def _require_head(db: str | Path, engine: Engine) -> None:
    """Refuse a database at an older schema revision than this platform's (one line
    naming ``asa db upgrade``)."""
    with engine.connect() as conn:
        current = schema.database_revision(conn)
    if current != schema.head():
        raise ValueError(
            f"{db}: schema revision {current} is older than this platform's "
            f"{schema.head()}; {schema.upgrade_line(db)}"
        )


def _read_source(src: str | Path) -> tuple[dict[str, Any], dict[str, PersonRows]]:
    """The source's study row and its participants' rows, read-only."""
    if not is_url(str(src)) and not Path(src).exists():
        raise ValueError(f"{src}: no such file; give the site's study database to push")
    engine = open_database(src, create=False)
    try:
        _require_head(src, engine)
        with engine.connect() as conn:
            studies = table_rows(conn, "study")
            if not studies:
                raise ValueError(f"{src}: holds no study; nothing to push")
            return studies[0], read_people(conn, lsl=True)
    finally:
        engine.dispose()


def _open_destination(dst: str | Path, dry_run: bool) -> Engine | None:
    """The destination opened for writing (made when missing or empty), or for a dry run
    read-only, then None when it has no study database yet."""
    if not dry_run:
        return open_database(dst)
    if not is_url(str(dst)) and not Path(dst).exists():
        return None
    if is_server(dst):
        probe = create_engine(database_url(dst))
        try:
            empty = not inspect(probe).get_table_names()
        except DBAPIError:
            empty = False  # open_database words the failure
        finally:
            probe.dispose()
        if empty:
            return None
    engine = open_database(dst, create=False)
    try:
        _require_head(dst, engine)
    except BaseException:
        engine.dispose()
        raise
    return engine


def _destination_study(
    conn: Connection, study: dict[str, Any], src: str | Path, dst: str | Path, dry_run: bool
) -> tuple[int | None, bool, tuple[str, ...]]:
    """The destination's study id (the source's study copied when it has none; None on a
    dry run), whether it was made, and notes; another protocol or seed is refused."""
    have = table_rows(conn, "study")
    if not have:
        return (None if dry_run else insert_row(conn, "study", study)), True, ()
    found = identity.mismatches(
        {k: have[0][k] for k in _IDENTITY}, {k: study[k] for k in _IDENTITY}
    )
    if found:
        words = "; ".join(
            f"field '{m.field}': {identity.show(m.stored)} there, {identity.show(m.wanted)} in "
            f"{src}"
            for m in found
        )
        raise ValueError(f"{dst}: study {have[0]['name']!r} is another study ({words}); "
                         "nothing was pushed")  # fmt: skip
    notes = ()
    if have[0]["platform_version"] != study["platform_version"]:
        notes = (
            f"note: {src} was made with platform version {study['platform_version']}, the "
            f"destination with {have[0]['platform_version']} (same schema revision); pushed",
        )
    return int(have[0]["id"]), False, notes


def _folders(src: str | Path, dst: str | Path) -> tuple[Path, Path] | None:
    """(source folder, destination folder) to rewrite recording paths between, or None
    when the destination is a server (paths kept as they are)."""
    if is_server(dst):
        return None
    return database_file(src).parent, database_file(dst).parent


def _recordings(src: str | Path, dst: str | Path) -> str:
    """Where the recordings are after a push (they are never copied)."""
    folder = database_file(src).parent
    if is_server(dst) or is_server(src):
        return (
            f"recordings: not copied; they stay beside {src} ({folder}), their paths stored "
            "as they were, relative to that folder"
        )
    return (
        f"recordings: not copied; they stay in {folder}, their paths rewritten relative to "
        f"{database_file(dst).parent}"
    )


def _report(
    src: str | Path,
    dst: str | Path,
    dry_run: bool,
    created: bool,
    plans: list[Plan],
    notes: tuple[str, ...],
) -> PushReport:
    people = tuple(
        PersonResult(p.code, p.site, p.action, len(p.sessions), p.trials, p.samples, p.detail)
        for p in plans
    )
    return PushReport(str(src), str(dst), dry_run, created, people, _recordings(src, dst),
                      notes)  # fmt: skip
