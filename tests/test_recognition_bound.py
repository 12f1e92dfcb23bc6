"""docs/experiments/recognition_bound.py runs (issue 40): on one scene with one driver it
records every tick's candidates from the trial, the in-loop row equals the recognition the
trial stored, the offline Eq. 5.8 row equals the thesis recogniser's own decisions, and
every row of the table is a share. Slow: a real trial and six recognisers."""

from __future__ import annotations

import importlib.util
import json
import sqlite3
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def _experiment():
    path = ROOT / "docs" / "experiments" / "recognition_bound.py"
    spec = importlib.util.spec_from_file_location("recognition_bound", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.mark.slow
def test_the_recognition_bound_experiment_runs_on_one_scene(tmp_path):
    rb = _experiment()
    rows = rb.record(tmp_path, 1, ["demo_docking"])
    with sqlite3.connect(tmp_path / "demo_docking_0.db") as con:
        (outcome,) = con.execute("select outcome from trial").fetchone()
        (ticks,) = con.execute("select count(*) from sample").fetchone()
    outcome = json.loads(outcome)
    assert len(rows) == ticks > 0
    recorded = [r for r in rows if r["ids"] is not None]
    assert recorded and all(len(r["ids"]) == len(r["kinds"]) == len(r["q"]) for r in recorded)
    calls = []

    def mine(rows_):  # the hook: any callable from the ticks to decisions is a row
        calls.append(len(rows_))
        return [(r["true_task"], r["true_target"], "", "") for r in rows_]

    table = rb.measure(rows, {**rb.recognisers(), "nothing": mine})
    assert calls == [len(rows)] and table["nothing"]["task"] == 0.0
    stored = outcome["recognition"]
    loop = table["in the loop (the mode's own output)"]
    assert loop["task"] == pytest.approx(stored["loop_task_match"], abs=6e-4)  # 3 vs 4 places
    assert loop["task_target"] == pytest.approx(stored["loop_task_target_match"], abs=6e-4)
    if outcome["mode_settings"].get("recogniser", "thesis") == "thesis":
        # the recorded features are the mode's: Eq. 5.8 offline decides as it did
        assert table["shipped recogniser, Eq. 5.8 per tick"] == loop
    for score in table.values():
        assert 0.0 <= score["task_target"] <= score["task"] <= 1.0
