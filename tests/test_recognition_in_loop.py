"""In-the-loop recognition: the tally of recognised against true intention, the contextual
task a primitive performs on a component, and the trial outcome that carries both."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from autonomy.task_types import KIND_TASK, MOTION_TASK, TASK_TYPES, contextual_task
from study.engine.recognition import RecognitionTally
from tasks.contextual import TARGET_KIND
from tasks.contextual import TASK_TYPES as ALL_TASKS
from tests.cli_helpers import asa


def test_every_named_task_targets_the_kind_that_names_it():
    assert set(TASK_TYPES) <= set(ALL_TASKS)
    for kind, task in KIND_TASK.items():
        assert TARGET_KIND[task] == kind
    for (kind, _motion), task in MOTION_TASK.items():
        assert TARGET_KIND[task] == kind


@pytest.mark.parametrize("motion", ["doorway_crossing", "object_inspection", "wall_following", ""])
def test_the_component_kind_names_the_task_and_the_motion_splits_objects(motion):
    assert contextual_task("gap", motion) == "gap_crossing"
    assert contextual_task("dock", motion) == "robot_docking"
    expected = "object_inspection" if motion == "object_inspection" else "object_bypass"
    assert contextual_task("object", motion) == expected
    assert contextual_task("unknown_kind", motion) == ""


def _random_rows(rng: np.random.Generator, n: int) -> list[tuple[str, str, str, str]]:
    tasks = ["a", "b", ""]
    targets = ["x", "y"]
    return [
        (
            str(rng.choice(["la", "lb", "", "other"])),
            str(rng.choice(targets)),
            str(rng.choice(tasks)),
            str(rng.choice(targets)),
        )
        for _ in range(n)
    ]


def test_tally_counts_agree_with_a_direct_count(rng):
    table = {"la": "a", "lb": "b"}
    rows = _random_rows(rng, 400)
    s = RecognitionTally(table).add_rows(rows).summary()
    labelled = [r for r in rows if r[2]]
    task = [table.get(r[0], "") == r[2] for r in labelled]
    both = [t and r[1] == r[3] for t, r in zip(task, labelled, strict=True)]
    null = [table.get(r[0], "") == "" for r in labelled]
    assert s["labelled_ticks"] == len(labelled)
    assert s["loop_task_match"] == round(sum(task) / len(labelled), 4)
    assert s["loop_task_target_match"] == round(sum(both) / len(labelled), 4)
    assert s["loop_null_rate"] == round(sum(null) / len(labelled), 4)
    assert sum(c["labelled_ticks"] for c in s["per_task"].values()) == len(labelled)
    assert s["loop_task_target_match"] <= s["loop_task_match"] <= 1 - s["loop_null_rate"]


def test_tally_survives_its_summary_and_merges_additively(rng):
    table = {"la": "a", "lb": "b"}
    rows = _random_rows(rng, 300)
    whole = RecognitionTally(table).add_rows(rows).summary()
    halves = RecognitionTally(table).add_rows(rows[:120])
    halves.merge(
        RecognitionTally.from_summary(RecognitionTally(table).add_rows(rows[120:]).summary())
    )
    merged = halves.summary()
    # the deciles are per trial (here two trials against one): compared in test_tally_assist
    assert {k: v for k, v in merged.items() if k != "deciles"} == {
        k: v for k, v in whole.items() if k != "deciles"
    }


def test_an_empty_tally_has_no_shares():
    s = RecognitionTally({"la": "a"}).add_rows([("la", "x", "", "")]).summary()
    assert s["labelled_ticks"] == 0 and s["loop_task_match"] is None and s["per_task"] == {}


def test_a_contextual_trial_with_a_synthetic_driver_stores_its_recognition(tmp_path, rng):
    from study.engine.standalone import standalone_trial
    from study.participants.synthetic import synthetic_participant

    result, engine = standalone_trial(
        tmp_path, synthetic_participant(rng), mode="contextual_task", timeout_s=25.0
    )
    engine.dispose()
    rec = result.outcome["recognition"]
    assert rec["labelled_ticks"] > 0
    assert set(rec["per_task"]) <= set(ALL_TASKS)
    assert 0.0 <= rec["loop_task_target_match"] <= rec["loop_task_match"] <= 1.0
    assert set(result.outcome["label_tasks"]) <= set(ALL_TASKS)
    # the assistance measures of issue 40, scored on every tick of the trial
    assist = rec["assist"]
    assert assist["ticks"] == result.outcome["ticks"]
    assert assist["seconds"] == pytest.approx(result.outcome["duration_s"], abs=1e-6)
    assert sum(d["labelled_ticks"] for d in rec["deciles"]) == rec["labelled_ticks"]
    assert rec["assist_coverage"] is not None and 0.0 <= rec["assist_coverage"] <= 1.0
    if assist["assist_all_ticks"]:
        assert 0.0 <= rec["assist_precision"] <= 1.0
    assert 0.0 <= rec["confident_wrong_longest_s"] <= rec["confident_wrong_s"]
    assert rec["confident_wrong_s_per_min"] >= 0.0
    # the model named by its file and content, not by the path on this machine
    model = Path(result.outcome["mode_settings"]["model_path"])
    digest = hashlib.sha256(model.read_bytes()).hexdigest()
    assert result.outcome["model"] == {"file": model.name, "sha256": digest}


def test_a_manual_trial_scores_no_recognition(tmp_path, rng):
    from study.engine.standalone import standalone_trial
    from study.participants.synthetic import synthetic_participant

    result, engine = standalone_trial(
        tmp_path, synthetic_participant(rng), mode="reactive_bn", timeout_s=5.0
    )
    engine.dispose()
    assert "recognition" not in result.outcome and "label_tasks" not in result.outcome


def test_the_recognition_bench_pools_its_scenes_and_checks_the_aims():
    from study.bench.budgets import check_budgets
    from study.bench.recognition import drivable_scenes, run

    assert {"cluttered_room", "demo_docking"} <= set(drivable_scenes())
    figures = run(quick=True, scenes=["demo_docking"], generated=(0,))
    assert figures["recognition_scenes"] == ["demo_docking", "generated_0"]
    scenes = figures["loop_per_scene"]
    assert all(s["labelled_ticks"] > 0 for s in scenes.values())
    assert figures["loop_shipped"]["labelled_ticks"] == scenes["demo_docking"]["labelled_ticks"]
    assert figures["loop_generated"]["labelled_ticks"] == scenes["generated_0"]["labelled_ticks"]
    total = sum(s["labelled_ticks"] for s in scenes.values())
    assert figures["labelled_ticks"] == total
    assert sum(c["labelled_ticks"] for c in figures["loop_per_task"].values()) == total
    assert 0.0 <= figures["loop_task_target_match"] <= figures["loop_task_match"] <= 1.0
    budgets = check_budgets(figures, ["recognition"])
    assert {b["value"] for b in budgets.values()} >= {figures["loop_task_match"]}
    # issue 40's aims: five budgets, the assistance figures pooled and per decile
    assert set(budgets) == {
        "loop_task_match",
        "loop_task_target_match",
        "assist_precision",
        "assist_coverage",
        "confident_wrong_s_per_min",
    }
    assert budgets["confident_wrong_s_per_min"]["op"] == "<="
    assert 0.0 <= figures["assist_coverage"] <= 1.0
    assert figures["confident_wrong_s_per_min"] >= 0.0
    assert len(figures["loop_deciles"]) == 10
    assert sum(d["labelled_ticks"] for d in figures["loop_deciles"]) == total
    assert "recognition_compare" not in figures


def test_the_recognition_bench_measures_other_settings_beside_the_default():
    from study.bench.recognition import run

    few = {"candidates": 2}  # a setting every contextual mode has; a recogniser's alike
    figures = run(quick=True, scenes=["demo_docking"], generated=(), compare={"few": few})
    both = figures["recognition_compare"]
    assert set(both) == {"default", "few"}
    assert both["default"]["loop_task_match"] == figures["loop_task_match"]
    # the same drivers and scenes: the labelled ticks differ only by how the runs drove
    assert both["few"]["labelled_ticks"] > 0
    for run_ in both.values():
        assert sum(d["labelled_ticks"] for d in run_["deciles"]) == run_["labelled_ticks"]
    assert figures["recognition_scenes"] == ["demo_docking"]


@pytest.mark.parametrize(
    ("text", "seeds"),
    [("20-29", tuple(range(20, 30))), ("0,3,5", (0, 3, 5)), ("0-2,7", (0, 1, 2, 7)), ("4", (4,))],
)
def test_generated_seeds_are_read_as_ranges_and_lists(text, seeds):
    from study.cli.bench import parse_seeds

    assert parse_seeds(text) == seeds


@pytest.mark.parametrize("text", ["", "a", "3-1", "-2", "1-", "1,,2"])
def test_bad_generated_seeds_are_refused_in_one_line(capsys, text):
    code, out, err = asa(capsys, "bench", "--only", "recognition", f"--generated-seeds={text}")
    assert code == 2 and out == ""
    assert f"--generated-seeds: generated seeds {text!r}" in err
    assert len(err.strip().splitlines()) == 1


def test_recognition_options_without_the_recognition_group_are_refused(capsys):
    code, _, err = asa(capsys, "bench", "--only", "sim", "--generated-seeds", "20-29")
    assert code == 2 and "apply to group recognition" in err
