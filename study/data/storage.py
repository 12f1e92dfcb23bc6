"""The study database: SQLAlchemy 2.0 ORM models, one module, versioned.

Nothing else in the platform writes SQL. SQLite (one file per study, WAL mode, foreign
keys on) by default; PostgreSQL (psycopg 3) or any SQLAlchemy URL for a server database,
timestamps UTC-aware on every backend. Tables (DESIGN.md "Data"):
``meta`` (``schema_version``, in step with Alembic's ``alembic_version``:
:mod:`study.data.schema`), ``study`` (protocol text and SHA-256, platform version,
seed), ``participant`` (pseudonymous code, synthetic parameters, mode order), ``session``
(one run for a participant; a forced second session is recorded), ``trial`` (phase, mode,
status, times, outcome), ``sample`` (one per control tick), ``event`` (with a JSON
``detail``), ``question`` (one per secondary-task question), ``response``
(questionnaire answers, NASA-TLX pairwise choices as items ``pair:<a>|<b>``) and
``order_slot`` (the counterbalancing ledger: every order slot issued, :mod:`study.data.ledger`);
the lab's recorded streams ``lsl_stream``, ``lsl_chunk``, ``lsl_offset``, ``lsl_gap``
(:mod:`study.data.lsl_tables`, re-exported here).
"""

from __future__ import annotations

import datetime as dt
import functools
import os
import re
import sqlite3
import uuid
from pathlib import Path
from typing import Any

from sqlalchemy import (
    JSON,
    Boolean,
    DateTime,
    Float,
    ForeignKey,
    Index,
    Integer,
    String,
    Text,
    TypeDecorator,
    UniqueConstraint,
    create_engine,
    event,
    inspect,
    select,
    text,
)
from sqlalchemy.engine import URL, Engine
from sqlalchemy.exc import ArgumentError, DBAPIError, DisconnectionError, NoSuchModuleError
from sqlalchemy.orm import DeclarativeBase, Mapped, Session, mapped_column, relationship

from study.data.dbfile import (
    check_existing,
    create_atomically,
    is_url,
    probe,
    ro_connect,
    sqlite_url_file,
)
from study.data.schema import check_revision, stamp_head

# kept equal to the Alembic head's number in meta.schema_version, which older platform
# versions and dbfile.probe read (study.data.schema; docs/decisions.md)
SCHEMA_VERSION = 5
# the advisory lock key of a study database's write lock on PostgreSQL (one study per
# database, so one key: "asastudy" in ASCII as a bigint; study.data.ledger.lock_study)
PG_STUDY_LOCK = int.from_bytes(b"asastudy", "big") & 0x7FFF_FFFF_FFFF_FFFF
BUSY_TIMEOUT_MS = 30_000  # [ms] wait for another process's write lock

TRIAL_PHASES = ("training", "practice", "baseline", "main")
TRIAL_STATUSES = ("running", "completed", "timed_out", "aborted")
# a trial that ran to its end (its task done or its time limit reached): it counts and is
# not run again; databases written before "timed_out" existed store a timeout as
# "completed" with completed_task false (docs/decisions.md)
TRIAL_FINISHED = ("completed", "timed_out")
PARTICIPANT_KINDS = ("human", "synthetic", "scripted")
# an order slot is "reserved" for a code by a synthetic study until its participant is
# merged, then "issued"; an issued slot whose holder was excluded is reissued (the earlier
# holders are kept in ``OrderSlot.released``)
SLOT_STATUSES = ("reserved", "issued")


def new_uid() -> str:
    """A new global key (a session's ``uid``): a random UUID4 as 36 characters."""
    return str(uuid.uuid4())


def utc_now() -> dt.datetime:
    """The current time, timezone-aware UTC (every timestamp the platform stores)."""
    return dt.datetime.now(dt.UTC)


