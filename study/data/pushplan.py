"""What a push does with one participant of the source (:mod:`study.data.push`): copy it,
add its new sessions, replace a resumed session, nothing, or hold it back; a conflict is
refused with one line naming the participant and the field. Reads the destination only;
:mod:`study.data.pushwrite` writes the plan."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.engine import Connection

from study.data import locks
from study.data.pushdata import (
    Difference,
    PersonRows,
    person_difference,
    person_responses,
    session_difference,
    session_views,
)
from study.data.storage import Base, database_file, is_server


@dataclass(slots=True)
class Plan:
    """One participant's part of a push: the source rows and what to write of them."""

    rows: PersonRows  # in the source
    action: str  # "pushed", "updated", "already there", "held back"
    person_id: int | None = None  # in the destination, when it is there
    slot: str = "none"  # "insert" the source's slot row, "take" row ``slot_id``, "none"
    slot_id: int | None = None
    sessions: list[dict[str, Any]] = field(default_factory=list)  # source rows to write
    replace: list[int] = field(default_factory=list)  # destination session ids to delete
    responses: list[dict[str, Any]] = field(default_factory=list)  # outside trials, to add
    detail: str = ""

    @property
    def code(self) -> str:
        return str(self.rows.person["code"])

    @property
    def site(self) -> str | None:
        return self.rows.person["site"]

    @property
    def trials(self) -> int:
        ids = {s["id"] for s in self.sessions}
        return sum(t["session_id"] in ids for t in self.rows.trials)

    @property
    def samples(self) -> int:
        ids = {s["id"] for s in self.sessions}
        tids = [t["id"] for t in self.rows.trials if t["session_id"] in ids]
        return sum(len(self.rows.samples.get(t, [])) for t in tids)


def conflict(code: str, d: Difference, src: str | Path, dst: str | Path) -> ValueError:
    """The one line refusing a push: the participant, the field, both values."""
    place = "on the server" if is_server(dst) else "in the destination"
    where = f" of {d.where}" if d.where else ""
    return ValueError(
        f"{dst}: participant {code} is {place} with other data (field '{d.field}'{where}: "
        f"{d.there} there, {d.here} in {src}); nothing was pushed"
    )


def plan_person(
    conn: Connection | None,
    there: PersonRows | None,
    here: PersonRows,
    src: str | Path,
    dst: str | Path,
) -> Plan:
    """The plan for participant ``here`` (the source's rows) given ``there`` (its rows in
    the destination on ``conn``, None when absent; ``conn`` None: no destination yet).
    Raises the :func:`conflict` line for any difference the rules do not allow."""
    running = here.running()
    if running:
        return _held_back(here, running, src)
    if there is None:
        plan = Plan(here, "pushed", sessions=list(here.sessions))
        plan.responses = [r for r in here.responses if r["trial_id"] is None]
        plan.slot, plan.slot_id = _slot_plan(conn, here, src, dst)
        _check_new_uids(conn, plan, src, dst)
        plan.detail = _counts(plan)
        return plan
    found = person_difference(there, here)
    if found is not None:
        raise conflict(here.person["code"], found, src, dst)
    return _update(conn, there, here, src, dst)


def _held_back(here: PersonRows, running: list[dict[str, Any]], src: str | Path) -> Plan:
    """A participant with a session still running in the source: not pushed."""
    code = str(here.person["code"])
    resume = "interrupted: resume it with asa run ... --resume"
    state = {True: "live", False: resume, None: f"live, or {resume}"}[_live(src, code)]
    uid = str(running[0]["uid"])[:8]
    detail = f"session {uid} is still running in {src} ({state}); a later push takes it"
    return Plan(here, "held back", detail=detail)


def _live(src: str | Path, code: str) -> bool | None:
    """Whether participant ``code``'s session in the SQLite file ``src`` is held by a live
    process (its lock file); None for a server source (not looked up)."""
    if is_server(src):
        return None
    return locks.is_held(locks.session_lock(database_file(src), code))


