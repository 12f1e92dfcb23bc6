"""Whole synthetic studies: every participant's session with synthetic participants, in
worker processes, into one database that does not depend on the number of workers
(issue 6; DESIGN.md "CI and pilots").

How it works (decisions where the spec is silent):

- Participants are ``P01`` .. ``PNN`` (two digits at least, more when ``N >= 100``), so
  the counterbalancing row follows the code (:mod:`study.engine.session`). Participant ``i``
  (from 0) has the seed ``derive_seed(seed, i)`` (stored as the participant's seed and
  used by the session for its trials) and draws its parameters and behaviour from a
  generator seeded with ``derive_seed(seed, i, 1)``: nothing depends on which process
  runs it or when. The participant's stored parameters add ``synthetic_study_seed`` and
  ``index``, so every participant can be drawn again.
- Each participant runs in its own temporary SQLite file ``<db stem>_work/<code>.db``
  beside the database, in a worker process (``concurrent.futures.ProcessPoolExecutor``
  with the *spawn* start method, so no pybullet connection or open database is ever
  inherited through ``fork``); with one worker it runs in this process. The parent merges
  finished participants into the database strictly in participant order, one
  transaction per participant, with fresh row ids (:func:`merge_participant`), and then
  deletes the temporary file. The sample rows (the bulk of a participant) are copied
  as the driver's plain tuples, their stored values unconverted. Recordings go straight
  to their final folder (``<db stem>_recordings/<code>/`` by default); the merge rewrites
  ``trial.recording_path`` relative to the database's folder. The temporary files are
  opened without fsync on commit (``durable=False``): after a crash they are deleted and
  rebuilt anyway, and the merge into the study database is durable as always.
- Interrupted and started again with the same options: participants already in the
  database are skipped (a merge is one transaction, so a participant is either wholly
  there or not at all); any other participant is run again from scratch, its temporary
  file and its recordings folder deleted first. Results tables are then the same as an
  uninterrupted run's (wall-clock timestamps excepted).
- A database that holds another protocol's study is refused (``ValueError``).
- Only SQLite files: the temporary files and the merge need a file path.
- JSON details of events are copied as they are (a fresh session has no event whose
  detail holds row ids).
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import os
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.engine import Connection, Engine

from study.data.storage import Base, open_database
from study.engine.protocol import Protocol, load_protocol
from study.engine.session import derive_seed, run_session
from study.participants.synthetic import Population, SyntheticParticipant

_CHUNK = 5000  # rows per executemany when copying samples


@dataclass(frozen=True, slots=True)
class SynthSummary:
    """What :func:`run_synthetic_study` did."""

    db: Path
    codes: tuple[str, ...]  # every participant of the study, in order
    run: tuple[str, ...]  # participants run and merged by this call
    skipped: tuple[str, ...]  # already in the database
    statuses: dict[str, str]  # code -> session status, for those run
    wall_s: float  # [s]


@dataclass(frozen=True, slots=True)
class _Job:
    index: int
    code: str
    seed: int
    behaviour_seed: int
    protocol: Protocol
    work_db: Path
    recordings: Path
    population: Population
    study_seed: int


@dataclass(frozen=True, slots=True)
class _Done:
    index: int
    code: str
    status: str
    wall_s: float
    simulated_s: float


def participant_codes(n: int) -> tuple[str, ...]:
    """``P01`` .. ``PNN`` (zero-padded to at least two digits)."""
    width = max(2, len(str(n)))
    return tuple(f"P{i + 1:0{width}d}" for i in range(n))


def _remove_db(path: Path) -> None:
    for suffix in ("", "-wal", "-shm", "-journal"):
        p = path.with_name(path.name + suffix)
        if p.exists():
            p.unlink()


def _run_job(job: _Job) -> _Done:
    """One participant's whole session into its own temporary database (worker side)."""
    import numpy as np

    try:
        from study._blas import limit_blas_threads

        limit_blas_threads()
    except ValueError:
        pass
    start = time.perf_counter()
    _remove_db(job.work_db)
    shutil.rmtree(job.recordings / job.code, ignore_errors=True)
    rng = np.random.default_rng(job.behaviour_seed)
    params = job.population.sample(rng)
    participant = SyntheticParticipant(params, rng)
    participant.parameters.update(synthetic_study_seed=job.study_seed, index=job.index)
    summary = run_session(
        job.protocol,
        job.code,
        job.work_db,
        participant=participant,
        seed=job.seed,
        recordings=job.recordings,
        durable=False,  # the scratch file is deleted and rebuilt after a crash
    )
    simulated = sum(
        (t.completion_time_s or 0.0) for t in summary.trials if t.completion_time_s is not None
    )
    return _Done(job.index, job.code, summary.status, time.perf_counter() - start, simulated)


