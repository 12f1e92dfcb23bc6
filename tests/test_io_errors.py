"""A full disk, a read-only folder, an I/O error (issue 20): one line naming the file,
exit status 2, the database left consistent; a bug still keeps its traceback."""

from __future__ import annotations

import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from study.cli import main
from tests.bad_input import run_in_process


def _fail_with(monkeypatch: pytest.MonkeyPatch, raise_it: Callable[[], None]) -> None:
    import study.cli

    monkeypatch.setattr(study.cli.cli, "main", lambda *a, **k: raise_it())


def _enospc_naming_the_file(path: Path) -> None:
    import errno
    import os

    raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))


def _enospc_from_a_write(path: Path) -> None:
    """As ``f.write`` reports a full disk: an OSError that names no file."""
    import errno
    import os

    with open(path, "w") as handle:  # noqa: F841 - the open file names the path
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))


def _sqlite_full(path: Path) -> None:
    """As SQLAlchemy reports SQLite's SQLITE_FULL, raised while handling a rollback."""
    import sqlite3

    from sqlalchemy import create_engine
    from sqlalchemy.exc import OperationalError

    engine = create_engine(f"sqlite:///{path}")  # noqa: F841 - names the database
    try:
        raise OperationalError(
            "INSERT INTO sample ...", {}, sqlite3.OperationalError("database or disk is full")
        )
    except OperationalError as error:
        raise RuntimeError("rollback failed too") from error


@pytest.mark.parametrize(
    ("raise_it", "expected"),
    [
        (_enospc_naming_the_file, "{path}: no space left on device"),
        (_enospc_from_a_write, "{path}: no space left on device"),
        (_sqlite_full, "{path}: database or disk is full"),
    ],
    ids=["oserror-with-filename", "oserror-from-write", "sqlite-full-chained"],
)
def test_a_full_disk_is_one_line_naming_the_file(
    raise_it: Callable[[Path], None],
    expected: str,
    tmp_path: Path,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    path = tmp_path / "study.db"
    _fail_with(monkeypatch, lambda: raise_it(path))
    code, err = run_in_process(["db", "check", "--db", str(path)], capsys)
    assert code == 2
    assert err == f"asa: error: {expected.format(path=path)}\n"


@pytest.mark.parametrize("name", ["EACCES", "EROFS", "EIO", "EFBIG", "EDQUOT"])
def test_other_file_system_errors_are_one_line(
    name: str, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    import errno
    import os

    number = getattr(errno, name)

    def fail() -> None:
        raise OSError(number, os.strerror(number), str(tmp_path / "x.csv"))

    _fail_with(monkeypatch, fail)
    code, err = run_in_process(["export", "--db", "x.db", "--out", str(tmp_path)], capsys)
    assert code == 2
    assert err == f"asa: error: {tmp_path / 'x.csv'}: {os.strerror(number).lower()}\n"


def test_a_bug_keeps_its_traceback(monkeypatch: pytest.MonkeyPatch) -> None:
    """Only a failing disk or file system is reported as one line; a bug still raises."""

    def fail() -> None:
        raise KeyError("a bug")

    _fail_with(monkeypatch, fail)
    with pytest.raises(KeyError):
        main(["db", "check", "--db", "x.db"])


def _with_file_size_limit(limit: int) -> Callable[[], None]:
    def apply() -> None:
        import resource
        import signal

        signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write fails with EFBIG instead
        resource.setrlimit(resource.RLIMIT_FSIZE, (limit, limit))

    return apply


@pytest.mark.slow  # 15-25 s: a real session's start-up; the in-process cases above run in CI
def test_a_disk_filling_up_during_a_session_leaves_a_consistent_database(tmp_path: Path) -> None:
    """A real process whose files cannot grow past 300 kB (RLIMIT_FSIZE, as a full disk
    but without root): `asa run` stops with one line naming the database, and `asa db
    check` finds it consistent (the unfinished session is kept, as after a crash)."""
    db = tmp_path / "study.db"
    argv = ["run", "--protocol", "pilot", "--participant", "P01", "--db", str(db)]
    done = subprocess.run(
        [sys.executable, "-m", "study.cli", *argv, "--input", "scripted", "--headless", "--fast"],
        capture_output=True,
        text=True,
        timeout=600,
        preexec_fn=_with_file_size_limit(300_000),
        cwd=Path(__file__).resolve().parents[1],
    )
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("asa: error: "), done.stderr
    assert str(tmp_path) in lines[0], lines[0]
    check = subprocess.run(
        [sys.executable, "-m", "study.cli", "db", "check", "--db", str(db), "--no-verify"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=Path(__file__).resolve().parents[1],
    )
    assert check.returncode == 0, check.stdout + check.stderr
    assert "clean" in check.stdout


def test_scene_names_follow_the_participant_code_rule() -> None:
    """sim.limits.SAFE_NAME (scenario names) is study.engine.session.CODE_PATTERN."""
    from sim.limits import SAFE_NAME
    from study.engine.session import CODE_PATTERN

    assert SAFE_NAME.pattern == CODE_PATTERN.pattern


@pytest.fixture
def tiny_disk(tmp_path: Path):
    """A 400 kB tmpfs mounted on a new folder (root only; skipped elsewhere), unmounted after."""
    import os

    if not hasattr(os, "geteuid") or os.geteuid() != 0:
        pytest.skip("mounting a tmpfs needs root")
    folder = tmp_path / "disk"
    folder.mkdir()
    mounted = subprocess.run(
        ["mount", "-t", "tmpfs", "-o", "size=400k", "tmpfs", str(folder)],
        capture_output=True,
        text=True,
    )
    if mounted.returncode != 0:
        pytest.skip(f"cannot mount a tmpfs: {mounted.stderr.strip()}")
    try:
        yield folder
    finally:
        subprocess.run(["umount", str(folder)], check=False)


@pytest.mark.slow  # 8-17 s: a real session's start-up
def test_a_full_tmpfs_ends_a_session_in_one_asa_line_and_a_consistent_database(
    tiny_disk: Path,
) -> None:
    """A real full disk (ENOSPC, SQLite's SQLITE_FULL): one ``asa:`` line naming the
    database, and `asa db check` finds it clean. rerun's own writer thread may log its
    failure to write the recording too (its lines are rerun's, not a traceback)."""
    db = tiny_disk / "study.db"
    root = Path(__file__).resolve().parents[1]
    argv = ["run", "--protocol", "pilot", "--participant", "P01", "--db", str(db)]
    done = subprocess.run(
        [sys.executable, "-m", "study.cli", *argv, "--input", "scripted", "--headless", "--fast"],
        capture_output=True,
        text=True,
        timeout=600,
        cwd=root,
    )
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    ours = [line for line in done.stderr.splitlines() if line.startswith("asa")]
    assert len(ours) == 1 and ours[0].startswith(f"asa: error: {tiny_disk}"), done.stderr
    assert "no space left on device" in ours[0] or "disk is full" in ours[0], ours[0]
    check = subprocess.run(
        [sys.executable, "-m", "study.cli", "db", "check", "--db", str(db), "--no-verify"],
        capture_output=True,
        text=True,
        timeout=300,
        cwd=root,
    )
    assert check.returncode == 0 and "clean" in check.stdout, check.stdout + check.stderr