def _update(
    conn: Connection | None, there: PersonRows, here: PersonRows, src: str | Path, dst: str | Path
) -> Plan:
    """A participant already in the destination: its new sessions, a resumed session's
    newer state, the responses outside trials added since; else nothing."""
    code = str(here.person["code"])
    plan = Plan(here, "already there", person_id=int(there.person["id"]))
    old, new = person_responses(there), person_responses(here)
    if new[: len(old)] != old:
        raise conflict(code, Difference("response", "", f"{len(old)} rows",
                                        f"{len(new)} rows"), src, dst)  # fmt: skip
    loose = [r for r in here.responses if r["trial_id"] is None]
    plan.responses = loose[len(old) :]
    views_there, views_here = session_views(there), session_views(here)
    ids_there = {s["uid"]: s for s in there.sessions}
    added, replaced = 0, []
    for row in here.sessions:
        uid = row["uid"]
        if uid not in views_there:
            plan.sessions.append(row)
            added += 1
            continue
        found = session_difference(uid, views_there[uid], views_here[uid])
        if found is None:
            continue
        if ids_there[uid]["status"] == "aborted" and (
            session_difference(uid, views_there[uid], views_here[uid], prefix=True) is None
        ):
            plan.sessions.append(row)
            plan.replace.append(int(ids_there[uid]["id"]))
            replaced.append(uid[:8])
            continue
        raise conflict(code, found, src, dst)
    _check_new_uids(conn, plan, src, dst)
    if plan.sessions or plan.responses:
        plan.action = "updated"
        words = [f"{added} new session" + ("s" if added > 1 else "")] if added else []
        words += [f"session {u} replaced by its resumed state" for u in replaced]
        words += [f"{len(plan.responses)} responses"] if plan.responses else []
        plan.detail = "; ".join(words) + f" ({_counts(plan)})"
    return plan


def _counts(plan: Plan) -> str:
    """``1 session, 3 trials, 106 samples``."""
    return ", ".join(
        f"{n} {noun}" + ("" if n == 1 else "s")
        for n, noun in ((len(plan.sessions), "session"), (plan.trials, "trial"),
                        (plan.samples, "sample"))
    )  # fmt: skip


def _check_new_uids(conn: Connection | None, plan: Plan, src: str | Path, dst: str | Path) -> None:
    """Refuse a session whose uid the destination holds for another participant."""
    new = [s["uid"] for s in plan.sessions]
    if conn is None or not new:
        return
    t, p = Base.metadata.tables["session"], Base.metadata.tables["participant"]
    query = select(p.c.code).join(p, p.c.id == t.c.participant_id)
    for code in conn.execute(query.where(t.c.uid.in_(new))).scalars():
        if code != plan.code:
            d = Difference("session.uid", "", f"a session of {code}", f"one of {plan.code}")
            raise conflict(plan.code, d, src, dst)


def _slot_plan(
    conn: Connection | None, here: PersonRows, src: str | Path, dst: str | Path
) -> tuple[str, int | None]:
    """How a new participant's order slot goes in: a new row, or a destination row taken
    over (reserved for its code, or released by an excluded holder the source names)."""
    mine = here.slot
    if mine is None:
        return "none", None
    if conn is None:
        return "insert", None
    t = Base.metadata.tables["order_slot"]
    code = str(here.person["code"])
    same = conn.execute(select(t).where(t.c.code == code)).first()
    if same is not None:
        if (same.site, same.slot) != (mine["site"], mine["slot"]):
            d = Difference("order_slot.slot", "", f"{same.slot} (site {same.site or '(none)'})",
                           f"{mine['slot']} (site {mine['site'] or '(none)'})")  # fmt: skip
            raise conflict(code, d, src, dst)
        return "take", int(same.id)
    held = conn.execute(select(t).where(t.c.site == mine["site"], t.c.slot == mine["slot"]))
    row = held.first()
    if row is None:
        return "insert", None
    if row.code in {h.get("code") for h in mine["released"] or []}:
        return "take", int(row.id)
    site = mine["site"] or "(none)"
    raise ValueError(
        f"{dst}: participant {code} holds order slot {mine['slot']} of site {site} in {src}, "
        f"but {row.code} holds it there (field 'order_slot.slot': two machines of site {site} "
        "gave out the same slot); nothing was pushed"
    )
