"""The report's Methods section (issue 18): built from the stored study alone, the
deviations that concern the study's modes, methods.md beside report.html, and
docs/methods.md listing every deviation."""

from __future__ import annotations

import json
import os
import sqlite3
import sys
from pathlib import Path

import numpy as np
import pytest

from analysis.data import load_study, tidy
from analysis.methods import DEVIATIONS, methods
from analysis.report import build_report

sys.path.insert(0, str(Path(__file__).parent))
from fixtures_db import FixtureSettings, make_study_db  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
SETTINGS = FixtureSettings(n_participants=6, samples=40, questions=4, baseline_questions=6)


@pytest.fixture(scope="module")
def study_db(tmp_path_factory) -> Path:
    rng = np.random.default_rng(int(os.environ.get("ASA_TEST_SEED", "20261126")))
    return make_study_db(tmp_path_factory.mktemp("m") / "study.db", rng, settings=SETTINGS)


def test_paragraphs_come_from_the_stored_protocol(study_db):
    data = load_study(study_db)
    section = methods(data, tidy(data))
    text = {p["title"]: p["text"] for p in section["paragraphs"]}
    assert set(text) == {
        "Platform",
        "Participants and design",
        "Procedure",
        "Assistance modes",
        "Analysis",
    }
    assert str(data.study["protocol_sha256"])[:12] in text["Platform"]
    assert "90 s" in text["Procedure"] and "5 attempts" in text["Procedure"]  # thesis-7-6
    assert "8 s counted as an error" in text["Procedure"]
    assert "left out as missing" in text["Analysis"]
    topics = {d["topic"] for d in section["deviations"]}
    # all three modes: every deviation but those of another protocol
    assert {d.topic for d in DEVIATIONS if not d.protocols} == topics


def test_stored_mode_settings_are_reported(study_db, tmp_path):
    copy = tmp_path / "copy.db"
    copy.write_bytes(study_db.read_bytes())
    with sqlite3.connect(copy) as con:
        con.execute(
            "UPDATE trial SET outcome = json_set(outcome, '$.mode_settings', json(?)) "
            "WHERE mode = 'reactive_bn'",
            (json.dumps({"arbitration": "exclusive", "d_safe": 0.3}),),
        )
    data = load_study(copy)
    modes = {p["title"]: p["text"] for p in methods(data, tidy(data))["paragraphs"]}
    assert (
        "reactive_bn (as stored with its trials): arbitration = exclusive, d_safe = 0.3"
        in (modes["Assistance modes"])
    )
    assert "manual: the platform's defaults" in modes["Assistance modes"]


@pytest.mark.parametrize(
    ("recogniser", "model", "named"),
    [
        (None, True, "recogniser thesis (Ch. 6)"),  # a study from before the setting
        ("kind_time", True, "recogniser kind_time"),
        ("thesis", False, "recogniser thesis"),
    ],
)
def test_the_model_is_named_by_file_and_sha256_never_by_path(
    study_db, tmp_path, recogniser, model, named
):
    copy = tmp_path / "copy.db"
    copy.write_bytes(study_db.read_bytes())
    settings = {"model_path": "/home/someone/lab-machine/models/default.npz", "candidates": 10}
    if recogniser is not None:
        settings["recogniser"] = recogniser
    digest = "0123456789abcdef" * 4
    with sqlite3.connect(copy) as con:
        con.execute(
            "UPDATE trial SET outcome = json_set(outcome, '$.mode_settings', json(?)) "
            "WHERE mode = 'contextual_task'",
            (json.dumps(settings),),
        )
        if model:
            con.execute(
                "UPDATE trial SET outcome = json_set(outcome, '$.model', json(?)) "
                "WHERE mode = 'contextual_task'",
                (json.dumps({"file": "default.npz", "sha256": digest}),),
            )
    data = load_study(copy)
    text = {p["title"]: p["text"] for p in methods(data, tidy(data))["paragraphs"]}
    modes = text["Assistance modes"]
    assert "/home/someone" not in modes and "lab-machine" not in modes
    if model:
        assert f"model default.npz (SHA-256 {digest})" in modes
    else:
        assert "model default.npz (SHA-256 not stored" in modes
    assert f"{named}, candidates = 10" in modes


def test_report_has_the_section_and_methods_md(study_db, tmp_path):
    # the section is built from the stored study whatever the metrics: one metric keeps the
    # report at ~2 s instead of ~15 s (test_report.py builds the report of every metric)
    paths = build_report(study_db, tmp_path / "r", metrics=("completion_time_s",))
    html = paths.html.read_text(encoding="utf-8")
    assert '<h2 id="methods">Methods</h2>' in html
    md = (tmp_path / "r" / "methods.md").read_text(encoding="utf-8")
    assert md.startswith("# Methods") and "## Deviations from the thesis" in md


def test_docs_methods_lists_every_deviation():
    page = (ROOT / "docs" / "methods.md").read_text(encoding="utf-8")
    for d in DEVIATIONS:
        assert d.text in page, d.topic
