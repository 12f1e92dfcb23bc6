"""A participant's rows in one study database, keyed globally, for pushing a site's
database into another (:mod:`study.data.push`).

Row ids are local to a database, so the same participant in two databases is matched by
global keys: the participant by its code, a session by its ``uid``, a trial by its
session's uid and (phase, ordinal, attempt) (with the occurrence of that triple in id
order, should a session hold it twice), and everything else by its trial, session or
participant. What is compared is what happened, not where or when: the columns of
:data:`study.data.dbdiff.WALL_CLOCK_COLUMNS` and the row ids are left out, and trial ids
inside an event's detail (``session_resumed``'s ``aborted_trials``) are read as trial keys.
"""

from __future__ import annotations

import hashlib
from array import array
from collections import defaultdict
from dataclasses import dataclass, field
from typing import Any

from sqlalchemy import Boolean, Float, Integer
from sqlalchemy.engine import Connection

from study.data.dbdiff import WALL_CLOCK_COLUMNS
from study.data.rows import sample_columns, sample_tuples, table_rows
from study.data.storage import Base

# the fields that make a participant the same participant in two databases
PERSON_FIELDS = ("kind", "parameters", "order_index", "mode_order", "seed", "site")
# row ids and references: local to a database, never compared
_LOCAL = frozenset({"id", "study_id", "participant_id", "session_id", "trial_id"})
TrialKey = tuple[str, int, int, int]  # (phase, ordinal, attempt, occurrence)


@dataclass(frozen=True, slots=True)
class Difference:
    """The first thing that differs: ``field`` as ``table.column`` (or a table for a row
    count), ``where`` (the session and trial it is in, "" for the participant) and the
    value in each database."""

    field: str
    where: str
    there: Any
    here: Any


@dataclass(slots=True)
class PersonRows:
    """Every row of one participant in one database (ids as stored there)."""

    person: dict[str, Any]
    slot: dict[str, Any] | None  # its order_slot row, if it holds one
    released: dict[str, Any] | None  # the slot row it was released from (excluded), if any
    sessions: list[dict[str, Any]]
    trials: list[dict[str, Any]]
    events: list[dict[str, Any]]
    questions: list[dict[str, Any]]
    responses: list[dict[str, Any]]
    samples: dict[int, list[tuple[Any, ...]]]  # trial id -> sample tuples (without id)
    # the lab's streams of its sessions: table name -> rows (read for a push's source only)
    lsl: dict[str, list[dict[str, Any]]] = field(default_factory=dict)

    def trial_keys(self) -> dict[int, TrialKey]:
        """Trial id -> its key within its session."""
        seen: dict[tuple[int, str, int, int], int] = defaultdict(int)
        out = {}
        for t in self.trials:
            triple = (t["session_id"], t["phase"], t["ordinal"], t["attempt"])
            out[t["id"]] = (t["phase"], t["ordinal"], t["attempt"], seen[triple])
            seen[triple] += 1
        return out

    def running(self) -> list[dict[str, Any]]:
        """The sessions still running (live or interrupted), or holding a running trial."""
        busy = {t["session_id"] for t in self.trials if t["status"] == "running"}
        return [r for r in self.sessions if r["status"] == "running" or r["id"] in busy]


def read_people(
    conn: Connection, codes: list[str] | None = None, *, lsl: bool = False
) -> dict[str, PersonRows]:
    """The participants of the database on ``conn`` (those of ``codes``, else all) by
    code, in id order, each with all its rows (with ``lsl``, also the lab's streams of
    its sessions: :func:`lsl_rows`)."""
    people = table_rows(conn, "participant", _within("code", codes))
    if not people:
        return {}
    pids = [p["id"] for p in people]
    sessions = table_rows(conn, "session", _within("participant_id", pids))
    trials = table_rows(conn, "trial", _within("participant_id", pids))
    tids = [t["id"] for t in trials]
    samples: dict[int, list[tuple[Any, ...]]] = defaultdict(list)
    at = sample_columns().index("trial_id")
    for row in sample_tuples(conn, tids):
        samples[row[at]].append(row)
    events = table_rows(conn, "event", _within("session_id", [s["id"] for s in sessions]))
    questions = table_rows(conn, "question", _within("trial_id", tids))
    responses = table_rows(conn, "response", _within("participant_id", pids))
    slots = table_rows(conn, "order_slot")  # a row a participant: few
    out = {}
    for p in people:
        mine = {s["id"] for s in sessions if s["participant_id"] == p["id"]}
        own = [t for t in trials if t["participant_id"] == p["id"]]
        out[p["code"]] = PersonRows(
            person=p,
            slot=next((r for r in slots if r["code"] == p["code"]), None),
            released=next(
                (r for r in slots if p["code"] in {h.get("code") for h in r["released"] or []}),
                None,
            ),
            sessions=[s for s in sessions if s["id"] in mine],
            trials=own,
            events=[e for e in events if e["session_id"] in mine],
            questions=[q for q in questions if q["trial_id"] in {t["id"] for t in own}],
            responses=[r for r in responses if r["participant_id"] == p["id"]],
            samples={t["id"]: samples.get(t["id"], []) for t in own},
            lsl=lsl_rows(conn, sorted(mine)) if lsl else {},
        )
    return out


