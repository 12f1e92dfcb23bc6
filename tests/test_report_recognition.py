"""In-the-loop recognition in the report and in the pilot's sanity summary (issue 16).

A small real synthetic study (manual and the contextual-task mode, two participants) gives
a report whose "Recognition in the loop" section, results.json ``recognition`` and the two
CSV tables equal the session engine's own tally (``study.engine.recognition``) recomputed
from the sample table; the same database with the stored recognition removed gives the
same figures from the samples; a database of the older kind (primitive labels, no stored
recognition: tests/fixtures_db.py) is scored from its samples; recognition never reaches
the ANOVA; human participants are not scored.
"""

from __future__ import annotations

import json
import os
import shutil
import sqlite3
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.data import load_study, tidy
from analysis.data.assistance import assistance
from analysis.data.recognition import COUNTS, recognition_counts, sample_counts
from analysis.recognition import describe
from analysis.report import build_report
from study.data.dbtools import export
from study.engine.recognition import RecognitionTally
from study.jobs.synth import format_summary, run_synthetic_study, sanity_summary

sys.path.insert(0, str(Path(__file__).parent))
from fixtures_db import FixtureSettings, make_study_db  # noqa: E402

TINY = """
# one short main trial per mode in the practice course (about 20 s for two participants)
[study]
name = "tiny-recognition"
participants = 2
seed = 5

[modes]
names = ["manual", "contextual_task"]
counterbalancing = "full_permutation"

[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false
timeout_s = 90.0
"""

SHARES = {
    "loop_task_match": "task_matches",
    "loop_task_target_match": "task_target_matches",
    "loop_null_rate": "null_ticks",
}


def _seed() -> int:
    return int(os.environ.get("ASA_TEST_SEED", "20261123"))


@pytest.fixture(scope="module")
def real_db(tmp_path_factory) -> Path:
    folder = tmp_path_factory.mktemp("real")
    proto = folder / "tiny.toml"
    proto.write_text(TINY)
    db = folder / "tiny.db"
    run_synthetic_study(str(proto), db, participants=2, seed=_seed() % 100_000, workers=1)
    return db


@pytest.fixture(scope="module")
def real_report(real_db, tmp_path_factory):
    out = tmp_path_factory.mktemp("real_report")
    return build_report(real_db, out), out


def _tallies(db: Path) -> dict[int, tuple[str, RecognitionTally]]:
    """Per main trial with ``label_tasks``: (mode, the engine's tally of its sample rows),
    read with sqlite3, not the analysis reader."""
    with sqlite3.connect(db) as con:
        trials = con.execute(
            "select id, mode, outcome from trial where phase = 'main' and status = 'completed'"
        ).fetchall()
        out = {}
        for tid, mode, outcome in trials:
            table = json.loads(outcome).get("label_tasks")
            if table is None:
                continue
            rows = con.execute(
                "select label, target, true_task, true_target from sample where trial_id = ? "
                "order by tick",
                (tid,),
            ).fetchall()
            out[tid] = (mode, RecognitionTally(table).add_rows(rows))
    return out


def _pooled(tallies, mode: str) -> dict:
    pooled = RecognitionTally({})
    for m, tally in tallies.values():
        if m == mode:
            pooled.merge(tally)
    return pooled.summary()


def _counts(summary: dict) -> dict:
    return {k: summary[k] for k in COUNTS}


def test_the_section_the_json_and_the_tables(real_db, real_report):
    paths, out = real_report
    results = json.loads(paths.results_json.read_text())
    rec = results["recognition"]
    assert list(rec) == ["contextual_task"]  # manual recognises nothing
    # described, never tested: no ANOVA of the recognition metric anywhere
    assert "recognition_accuracy" not in results and "recognition_accuracy" not in paths.metrics
    summary = pd.read_csv(out / "tables" / "summary.csv")
    assert "recognition_accuracy" not in set(summary["metric"])
    html = paths.html.read_text(encoding="utf-8")
    assert 'id="recognition"' in html and "Recognition in the loop" in html
    assert "recognition_accuracy" not in html.split('id="recognition"')[0]  # no metric section
    d = rec["contextual_task"]
    for task in d["per_task"]:
        assert f"<td>{task}</td>" in html
    per_mode = pd.read_csv(out / "tables" / "recognition.csv")
    per_task = pd.read_csv(out / "tables" / "recognition_per_task.csv")
    assert per_mode["mode"].tolist() == ["contextual_task"]
    row = per_mode.iloc[0]
    for key in (*COUNTS, *SHARES):
        assert row[key] == pytest.approx(d[key])
    assert sorted(per_task["task"]) == sorted(d["per_task"])
    assert per_task["labelled_ticks"].sum() == d["labelled_ticks"]


