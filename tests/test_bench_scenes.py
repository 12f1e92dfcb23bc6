"""The ``scenes`` benchmark group (issue 17): its summary of per-scene rows (default run)
and one generated scene driven in every mode (slow)."""

from __future__ import annotations

import pytest

from study.bench.budgets import check_budgets
from study.bench.scenes import MODES, _summary, run


def _trial(completed: bool, collisions: int, rec: dict | None = None) -> dict:
    return {
        "completed": completed,
        "timed_out": not completed,
        "collisions": collisions,
        "completion_time_s": 100.0 if completed else 600.0,
        "recognition": rec,
    }


def _rec(ticks: int, task: int, both: int) -> dict:
    counts = dict(labelled_ticks=ticks, task_matches=task, task_target_matches=both)
    return {"per_task": {"doorway_crossing": {**counts, "null_ticks": 0}}}


def test_summary_counts_modes_failures_and_rejects():
    rows = [
        {
            "seed": 0,
            "problems": [],
            "manual": _trial(True, 2),
            "reactive_bn": _trial(True, 0),
            "contextual_task": _trial(True, 1, _rec(100, 80, 60)),
        },
        {
            "seed": 1,
            "problems": ["g1.toml: table: too low"],
            "manual": _trial(False, 4),
            "reactive_bn": _trial(True, 0),
            "contextual_task": _trial(True, 0, _rec(50, 20, 10)),
        },
    ]
    f = _summary(rows)
    assert f["scene_checker_rejects"] == 1 and f["scene_problems"] == ["g1.toml: table: too low"]
    assert f["scene_completion_rate"] == {"manual": 0.5, "reactive_bn": 1.0, "contextual_task": 1.0}
    assert f["scene_completion_min"] == 0.5
    assert f["scene_collisions_mean"]["manual"] == 3.0
    assert f["scene_collisions_ratio"] == pytest.approx(0.5 / 3.0, abs=1e-4)
    assert f["scene_timeouts"] == {"manual": 1, "reactive_bn": 0, "contextual_task": 0}
    assert f["scene_failures"] == ["1/manual"]
    assert f["scene_task_match"] == pytest.approx(100 / 150, abs=1e-4)
    assert f["scene_recognition_match"] == pytest.approx(70 / 150, abs=1e-4)
    met = {k: v["met"] for k, v in check_budgets(f, ["scenes"]).items()}
    assert met == {
        "scene_checker_rejects": False,
        "scene_completion_min": False,
        "scene_collisions_ratio": True,
        "scene_task_match": False,
    }


@pytest.mark.slow
def test_one_generated_scene_in_every_mode():
    f = run(quick=True, seeds=(0,), workers=1)
    assert f["scene_seeds"] == [0] and f["scene_checker_rejects"] == 0
    assert set(f["scene_completion_rate"]) == set(MODES)
    assert 0.0 <= f["scene_recognition_match"] <= f["scene_task_match"] <= 1.0


@pytest.mark.slow
@pytest.mark.parametrize("seed", [17, 19])
def test_the_reactive_mode_lets_the_driver_finish_where_it_was_trapped(seed):
    """Generated scenes 17 and 19 timed out in the exclusive reactive mode: the driver,
    backing towards a wall next to the inspection object, could neither back off (OA,
    alpha ~ 0) nor turn (OA scaled the turn too), and insisted on its orbit's exact entry."""
    from study.bench.scenes import scene_trials

    row = scene_trials(seed)
    assert row["reactive_bn"]["completed"] and row["reactive_bn"]["collisions"] == 0