# ------------------------------------------------------------------------- merging


def _rows(conn: Connection, table: str, where: Any = None) -> list[dict[str, Any]]:
    t = Base.metadata.tables[table]
    query = select(t).order_by(t.c.id)
    if where is not None:
        query = query.where(where(t))
    return [dict(r._mapping) for r in conn.execute(query)]


def _insert(conn: Connection, table: str, row: dict[str, Any]) -> int:
    t = Base.metadata.tables[table]
    values = {k: v for k, v in row.items() if k != "id"}
    return int(conn.execute(t.insert().values(**values)).inserted_primary_key[0])


def _bulk(conn: Connection, table: str, rows: list[dict[str, Any]]) -> None:
    t = Base.metadata.tables[table]
    for i in range(0, len(rows), _CHUNK):
        chunk = [{k: v for k, v in r.items() if k != "id"} for r in rows[i : i + _CHUNK]]
        if chunk:
            conn.execute(t.insert(), chunk)


def _sample_columns() -> list[str]:
    return [c.name for c in Base.metadata.tables["sample"].columns if c.name != "id"]


def _sample_tuples(conn: Connection) -> list[tuple[Any, ...]]:
    """Every sample row (without ``id``, in id order) as the driver's plain tuples: the
    bulk of a participant (some 16,000 rows), copied without per-row dictionaries."""
    columns = ", ".join(f'"{c}"' for c in _sample_columns())
    return list(conn.exec_driver_sql(f"SELECT {columns} FROM sample ORDER BY id"))


def _copy_samples(
    conn: Connection, samples: list[tuple[Any, ...]], trial_ids: dict[int, int]
) -> None:
    """Insert ``samples`` (from :func:`_sample_tuples`) with their trial ids remapped; the
    stored values are those of the source rows (SQLite's own types, unconverted)."""
    names = _sample_columns()
    at = names.index("trial_id")
    columns = ", ".join(f'"{c}"' for c in names)
    marks = ", ".join("?" * len(names))
    sql = f"INSERT INTO sample ({columns}) VALUES ({marks})"
    for i in range(0, len(samples), _CHUNK):
        chunk = [(*r[:at], trial_ids[r[at]], *r[at + 1 :]) for r in samples[i : i + _CHUNK]]
        if chunk:
            conn.exec_driver_sql(sql, chunk)


def merge_participant(src: Path, dst: Engine, *, src_folder: Path, dst_folder: Path) -> str:
    """Copy the one participant of the database ``src`` into ``dst`` in one transaction.

    Row ids are assigned afresh in ``dst`` and every reference is remapped; the study row
    is copied if ``dst`` has none; ``trial.recording_path`` is rewritten from relative to
    ``src_folder`` to relative to ``dst_folder``.

    Returns
    -------
    str
        The participant's code.

    Raises
    ------
    ValueError
        ``dst`` holds a study of another protocol, or ``src`` does not hold exactly one
        participant, or the participant is already in ``dst``.
    """
    source = open_database(src, create=False)
    try:
        with source.connect() as sc:
            study = _rows(sc, "study")
            people = _rows(sc, "participant")
            sessions = _rows(sc, "session")
            trials = _rows(sc, "trial")
            samples = _sample_tuples(sc)
            events = _rows(sc, "event")
            questions = _rows(sc, "question")
            responses = _rows(sc, "response")
    finally:
        source.dispose()
    if len(study) != 1 or len(people) != 1:
        raise ValueError(f"{src}: expected one study and one participant to merge")
    person = people[0]
    with dst.begin() as conn:
        have = _rows(conn, "study")
        if have:
            study_id = have[0]["id"]
            if have[0]["protocol_sha256"] != study[0]["protocol_sha256"]:
                raise ValueError(
                    f"field 'study.protocol_sha256': the database holds study "
                    f"{have[0]['name']!r} of another protocol; use a new database file"
                )
        else:
            study_id = _insert(conn, "study", study[0])
        pt = Base.metadata.tables["participant"]
        if conn.execute(
            select(pt.c.id).where(pt.c.study_id == study_id, pt.c.code == person["code"])
        ).first():
            raise ValueError(f"participant {person['code']} is already in the database")
        pid = _insert(conn, "participant", {**person, "study_id": study_id})
        session_ids = {
            s["id"]: _insert(conn, "session", {**s, "participant_id": pid}) for s in sessions
        }
        trial_ids: dict[int, int] = {}
        for t in trials:
            path = t["recording_path"]
            if path:
                path = os.path.relpath((src_folder / path).resolve(), dst_folder.resolve())
            trial_ids[t["id"]] = _insert(
                conn,
                "trial",
                {
                    **t,
                    "participant_id": pid,
                    "session_id": session_ids[t["session_id"]],
                    "recording_path": path,
                },
            )

        def tid(value: int | None) -> int | None:
            return None if value is None else trial_ids[value]

        _copy_samples(conn, samples, trial_ids)
        _bulk(
            conn,
            "event",
            [
                {**r, "session_id": session_ids[r["session_id"]], "trial_id": tid(r["trial_id"])}
                for r in events
            ],
        )
        _bulk(conn, "question", [{**r, "trial_id": trial_ids[r["trial_id"]]} for r in questions])
        _bulk(
            conn,
            "response",
            [{**r, "participant_id": pid, "trial_id": tid(r["trial_id"])} for r in responses],
        )
    return str(person["code"])