def test_pooled_figures_equal_the_engine_tally_of_the_sample_table(real_db, real_report):
    paths, _ = real_report
    d = json.loads(paths.results_json.read_text())["recognition"]["contextual_task"]
    tallies = _tallies(real_db)
    truth = _pooled(tallies, "contextual_task")
    assert truth["labelled_ticks"] > 0
    assert _counts(d) == _counts(truth)
    for share, count in SHARES.items():
        assert d[share] == pytest.approx(truth[count] / truth["labelled_ticks"])
        assert d[share] == pytest.approx(truth[share], abs=5e-5)  # the tally rounds to 4
    assert {t: _counts(c) for t, c in d["per_task"].items()} == {
        t: _counts(c) for t, c in truth["per_task"].items()
    }
    # mean and SD over trials of each trial's own share
    per_trial = [t.summary() for m, t in tallies.values() if m == "contextual_task"]
    assert d["trials"] == len(per_trial) == 2
    for share, count in SHARES.items():
        values = [s[count] / s["labelled_ticks"] for s in per_trial]
        assert d["per_trial"][share]["mean"] == pytest.approx(np.mean(values))
        assert d["per_trial"][share]["sd"] == pytest.approx(np.std(values, ddof=1))
    # ... and what the session engine stored in each trial's outcome
    with sqlite3.connect(real_db) as con:
        stored = [
            json.loads(o)["recognition"]
            for (o,) in con.execute("select outcome from trial where mode = 'contextual_task'")
        ]
    assert d["sources"] == {"outcome": len(stored)}
    merged = RecognitionTally({})
    for s in stored:
        merged.merge(RecognitionTally.from_summary(s))
    assert _counts(merged.summary()) == _counts(truth)


def _assist_tallies(db: Path) -> dict[int, RecognitionTally]:
    """Per contextual main trial: the engine's tally of its samples with their blend
    weights, at the tick of the samples' simulated time."""
    with sqlite3.connect(db) as con:
        trials = con.execute(
            "select id, outcome from trial where phase = 'main' and status = 'completed' "
            "and mode = 'contextual_task'"
        ).fetchall()
        out = {}
        for tid, outcome in trials:
            rows = con.execute(
                "select label, target, true_task, true_target, beta, t from sample "
                "where trial_id = ? order by tick",
                (tid,),
            ).fetchall()
            dt = rows[0][5]  # the first tick ends at t = dt
            tally = RecognitionTally(json.loads(outcome)["label_tasks"], dt_s=dt)
            out[tid] = tally.add_rows(r[:5] for r in rows)
    return out


def test_the_assistance_measures_equal_the_engine_tally_of_the_samples(real_db, real_report):
    paths, out = real_report
    d = json.loads(paths.results_json.read_text())["recognition"]["contextual_task"]
    tallies = _assist_tallies(real_db)
    pooled = RecognitionTally({})
    for tally in tallies.values():
        pooled.merge(tally)
    truth = pooled.summary()
    assert d["assist_trials"] == len(tallies) == 2
    a = truth["assist"]
    if a["assist_all_ticks"]:
        assert d["assist_precision"] == pytest.approx(
            a["assist_correct_ticks"] / a["assist_all_ticks"]
        )
    else:  # nothing assisted: undefined
        assert d["assist_precision"] is None
    assert d["assist_coverage"] == pytest.approx(
        a["assist_covered_ticks"] / a["assist_labelled_ticks"]
    )
    assert d["assist_unlabelled_ticks"] == a["assist_unlabelled_ticks"]
    # seconds: the tally sums the tick, the samples' times telescope (float rounding only)
    assert d["confident_wrong_s_per_min"] == pytest.approx(
        60 * a["confident_wrong_s"] / a["seconds"], abs=1e-6
    )
    assert d["confident_wrong_longest_s"] == pytest.approx(a["confident_wrong_longest_s"])
    assert [c["labelled_ticks"] for c in d["deciles"]] == [
        c["labelled_ticks"] for c in truth["deciles"]
    ]
    assert [c["task_target_matches"] for c in d["deciles"]] == [
        c["task_target_matches"] for c in truth["deciles"]
    ]
    for task, c in d["per_task"].items():
        assert c["assist_ticks"] == truth["per_task"][task]["assist_ticks"]
        assert c["confident_wrong_ticks"] == truth["per_task"][task]["confident_wrong_ticks"]
    # the tables carry them
    per_mode = pd.read_csv(out / "tables" / "recognition.csv").iloc[0]
    assert per_mode["assist_coverage"] == pytest.approx(d["assist_coverage"])
    deciles = pd.read_csv(out / "tables" / "recognition_deciles.csv")
    assert deciles["decile"].tolist() == list(range(1, 11))
    assert deciles["labelled_ticks"].sum() == d["labelled_ticks"]
    html = paths.html.read_text(encoding="utf-8")
    assert "assist precision" in html and "per decile of each trial" in html


