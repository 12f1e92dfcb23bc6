"""The ``storage`` benchmark group (issue 24): the single writer's rows all land, and
concurrent sessions in their own processes write every batch without an error, on
SQLite and on the real PostgreSQL server."""

from __future__ import annotations

import pytest
from sqlalchemy import func, select

from study.bench.storage import FLUSH_EVERY_TICKS, concurrent_level, sample_rows_per_s
from study.data.storage import Sample, open_database


def _samples(db: str) -> int:
    engine = open_database(db, create=False)
    try:
        with engine.connect() as conn:
            return int(conn.execute(select(func.count()).select_from(Sample)).scalar_one())
    finally:
        engine.dispose()


def test_single_writer_commits_every_row(tmp_path):
    db = str(tmp_path / "s.db")
    assert sample_rows_per_s(db, 10 * FLUSH_EVERY_TICKS) > 0
    assert _samples(db) == 10 * FLUSH_EVERY_TICKS


@pytest.mark.parametrize(
    "backend",
    # PostgreSQL's concurrent writers are tested in CI by test_multisite_concurrency.py
    ["sqlite", pytest.param("postgresql", marks=[pytest.mark.postgres, pytest.mark.slow])],
)
def test_concurrent_sessions_write_every_batch(backend, tmp_path, request):
    db = str(tmp_path / "c.db") if backend == "sqlite" else request.getfixturevalue("pg_url")
    result = concurrent_level(db, 3, 2.0)
    assert result["errors"] == [] and result["batches"] == 3 * 2
    assert 0.0 <= result["max_lag_s"] < 5.0
    assert _samples(db) == 3 * 2 * FLUSH_EVERY_TICKS
