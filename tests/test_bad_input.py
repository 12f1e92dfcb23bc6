"""The bad-input corpus (issue 20): every input the platform reads, made wrong.

Protocol TOML, scenario TOML, the long CSV of ``asa stats``, the CSV folder of ``asa
export`` (questionnaire answers among it), study database files, model files,
demonstration folders, and the options of every command. Each case runs ``asa`` in
process and asserts what the CLI promises for bad input: exit status 2, exactly one
line on stderr, no traceback, no printed warning. A few run as real subprocesses to
prove the console path. The cases are written in ``tests/bad_input/`` (``toml_cases``,
``data_cases``, ``option_cases``) and all of them are counted here (``len(CASES)`` >= 150);
failing disks are ``tests/test_io_errors.py``.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import tests.bad_input.data_cases
import tests.bad_input.option_cases
import tests.bad_input.toml_cases  # noqa: F401 - the cases register themselves
from autonomy.model import DEFAULT_MODEL
from study.cli import main
from tests.bad_input import CASES, DEEP, Env, Setup, run_in_process
from tests.bad_input import write as _write
from tests.bad_input.data_cases import STATS


@pytest.fixture(scope="module")
def env(tmp_path_factory: pytest.TempPathFactory) -> Env:
    from tests.fixtures_db import FixtureSettings, make_study_db

    root = tmp_path_factory.mktemp("corpus")
    db = make_study_db(
        root / "study.db",
        np.random.default_rng(0),
        settings=FixtureSettings(n_participants=3, samples=10),
    )
    export = root / "export"
    demos = root / "demos"
    for argv in (
        ["export", "--db", str(db), "--out", str(export)],
        ["demonstrations", "record", "--task", "doorway_crossing", "--runs", "1"]
        + ["--out", str(demos)],
    ):
        try:
            main([*argv])
        except SystemExit as done:
            assert done.code in (0, None), argv
    return Env(db=db, export=export, demos=demos, model=Path(DEFAULT_MODEL))


# ------------------------------------------------------------------------------ tests


def test_the_corpus_holds_at_least_150_cases() -> None:
    names = [name for name, _ in CASES]
    assert len(names) >= 150, len(names)
    assert len(set(names)) == len(names), "case names must be unique"


def _params() -> list:
    return [pytest.param(name, setup, id=name) for name, setup in CASES]


@pytest.mark.parametrize(("name", "setup"), _params())
def test_bad_input_is_one_line_and_exit_2(
    name: str, setup: Setup, env: Env, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = setup(tmp_path, env)
    code, err = run_in_process(argv, capsys)
    lines = err.strip().splitlines()
    assert "Traceback" not in err, err
    assert code == 2, (code, err)
    assert len(lines) == 1, err
    assert lines[0].startswith("asa"), err


@pytest.mark.parametrize(
    "argv",
    [
        ["plan", "--protocol", "pilot", "--seed", str(10**23)],
        ["stats", "--csv", "{tmp}/big.csv", *STATS],
        ["scenario", "show", "{tmp}/deep.toml"],
        ["plan", "--protocol", "{tmp}/deep.toml"],
    ],
    ids=["seed-10e23", "csv-1e307", "scenario-deep", "protocol-deep"],
)
def test_the_console_path_prints_one_line(argv: list[str], tmp_path: Path) -> None:
    """The same promise through a real process: python -m study.cli, with warnings on."""
    _write(
        tmp_path / "big.csv",
        "s,m,y\n" + "".join(f"{i},{m},1e307\n" for i in range(4) for m in "ab"),
    )
    _write(tmp_path / "deep.toml", DEEP)
    args = [a.replace("{tmp}", str(tmp_path)) for a in argv]
    done = subprocess.run(
        [sys.executable, "-W", "default", "-m", "study.cli", *args],
        capture_output=True,
        text=True,
        timeout=120,
        cwd=Path(__file__).resolve().parents[1],
    )
    assert done.returncode == 2, done.stderr
    assert "Traceback" not in done.stderr
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr
