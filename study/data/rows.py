"""Copying rows between study databases with fresh ids: the table-level helpers shared by
merging a synthetic participant (:mod:`study.data.merge`) and pushing a site's database
(:mod:`study.data.push`). Row ids are local to a database; every insert leaves ``id`` to
the destination."""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any

from sqlalchemy import Boolean, select
from sqlalchemy.engine import Connection

from study.data.storage import Base

CHUNK = 5000  # rows per executemany when copying samples


def table_rows(conn: Connection, table: str, where: Any = None) -> list[dict[str, Any]]:
    """The rows of ``table`` in id order as dictionaries (``where(t)`` filters them)."""
    t = Base.metadata.tables[table]
    query = select(t).order_by(t.c.id)
    if where is not None:
        query = query.where(where(t))
    return [dict(r._mapping) for r in conn.execute(query)]


def insert_row(conn: Connection, table: str, row: dict[str, Any]) -> int:
    """Insert ``row`` (its ``id`` left out) into ``table``; returns the new id."""
    t = Base.metadata.tables[table]
    values = {k: v for k, v in row.items() if k != "id"}
    return int(conn.execute(t.insert().values(**values)).inserted_primary_key[0])


def bulk_insert(conn: Connection, table: str, rows: list[dict[str, Any]]) -> None:
    """Insert ``rows`` (their ``id`` left out) into ``table`` as executemany batches."""
    t = Base.metadata.tables[table]
    for i in range(0, len(rows), CHUNK):
        chunk = [{k: v for k, v in r.items() if k != "id"} for r in rows[i : i + CHUNK]]
        if chunk:
            conn.execute(t.insert(), chunk)


def sample_columns() -> list[str]:
    """The columns of ``sample`` without ``id``, in table order."""
    return [c.name for c in Base.metadata.tables["sample"].columns if c.name != "id"]


def sample_tuples(
    conn: Connection, trial_ids: Iterable[int] | None = None
) -> list[tuple[Any, ...]]:
    """Every sample row (without ``id``, in id order), or those of ``trial_ids`` (in id
    order within each trial), as the driver's plain tuples: the bulk of a participant
    (some 16,000 rows), copied without per-row dictionaries. SQLite's booleans stay 0/1
    (:func:`copy_samples` converts)."""
    columns = ", ".join(f'"{c}"' for c in sample_columns())
    if trial_ids is None:
        return list(conn.exec_driver_sql(f"SELECT {columns} FROM sample ORDER BY id").fetchall())
    ids = sorted({int(t) for t in trial_ids})  # integers only: safe to write into the SQL
    out: list[tuple[Any, ...]] = []
    for i in range(0, len(ids), 500):
        where = ", ".join(str(t) for t in ids[i : i + 500])
        sql = f"SELECT {columns} FROM sample WHERE trial_id IN ({where}) ORDER BY id"
        out += conn.exec_driver_sql(sql).fetchall()
    return out


def copy_samples(
    conn: Connection, samples: list[tuple[Any, ...]], trial_ids: dict[int, int]
) -> None:
    """Insert ``samples`` (from :func:`sample_tuples`) with their trial ids remapped; the
    stored values are those of the source rows (SQLite's own types, unconverted). Into a
    server database the rows go through the table's types (SQLite's 0/1 become booleans)
    as executemany-style ``insert()`` batches (SQLAlchemy's insertmanyvalues)."""
    names = sample_columns()
    at = names.index("trial_id")
    if conn.dialect.name == "postgresql" and conn.dialect.driver == "psycopg":
        _copy_samples_pg(conn, samples, trial_ids)
        return
    if conn.dialect.name != "sqlite":
        _copy_samples_typed(conn, samples, trial_ids)
        return
    columns = ", ".join(f'"{c}"' for c in names)
    marks = ", ".join("?" * len(names))
    sql = f"INSERT INTO sample ({columns}) VALUES ({marks})"
    for i in range(0, len(samples), CHUNK):
        chunk = [(*r[:at], trial_ids[r[at]], *r[at + 1 :]) for r in samples[i : i + CHUNK]]
        if chunk:
            conn.exec_driver_sql(sql, chunk)


def _copy_samples_pg(
    conn: Connection, samples: list[tuple[Any, ...]], trial_ids: dict[int, int]
) -> None:
    """:func:`copy_samples` into PostgreSQL through psycopg 3: one ``COPY ... FROM STDIN``
    on the caller's connection and transaction (a rollback undoes it), SQLite's 0/1 made
    booleans; several times faster than executemany batches."""
    table = Base.metadata.tables["sample"]
    names = sample_columns()
    flags = [i for i, n in enumerate(names) if isinstance(table.c[n].type, Boolean)]
    at = names.index("trial_id")
    columns = ", ".join(f'"{c}"' for c in names)
    cursor = conn.connection.driver_connection.cursor()  # type: ignore[union-attr]
    try:
        with cursor.copy(f"COPY sample ({columns}) FROM STDIN") as copy:
            for r in samples:
                values = list(r)
                values[at] = trial_ids[r[at]]
                for k in flags:
                    values[k] = None if values[k] is None else bool(values[k])
                copy.write_row(values)
    finally:
        cursor.close()


def _copy_samples_typed(
    conn: Connection, samples: list[tuple[Any, ...]], trial_ids: dict[int, int]
) -> None:
    """:func:`copy_samples` into a server database: SQLite's 0/1 made booleans, the rows
    inserted through the table as executemany-style batches (insertmanyvalues)."""
    table = Base.metadata.tables["sample"]
    names = sample_columns()
    flags = [i for i, n in enumerate(names) if isinstance(table.c[n].type, Boolean)]
    at = names.index("trial_id")
    for i in range(0, len(samples), CHUNK):
        chunk = []
        for r in samples[i : i + CHUNK]:
            values = list(r)
            values[at] = trial_ids[r[at]]
            for k in flags:
                values[k] = None if values[k] is None else bool(values[k])
            chunk.append(dict(zip(names, values, strict=True)))
        if chunk:
            conn.execute(table.insert(), chunk)