def lsl_rows(conn: Connection, session_ids: list[int]) -> dict[str, list[dict[str, Any]]]:
    """The lab's recorded or imported streams of ``session_ids`` and their chunks, offsets
    and gaps (revision 0004), in id order."""
    streams = table_rows(conn, "lsl_stream", _within("session_id", session_ids))
    ids = [r["id"] for r in streams]
    out = {"lsl_stream": streams}
    for name in ("lsl_chunk", "lsl_offset", "lsl_gap"):
        out[name] = table_rows(conn, name, _within("stream_id", ids)) if ids else []
    return out


def _within(column: str, values: list[Any] | None) -> Any:
    """A ``where`` for :func:`table_rows`: ``column IN values`` (None: every row)."""
    if values is None:
        return None
    return lambda t: t.c[column].in_(values)


def _what(row: dict[str, Any], skip: frozenset[str] = frozenset()) -> dict[str, Any]:
    """The compared columns of ``row``: without ids, references and wall-clock columns."""
    return {
        k: _strip(v)
        for k, v in row.items()
        if k not in _LOCAL and k not in WALL_CLOCK_COLUMNS and k not in skip
    }


def _strip(value: Any) -> Any:
    """A JSON value without its wall-clock keys, at any depth."""
    if isinstance(value, dict):
        return {k: _strip(v) for k, v in value.items() if k not in WALL_CLOCK_COLUMNS}
    if isinstance(value, list):
        return [_strip(v) for v in value]
    return value


def _sample_digest(rows: list[tuple[Any, ...]]) -> str:
    """A trial's samples as their count and one SHA-256 over their values, column by
    column (trial id left out; SQLite's 0/1 read as booleans, floats as IEEE doubles), so
    both backends agree."""
    table = Base.metadata.tables["sample"]
    h = hashlib.sha256()
    names = sample_columns()
    columns = list(zip(*rows, strict=True)) or [()] * len(names)
    for name, column in zip(names, columns, strict=True):
        if name != "trial_id":
            h.update(_column_bytes(table.c[name].type, column) + b"\x1e")
    return f"{len(rows)} rows, sha256 {h.hexdigest()[:12]}"


def _column_bytes(kind: Any, values: tuple[Any, ...]) -> bytes:
    """One sample column's values as bytes for :func:`_sample_digest`."""
    if None in values:
        return repr([None if v is None else _plain(kind, v) for v in values]).encode()
    if isinstance(kind, Boolean):
        return bytes(bool(v) for v in values)
    if isinstance(kind, Float):
        return array("d", values).tobytes()
    if isinstance(kind, Integer):
        return array("q", values).tobytes()
    return "\x1f".join(map(str, values)).encode()


def _plain(kind: Any, value: Any) -> Any:
    return bool(value) if isinstance(kind, Boolean) else (
        float(value) if isinstance(kind, Float) else value
    )  # fmt: skip


@dataclass(frozen=True, slots=True)
class SessionView:
    """One session as compared: its fields, its trials by key (each with its samples,
    questions, events and responses) and its events outside trials, in order."""

    fields: dict[str, Any]
    trials: dict[TrialKey, dict[str, Any]]
    events: list[dict[str, Any]]


def session_views(rows: PersonRows) -> dict[str, SessionView]:
    """Each session of ``rows`` by uid, as compared between databases."""
    keys = rows.trial_keys()
    by_trial: dict[int, dict[str, list[Any]]] = defaultdict(lambda: defaultdict(list))
    for q in rows.questions:
        by_trial[q["trial_id"]]["question"].append(_what(q))
    for r in rows.responses:
        if r["trial_id"] is not None:
            by_trial[r["trial_id"]]["response"].append(_what(r))
    loose: dict[int, list[dict[str, Any]]] = defaultdict(list)
    for e in rows.events:
        seen = _event(e, keys)
        if e["trial_id"] is None:
            loose[e["session_id"]].append(seen)
        else:
            by_trial[e["trial_id"]]["event"].append(seen)
    trials: dict[int, dict[TrialKey, dict[str, Any]]] = defaultdict(dict)
    for t in rows.trials:
        trials[t["session_id"]][keys[t["id"]]] = {
            **_what(t),
            "sample": _sample_digest(rows.samples.get(t["id"], [])),
            "question": by_trial[t["id"]]["question"],
            "event": by_trial[t["id"]]["event"],
            "response": by_trial[t["id"]]["response"],
        }
    return {s["uid"]: SessionView(_what(s), trials[s["id"]], loose[s["id"]]) for s in rows.sessions}