class UTCDateTime(TypeDecorator[dt.datetime]):
    """A timestamp stored as UTC and read back timezone-aware UTC on every backend.

    SQLite keeps no zone (SQLAlchemy writes the wall-clock digits and reads them back
    naive) and PostgreSQL's ``timestamptz`` answers in the connection's time zone; so
    values are converted to UTC on the way in (a naive one is taken as UTC) and marked
    or converted to UTC on the way out. On SQLite the stored text is as before.
    """

    impl = DateTime(timezone=True)
    cache_ok = True

    def process_bind_param(self, value: dt.datetime | None, dialect: Any) -> dt.datetime | None:
        if value is None or value.tzinfo is None:
            return value
        value = value.astimezone(dt.UTC)
        return value.replace(tzinfo=None) if dialect.name == "sqlite" else value

    def process_result_value(self, value: dt.datetime | None, dialect: Any) -> dt.datetime | None:
        if value is None:
            return None
        if value.tzinfo is None:
            return value.replace(tzinfo=dt.UTC)
        return value.astimezone(dt.UTC)


class Base(DeclarativeBase):
    type_annotation_map = {dict[str, Any]: JSON, list[Any]: JSON, dt.datetime: UTCDateTime}


class Meta(Base):
    __tablename__ = "meta"
    key: Mapped[str] = mapped_column(String(64), primary_key=True)
    value: Mapped[str] = mapped_column(Text)


class Study(Base):
    __tablename__ = "study"
    id: Mapped[int] = mapped_column(primary_key=True)
    name: Mapped[str] = mapped_column(String(200))
    protocol_text: Mapped[str] = mapped_column(Text)
    protocol_sha256: Mapped[str] = mapped_column(String(64))
    platform_version: Mapped[str] = mapped_column(String(64))
    seed: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utc_now)
    # the sites of a multi-site study, from the protocol's [study] sites (revision 0002)
    sites: Mapped[list[Any]] = mapped_column(default=list, server_default=text("'[]'"))

    participants: Mapped[list[Participant]] = relationship(back_populates="study")


class Participant(Base):
    __tablename__ = "participant"
    __table_args__ = (UniqueConstraint("study_id", "code"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    study_id: Mapped[int] = mapped_column(ForeignKey("study.id"))
    code: Mapped[str] = mapped_column(String(64))  # pseudonymous, e.g. "P01"
    kind: Mapped[str] = mapped_column(String(16))  # PARTICIPANT_KINDS
    parameters: Mapped[dict[str, Any]] = mapped_column(default=dict)  # synthetic model params
    order_index: Mapped[int] = mapped_column(Integer)  # row of the counterbalancing scheme
    mode_order: Mapped[list[Any]] = mapped_column(
        default=list
    )  # e.g. ["manual", "reactive_bn", ...]
    seed: Mapped[int] = mapped_column(Integer)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utc_now)
    # the site the participant belongs to (its ledger; revision 0003; None without sites)
    site: Mapped[str | None] = mapped_column(String(64))

    study: Mapped[Study] = relationship(back_populates="participants")
    sessions: Mapped[list[SessionRow]] = relationship(back_populates="participant")
    trials: Mapped[list[Trial]] = relationship(back_populates="participant")


class SessionRow(Base):
    """One run of a participant's session (named ``SessionRow`` so as not to shadow the ORM
    ``Session``)."""

    __tablename__ = "session"
    id: Mapped[int] = mapped_column(primary_key=True)
    participant_id: Mapped[int] = mapped_column(ForeignKey("participant.id"))
    started_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utc_now)
    ended_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime)
    status: Mapped[str] = mapped_column(String(16), default="running")  # running/completed/aborted
    resumed: Mapped[bool] = mapped_column(Boolean, default=False)
    forced: Mapped[bool] = mapped_column(Boolean, default=False)
    note: Mapped[str] = mapped_column(Text, default="")
    # where the session ran (revision 0002; None before multi-site studies)
    site: Mapped[str | None] = mapped_column(String(64))
    machine: Mapped[str | None] = mapped_column(String(128))
    # the session's key in every database it is pushed to (a UUID4; revision 0003)
    uid: Mapped[str | None] = mapped_column(String(36), default=new_uid, unique=True, index=True)

    participant: Mapped[Participant] = relationship(back_populates="sessions")


