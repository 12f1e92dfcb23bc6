"""Shared fixtures. Every random thing is seeded from ``seed``; tests must pass for any
seed, so CI may vary it with ``ASA_TEST_SEED``."""

from __future__ import annotations

import os

import numpy as np
import pytest
from threadpoolctl import threadpool_limits

os.environ.setdefault("SDL_VIDEODRIVER", "dummy")
os.environ.setdefault("SDL_AUDIODRIVER", "dummy")

# As `asa` does (study._blas.limit_blas_threads): small matrices, two cores, no contention.
threadpool_limits(1, user_api="blas")


@pytest.fixture
def seed() -> int:
    return int(os.environ.get("ASA_TEST_SEED", "20261123"))


@pytest.fixture
def rng(seed: int) -> np.random.Generator:
    return np.random.default_rng(seed)


@pytest.fixture(scope="session")
def pg_server():
    """A PostgreSQL server for the whole run (study/data/pg_local.py); fails, never skips,
    when the binaries are missing."""
    from study.data import pg_local as pg

    try:
        pg.bin_folder()
    except RuntimeError as error:
        pytest.fail(str(error), pytrace=False)
    with pg.running() as server:
        yield server


@pytest.fixture
def pg_url(pg_server) -> str:
    """The URL of a fresh, empty database on the session's PostgreSQL server
    (``postgresql+psycopg://asa@127.0.0.1:<port>/t_<n>``)."""
    return pg_server.new_database()


@pytest.fixture(scope="session")
def generated_report(tmp_path_factory):
    """One generated study (tests/fixtures_db.py, six participants) and its report of every
    metric, built once for test_report.py and test_report_presentation.py (~15 s each):
    ``(db, paths, out, progress_lines)``."""
    import sys
    from pathlib import Path

    from analysis.report import build_report

    sys.path.insert(0, str(Path(__file__).parent))
    from fixtures_db import REPORT_STUDY, make_study_db

    seed = int(os.environ.get("ASA_TEST_SEED", "20261123"))  # as the seed fixture
    db = make_study_db(
        tmp_path_factory.mktemp("study") / "study.db", np.random.default_rng(seed),
        settings=REPORT_STUDY,
    )  # fmt: skip
    out = tmp_path_factory.mktemp("report")
    lines: list[str] = []
    paths = build_report(db, out, progress=lines.append)
    return db, paths, out, lines
