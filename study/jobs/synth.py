"""Whole synthetic studies: every participant's session with synthetic participants, in
worker processes, into one database that does not depend on the number of workers
(issue 6; DESIGN.md "CI and pilots"; thesis section 7.6).

Each participant runs into its own temporary SQLite file in a *spawn* worker; the parent
merges finished participants in participant order (:mod:`study.data.merge`). Started
again after an interruption, participants already in the database are skipped and the
others run from scratch. One synthetic study writes a database at a time (its lock file,
:mod:`study.data.locks`; a second one waits); each participant's order slot is reserved
in the study's ledger before it runs. Also the pilot's sanity summary.
"""

from __future__ import annotations

import concurrent.futures as cf
import contextlib
import dataclasses
import multiprocessing
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from sqlalchemy import select
from sqlalchemy.engine import Connection, Engine
from sqlalchemy.orm import Session

from sim.limits import MAX_PARTICIPANTS, MAX_SEED
from study.data import identity, locks, server_locks
from study.data.dbfile import is_url, sqlite_url_file
from study.data.dbtools import remove_recordings_of
from study.data.merge import merge_participant
from study.data.rows import table_rows
from study.data.storage import (
    TRIAL_FINISHED,
    Base,
    Participant,
    database_file,
    database_url,
    is_postgresql,
    is_server,
    open_database,
)
from study.engine.counterbalance import site_seed
from study.engine.protocol import Protocol, load_protocol
from study.engine.recognition import RecognitionTally
from study.engine.session import derive_seed, reserve_slots, run_session
from study.engine.sites import Place
from study.participants.synthetic import Population, SyntheticParticipant


@dataclass(frozen=True, slots=True)
class SynthSummary:
    """What :func:`run_synthetic_study` did."""

    db: Path | str  # the database file, or a server database's URL
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
    recordings: Path  # the study's folder of recordings (and of the scenes' maps)
    population: Population
    study_seed: int
    slot: int = 0  # the order slot reserved in the study database
    record: bool = True  # False: no recordings (``asa synth --no-recordings``)
    place: Place = Place()  # the site (of a multi-site study) and this machine


@dataclass(frozen=True, slots=True)
class _Done:
    index: int
    code: str
    status: str
    wall_s: float
    simulated_s: float


def participant_codes(n: int, site: str | None = None) -> tuple[str, ...]:
    """``P01`` .. ``PNN`` (zero-padded to at least two digits), ``<site>-P01`` ... at a
    site of a multi-site study (codes are unique across sites)."""
    width = max(2, len(str(n)))
    prefix = f"{site}-" if site else ""
    return tuple(f"{prefix}P{i + 1:0{width}d}" for i in range(n))


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
    remove_recordings_of(job.work_db)  # an earlier attempt's, not the shared folder's
    _remove_db(job.work_db)
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
        record=job.record,
        durable=False,  # the scratch file is deleted and rebuilt after a crash
        slot=job.slot,
        lock=False,  # the study's synth lock covers the scratch folder
        place=job.place,
        lsl_record=False,  # the protocol's LSL outlets, none of the lab's streams recorded
    )
    simulated = sum(
        (t.completion_time_s or 0.0) for t in summary.trials if t.completion_time_s is not None
    )
    return _Done(job.index, job.code, summary.status, time.perf_counter() - start, simulated)


# ------------------------------------------------------------------------- the study


