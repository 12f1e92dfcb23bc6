"""The `asa` shell: help, version, and the bad-input contract (one line, exit 2)."""

from __future__ import annotations

import subprocess
import sys

import pytest

from study.cli import COMMANDS, main


def run_asa(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [sys.executable, "-m", "study.cli", *args], capture_output=True, text=True, timeout=120
    )


def test_help_lists_every_registered_command():
    result = run_asa("--help")
    assert result.returncode == 0
    for name in COMMANDS:
        assert name in result.stdout


def test_version():
    result = run_asa("--version")
    assert result.returncode == 0
    assert "asa" in result.stdout


@pytest.mark.parametrize("name", sorted(COMMANDS))
def test_every_command_has_help(name):
    result = run_asa(name, "--help")
    assert result.returncode == 0, result.stderr
    assert "Usage" in result.stdout


def test_unknown_command_is_one_line_exit_2():
    result = run_asa("no-such-job")
    assert result.returncode == 2
    assert len(result.stderr.strip().splitlines()) == 1
    assert "Traceback" not in result.stderr


def test_value_error_becomes_one_line(capsys):
    with pytest.raises(SystemExit) as exit_info:
        main(["bench", "--only", "no-such-group"])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    assert "no-such-group" in err[0] and "allowed" in err[0]
