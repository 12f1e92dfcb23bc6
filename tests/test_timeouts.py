"""Timed-out main trials in the analysis (issue 17): flagged in the trial frame, their
completion time and score left out as missing ([analysis] timeouts = "exclude", the
default; the participant then drops listwise from those ANOVAs) or kept at the limit as
censored values ("censor"), and the choice stated in the report's data-quality section."""

from __future__ import annotations

import os
import sqlite3
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from analysis.data import load_study, tidy
from analysis.data.load import read_config
from analysis.metrics import BY_NAME, long_frame
from analysis.report import build_report
from analysis.stats import analyse

sys.path.insert(0, str(Path(__file__).parent))
from fixtures_db import FixtureSettings, make_study_db  # noqa: E402

SETTINGS = FixtureSettings(n_participants=6, samples=60, questions=6, baseline_questions=10)
LIMIT_S = 900.0


def _seed() -> int:
    return int(os.environ.get("ASA_TEST_SEED", "20261123"))


@pytest.fixture(scope="module")
def timed_out_db(tmp_path_factory) -> tuple[Path, list[int]]:
    """A study whose two randomly chosen main trials (of different participants) timed
    out: completed_task false, completion time the limit."""
    rng = np.random.default_rng(_seed())
    path = make_study_db(tmp_path_factory.mktemp("t") / "study.db", rng, settings=SETTINGS)
    with sqlite3.connect(path) as con:
        rows = con.execute(
            "SELECT t.id, p.code FROM trial t JOIN participant p ON p.id = t.participant_id "
            "WHERE t.phase = 'main' AND t.status = 'completed' ORDER BY t.id"
        ).fetchall()
        by_person: dict[str, list[int]] = {}
        for trial_id, code in rows:
            by_person.setdefault(code, []).append(trial_id)
        people = rng.choice(sorted(by_person), size=2, replace=False)
        chosen = [int(rng.choice(by_person[p])) for p in people]
        for trial_id in chosen:
            con.execute(
                "UPDATE trial SET completed_task = 0, completion_time_s = ?, score = ? + "
                "60 * collisions WHERE id = ?",
                (LIMIT_S, LIMIT_S, trial_id),
            )
    return path, chosen


def test_excluded_by_default_and_dropped_listwise(timed_out_db):
    path, chosen = timed_out_db
    frames = tidy(load_study(path))
    t = frames.trials.set_index("trial_id")
    assert set(t.index[t["timed_out"]]) == set(chosen)
    assert t.loc[chosen, ["completion_time_s", "score_s"]].isna().all().all()
    assert t.drop(index=chosen)[["completion_time_s", "score_s"]].notna().all().all()
    assert not t["censored"].any()
    assert any("timed out" in w and '"exclude"' in w for w in frames.warnings)
    long = long_frame(frames, BY_NAME["completion_time_s"])
    result = analyse(long, dv="value", within="mode", subject="participant")
    who = set(t.loc[chosen, "participant"])
    assert who <= set(result["dropped_subjects"])  # both participants dropped listwise


def test_censored_keeps_the_limit(timed_out_db):
    path, chosen = timed_out_db
    data = load_study(path)
    frames = tidy(replace(data, config=replace(data.config, timeouts="censor")))
    t = frames.trials.set_index("trial_id")
    assert (t.loc[chosen, "completion_time_s"] == LIMIT_S).all()
    assert t.loc[chosen, "censored"].all() and t["censored"].sum() == len(chosen)
    assert any('"censor"' in w for w in frames.warnings)


def test_report_states_the_choice(timed_out_db, tmp_path):
    path, _ = timed_out_db
    # the data-quality section does not depend on the metrics analysed: one metric (the one
    # the choice changes) keeps each report at ~2 s instead of ~15 s; test_report.py builds
    # the report of every metric
    only = ("completion_time_s",)
    html = build_report(path, tmp_path / "r", metrics=only).html.read_text(encoding="utf-8")
    assert "timed out" in html and "left out as missing" in html
    with sqlite3.connect(path) as con:
        text = con.execute("SELECT protocol_text FROM study").fetchone()[0]
    censor = text.replace('timeouts = "exclude"', 'timeouts = "censor"', 1)
    assert censor != text
    with sqlite3.connect(path) as con:
        con.execute("UPDATE study SET protocol_text = ?", (censor,))
    try:
        html = build_report(path, tmp_path / "c", metrics=only).html.read_text(encoding="utf-8")
    finally:
        with sqlite3.connect(path) as con:
            con.execute("UPDATE study SET protocol_text = ?", (text,))
    assert "right-censored" in html


def test_bad_choice_names_the_field():
    with pytest.raises(ValueError, match=r"^p\.toml: field 'analysis\.timeouts' must be one of"):
        read_config('[analysis]\ntimeouts = "drop"\n', source="p.toml")
