"""The participant bank of a power analysis (issue 22): B synthetic participants, each
driving one main trial per mode of the protocol (and answering its baseline questions),
headless and without recordings; per participant its parameters, its order and the long
rows of every planned metric (:func:`analysis.metrics.long_frame`, the report's values).

Each bank entry is one task (:func:`run_entry`, run on a Dask worker) seeded from
(protocol hash, seed, index), so the bank is the same whatever the cluster; it drives the
protocol cut to its baseline and main phases (:func:`bank_protocol`) into a temporary
SQLite file of its own and returns plain rows. Only the client writes the bank file
(:class:`BankFile`), one transaction per entry as it completes, so a run cut short
resumes with what is missing.
"""

from __future__ import annotations

import dataclasses
import json
import math
import sqlite3
import tempfile
import time
from collections.abc import Iterable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import pandas as pd

from study.engine.protocol import Protocol
from study.participants.synthetic import Population

BANK_FILE = "bank.sqlite"
BANK_PHASES: tuple[str, ...] = ("baseline", "main")
SCHEMA_VERSION = 1


@dataclass(frozen=True, slots=True)
class BankJob:
    """What one bank entry needs (sent to a worker)."""

    protocol: Protocol  # cut to BANK_PHASES
    index: int  # from 0; also the counterbalancing slot
    session_seed: int
    behaviour_seed: int
    population: Population
    proposal: Any = None  # redraws some person-level values (asa calibrate's bank), or None


@dataclass(frozen=True, slots=True)
class BankEntry:
    """One bank participant, as a worker returns it.

    Attributes
    ----------
    index : entry number (from 0).
    code : ``B0001``... (the participant label in resampled studies).
    row : counterbalancing row of the order driven (``participant.order_index``).
    mode_order : the modes in the order driven.
    status : the session's status ("completed" or "aborted").
    parameters : the synthetic person (:class:`ParticipantParams` as a dict).
    outcomes : (metric, mode, position, value) per planned metric and level; value None
        when missing (a timed-out trial's time under ``timeouts = "exclude"``).
    main_trials, timed_out : main trials driven, and how many timed out.
    simulated_s : [s] simulated time of the main trials.
    cpu_s : [s] the worker's CPU time for the entry (process time).
    wall_s : [s] its wall time.
    """

    index: int
    code: str
    row: int
    mode_order: tuple[str, ...]
    status: str
    parameters: dict[str, Any]
    outcomes: tuple[tuple[str, str, int, float | None], ...]
    main_trials: int
    timed_out: int
    simulated_s: float
    cpu_s: float
    wall_s: float


def bank_protocol(protocol: Protocol) -> Protocol:
    """``protocol`` with only its baseline and main phases (the training and practice
    phases do not change a synthetic participant, who does not learn: docs/decisions.md)."""
    phases = tuple(p for p in protocol.phases if p.kind in BANK_PHASES)
    return dataclasses.replace(protocol, phases=phases)


def entry_code(index: int) -> str:
    """The bank participant's label, ``B0001`` for entry 0."""
    return f"B{index + 1:04d}"


def bank_root(protocol: Protocol) -> int:
    """The protocol's part of every bank seed: the first 8 hex digits of its SHA-256."""
    return int(protocol.sha256[:8], 16)


def bank_jobs(
    protocol: Protocol,
    seed: int,
    indices: Iterable[int],
    population: Population,
    proposal: Any = None,
) -> list[BankJob]:
    """The jobs of bank entries ``indices``, seeded from (protocol hash, seed, index);
    ``proposal`` (an object with ``draw(person, rng) -> person``, e.g.
    :class:`study.jobs.calibrate.model.Proposal`) redraws part of each person."""
    from study.engine.runner import derive_seed

    cut, root = bank_protocol(protocol), bank_root(protocol)
    return [
        BankJob(
            protocol=cut,
            index=i,
            session_seed=derive_seed(root, seed, i),
            behaviour_seed=derive_seed(root, seed, i, 1),
            population=population,
            proposal=proposal,
        )
        for i in indices
    ]


def run_entry(job: BankJob) -> BankEntry:
    """Drive one bank entry (worker side): its session in a temporary database, then its
    planned metrics' long rows as the report computes them."""
    from study._blas import limit_blas_threads

    limit_blas_threads()
    from study.engine.session import run_session
    from study.participants.synthetic import SyntheticParticipant

    wall, cpu = time.perf_counter(), time.process_time()
    rng = np.random.default_rng(job.behaviour_seed)
    person = job.population.sample(rng)
    if job.proposal is not None:
        person = job.proposal.draw(person, rng)
    participant = SyntheticParticipant(person, rng)
    with tempfile.TemporaryDirectory(prefix="asa-bank-") as folder:
        db = Path(folder) / "entry.db"
        summary = run_session(
            job.protocol, entry_code(job.index), db, participant=participant,
            seed=job.session_seed, recordings=Path(folder) / "rec", record=False,
            durable=False, slot=job.index, lock=False, lsl=False,
        )  # fmt: skip
        row, outcomes = _outcomes(db)
    main = [t for t in summary.trials if t.phase == "main"]
    return BankEntry(
        index=job.index,
        code=entry_code(job.index),
        row=row,
        mode_order=tuple(summary.mode_order),
        status=summary.status,
        parameters=dict(participant.parameters),
        outcomes=outcomes,
        main_trials=len(main),
        timed_out=sum(t.status == "timed_out" for t in main),
        simulated_s=float(sum(t.completion_time_s or 0.0 for t in main)),
        cpu_s=time.process_time() - cpu,
        wall_s=time.perf_counter() - wall,
    )