def _check_int(value: Any, field: str, minimum: int, maximum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not minimum <= value <= maximum:
        raise ValueError(f"{field}: must be an integer in {minimum}..{maximum}, got {value!r}")
    return value


def _check_options(
    participants: Any, seed: Any, workers: Any, db: str | Path
) -> tuple[int, int, int]:
    n = _check_int(participants, "participants", 1, MAX_PARTICIPANTS)
    seed = _check_int(seed, "seed", 0, MAX_SEED)
    workers = _check_int(workers, "workers", 1, 1024)
    if is_url(str(db)) and not is_server(db) and sqlite_url_file(database_url(db)) is None:
        raise ValueError(f"db: an in-memory database cannot hold a synthetic study, got {db}")
    return n, seed, workers


def run_synthetic_study(
    protocol: Protocol | str,
    db: str | Path,
    *,
    participants: int,
    seed: int,
    workers: int = 1,
    recordings: str | Path | None = None,
    record: bool = True,
    progress: Callable[[str], None] | None = None,
    population: Population | None = None,
    force: bool = False,
    site: str | None = None,
) -> SynthSummary:
    """Run ``participants`` synthetic participants' sessions of ``protocol`` into ``db``.

    Parameters
    ----------
    protocol : Protocol or str
        A loaded protocol or a shipped name / TOML file
        (:func:`study.engine.protocol.load_protocol`).
    db : str or Path
        SQLite file (created if missing) or a database URL (a server database, empty or
        of this study); participants already in it are skipped.
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
    record : bool
        False: no recordings (the trials' ``recording_path`` empty, every other row the
        same as with them): for studies that need only the outcomes, faster.
    progress : callable, optional
        One line per finished participant, with the live count; one line when another
        synthetic study holds the database and this one waits for it.
    population : Population, optional
        The population model; default ``Population()``.
    force : bool
        Write into a study made with another protocol, protocol seed, platform version or
        synthetic seed (recorded in each merged session's ``forced`` and ``note``).
    site : str, optional
        The site of a multi-site study the participants belong to (required when the
        protocol has ``[study] sites``): codes ``<site>-P01`` ..., the site's order
        ledger, and people drawn with the site's own seed (:func:`site_seed`) so that two
        sites' synthetic participants differ.

    Returns
    -------
    SynthSummary

    Raises
    ------
    ValueError
        Bad parameters (naming them), an in-memory database URL, a database of
        another protocol, seed or platform version without ``force``.
    """
    start = time.perf_counter()
    say = progress if progress is not None else (lambda line: None)
    n, seed, workers = _check_options(participants, seed, workers, db)
    proto = load_protocol(protocol) if isinstance(protocol, str | Path) else protocol
    population = population if population is not None else Population()
    db_path, work, rec = _paths(db, recordings)
    codes = participant_codes(n, site)
    place = Place(site)

    def waiting(pid: str) -> None:
        name = database_url(db) if is_server(db) else db_path.name
        say(f"{name}: another synthetic study (pid {pid}) is writing it; waiting")

    with _synth_locks(db, db_path, waiting):
        engine = open_database(db if is_server(db) else db_path)
        try:
            merger = _study(
                engine, proto, db, codes, seed, force, work, rec, population, say, place
            )
            jobs = [
                dataclasses.replace(j, record=record, place=place) for j in merger.jobs.values()
            ]
            _run_jobs(jobs, workers, merger.finish)
        finally:
            engine.dispose()
    if not merger.order:
        with contextlib.suppress(OSError):
            work.rmdir()
    return SynthSummary(
        db=database_url(db) if is_server(db) else db_path,
        codes=codes,
        run=tuple(j.code for j in merger.jobs.values()),
        skipped=merger.skipped_codes,
        statuses=merger.statuses,
        wall_s=time.perf_counter() - start,
    )


@contextlib.contextmanager
def _synth_locks(db: str | Path, db_path: Path, waiting: Callable[[str], None]) -> Iterator[None]:
    """The synthetic study's lock file (it owns the local scratch folder) and, for a
    PostgreSQL database, its advisory lock (one synthetic study per database, whichever
    machine runs it); a second study waits for the first."""
    with contextlib.ExitStack() as stack:
        stack.enter_context(locks.held(locks.synth_lock(db_path), wait=True, on_wait=waiting))
        if is_postgresql(db):
            lock = server_locks.held(
                database_url(db), server_locks.SYNTH, wait=True, on_wait=waiting
            )
            stack.enter_context(lock)
        yield


def _study(
    engine: Engine,
    proto: Protocol,
    db: str | Path,
    codes: tuple[str, ...],
    seed: int,
    force: bool,
    work: Path,
    rec: Path,
    population: Population,
    say: Callable[[str], None],
    place: Place,
) -> _Merger:
    """Under the synth lock: the participants still to run, their order slots reserved
    and the study's identity checked; the merger that takes them in."""
    merged, study_seed = _merged(engine)
    notes = identity.check(
        db,
        identity.mismatches(
            {"synthetic_study_seed": study_seed}, {"synthetic_study_seed": seed},
            prefix="participant.parameters",
        ),
        force,
    )  # fmt: skip
    todo = [i for i, code in enumerate(codes) if code not in merged]
    skipped = tuple(c for c in codes if c in merged)
    if skipped:
        say(f"{len(skipped)} participant(s) already in {Path(db).name}: skipped")
    slots, more = reserve_slots(
        engine, proto, db, [codes[i] for i in todo], force=force, place=place
    )
    work.mkdir(exist_ok=True)
    jobs = [
        _job(i, codes[i], site_seed(seed, place.site), proto, work=work, recordings=rec,
             population=population, slot=slots[codes[i]], study_seed=seed)
        for i in todo
    ]  # fmt: skip
    return _Merger(
        engine, jobs, work, total=len(codes), skipped=skipped, say=say,
        note="; ".join(notes + more),
    )  # fmt: skip


def _merged(engine: Engine) -> tuple[set[str], int | None]:
    """The participant codes in the study database and its synthetic seed (that of its
    first synthetic participant; None without one)."""
    with Session(engine) as s:
        people = s.scalars(select(Participant).order_by(Participant.id)).all()
        seeds = [
            p.parameters.get("synthetic_study_seed")
            for p in people
            if p.kind == "synthetic" and isinstance(p.parameters, dict)
        ]
        seeds = [x for x in seeds if x is not None]
        return {p.code for p in people}, (int(seeds[0]) if seeds else None)


def _job(
    index: int,
    code: str,
    seed: int,
    protocol: Protocol,
    *,
    work: Path,
    recordings: Path,
    population: Population,
    slot: int = 0,
    study_seed: int | None = None,
) -> _Job:
    """Participant ``index`` of a study (a site) seeded with ``seed``: its session seed,
    its behaviour seed and its temporary database; ``study_seed`` (default ``seed``) is
    the synthetic study's seed, recorded with the participant."""
    return _Job(
        index=index,
        code=code,
        seed=derive_seed(seed, index),
        behaviour_seed=derive_seed(seed, index, 1),
        protocol=protocol,
        work_db=work / f"{code}.db",
        recordings=recordings,
        population=population,
        study_seed=seed if study_seed is None else study_seed,
        slot=slot,
    )


def _paths(db: str | Path, recordings: str | Path | None) -> tuple[Path, Path, Path]:
    """The database file, the folder of the temporary files and the recordings folder
    (the database's folder is created). For a server database the local folders are
    those beside its stand-in file (:func:`study.data.storage.database_file`)."""
    db_path = database_file(db)
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
    return db_path, work, rec


class _Merger:
    """Reports each finished participant and merges finished participants into the study
    database strictly in participant order, whatever order they finish in."""

    def __init__(
        self,
        engine: Engine,
        jobs: list[_Job],
        work: Path,
        *,
        total: int,
        skipped: tuple[str, ...],
        say: Callable[[str], None],
        note: str = "",
    ) -> None:
        self.engine = engine
        self.note = note  # a forced identity mismatch, recorded in every merged session
        self.skipped_codes = skipped
        self.work = work
        self.jobs = {j.index: j for j in jobs}
        self.order = [j.index for j in jobs]  # not yet merged, in participant order
        self.done: dict[int, _Done] = {}
        self.statuses: dict[str, str] = {}
        self.total = total
        self.skipped = len(skipped)
        self.finished = 0
        self.say = say

    def finish(self, d: _Done) -> None:
        """Report ``d``, then merge every participant whose turn has come."""
        self.finished += 1
        self.statuses[d.code] = d.status
        self.say(
            f"[{self.skipped + self.finished}/{self.total}] {d.code} {d.status}: "
            f"{d.simulated_s:.0f} s of trials in {d.wall_s:.1f} s "
            f"({d.simulated_s / max(d.wall_s, 1e-9):.0f}x real time)"
        )
        self.done[d.index] = d
        while self.order and self.order[0] in self.done:
            done = self.done.pop(self.order.pop(0))
            job = self.jobs[done.index]
            merge_participant(
                job.work_db, self.engine, src_folder=self.work, dst_folder=self.work.parent,
                note=self.note,
            )  # fmt: skip
            _remove_db(job.work_db)


def _run_jobs(jobs: list[_Job], workers: int, finish: Callable[[_Done], None]) -> None:
    """Run ``jobs`` in this process (one worker) or in a spawn pool; ``finish`` each."""
    if workers == 1 or len(jobs) <= 1:
        for job in jobs:
            finish(_run_job(job))
        return
    ctx = multiprocessing.get_context("spawn")
    pool = cf.ProcessPoolExecutor(max_workers=min(workers, len(jobs)), mp_context=ctx)
    clean = False
    try:
        futures = [pool.submit(_run_job, job) for job in jobs]
        for fut in cf.as_completed(futures):
            finish(fut.result())
        clean = True
    finally:
        if not clean:
            # interrupted: stop the running participants (they are run again next
            # time); a worker would otherwise go on with jobs already queued to it
            for proc in list(getattr(pool, "_processes", {}).values()):
                proc.terminate()
        pool.shutdown(wait=clean, cancel_futures=True)


# ------------------------------------------------------------------------- sanity summary


def sanity_summary(db: str | Path, *, phase: str = "main") -> dict[str, dict[str, Any]]:
    """Per mode over the finished ``phase`` trials (completed or timed out): trials,
    completion rate (route finished), mean collisions and score; for modes with task
    recognition, the in-the-loop recognition
    pooled over the trials' labelled ticks (ticks with a true task): ``labelled_ticks``,
    the share whose recognised task and target both match (``recognition_match``), whose
    task alone matches (``task_match``) and that recognised nothing (``null_rate``).

    The counts are those the trial outcome stores (``outcome["recognition"]``); a trial
    stored without them is scored from its samples and its ``label_tasks``. A summary for
    people (printed by ``asa pilot``), not a test.
    """
    engine = open_database(db, create=False)
    out: dict[str, dict[str, Any]] = {}
    try:
        with engine.connect() as conn:
            trials = table_rows(conn, "trial", lambda t: t.c.phase == phase)
            by_mode: dict[str, list[dict[str, Any]]] = {}
            for t in trials:
                if t["status"] in TRIAL_FINISHED:
                    by_mode.setdefault(t["mode"], []).append(t)
            for mode, rows in sorted(by_mode.items()):
                n = len(rows)
                entry: dict[str, Any] = {
                    "trials": n,
                    "completion_rate": sum(bool(r["completed_task"]) for r in rows) / n,
                    "collisions_mean": sum(r["collisions"] or 0 for r in rows) / n,
                    "score_mean_s": sum(r["score"] or 0.0 for r in rows) / n,
                }
                tally = _recognition(conn, rows)
                if tally is not None:
                    rec = tally.summary()
                    entry["labelled_ticks"] = rec["labelled_ticks"]
                    entry["task_match"] = rec["task_matches"] / rec["labelled_ticks"]
                    entry["recognition_match"] = rec["task_target_matches"] / rec["labelled_ticks"]
                    entry["null_rate"] = rec["null_ticks"] / rec["labelled_ticks"]
                    for key in ("assist_precision", "assist_coverage", "confident_wrong_s_per_min"):
                        if rec.get(key) is not None:
                            entry[key] = rec[key]
                out[mode] = entry
    finally:
        engine.dispose()
    return out


def _recognition(conn: Connection, rows: list[dict[str, Any]]) -> RecognitionTally | None:
    """The recognition tally pooled over the trials ``rows``: each trial's stored counts,
    or its samples scored with its ``label_tasks`` (modes whose labels are situations
    store neither and are not scored); None without any labelled tick."""
    st = Base.metadata.tables["sample"]
    pooled = RecognitionTally({})
    for r in rows:
        outcome = r["outcome"] if isinstance(r["outcome"], dict) else {}
        if isinstance(outcome.get("recognition"), dict):
            pooled.merge(RecognitionTally.from_summary(outcome["recognition"]))
        elif isinstance(outcome.get("label_tasks"), dict):
            q = (
                select(st.c.label, st.c.target, st.c.true_task, st.c.true_target, st.c.beta, st.c.t)
                .where(st.c.trial_id == r["id"])
                .order_by(st.c.tick)
            )
            ticks = conn.execute(q).all()
            # the tick's duration from the stored simulated times (the first ends at t = dt)
            dt = float(ticks[0][5]) if ticks else 0.0
            tally = RecognitionTally(outcome["label_tasks"], dt_s=dt)
            pooled.merge(tally.add_rows(row[:5] for row in ticks))
    return pooled if sum(c[0] for c in pooled.counts.values()) else None


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
                f"task matches {e['task_match']:.0%}, nothing recognised "
                f"{e['null_rate']:.1%} of {e['labelled_ticks']} labelled ticks"
            )
        if "assist_precision" in e:
            line += (
                f"; assistance right {e['assist_precision']:.0%} of the time it engaged, on "
                f"{e.get('assist_coverage', 0.0):.0%} of labelled ticks, confidently wrong "
                f"{e.get('confident_wrong_s_per_min', 0.0):.1f} s/min"
            )
        lines.append(line)
    return lines
