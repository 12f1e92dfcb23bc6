"""analysis.data and analysis.metrics on a generated study database (tests/fixtures_db.py):
rows and columns of the tidy frames, one trial's metrics recomputed by hand from the raw
rows (sqlite3, not the platform's reader), the generated mode effects, the baseline level,
the CSV export giving the same frames, and the bad-input errors."""

from __future__ import annotations

import json
import os
import sqlite3
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.data import BASELINE, load_study, read_config, tidy
from analysis.metrics import BY_NAME, METRICS, long_frame, ordered_metrics
from study.data.dbtools import export

sys.path.insert(0, str(Path(__file__).parent))
from fixtures_db import MODES, FixtureSettings, make_study_db  # noqa: E402

N = 6
SETTINGS = FixtureSettings(n_participants=N, samples=120)


def _seed() -> int:
    return int(os.environ.get("ASA_TEST_SEED", "20261123"))


@pytest.fixture(scope="module")
def study_db(tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("study") / "study.db"
    return make_study_db(path, np.random.default_rng(_seed()), settings=SETTINGS)


@pytest.fixture(scope="module")
def frames(study_db):
    return tidy(load_study(study_db))


def test_rows_and_columns(study_db, frames):
    t = frames.trials
    # N complete participants x 3 modes, plus the incomplete one's single counted trial
    assert len(t) == N * 3 + 1
    assert t["trial_id"].is_unique
    for metric in METRICS:
        assert metric.name in t.columns
    for col in ("participant", "kind", "mode", "position", "order", "order_index"):
        assert col in t.columns
    assert frames.modes == MODES  # the protocol's order
    assert set(t["position"]) == {0, 1, 2}
    # aborted attempts are not counted but listed
    assert len(frames.aborted) == 2
    assert set(frames.aborted["status"]) == {"aborted"}
    assert (frames.aborted["reason"] == "input lost").all()
    # every question of counted trials and completed baselines, baseline as its own level
    q = frames.questions
    assert (q["mode"] == BASELINE).sum() == (N + 1) * SETTINGS.baseline_questions
    assert (q["mode"] != BASELINE).sum() == len(t) * SETTINGS.questions
    with sqlite3.connect(study_db) as con:
        n_responses = con.execute("select count(*) from response").fetchone()[0]
    assert len(frames.responses) == n_responses
    p = frames.participants
    assert p["complete"].sum() == N and len(p) == N + 1
    # each participant's positions follow their stored order
    for _, row in t.iterrows():
        assert row["order"].split(" > ")[row["position"]] == row["mode"]


def test_one_trial_by_hand(study_db, frames, seed):
    t = frames.trials
    row = t.iloc[np.random.default_rng(seed).integers(len(t))]
    tid = int(row["trial_id"])
    con = sqlite3.connect(study_db)
    try:
        beta, truth, ttarget, label, target, clear = zip(
            *con.execute(
                "select beta, true_task, true_target, label, target, min_clearance_m "
                "from sample where trial_id = ? order by tick",
                (tid,),
            ),
            strict=True,
        )
        time_s, coll, outcome = con.execute(
            "select completion_time_s, collisions, outcome from trial where id = ?", (tid,)
        ).fetchone()
        label_tasks = json.loads(outcome).get("label_tasks")
        qs = con.execute(
            "select correct, answer_time_s, response from question where trial_id = ?", (tid,)
        ).fetchall()
        ratings = dict(
            con.execute(
                "select item, value from response where trial_id = ? and item not like 'pair:%'",
                (tid,),
            ).fetchall()
        )
        picks = [
            r[0]
            for r in con.execute(
                "select text from response where trial_id = ? and item like 'pair:%'", (tid,)
            )
        ]
    finally:
        con.close()
    beta = np.array(beta)
    assert row["assist_share"] == pytest.approx(np.mean(beta > 0.05))
    assert row["beta_mean"] == pytest.approx(beta.mean())
    assert row["clearance_std_m"] == pytest.approx(np.std(clear, ddof=1))
    assert row["score_s"] == pytest.approx(time_s + 60.0 * coll)
    has_truth = [tt != "" for tt in truth]
    hits = [
        h and (label_tasks or {}).get(lb) == tt and tg == tt2
        for h, lb, tt, tg, tt2 in zip(has_truth, label, truth, target, ttarget, strict=True)
    ]
    if label_tasks and any(has_truth):
        assert row["recognition_accuracy"] == pytest.approx(sum(hits) / sum(has_truth))
    else:
        assert np.isnan(row["recognition_accuracy"])
    times = [a for c, a, r in qs if a is not None]
    assert row["secondary_answer_time_s"] == pytest.approx(np.mean(times))
    assert row["secondary_errors"] == sum(1 for c, a, r in qs if not c)
    assert row["secondary_misses"] == sum(1 for c, a, r in qs if r is None)
    assert row["tlx_raw"] == pytest.approx(np.mean(list(ratings.values())))
    weights = {k: picks.count(k) for k in ratings}
    assert sum(weights.values()) == 15
    assert row["tlx_weighted"] == pytest.approx(
        sum(ratings[k] * weights[k] for k in ratings) / 15.0
    )
    for k, v in ratings.items():
        assert row[f"tlx_{k}"] == v


def test_mode_effects_direction(frames):
    means = frames.trials.groupby("mode")[["completion_time_s", "tlx_raw", "assist_share"]].mean()
    m, r, c = MODES
    assert means.loc[m, "completion_time_s"] > means.loc[r, "completion_time_s"]
    assert means.loc[r, "completion_time_s"] > means.loc[c, "completion_time_s"]
    assert means.loc[m, "tlx_raw"] > means.loc[c, "tlx_raw"]
    assert means.loc[m, "assist_share"] == 0.0 < means.loc[r, "assist_share"]
    answer = long_frame(frames, "secondary_answer_time_s").groupby("mode")["value"].mean()
    assert all(answer[BASELINE] < answer[mode] for mode in MODES)


def test_long_frame_levels(frames):
    sec = long_frame(frames, "secondary_errors")
    assert list(dict.fromkeys(sec["mode"])) == [*MODES, BASELINE]
    assert (sec.loc[sec["mode"] == BASELINE, "position"] == -1).all()
    assert list(dict.fromkeys(long_frame(frames, "secondary_errors", baseline=False)["mode"])) == [
        *MODES
    ]
    prim = long_frame(frames, "completion_time_s")
    assert len(prim) == len(frames.trials)
    # manual control recognises nothing: its level is left out
    rec = long_frame(frames, "recognition_accuracy")
    assert "manual" not in set(rec["mode"])
    # the reactive mode's situation labels are no task types: not scored either
    assert set(rec["mode"]) == {"contextual_task"}
    planned = ("tlx_raw", "collisions")
    assert [m.name for m in ordered_metrics(planned)[:2]] == list(planned)
    assert len(ordered_metrics(planned)) == len(METRICS)
    assert BY_NAME["score_s"].group == "primary"


def test_csv_folder_gives_the_same_frames(study_db, frames, tmp_path):
    export(study_db, tmp_path / "csv")
    again = tidy(load_study(tmp_path / "csv"))
    for name in ("trials", "questions", "responses", "participants", "aborted", "recognition"):
        pd.testing.assert_frame_equal(
            getattr(frames, name), getattr(again, name), check_dtype=False, obj=name
        )
    assert again.modes == frames.modes


def test_score_recomputed_with_the_protocol_penalty(study_db, tmp_path):
    copy = tmp_path / "copy.db"
    copy.write_bytes(study_db.read_bytes())
    with sqlite3.connect(copy) as con:
        text = con.execute("select protocol_text from study").fetchone()[0]
        assert "collision_penalty_s = 60.0" in text
        con.execute(
            "update study set protocol_text = ?",
            (text.replace("collision_penalty_s = 60.0", "collision_penalty_s = 25.0"),),
        )
        con.execute("update trial set score = NULL")
    data = load_study(copy)
    assert data.config.collision_penalty_s == 25.0
    t = tidy(data).trials
    np.testing.assert_allclose(t["score_s"], t["completion_time_s"] + 25.0 * t["collisions"])


def test_read_config():
    cfg = read_config("")
    assert (cfg.alpha, cfg.gate, cfg.posthoc, cfg.collision_penalty_s) == (
        0.05,
        "auto",
        "lsd_paired",
        60.0,
    )
    cfg = read_config(
        '[analysis]\nalpha = 0.01\nposthoc = "lsd_pooled"\n[modes]\nnames = ["b", "a"]'
    )
    assert cfg.alpha == 0.01 and cfg.posthoc == "lsd_pooled" and cfg.modes == ("b", "a")
    with pytest.raises(ValueError, match="protocol_text"):
        read_config("[[[", source="x.db")


def test_bad_sources(tmp_path, seed):
    with pytest.raises(FileNotFoundError):
        load_study(tmp_path / "missing.db")
    text = tmp_path / "notes.db"
    text.write_text("hello, not a database\n" * 20)
    with pytest.raises(ValueError, match="notes.db"):
        load_study(text)
    other = tmp_path / "other.db"
    with sqlite3.connect(other) as con:
        con.execute("create table things (id integer primary key)")
    with pytest.raises(ValueError, match="not an asa-study database"):
        load_study(other)
    (tmp_path / "folder").mkdir()
    with pytest.raises(ValueError, match="study.csv is missing"):
        load_study(tmp_path / "folder")
    # no completed main trial
    empty = make_study_db(
        tmp_path / "tiny.db",
        np.random.default_rng(seed),
        settings=replace(SETTINGS, n_participants=1, samples=20, aborted_retry=False),
    )
    with sqlite3.connect(empty) as con:
        con.execute("update trial set status = 'aborted' where phase = 'main'")
    with pytest.raises(ValueError, match="no completed main trial"):
        tidy(load_study(empty))
