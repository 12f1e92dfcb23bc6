"""Shared parts of the bad-input corpus (issue 20): the case registry, the valid inputs
the cases break, and small file helpers. The cases live in the modules beside this one;
``tests/test_bad_input.py`` runs them."""

from __future__ import annotations

import re
import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import pytest

from protocols import PROTOCOL_DIR
from sim.scenario import SCENARIO_DIR
from study.cli import main

PILOT = (PROTOCOL_DIR / "pilot.toml").read_text(encoding="utf-8")
PRACTICE = (SCENARIO_DIR / "practice_course.toml").read_text(encoding="utf-8")
DOCKING = (SCENARIO_DIR / "demo_docking.toml").read_text(encoding="utf-8")
DEEP = "x = " + "[" * 5000 + "]" * 5000 + "\n"  # tomllib recurses once per level
DEEPISH = "x = " + "[" * 100 + "]" * 100 + "\n"  # parses, but nests beyond the limit


@dataclass(frozen=True)
class Env:
    """Valid inputs to break: a study database, its export folder, a demonstrations
    folder and the shipped model."""

    db: Path
    export: Path
    demos: Path
    model: Path


Setup = Callable[[Path, Env], list[str]]
CASES: list[tuple[str, Setup]] = []


def case(name: str, setup: Setup) -> None:
    """Register a case: ``setup(folder, env)`` writes its files and returns ``asa``'s argv."""
    CASES.append((re.sub(r"[^A-Za-z0-9_.+-]+", "_", name), setup))


def write(path: Path, content: str | bytes) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    if isinstance(content, bytes):
        path.write_bytes(content)
    else:
        path.write_text(content, encoding="utf-8")
    return path


def sub(text: str, pattern: str, new: str) -> str:
    """``text`` with the first line matching ``pattern`` (a regex of a whole line) replaced."""
    out, n = re.subn(f"(?m)^{pattern}$", new, text, count=1)
    assert n == 1, pattern
    return out


def run_in_process(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, str]:
    """Run ``asa argv`` in this process; its exit status and stderr. Warnings that Python
    would print count as lines of stderr."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            main(argv)
        except SystemExit as done:
            code = done.code if isinstance(done.code, int) else (0 if done.code is None else 1)
        else:
            code = 0
    err = capsys.readouterr().err
    shown = [
        f"{w.category.__name__}: {w.message}"
        for w in caught
        if not issubclass(w.category, DeprecationWarning | PendingDeprecationWarning)
    ]
    return code, err + "".join(line + "\n" for line in shown)