def _event(row: dict[str, Any], keys: dict[int, TrialKey]) -> dict[str, Any]:
    """An event as compared: trial ids in its detail read as trial keys."""
    seen = _what(row)
    detail = seen.get("detail")
    if isinstance(detail, dict) and isinstance(detail.get("aborted_trials"), list):
        ids = detail["aborted_trials"]
        seen["detail"] = {**detail, "aborted_trials": [keys.get(i, i) for i in ids]}
    return seen


def person_responses(rows: PersonRows) -> list[dict[str, Any]]:
    """The participant's responses outside trials (per session), in order, as compared."""
    return [_what(r) for r in rows.responses if r["trial_id"] is None]


def person_difference(there: PersonRows, here: PersonRows) -> Difference | None:
    """The first participant field, or order slot, that differs between two databases."""
    for name in PERSON_FIELDS:
        if there.person[name] != here.person[name]:
            return Difference(f"participant.{name}", "", there.person[name], here.person[name])
    slot_there, slot_here = _slot(there.slot), _slot(here.slot)
    if here.slot is None and here.released is not None and there.slot is not None:
        # excluded at the site, its slot reissued there: the new holder takes it over
        slot_here = _slot(here.released)
    if slot_there != slot_here:
        return Difference("order_slot", "", slot_there, slot_here)
    return None


def _slot(row: dict[str, Any] | None) -> str:
    """An order slot as the messages show it."""
    if row is None:
        return "none"
    return f"site {row['site'] or '(none)'} slot {row['slot']}"


def trial_name(key: TrialKey) -> str:
    """``main #1`` (``attempt 1`` when repeated)."""
    phase, ordinal, attempt, occurrence = key
    more = f" attempt {attempt}" if attempt else ""
    return f"{phase} #{ordinal}{more}" + (f" ({occurrence + 1})" if occurrence else "")


def session_difference(
    uid: str, there: SessionView, here: SessionView, *, prefix: bool = False
) -> Difference | None:
    """The first difference between a session as held there and here; with ``prefix``
    what is there need only be the start of what is here (its fields but status,
    resumption and note the same, its note the start of the note here, every trial there
    the same here, its events outside trials the first ones here)."""
    where = f"session {uid[:8]}"
    loose = ("status", "resumed", "forced", "note") if prefix else ()
    for name, value in there.fields.items():
        if name not in loose and value != here.fields.get(name):
            return Difference(f"session.{name}", where, value, here.fields.get(name))
    if prefix and not str(here.fields["note"]).startswith(str(there.fields["note"])):
        return Difference("session.note", where, there.fields["note"], here.fields["note"])
    for key, trial in there.trials.items():
        mine = here.trials.get(key)
        at = f"{where}, {trial_name(key)}"
        if mine is None:
            return Difference("trial", at, "a trial", "none")
        for name, value in trial.items():
            if value != mine[name]:
                if isinstance(value, list):
                    return _rows_difference(name, at, value, mine[name])
                table = "" if name == "sample" else "trial."
                return Difference(f"{table}{name}", at, value, mine[name])
    if not prefix and there.trials.keys() != here.trials.keys():
        extra = sorted(here.trials.keys() - there.trials.keys())
        return Difference("trial", where, "none", trial_name(extra[0]))
    events = here.events[: len(there.events)] if prefix else here.events
    if there.events != events:
        return _rows_difference("event", where, there.events, events)
    return None


def _rows_difference(table: str, where: str, there: list[Any], here: list[Any]) -> Difference:
    """The first difference of two lists of rows of ``table``: a column of a row (numbered
    from 1), else their lengths (the messages stay one short line)."""
    for k, (a, b) in enumerate(zip(there, here, strict=False)):
        for name, value in a.items():
            if value != b.get(name):
                return Difference(f"{table}.{name}", f"{where}, row {k + 1}", value, b.get(name))
    return Difference(table, where, f"{len(there)} rows", f"{len(here)} rows")
