"""The ``map_semantics`` benchmark group (issue 23): passage agreement counts, the
noisy-map copy of a scene, and one generated scene driven with both semantics (slow)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from sim.occupancy import OccupancyGrid, build_grid
from sim.scenario import load_scenario
from study.bench.budgets import check_budgets
from study.bench.map_semantics import _rates, _with_noisy_map, agreement, drive_both


def test_agreement_counts_matches_extras_and_misses():
    sc = load_scenario("demo_doorway_crossing")
    exact = agreement(sc, build_grid(sc))
    assert exact == {"found": 2, "extra": 0, "missed": 0, "same_kind": 2}
    grid = build_grid(sc)
    blank = OccupancyGrid(np.zeros_like(grid.occupied), grid.origin, grid.resolution)
    assert agreement(sc, blank) == {"found": 0, "extra": 0, "missed": 2, "same_kind": 0}
    rates = _rates({"found": 9, "extra": 1, "missed": 3, "same_kind": 9})
    assert rates["precision"] == 0.9 and rates["recall"] == 0.75


def test_noisy_copy_reads_its_map(tmp_path):
    src = tmp_path / "scene.toml"
    src.write_text(Path(load_scenario("practice_course").source).read_text())
    copy = _with_noisy_map(src, 3)
    sc = load_scenario(copy)
    assert sc.semantics.source == "map" and sc.semantics.map_file == "map.yaml"
    assert sc.semantics.map_grid.occupied.shape == build_grid(sc).occupied.shape
    assert not np.array_equal(sc.semantics.map_grid.occupied, build_grid(sc).occupied)


def test_budgets_read_the_figures():
    figures = {
        "map_passage_precision_min": 0.93,
        "map_passage_recall_min": 0.85,
        "map_task_match_gap": 0.02,
    }
    met = {k: v["met"] for k, v in check_budgets(figures, ["map_semantics"]).items()}
    assert met == {
        "map_passage_precision_min": True,
        "map_passage_recall_min": False,
        "map_task_match_gap": True,
    }


@pytest.mark.slow
def test_one_scene_driven_with_both_semantics():
    row = drive_both(100)
    for source in ("geometry", "map"):
        assert row[source]["completed"]
        rec = row[source]["recognition"]
        assert rec is not None and sum(c["labelled_ticks"] for c in rec["per_task"].values()) > 0