def _outcomes(db: Path) -> tuple[int, tuple[tuple[str, str, int, float | None], ...]]:
    """(the participant's order row, the long rows of every planned metric)."""
    from analysis.data import load_study, tidy
    from analysis.metrics import BY_NAME, long_frame

    data = load_study(db)
    frames = tidy(data)
    cfg = data.config
    rows: list[tuple[str, str, int, float | None]] = []
    for metric in cfg.metrics:
        if metric not in BY_NAME or BY_NAME[metric].descriptive:
            continue
        baseline = cfg.secondary_baseline_level and BY_NAME[metric].baseline
        long = long_frame(frames, metric, baseline=baseline)
        for r in long.itertuples(index=False):
            value = None if math.isnan(r.value) else float(r.value)
            rows.append((metric, str(r.mode), int(r.position), value))
    people = data.tables["participant"]
    return int(people["order_index"].iloc[0]), tuple(rows)


# ------------------------------------------------------------------------- the bank file


class BankFile:
    """The bank as a SQLite file (``DIR/bank.sqlite``), written only by the client.

    Tables: ``meta`` (key, value: the protocol hash, seed and population the bank was made
    with), ``entry`` (one row per bank participant) and ``outcome`` (entry, metric, mode,
    position, value). An entry and its outcomes go in one transaction.
    """

    def __init__(self, path: Path, identity: dict[str, Any], *, resume: bool) -> None:
        self.path = path
        self.conn = sqlite3.connect(path)
        self.conn.executescript(_SCHEMA)
        if self.done() and not resume:
            self.conn.close()
            raise ValueError(
                f"out: {path} holds a bank of an earlier run; pass --resume to continue "
                f"it, or choose another --out"
            )
        stored = dict(self.conn.execute("SELECT key, value FROM meta"))
        wanted = {k: json.dumps(v, sort_keys=True) for k, v in identity.items()}
        if not stored:
            with self.conn:
                self.conn.executemany("INSERT INTO meta VALUES (?, ?)", sorted(wanted.items()))
            return
        for key, value in wanted.items():
            if stored.get(key) != value:
                self.conn.close()
                raise ValueError(
                    f"{path}: field {key!r} of meta is {stored.get(key)}, this run has {value}; "
                    f"a bank holds one protocol, seed and population: choose another --out"
                )

    def done(self) -> set[int]:
        """The entries already in the bank."""
        return {int(i) for (i,) in self.conn.execute("SELECT entry FROM entry")}

    def add(self, e: BankEntry) -> None:
        """Store one entry and its outcomes (one transaction)."""
        with self.conn:
            self.conn.execute(
                "INSERT INTO entry VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (e.index, e.code, e.row, json.dumps(list(e.mode_order)), e.status,
                 json.dumps(e.parameters, sort_keys=True), e.main_trials, e.timed_out,
                 e.simulated_s, e.cpu_s, e.wall_s),
            )  # fmt: skip
            self.conn.executemany(
                "INSERT INTO outcome VALUES (?, ?, ?, ?, ?, ?)",
                [(e.index, e.code, m, mode, pos, v) for m, mode, pos, v in e.outcomes],
            )

    def frames(self, limit: int) -> tuple[pd.DataFrame, pd.DataFrame]:
        """(entries, outcomes) of entries ``0 .. limit - 1`` (the columns of
        :mod:`analysis.power.resample`), in entry order."""
        entries = pd.read_sql_query(
            "SELECT * FROM entry WHERE entry < ? ORDER BY entry", self.conn, params=(limit,)
        )
        outcomes = pd.read_sql_query(
            "SELECT entry, participant, metric, mode, position, value FROM outcome "
            "WHERE entry < ? ORDER BY entry, rowid",
            self.conn,
            params=(limit,),
        )
        outcomes["value"] = outcomes["value"].astype(float)
        return entries, outcomes

    def close(self) -> None:
        self.conn.close()


_SCHEMA = f"""
PRAGMA user_version = {SCHEMA_VERSION};
CREATE TABLE IF NOT EXISTS meta (key TEXT PRIMARY KEY, value TEXT NOT NULL);
CREATE TABLE IF NOT EXISTS entry (
    entry INTEGER PRIMARY KEY, code TEXT NOT NULL, row INTEGER NOT NULL,
    mode_order TEXT NOT NULL, status TEXT NOT NULL, parameters TEXT NOT NULL,
    main_trials INTEGER NOT NULL, timed_out INTEGER NOT NULL, simulated_s REAL NOT NULL,
    cpu_s REAL NOT NULL, wall_s REAL NOT NULL
);
CREATE TABLE IF NOT EXISTS outcome (
    entry INTEGER NOT NULL REFERENCES entry (entry), participant TEXT NOT NULL,
    metric TEXT NOT NULL, mode TEXT NOT NULL, position INTEGER NOT NULL, value REAL,
    PRIMARY KEY (entry, metric, mode)
);
"""