class Trial(Base):
    __tablename__ = "trial"
    __table_args__ = (Index("ix_trial_participant", "participant_id", "phase", "ordinal"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    participant_id: Mapped[int] = mapped_column(ForeignKey("participant.id"))
    session_id: Mapped[int] = mapped_column(ForeignKey("session.id"))
    phase: Mapped[str] = mapped_column(String(16))  # TRIAL_PHASES
    mode: Mapped[str] = mapped_column(String(32))  # "" for the baseline block
    ordinal: Mapped[int] = mapped_column(Integer)  # position within its phase, from 0
    attempt: Mapped[int] = mapped_column(Integer, default=0)  # repeats (practice, resume)
    scenario: Mapped[str] = mapped_column(String(200))
    seed: Mapped[int] = mapped_column(Integer)
    status: Mapped[str] = mapped_column(String(16), default="running")  # TRIAL_STATUSES
    started_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utc_now)
    ended_at: Mapped[dt.datetime | None] = mapped_column(UTCDateTime)
    # outcome, set in the completing transaction
    completed_task: Mapped[bool | None] = mapped_column(Boolean)  # False on timeout
    completion_time_s: Mapped[float | None] = mapped_column(Float)
    collisions: Mapped[int | None] = mapped_column(Integer)
    score: Mapped[float | None] = mapped_column(Float)  # time + penalty per collision
    path_length_m: Mapped[float | None] = mapped_column(Float)
    clearance_mean_m: Mapped[float | None] = mapped_column(Float)
    clearance_min_m: Mapped[float | None] = mapped_column(Float)
    tick_jitter_ms: Mapped[float | None] = mapped_column(Float)  # p99 |period - dt|, humans
    recording_path: Mapped[str] = mapped_column(Text, default="")
    outcome: Mapped[dict[str, Any]] = mapped_column(default=dict)  # further metrics

    participant: Mapped[Participant] = relationship(back_populates="trials")


class Sample(Base):
    __tablename__ = "sample"
    __table_args__ = (Index("ix_sample_trial_tick", "trial_id", "tick"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    trial_id: Mapped[int] = mapped_column(ForeignKey("trial.id"))
    tick: Mapped[int] = mapped_column(Integer)
    t: Mapped[float] = mapped_column(Float)  # [s] simulated time
    x: Mapped[float] = mapped_column(Float)  # true pose [m, m, rad]
    y: Mapped[float] = mapped_column(Float)
    yaw: Mapped[float] = mapped_column(Float)
    u_x: Mapped[float] = mapped_column(Float)  # joystick command [m/s, m/s, rad/s]
    u_y: Mapped[float] = mapped_column(Float)
    u_w: Mapped[float] = mapped_column(Float)
    v_x: Mapped[float] = mapped_column(Float)  # command sent to the robot
    v_y: Mapped[float] = mapped_column(Float)
    v_w: Mapped[float] = mapped_column(Float)
    beta: Mapped[float] = mapped_column(Float)
    label: Mapped[str] = mapped_column(String(32), default="")  # situation or task
    target: Mapped[str] = mapped_column(String(64), default="")  # recognised component
    min_clearance_m: Mapped[float] = mapped_column(Float)
    in_region: Mapped[bool] = mapped_column(Boolean)
    true_task: Mapped[str] = mapped_column(String(32), default="")  # synthetic ground truth
    true_target: Mapped[str] = mapped_column(String(64), default="")
    # [s] the session machine's LSL local_clock() when the tick happened (revision 0004;
    # None without LSL)
    lsl_clock_s: Mapped[float | None] = mapped_column(Float)
    # a browser participant's input (revision 0005; None for others): how many ticks
    # before this one the page had drawn the state it answered, and that state's round
    # trip [ms] (study.web; docs/decisions.md)
    input_age_ticks: Mapped[int | None] = mapped_column(Integer)
    rtt_ms: Mapped[float | None] = mapped_column(Float)


class Event(Base):
    __tablename__ = "event"
    __table_args__ = (Index("ix_event_trial", "trial_id", "t"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    session_id: Mapped[int] = mapped_column(ForeignKey("session.id"))
    trial_id: Mapped[int | None] = mapped_column(ForeignKey("trial.id"))
    t: Mapped[float] = mapped_column(Float)  # [s] trial time (session time outside trials)
    kind: Mapped[str] = mapped_column(String(32))
    detail: Mapped[dict[str, Any]] = mapped_column(default=dict)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utc_now)


class Question(Base):
    __tablename__ = "question"
    __table_args__ = (Index("ix_question_trial", "trial_id"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    trial_id: Mapped[int] = mapped_column(ForeignKey("trial.id"))
    block: Mapped[int] = mapped_column(Integer)
    index: Mapped[int] = mapped_column(Integer)  # within the block
    text: Mapped[str] = mapped_column(String(64))
    shown_is_correct: Mapped[bool] = mapped_column(Boolean)
    shown_t: Mapped[float] = mapped_column(Float)
    answered_t: Mapped[float | None] = mapped_column(Float)
    response: Mapped[bool | None] = mapped_column(Boolean)  # said "correct"?; None = timeout
    correct: Mapped[bool] = mapped_column(Boolean)  # False for a wrong answer or a timeout
    answer_time_s: Mapped[float | None] = mapped_column(Float)


class Response(Base):
    __tablename__ = "response"
    __table_args__ = (Index("ix_response_participant", "participant_id", "instrument"),)
    id: Mapped[int] = mapped_column(primary_key=True)
    participant_id: Mapped[int] = mapped_column(ForeignKey("participant.id"))
    trial_id: Mapped[int | None] = mapped_column(ForeignKey("trial.id"))  # None: per session
    instrument: Mapped[str] = mapped_column(String(32))  # "nasa_tlx", "experience", ...
    item: Mapped[str] = mapped_column(String(64))
    value: Mapped[float | None] = mapped_column(Float)
    text: Mapped[str] = mapped_column(Text, default="")
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utc_now)


class OrderSlot(Base):
    """One slot of the counterbalancing ledger: slot ``k`` (from 0) gives row ``k mod
    cycle`` of a deterministic scheme, the ``k``-th draw of the random scheme. One row per
    slot and study; ``participant_id`` is its current holder (None while ``reserved``)."""

    __tablename__ = "order_slot"
    __table_args__ = (
        UniqueConstraint("study_id", "site", "slot", name="uq_order_slot_site_slot"),
        UniqueConstraint("study_id", "code", name="uq_order_slot_code"),
    )
    id: Mapped[int] = mapped_column(primary_key=True)
    study_id: Mapped[int] = mapped_column(ForeignKey("study.id"))
    # the site whose ledger this slot belongs to ("" in a study without sites; revision 0003)
    site: Mapped[str] = mapped_column(String(64), default="", server_default=text("''"))
    slot: Mapped[int] = mapped_column(Integer)  # from 0
    code: Mapped[str] = mapped_column(String(64))  # the current holder's code
    participant_id: Mapped[int | None] = mapped_column(ForeignKey("participant.id"))
    status: Mapped[str] = mapped_column(String(16), default="issued")  # SLOT_STATUSES
    # earlier holders released by exclusion: [{"code", "participant_id", "released_at"}]
    released: Mapped[list[Any]] = mapped_column(default=list)
    created_at: Mapped[dt.datetime] = mapped_column(UTCDateTime, default=utc_now)


# ------------------------------------------------------------------------- engine


# URL schemes without a driver, and the driver the platform uses for them
_DEFAULT_DRIVERS = {"postgresql": "postgresql+psycopg", "postgres": "postgresql+psycopg"}


def database_url(db: str | Path) -> str:
    """``db`` as a SQLAlchemy URL: text of the form ``scheme://...`` is taken as written
    (``sqlite:///x.db``, ``postgresql+psycopg://user@host/study``), except that
    ``postgresql://`` and ``postgres://`` get the psycopg 3 driver; anything else is a
    file path and becomes ``sqlite:///<absolute path>``."""
    text = str(db)
    if not is_url(text):
        return f"sqlite:///{Path(text).resolve()}"
    scheme, rest = text.split("://", 1)
    return f"{_DEFAULT_DRIVERS.get(scheme.lower(), scheme)}://{rest}"


def database_file(db: str | Path) -> Path:
    """The SQLite file of ``db`` (a path or a ``sqlite://`` URL), absolute; for a server
    database a stand-in ``<working folder>/<database name>.db`` (never made), whose parent
    and stem name the local folders beside it: recordings, a synthetic study's scratch
    files and lock files (docs/decisions.md, "PostgreSQL")."""
    text = str(db)
    if not is_url(text):
        return Path(text).resolve()
    path = sqlite_url_file(text)
    if path is not None:
        return path
    return Path.cwd() / f"{server_database_name(text)}.db"


def is_server(db: str | Path) -> bool:
    """Whether ``db`` names a server database (a URL of a backend other than SQLite)."""
    return is_url(str(db)) and not database_url(db).startswith("sqlite:")


def is_postgresql(db: str | Path) -> bool:
    """Whether ``db`` names a PostgreSQL database (any driver)."""
    return is_url(str(db)) and database_url(db).startswith(("postgresql:", "postgresql+"))


def server_database_name(url: str) -> str:
    """The database name of a server URL as a plain file name (``asa_study`` without
    one; characters other than letters, digits, ``-``, ``_`` and ``.`` become ``_``)."""
    from sqlalchemy.engine import make_url

    try:
        name = make_url(database_url(url)).database or ""
    except ArgumentError:
        name = ""
    name = re.sub(r"[^A-Za-z0-9._-]", "_", name).strip(".")
    return name or "asa_study"


def _sqlite_pragmas(
    dbapi_connection: Any, _record: Any, *, durable: bool = True, readonly: bool = False
) -> None:
    cursor = dbapi_connection.cursor()
    # first: another process (asa db check, export, a second session) may hold the write
    # lock, also while this connection switches to WAL
    cursor.execute(f"PRAGMA busy_timeout={BUSY_TIMEOUT_MS}")
    cursor.execute("PRAGMA foreign_keys=ON")
    if readonly:
        cursor.execute("PRAGMA query_only=ON")
        cursor.close()
        return
    cursor.execute("PRAGMA journal_mode=WAL")
    # FULL: a committed transaction survives a power cut, not only a crash of the process
    # (WAL + NORMAL may lose the last commits); the trial loop commits about once a second.
    # OFF only for scratch databases that are thrown away after a crash anyway.
    cursor.execute(f"PRAGMA synchronous={'FULL' if durable else 'OFF'}")
    cursor.close()


def open_database(
    db: str | Path, *, create: bool = True, durable: bool = True, readonly: bool | None = None
) -> Engine:
    """Open (and with ``create`` make) a study database and check it is ours.

    ``db`` is a file path or a SQLAlchemy URL, as written (:func:`database_url`). A file
    that does not exist is a new study (made atomically, tables and schema version in one
    go, so two processes starting on a fresh file both see a whole study); an existing
    file must be an asa-study database and is left untouched when it is not.

    ``readonly`` (default: ``not create``) opens an SQLite file without writing anything
    (no tables, no ``-wal``/``-shm`` files; :mod:`study.data.dbfile`), so a study the user
    cannot write can be checked, exported and reported.

    Raises ``ValueError`` (one line naming the database) when it is a folder, an empty
    file, not an SQLite file, not made by this platform, made by a newer schema version
    (an unknown revision), at an older schema revision (for writing, or for reading when
    its tables lack columns the models map: the line names ``asa db upgrade``;
    :mod:`study.data.schema`), or cannot be opened or written (a missing folder, no
    permission, a full disk), and for a URL whose database driver is not installed;
    ``FileNotFoundError`` when the file does not exist and ``create`` is false.

    ``durable=False`` skips SQLite's fsync on commit: only for a scratch database that is
    deleted and rebuilt when its process dies (a synthetic study's per-participant file,
    :mod:`study.jobs.synth`); a study database always keeps the default.
    """
    readonly = (not create) if readonly is None else readonly
    create = create and not readonly
    url = database_url(db)
    try:
        if is_url(str(db)) and sqlite_url_file(url) is None:
            return _open_server(db, url, create, write=not readonly)
        return _open_sqlite(db, url, create=create, durable=durable, readonly=readonly)
    except DBAPIError as error:
        reason = " ".join(str(error.orig).split()) if error.orig is not None else str(error)
        raise ValueError(
            f"{db}: cannot be used as a study database ({reason}); give an asa-study "
            "database or a new file name in a writable folder"
        ) from error
    except sqlite3.Error as error:
        raise ValueError(
            f"{db}: cannot be read as a study database ({' '.join(str(error).split())})"
        ) from error
    except ImportError as error:
        raise ValueError(
            f"{db}: the database driver for this URL is not installed ({error}); give a "
            "SQLite file path, or install the driver"
        ) from error
    except (NoSuchModuleError, ArgumentError) as error:
        raise ValueError(
            f"{db}: not a database URL SQLAlchemy knows ({' '.join(str(error).split())}); "
            "give a SQLite file path or a SQLAlchemy URL such as sqlite:///study.db"
        ) from error


def _check_schema(db: str | Path, tables: set[str], version: str | None) -> None:
    """Refuse a database without the asa tables or with a schema version not ours."""
    if not tables:
        raise ValueError(f"{db}: holds no tables; not an asa-study database")
    if not {"meta", "study"} <= tables:
        raise ValueError(f"{db}: not an asa-study database (tables: {', '.join(sorted(tables))})")
    if version is None or not version.isdigit():
        raise ValueError(f"{db}: field 'meta.schema_version' is missing; not an asa-study database")
    if int(version) > SCHEMA_VERSION:
        raise ValueError(
            f"{db}: field 'meta.schema_version' is {version}; this platform reads up to "
            f"{SCHEMA_VERSION}, upgrade asa-study"
        )


def _sqlite_engine(path: Path, url: str | None, *, durable: bool, readonly: bool) -> Engine:
    """An engine on the SQLite file ``path``: read-only (:func:`dbfile.ro_connect`), else
    on ``url`` as written (a URL the user gave) or on ``path`` itself."""
    nominal = URL.create("sqlite", database=str(path))
    if readonly:
        engine = create_engine(nominal, creator=lambda: ro_connect(path))
    elif url is not None:
        engine = create_engine(url)
    else:
        engine = create_engine(
            nominal, creator=lambda: sqlite3.connect(str(path), check_same_thread=False)
        )
    pragmas = functools.partial(_sqlite_pragmas, durable=durable, readonly=readonly)
    event.listen(engine, "connect", pragmas)
    return engine


def _open_sqlite(
    db: str | Path, url: str, *, create: bool, durable: bool, readonly: bool
) -> Engine:
    path = database_file(db)
    given = url if is_url(str(db)) else None
    if not path.exists():
        if not create:
            raise FileNotFoundError(2, "No such file", str(path))
        if not path.parent.is_dir():
            raise ValueError(f"{db}: the folder {path.parent} does not exist")
        try:
            create_atomically(path, functools.partial(_new_sqlite, durable=durable))
        except OSError as error:
            raise ValueError(
                f"{db}: cannot create the study database in {path.parent} "
                f"({error.strerror or error})"
            ) from None
    check_existing(path, db)
    tables, version = probe(path)
    _check_schema(db, tables, version)
    engine = _sqlite_engine(path, given, durable=durable, readonly=readonly)
    try:
        _check_revision(db, engine, write=not readonly)
    except BaseException:
        engine.dispose()
        raise
    return engine


def _check_revision(db: str | Path, engine: Engine, *, write: bool) -> None:
    """Refuse a database at a revision other than head for writing, an unknown revision,
    or an older one this code cannot read (:func:`study.data.schema.check_revision`)."""
    with engine.connect() as conn:
        check_revision(db, conn, Base.metadata, write=write)


def _new_sqlite(path: Path, *, durable: bool) -> None:
    """A complete new study file at ``path``: every table and the schema version."""
    engine = _sqlite_engine(path, None, durable=durable, readonly=False)
    try:
        _add_tables(engine, sqlite=True)
    finally:
        engine.dispose()  # the last connection checkpoints and removes the -wal file


def _add_tables(engine: Engine, *, sqlite: bool) -> None:
    """Create the missing tables, stamp the schema version and the Alembic head
    revision in one transaction under
    the database's write lock (SQLite ``BEGIN IMMEDIATE``, PostgreSQL the study's
    advisory lock), so concurrent openers wait and then find the tables made."""
    with engine.connect() as conn:
        if sqlite:
            conn.exec_driver_sql("BEGIN IMMEDIATE")
        elif conn.dialect.name == "postgresql":
            conn.execute(text("SELECT pg_advisory_xact_lock(:key)"), {"key": PG_STUDY_LOCK})
        Base.metadata.create_all(conn)
        if conn.execute(select(Meta.value).where(Meta.key == "schema_version")).first() is None:
            conn.execute(
                Meta.__table__.insert().values(key="schema_version", value=str(SCHEMA_VERSION))
            )
        stamp_head(conn)
        conn.commit()


def _guard_fork(engine: Engine) -> None:
    """Never hand a pooled connection to another process: one checked out in a process
    other than the one that opened it is dropped for a new one (a forked child's copy of
    the parent's pool), as SQLAlchemy's "Using Connection Pools with Multiprocessing or
    os.fork()" does. The platform's own workers are spawned and open their own engines."""

    def remember(_dbapi: Any, record: Any) -> None:
        record.info["pid"] = os.getpid()

    def check(_dbapi: Any, record: Any, proxy: Any) -> None:
        if record.info.get("pid") != os.getpid():
            record.dbapi_connection = proxy.dbapi_connection = None
            raise DisconnectionError(
                f"connection opened in process {record.info.get('pid')}, not this one"
            )

    event.listen(engine, "connect", remember)
    event.listen(engine, "checkout", check)


def _open_server(db: str | Path, url: str, create: bool, *, write: bool) -> Engine:
    """A server database (any SQLAlchemy URL but SQLite); an empty one is a new study.
    Connections are tested before use (``pool_pre_ping``: a server restart or a dropped
    idle connection costs a reconnect, not a failed write)."""
    engine = create_engine(url, pool_pre_ping=True)
    _guard_fork(engine)
    try:
        tables = set(inspect(engine).get_table_names())
        if tables or not create:
            version = None
            if "meta" in tables:
                with engine.connect() as conn:
                    row = conn.execute(select(Meta.value).where(Meta.key == "schema_version"))
                    version = row.scalar()
            _check_schema(db, tables, version)
        else:
            try:
                _add_tables(engine, sqlite=False)
            except DBAPIError:  # another process made them at the same moment
                if not set(Base.metadata.tables) <= set(inspect(engine).get_table_names()):
                    raise
        _check_revision(db, engine, write=write)
    except BaseException:
        engine.dispose()
        raise
    return engine


def get_study(session: Session) -> Study | None:
    """The study row of a database (one study per database), or None if empty."""
    return session.scalars(select(Study).order_by(Study.id)).first()


# the lab's streams (revision 0004): defined beside, mapped on the same metadata
from study.data.lsl_tables import LslChunk, LslGap, LslOffset, LslStream  # noqa: E402, F401

# invitations of browser participants (revision 0005)
from study.data.web_tables import Invite  # noqa: E402, F401
