"""The Python API of DESIGN.md ("Interfaces"): every CLI job is a plain function first."""

from __future__ import annotations

import pytest

import analysis
import study


def test_the_documented_functions_are_reachable_from_the_packages():
    from analysis.report import build_report
    from study.engine.session import run_session
    from study.jobs.pilot import run_pilot
    from study.jobs.power import PowerSettings, run_power
    from study.jobs.synth import run_synthetic_study

    assert study.run_session is run_session
    assert study.run_synthetic_study is run_synthetic_study
    assert study.run_pilot is run_pilot
    assert study.run_power is run_power and study.PowerSettings is PowerSettings
    assert analysis.build_report is build_report
    assert callable(study.load_protocol) and callable(analysis.analyse)


def test_unknown_names_are_attribute_errors():
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        study.nothing  # noqa: B018
    with pytest.raises(AttributeError):
        analysis.nothing  # noqa: B018


def test_importing_the_screen_prints_nothing_to_stdout():
    """pygame's import banner would corrupt `asa ... --json` output."""
    import os
    import subprocess
    import sys

    env = {k: v for k, v in os.environ.items() if k != "PYGAME_HIDE_SUPPORT_PROMPT"}
    done = subprocess.run(
        [sys.executable, "-c", "import study.participants.human, study.ui.screen"],
        capture_output=True, text=True, env=env, timeout=60, check=True,
    )  # fmt: skip
    assert done.stdout == ""
