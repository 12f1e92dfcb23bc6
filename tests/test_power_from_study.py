"""``asa power --from-study`` end to end (issue 39): a study database (tests/fixtures_db.py,
written through the storage models), the real analysis chain, a real Dask cluster, the
report; and its bad input, one line and exit 2 each."""

from __future__ import annotations

import json
import sqlite3

import numpy as np
import pytest
from cli_helpers import asa
from fixtures_db import FixtureSettings, make_study_db

from analysis.power import Batch, tally
from analysis.power.parametric import simulate_batch
from study.jobs.power.from_study import FromStudySettings, _planned, pilot_models

SMALL = ["--sizes", "4,6", "--studies", "20", "--draws", "5", "--workers", "1"]


@pytest.fixture
def pilot_db(tmp_path, rng):
    return make_study_db(tmp_path / "pilot.db", rng)


def test_from_study_writes_the_power_report_of_the_pilot(pilot_db, tmp_path, capsys, seed):
    out = tmp_path / "pw"
    code, stdout, err = asa(
        capsys, "power", "--from-study", str(pilot_db), *SMALL, "--seed", str(seed % 1000),
        "--metric", "completion_time_s", "--metric", "tlx_raw",
        "--effect-of-interest", "completion_time_s=20", "--out", str(out),
    )  # fmt: skip
    assert code == 0, err
    result = json.loads((out / "power.json").read_text())
    assert result["source"] == "pilot"
    keys = [m["metric"] for m in result["metrics"]]
    assert keys == [
        "completion_time_s", "completion_time_s@uncertain", "completion_time_s@interest",
        "tlx_raw", "tlx_raw@uncertain",
    ]  # fmt: skip
    fitted = result["pilot"]["fitted"]["completion_time_s"]
    assert fitted["n"] == 6 and fitted["levels"] == ["manual", "reactive_bn", "contextual_task"]
    assert fitted["mean"][0] > fitted["mean"][2]  # the fixture's manual mode is slowest
    spread = result["metrics"][1]["tests"][0]["replicates"]
    assert [r["n"] for r in spread] == [4, 6] and all(r["low"] <= r["high"] for r in spread)
    # the cluster's counts are the in-process simulation's: same seeds, same studies
    settings = FromStudySettings(
        sizes=(4, 6), studies=20, draws=5, seed=seed % 1000,
        metrics=("completion_time_s", "tlx_raw"), interest={"completion_time_s": 20.0},
    )  # fmt: skip
    data, models, _ = pilot_models(str(pilot_db), settings)
    planned = _planned(data.config, models, settings)
    local = tally(
        [(n, simulate_batch(models, planned, Batch(n, 0, 20), seed=seed % 1000, draws=5))
         for n in (4, 6)],
        planned,
    )  # fmt: skip
    for m in result["metrics"]:
        for t in m["tests"]:
            got = [(p["rejections"], p["studies"]) for p in t["curve"]]
            assert got == [local[m["metric"]][t["test"]][n] for n in (4, 6)]
    html = (out / "power.html").read_text()
    assert "Power from a pilot" in html and "bootstrap replicates of the pilot" in html
    assert "smallest effect size of interest" in html and "20 for completion_time_s" in html
    assert "completion_time_s: omnibus test" in stdout


def _bad(capsys, *args):
    code, out, err = asa(capsys, "power", *args)
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_a_pilot_without_a_planned_metric_is_refused(pilot_db, tmp_path, capsys):
    with sqlite3.connect(pilot_db) as db:
        db.execute("UPDATE trial SET completion_time_s = NULL")
    line = _bad(capsys, "--from-study", str(pilot_db), *SMALL, "--out", str(tmp_path / "o"))
    assert str(pilot_db) in line and "completion_time_s" in line and "no values" in line
    line = _bad(capsys, "--from-study", str(pilot_db), "--metric", "speed", *SMALL)
    assert "'speed' is not planned" in line and "completion_time_s" in line


def test_fewer_than_three_complete_participants_are_refused(tmp_path, capsys, rng):
    db = make_study_db(tmp_path / "two.db", rng, settings=FixtureSettings(n_participants=2))
    line = _bad(capsys, "--from-study", str(db), *SMALL, "--out", str(tmp_path / "o"))
    assert str(db) in line and "2 complete participants" in line and "at least 3" in line


def test_bad_flags_of_from_study(pilot_db, tmp_path, capsys):
    missing = tmp_path / "none.db"
    assert str(missing) in _bad(capsys, "--from-study", str(missing), *SMALL)
    line = _bad(capsys, "--from-study", str(pilot_db), "--effect-of-interest", "score_s", *SMALL)
    assert "--effect-of-interest" in line and "METRIC=VALUE" in line
    line = _bad(capsys, "--from-study", str(pilot_db), "--effect-of-interest", "score_s=-3", *SMALL)
    assert "--effect-of-interest" in line and "positive" in line
    line = _bad(
        capsys, "--from-study", str(pilot_db), "--metric", "tlx_raw",
        "--effect-of-interest", "score_s=3", *SMALL,
    )  # fmt: skip
    assert "--effect-of-interest: score_s is not among" in line
    line = _bad(capsys, "--from-study", str(pilot_db), "--protocol", "pilot", *SMALL)
    assert "exactly one of --protocol and --from-study" in line
    line = _bad(capsys, "--from-study", str(pilot_db), "--bank", "10", *SMALL)
    assert "--bank" in line
    assert "--sizes" in _bad(capsys, "--from-study", str(pilot_db), "--sizes", "2,4")


def test_pilot_models_fit_the_complete_participants(pilot_db):
    data, models, longs = pilot_models(str(pilot_db), FromStudySettings(metrics=("tlx_raw",)))
    model = models["tlx_raw"]
    wide = longs["tlx_raw"].pivot(index="participant", columns="mode", values="value")
    wide = wide.dropna()[list(model.levels)].to_numpy()
    assert np.allclose(np.sort(model.wide, axis=0), np.sort(wide, axis=0))
