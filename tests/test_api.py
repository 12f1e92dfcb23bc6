"""The Python API of DESIGN.md ("Interfaces"): every CLI job is a plain function first."""

from __future__ import annotations

import pytest

import analysis
import study


def test_the_documented_functions_are_reachable_from_the_packages():
    from analysis.report import build_report
    from study.session import run_session
    from study.synth import run_synthetic_study

    assert study.run_session is run_session
    assert study.run_synthetic_study is run_synthetic_study
    assert analysis.build_report is build_report
    assert callable(study.load_protocol) and callable(analysis.analyse)


def test_unknown_names_are_attribute_errors():
    with pytest.raises(AttributeError, match="no attribute 'nothing'"):
        study.nothing  # noqa: B018
    with pytest.raises(AttributeError):
        analysis.nothing  # noqa: B018