def test_without_the_stored_recognition_the_samples_give_the_same_numbers(
    real_db, real_report, tmp_path
):
    paths, _ = real_report
    old = tmp_path / "old.db"
    shutil.copy(real_db, old)
    with sqlite3.connect(old) as con:
        con.execute("update trial set outcome = json_remove(outcome, '$.recognition')")
        assert not con.execute(
            "select count(*) from trial where json_extract(outcome, '$.recognition') is not null"
        ).fetchone()[0]
    again = build_report(old, tmp_path / "report")
    new = json.loads(paths.results_json.read_text())["recognition"]
    fallback = json.loads(again.results_json.read_text())["recognition"]
    assert fallback["contextual_task"]["sources"] == {"samples": 2}
    for d in (new, fallback):
        d["contextual_task"].pop("sources")
    assert fallback == new
    # the per-trial metric and the pilot's summary agree too
    a, b = tidy(load_study(real_db)).trials, tidy(load_study(old)).trials
    pd.testing.assert_series_equal(a["recognition_accuracy"], b["recognition_accuracy"])
    assert sanity_summary(old) == sanity_summary(real_db)


def test_the_csv_export_gives_the_same_recognition(real_db, real_report, tmp_path):
    paths, _ = real_report
    export(real_db, tmp_path / "csv")
    stored = json.loads(paths.results_json.read_text())["recognition"]
    assert describe(tidy(load_study(tmp_path / "csv"))) == stored


def test_the_sanity_summary_pools_the_stored_counts(real_db):
    summary = sanity_summary(real_db)
    truth = _pooled(_tallies(real_db), "contextual_task")
    e = summary["contextual_task"]
    n = truth["labelled_ticks"]
    assert e["labelled_ticks"] == n
    assert e["task_match"] == pytest.approx(truth["task_matches"] / n)
    assert e["recognition_match"] == pytest.approx(truth["task_target_matches"] / n)
    assert e["null_rate"] == pytest.approx(truth["null_ticks"] / n)
    assert "labelled_ticks" not in summary["manual"]
    line = next(x for x in format_summary(summary) if "contextual_task" in x)
    assert f"nothing recognised {e['null_rate']:.1%}" in line and f"of {n} labelled" in line


def test_an_older_database_is_scored_from_its_samples_and_label_tasks(tmp_path, seed):
    settings = FixtureSettings(n_participants=3, samples=60, questions=4, baseline_questions=4)
    db = make_study_db(tmp_path / "fx.db", np.random.default_rng(seed), settings=settings)
    frames = tidy(load_study(db))
    rec = describe(frames)
    assert list(rec) == ["contextual_task"]  # the reactive mode's situations are not scored
    d = rec["contextual_task"]
    counted = set(frames.trials["trial_id"])
    tallies = {k: v for k, v in _tallies(db).items() if k in counted}
    truth = _pooled(tallies, "contextual_task")
    assert d["sources"] == {"samples": len(tallies)}
    assert _counts(d) == _counts(truth)
    # the fixture's wrong recognitions name another primitive, never nothing
    assert d["null_ticks"] == 0 < d["task_matches"] < d["labelled_ticks"]
    accuracy = frames.trials.set_index("trial_id")["recognition_accuracy"]
    for tid, (_, tally) in tallies.items():
        s = tally.summary()
        assert accuracy[tid] == pytest.approx(s["task_target_matches"] / s["labelled_ticks"])
    assert accuracy[frames.trials.set_index("trial_id")["mode"] != "contextual_task"].isna().all()


def test_human_participants_are_not_scored(tmp_path, seed):
    settings = FixtureSettings(
        n_participants=2, samples=40, questions=4, baseline_questions=4, kind="human"
    )
    db = make_study_db(tmp_path / "h.db", np.random.default_rng(seed), settings=settings)
    paths = build_report(db, tmp_path / "report", metrics=("collisions", "recognition_accuracy"))
    assert json.loads(paths.results_json.read_text())["recognition"] == {}
    assert "No trial has recognition data" in paths.html.read_text(encoding="utf-8")
    assert tidy(load_study(db)).trials["recognition_accuracy"].isna().all()
    assert "labelled_ticks" not in sanity_summary(db)["contextual_task"]


