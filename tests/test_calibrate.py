"""``asa calibrate`` (issue 39): the bank's importance weights turn the proposal into any
candidate population; a study simulated from a known population (not the default) is
calibrated back within the reported intervals (small here, full under ``-m slow``); the
population file is read by ``--population``; bad input is one line and exit 2."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import numpy as np
import pytest
from cli_helpers import asa
from fixtures_db import FixtureSettings, make_study_db

from study.jobs.calibrate import CalibrateSettings, run_calibration
from study.jobs.calibrate.model import (
    SPEED_CLIP,
    Proposal,
    base_values,
    block_log_ratios,
    population_with,
)
from study.jobs.synth import run_synthetic_study
from study.participants.population import Population
from study.participants.population_file import load_population

# two modes on the practice course, NASA-TLX after each: about 1 s of CPU a participant
SMALL = """
[study]
name = "small-calibrate"
participants = 2
seed = 5

[modes]
names = ["manual", "reactive_bn"]
counterbalancing = "full_permutation"

[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false
timeout_s = 90.0

[phases.after_trial]
instrument = "nasa_tlx"
weights = "raw"

[analysis]
metrics = ["completion_time_s", "collisions", "score_s", "tlx_raw"]
"""

# the cluttered room from A to B with the secondary task and its baseline: every block
FULL = (
    SMALL.replace('name = "small-calibrate"', 'name = "full-calibrate"')
    .replace("timeout_s = 90.0", "timeout_s = 400.0")
    .replace(
        """[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false""",
        """[[phases]]
kind = "baseline"
questions = 8

[[phases]]
kind = "main"
scenario = "cluttered_room"
route = ["A", "B"]
inspection = false
secondary = true
block_size = 5""",
    )
    .replace(
        '"tlx_raw"]',
        '"secondary_answer_time_s", "secondary_errors", "tlx_raw"]\n'
        "secondary_baseline_level = true",
    )
)

TRUE = dataclasses.replace(
    Population(), speed_median=0.36, speed_sigma=0.25, speed_range=SPEED_CLIP,
    answer_time_median_s=2.5, slowdown_range=(1.35, 1.85),
    tlx_bias_mean=8.0, tlx_bias_sd=12.0,
)  # fmt: skip
TRUE_VALUES = {**base_values(TRUE), "slowdown_mid": 1.6}


def test_importance_weights_turn_the_proposal_into_the_population(rng):
    """The bank's weighted values have the candidate population's distribution: means and
    the clip bounds' masses agree within Monte Carlo error (4 standard errors)."""
    blocks = ("speed", "answer", "tlx")
    base, n = Population(), 6000
    people = [Proposal(blocks).draw(base.sample(rng), rng) for _ in range(n)]
    fields = ("preferred_speed", "answer_time_s", "dual_task_slowdown", "tlx_bias")
    values = {f: np.array([getattr(p, f) for p in people]) for f in fields}
    ratios = block_log_ratios(values, TRUE_VALUES)
    target = population_with(base, blocks, TRUE_VALUES)
    direct = [target.sample(rng) for _ in range(n)]
    for field, block in zip(fields, ("speed", "answer", "answer", "tlx"), strict=True):
        w = np.exp(ratios[block] - ratios[block].max())
        w /= w.sum()
        x, y = values[field], np.array([getattr(p, field) for p in direct])
        mean = float(w @ x)
        se = np.sqrt(float(w @ w) * np.var(x) + np.var(y) / n)
        assert abs(mean - y.mean()) < 4 * se, (field, mean, y.mean(), se)
    w = np.exp(ratios["speed"] - ratios["speed"].max())
    at_low = np.isclose(values["preferred_speed"], SPEED_CLIP[0])
    share = float(w[at_low].sum() / w.sum())
    direct_share = np.mean([p.preferred_speed == SPEED_CLIP[0] for p in direct])
    assert abs(share - direct_share) < 0.02


def _study(folder: Path, text: str, participants: int, seed: int) -> Path:
    (folder / "protocol.toml").write_text(text)
    db = folder / "target.db"
    run_synthetic_study(
        str(folder / "protocol.toml"), db, participants=participants, seed=seed, workers=2,
        record=False, population=TRUE,
    )  # fmt: skip
    return db


def _recovered(summary, fitted: set[str], informative: set[str]) -> None:
    """Every fitted parameter's true value inside its interval; the ``informative`` ones'
    intervals narrower than 0.8 of their search range (an interval that covers everything
    recovers nothing)."""
    params = {p["name"]: p for p in summary.result["parameters"]}
    assert set(params) == fitted
    for name, p in params.items():
        truth = TRUE_VALUES[name]
        assert p["low"] <= truth <= p["high"], (name, truth, p)
        if name in informative:
            assert p["high"] - p["low"] < 0.8 * (p["search"][1] - p["search"][0]), (name, p)


def test_a_known_population_is_recovered_small(tmp_path, seed):
    """12 people and a bank of 40 (about 50 s on two cores): 99 % intervals, so that a
    correct calibration fails this test for few seeds; at this size only the median speed
    is pinned down (docs/results.md has the full recovery at 95 %)."""
    db = _study(tmp_path, SMALL, 12, seed % 10_000)
    out = tmp_path / "population.toml"
    s = CalibrateSettings(bank=40, replicates=30, level=0.99, seed=seed % 10_000, workers=2)
    summary = run_calibration(db, out, s)
    fitted = {"speed_median", "speed_sigma", "tlx_bias_mean", "tlx_bias_sd"}
    _recovered(summary, fitted, {"speed_median"})
    loaded = load_population(out)
    assert loaded.speed_range == SPEED_CLIP
    for f in dataclasses.fields(Population):  # the file keeps 6 decimals
        assert np.allclose(getattr(loaded, f.name), getattr(summary.population, f.name), atol=1e-6)
    assert "[calibration]" in out.read_text() and str(db) in out.read_text()
    assert summary.html == tmp_path / "population.html"
    assert "speed_sigma" in summary.html.read_text()
    moments = json.loads(out.with_suffix(".json").read_text())["moments"]
    names = {m["moment"] for m in moments}
    assert "completion_time_s: corr manual~reactive_bn" in names
    assert all(m["target"] is None or m["se"] is not None for m in moments)


@pytest.mark.slow
def test_a_known_population_is_recovered_full(tmp_path, seed):
    db = _study(tmp_path, FULL, 24, seed % 10_000)
    s = CalibrateSettings(bank=200, replicates=60, level=0.99, seed=seed % 10_000, workers=2)
    summary = run_calibration(db, tmp_path / "population.toml", s)
    fitted = {
        "speed_median", "speed_sigma", "answer_time_median_s", "slowdown_mid",
        "tlx_bias_mean", "tlx_bias_sd",
    }  # fmt: skip
    _recovered(summary, fitted, {"answer_time_median_s", "slowdown_mid"})


def _bad(capsys, *args):
    code, out, err = asa(capsys, "calibrate", *args)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_bad_studies_are_refused(tmp_path, capsys, rng):
    db = make_study_db(tmp_path / "two.db", rng, settings=FixtureSettings(n_participants=2))
    line = _bad(capsys, "--study", str(db), "--out", str(tmp_path / "p.toml"), "--workers", "1")
    assert str(db) in line and "2 complete participants" in line and "at least 3" in line
    db = make_study_db(tmp_path / "six.db", rng)
    import sqlite3

    with sqlite3.connect(db) as conn:
        conn.execute("UPDATE trial SET completion_time_s = NULL")
    line = _bad(capsys, "--study", str(db), "--workers", "1")
    assert str(db) in line and "completion_time_s" in line and "no values" in line
    missing = tmp_path / "none.db"
    assert str(missing) in _bad(capsys, "--study", str(missing))
    assert "--bank" in _bad(capsys, "--study", str(db), "--bank", "3")
    assert "--level" in _bad(capsys, "--study", str(db), "--level", "1.5")