def _merged_codes(db: Path) -> tuple[set[str], str | None]:
    if not db.exists():
        return set(), None
    engine = open_database(db, create=False)
    try:
        with engine.connect() as conn:
            names = {r["code"] for r in _rows(conn, "participant")}
            study = _rows(conn, "study")
    finally:
        engine.dispose()
    return names, (study[0]["protocol_sha256"] if study else None)


# ------------------------------------------------------------------------- the study


def _check_int(value: Any, field: str, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < minimum:
        raise ValueError(f"{field}: must be an integer >= {minimum}, got {value!r}")
    return value


def run_synthetic_study(
    protocol: Protocol | str,
    db: str | Path,
    *,
    participants: int,
    seed: int,
    workers: int = 1,
    recordings: str | Path | None = None,
    progress: Callable[[str], None] | None = None,
    population: Population | None = None,
) -> SynthSummary:
    """Run ``participants`` synthetic participants' sessions of ``protocol`` into ``db``.

    Parameters
    ----------
    protocol : Protocol or str
        A loaded protocol or a shipped name / TOML file
        (:func:`study.engine.protocol.load_protocol`).
    db : str or Path
        SQLite file (created if missing; participants already in it are skipped).
    participants : int
        How many (codes ``P01`` .. ``PNN``), at least 1.
    seed : int
        The study's synthetic seed (>= 0): the same seed gives the same results tables
        whatever ``workers`` is.
    workers : int
        Worker processes (>= 1; 1 runs in this process).
    recordings : str or Path, optional
        Folder for the recordings (``<code>/...rrd``); default ``<db stem>_recordings``
        beside the database.
    progress : callable, optional
        One line per finished participant, with the live count.
    population : Population, optional
        The population model; default ``Population()``.

    Returns
    -------
    SynthSummary

    Raises
    ------
    ValueError
        Bad options (naming them), a database URL instead of a file, a database of
        another protocol.
    """
    start = time.perf_counter()
    say = progress if progress is not None else (lambda line: None)
    n = _check_int(participants, "participants", 1)
    seed = _check_int(seed, "seed", 0)
    workers = _check_int(workers, "workers", 1)
    if "://" in str(db):
        raise ValueError(f"db: a SQLite file path is needed for synthetic studies, got {db}")
    proto = load_protocol(protocol) if isinstance(protocol, str | Path) else protocol
    population = population if population is not None else Population()
    db_path = Path(db).resolve()
    if db_path.exists() and db_path.is_dir():
        raise ValueError(f"db: {db} is a folder; give a database file")
    folder = db_path.parent
    folder.mkdir(parents=True, exist_ok=True)
    work = folder / f"{db_path.stem}_work"
    rec = (
        Path(recordings).resolve()
        if recordings is not None
        else folder / f"{db_path.stem}_recordings"
    )
    codes = participant_codes(n)
    merged, sha = _merged_codes(db_path)
    if sha is not None and sha != proto.sha256:
        raise ValueError(
            f"{db}: field 'study.protocol_sha256': the database was made with another "
            f"protocol than {proto.source}; use a new database file"
        )
    todo = [i for i, code in enumerate(codes) if code not in merged]
    skipped = tuple(c for c in codes if c in merged)
    if skipped:
        say(f"{len(skipped)} participant(s) already in {db_path.name}: skipped")
    work.mkdir(exist_ok=True)
    jobs = [
        _Job(
            index=i,
            code=codes[i],
            seed=derive_seed(seed, i),
            behaviour_seed=derive_seed(seed, i, 1),
            protocol=proto,
            work_db=work / f"{codes[i]}.db",
            recordings=rec,
            population=population,
            study_seed=seed,
        )
        for i in todo
    ]
    engine = open_database(db_path)
    statuses: dict[str, str] = {}
    done: dict[int, _Done] = {}
    order = [j.index for j in jobs]
    finished = 0

    def merge_ready() -> None:
        while order and order[0] in done:
            d = done.pop(order.pop(0))
            job = next(j for j in jobs if j.index == d.index)
            merge_participant(job.work_db, engine, src_folder=work, dst_folder=folder)
            _remove_db(job.work_db)

    def report(d: _Done) -> None:
        nonlocal finished
        finished += 1
        statuses[d.code] = d.status
        total = len(skipped) + finished
        say(
            f"[{total}/{n}] {d.code} {d.status}: {d.simulated_s:.0f} s of trials in "
            f"{d.wall_s:.1f} s ({d.simulated_s / max(d.wall_s, 1e-9):.0f}x real time)"
        )

    try:
        if workers == 1 or len(jobs) <= 1:
            for job in jobs:
                d = _run_job(job)
                report(d)
                done[d.index] = d
                merge_ready()
        else:
            ctx = multiprocessing.get_context("spawn")
            pool = cf.ProcessPoolExecutor(max_workers=min(workers, len(jobs)), mp_context=ctx)
            clean = False
            try:
                futures = [pool.submit(_run_job, job) for job in jobs]
                for fut in cf.as_completed(futures):
                    d = fut.result()
                    report(d)
                    done[d.index] = d
                    merge_ready()
                clean = True
            finally:
                if not clean:
                    # interrupted: stop the running participants (they are run again next
                    # time); a worker would otherwise go on with jobs already queued to it
                    for proc in list(getattr(pool, "_processes", {}).values()):
                        proc.terminate()
                pool.shutdown(wait=clean, cancel_futures=True)
    finally:
        engine.dispose()
    if not order:
        try:
            work.rmdir()
        except OSError:
            pass
    return SynthSummary(
        db=db_path,
        codes=codes,
        run=tuple(j.code for j in jobs),
        skipped=skipped,
        statuses=statuses,
        wall_s=time.perf_counter() - start,
    )


# ------------------------------------------------------------------------- sanity summary


def sanity_summary(db: str | Path, *, phase: str = "main") -> dict[str, dict[str, Any]]:
    """Per mode over the ``phase`` trials: trials, completion rate, mean collisions and
    score; for modes with task recognition, the share of ticks with a true task whose
    recognised task (the label translated by the trial's stored ``label_tasks``: a motion
    primitive's dominant task type) and target both match it
    (``recognition_match``) and whose task alone matches (``task_match``).

    A summary for people (printed by ``asa pilot``), not a test.
    """
    engine = open_database(db, create=False)
    out: dict[str, dict[str, Any]] = {}
    try:
        with engine.connect() as conn:
            trials = _rows(conn, "trial", lambda t: t.c.phase == phase)
            by_mode: dict[str, list[dict[str, Any]]] = {}
            for t in trials:
                if t["status"] == "completed":
                    by_mode.setdefault(t["mode"], []).append(t)
            st = Base.metadata.tables["sample"]
            for mode, rows in sorted(by_mode.items()):
                n = len(rows)
                entry: dict[str, Any] = {
                    "trials": n,
                    "completion_rate": sum(bool(r["completed_task"]) for r in rows) / n,
                    "collisions_mean": sum(r["collisions"] or 0 for r in rows) / n,
                    "score_mean_s": sum(r["score"] or 0.0 for r in rows) / n,
                }
                ids = [r["id"] for r in rows]
                q = select(st.c.label, st.c.target, st.c.true_task, st.c.true_target).where(
                    st.c.trial_id.in_(ids), st.c.true_task != ""
                )
                labelled = conn.execute(q).all()
                # what the labels mean, as the trial loop stored it (modes whose labels
                # are situations, not task types, store nothing and are not scored)
                tasks: dict[str, str] = {}
                for r in rows:
                    outcome = r["outcome"] if isinstance(r["outcome"], dict) else {}
                    tasks.update(outcome.get("label_tasks") or {})
                if tasks and labelled:
                    both = task_only = 0
                    for label, target, true_task, true_target in labelled:
                        same = tasks.get(label) == true_task
                        task_only += same
                        both += same and target == true_target
                    entry["task_match"] = task_only / len(labelled)
                    entry["recognition_match"] = both / len(labelled)
                    entry["labelled_ticks"] = len(labelled)
                out[mode] = entry
    finally:
        engine.dispose()
    return out


def format_summary(summary: dict[str, dict[str, Any]]) -> list[str]:
    """The sanity summary as lines of text."""
    lines = []
    for mode, e in summary.items():
        line = (
            f"  {mode or '(none)'}: {e['trials']} trials, completed {e['completion_rate']:.0%}, "
            f"collisions {e['collisions_mean']:.2f}/trial, score {e['score_mean_s']:.1f} s"
        )
        if "recognition_match" in e:
            line += (
                f", recognition: task and target match {e['recognition_match']:.0%}, "
                f"task matches {e['task_match']:.0%} of {e['labelled_ticks']} ticks"
            )
        lines.append(line)
    return lines