def _random_samples(rng: np.random.Generator, n: int) -> pd.DataFrame:
    return pd.DataFrame(
        {
            "trial_id": rng.choice([1, 2, 3], n),
            "label": rng.choice(["la", "lb", "", "other"], n),
            "target": rng.choice(["x", "y", ""], n),
            "true_task": rng.choice(["a", "b", ""], n),
            "true_target": rng.choice(["x", "y"], n),
        }
    )


def test_sample_counts_equal_the_engine_tally_for_any_rows(rng):
    samples = _random_samples(rng, 600)
    tables = {1: {"la": "a", "lb": "b"}, 2: {"la": "b"}}  # trial 3: a mode without tasks
    counts = sample_counts(samples, tables)
    assert set(counts["trial_id"]) <= {1, 2}
    assert (counts["source"] == "samples").all()
    for tid, table in tables.items():
        rows = samples[samples["trial_id"] == tid][["label", "target", "true_task", "true_target"]]
        truth = RecognitionTally(table).add_rows(rows.itertuples(index=False)).summary()
        mine = counts[counts["trial_id"] == tid].set_index("task")
        assert {t: _counts(c) for t, c in truth["per_task"].items()} == {
            t: {k: int(mine.loc[t, k]) for k in COUNTS} for t in mine.index
        }


def test_assistance_from_samples_equals_the_engine_tally_for_any_rows(rng):
    n = 900
    samples = _random_samples(rng, n).assign(
        beta=rng.choice([0.0, 0.2, 0.5, 0.9, 1.0], n), tick=np.arange(n)
    )
    samples["true_target"] = samples["true_target"].where(samples["true_task"] != "", "")
    samples["t"] = 0.05 * (samples.groupby("trial_id").cumcount() + 1)
    tables = {1: {"la": "a", "lb": "b"}, 2: {"la": "b"}}
    outcomes = [{"label_tasks": tables[1]}, {"label_tasks": tables[2]}, {}]
    got = assistance([1, 2, 3], outcomes, samples)
    assert set(got.per_trial["trial_id"]) == {1, 2}
    assert (got.per_trial["source"] == "samples").all()
    for tid, table in tables.items():
        rows = samples[samples["trial_id"] == tid]
        cols = ["label", "target", "true_task", "true_target", "beta"]
        truth = RecognitionTally(table, dt_s=0.05).add_rows(rows[cols].itertuples(index=False))
        s = truth.summary()
        mine = got.per_trial[got.per_trial["trial_id"] == tid].iloc[0]
        for k, v in s["assist"].items():
            assert mine[k] == pytest.approx(v, abs=1e-6), k
        deciles = got.deciles[got.deciles["trial_id"] == tid].sort_values("decile")
        for k in ("labelled_ticks", "task_matches", "task_target_matches", "assist_ticks"):
            assert deciles[k].tolist() == [d[k] for d in s["deciles"]], k
        tasks = got.per_task[got.per_task["trial_id"] == tid].set_index("task")
        for task, c in s["per_task"].items():
            for k in ("assist_ticks", "assist_correct_ticks", "confident_wrong_ticks"):
                assert tasks.loc[task, k] == c[k], (task, k)


def test_a_malformed_stored_assistance_names_the_trial_and_field(seed):
    rec = {"per_task": {}, "assist": {"ticks": 3, "seconds": "soon"}}
    with pytest.raises(
        ValueError, match=r"lab\.db: trial 4: field 'outcome\.recognition\.assist\."
    ):
        assistance(
            [4],
            [{"recognition": rec}],
            _random_samples(np.random.default_rng(seed), 5),
            source="lab.db",
        )


def test_a_malformed_stored_recognition_names_the_trial(tmp_path, seed):
    with pytest.raises(ValueError, match=r"study: trial 7: field 'outcome.recognition.per_task.a'"):
        recognition_counts(
            [7],
            [{"recognition": {"per_task": {"a": {"labelled_ticks": 2}}}}],
            _random_samples(np.random.default_rng(seed), 5),
        )
    settings = replace(FixtureSettings(), n_participants=1, samples=20, incomplete=False)
    db = make_study_db(tmp_path / "bad.db", np.random.default_rng(seed), settings=settings)
    with sqlite3.connect(db) as con:
        con.execute(
            "update trial set outcome = json_set(outcome, '$.recognition', json('{}')) "
            "where mode = 'contextual_task'"
        )
    with pytest.raises(ValueError, match=r"bad\.db: trial \d+: field 'outcome\.recognition"):
        tidy(load_study(db))
