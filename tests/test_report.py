"""analysis.report and `asa report` on a generated study database: the written files, every
figure inlined in report.html, an APA sentence per metric, results.json equal to analyse() on
the tidy frame, the generated effects in the right direction, the data-quality section, the
CSV-folder input, and the bad-input contract (one stderr line, exit 2)."""

from __future__ import annotations

import json
import sqlite3
import sys
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
from markupsafe import escape

from analysis.data import load_study, tidy
from analysis.metrics import BY_NAME, long_frame
from analysis.presentation import without_constant_levels
from analysis.report import analysis_frame
from analysis.stats import analyse
from analysis.tables import apa_anova
from study.cli import main
from study.data.dbtools import export

sys.path.insert(0, str(Path(__file__).parent))
from fixtures_db import REPORT_STUDY, make_study_db  # noqa: E402

SETTINGS = REPORT_STUDY


@pytest.fixture(scope="module")
def study_db(generated_report) -> Path:
    return generated_report[0]  # tests/conftest.py: shared with test_report_presentation.py


@pytest.fixture(scope="module")
def report(generated_report):
    _, paths, out, lines = generated_report
    return paths, out, lines


def run(capsys, *args: str) -> tuple[int, str, str]:
    try:
        main(list(args))
        status = 0
    except SystemExit as exit_:
        status = int(exit_.code or 0)
    captured = capsys.readouterr()
    return status, captured.out, captured.err


def test_files_and_inlined_figures(report):
    paths, out, lines = report
    html = paths.html.read_text(encoding="utf-8")
    svgs = sorted(p for p in paths.figures if p.suffix == ".svg")
    pngs = sorted(p for p in paths.figures if p.suffix == ".png")
    assert [p.stem for p in svgs] == [p.stem for p in pngs]
    assert all(p.is_file() and p.stat().st_size > 1000 for p in paths.figures)
    assert {"tlx_profile", "clearance_distribution", "paths"} <= {p.stem for p in svgs}
    assert {f"metric_{m}" for m in paths.metrics} <= {p.stem for p in svgs}
    # every figure inlined once; nothing fetched from elsewhere (self-contained)
    assert html.count("<svg") == len(svgs)
    assert "<script src" not in html and "<link" not in html
    for name in ("trials", "questions", "responses", "summary", "counterbalancing", "aborted"):
        assert (out / "tables" / f"{name}.csv").is_file()
    assert lines and lines[-1].startswith("wrote ")
    assert "thesis-7-6" in html


def test_apa_sentence_per_metric_and_results_json(study_db, report):
    paths, _, _ = report
    html = paths.html.read_text(encoding="utf-8")
    results = json.loads(paths.results_json.read_text())
    # one ANOVA object per analysed metric; the recognition is described under its own key
    assert list(results) == [*paths.metrics, "recognition"]
    assert not any(BY_NAME[m].descriptive for m in paths.metrics)
    results.pop("recognition")
    data = load_study(study_db)
    frames, cfg = tidy(data), data.config
    for name, stored in results.items():
        assert str(escape(apa_anova(stored, alpha=0.05))) in html
        long, constant = without_constant_levels(BY_NAME[name], long_frame(frames, BY_NAME[name]))
        frame, order = analysis_frame(long)
        fresh = analyse(
            frame, dv="value", within="mode", subject="participant",
            test=cfg.test_for(name), posthoc=cfg.posthoc, order=order,
        )  # fmt: skip
        if constant:  # levels 0 by construction are described, not tested
            fresh["warnings"].append(
                f"{', '.join(constant)} left out of the test: 0 by construction "
                "(described in Table 1)"
            )
        assert json.loads(json.dumps(fresh)) == stored, name
    # planned metrics of the thesis protocol come first
    assert list(results)[:3] == ["completion_time_s", "collisions", "score_s"]
    # the incomplete participant is dropped listwise, and the warning reaches the report
    assert results["completion_time_s"]["dropped_subjects"] == ["P07"]
    assert "P07" in html


def test_recognition_is_described_from_the_samples(report):
    paths, out, _ = report
    rec = json.loads(paths.results_json.read_text())["recognition"]
    # the fixture stores primitive labels and label_tasks, no recognition in the outcome
    assert list(rec) == ["contextual_task"]
    d = rec["contextual_task"]
    assert d["sources"] == {"samples": d["trials"]} and d["trials"] == SETTINGS.n_participants
    assert d["labelled_ticks"] == SETTINGS.n_participants * SETTINGS.samples
    assert d["task_target_matches"] <= d["task_matches"] <= d["labelled_ticks"] - d["null_ticks"]
    html = paths.html.read_text(encoding="utf-8")
    assert "Recognition in the loop" in html and "re-derived from the samples" in html
    per_task = np.loadtxt(
        out / "tables" / "recognition_per_task.csv", delimiter=",", skiprows=1, usecols=(2,)
    )
    assert per_task.sum() == d["labelled_ticks"]


def test_effects_in_the_right_direction(report):
    paths, _, _ = report
    r = json.loads(paths.results_json.read_text())
    time = r["completion_time_s"]
    d = time["descriptives"]
    assert d["manual"]["mean"] > d["reactive_bn"]["mean"] > d["contextual_task"]["mean"]
    assert time["significant"] and time["posthoc"]["ran"]
    pair = next(
        p
        for p in time["posthoc"]["lsd_paired"]
        if {p["a"], p["b"]} == {"manual", "contextual_task"}
    )
    assert pair["significant"]
    answer = r["secondary_answer_time_s"]
    assert answer["levels"][-1] == "baseline"
    assert all(
        answer["descriptives"]["baseline"]["mean"] < answer["descriptives"][m]["mean"]
        for m in ("manual", "reactive_bn", "contextual_task")
    )


def test_data_quality_and_counterbalancing(report):
    paths, out, _ = report
    html = paths.html.read_text(encoding="utf-8")
    assert "input lost" in html  # the aborted trials are listed with their reason
    counts = np.loadtxt(
        out / "tables" / "counterbalancing.csv", delimiter=",", skiprows=1, usecols=(1, 2, 3)
    )
    # six complete participants over the six permutations (plus P07's first trial)
    assert counts.sum() == 6 * 3 + 1
    assert counts.min() >= 2


def test_cli_and_csv_folder(study_db, tmp_path, capsys):
    status, out, err = run(
        capsys,
        "report",
        "--db",
        str(study_db),
        "--out",
        str(tmp_path / "a"),
        "--metric",
        "completion_time_s",
        "--metric",
        "secondary_errors",
    )
    assert status == 0, err
    assert out.splitlines()[0].endswith("report.html")
    assert "asa report: read " in err
    export(study_db, tmp_path / "csv")
    status, _, err = run(
        capsys,
        "report",
        "--db",
        str(tmp_path / "csv"),
        "--out",
        str(tmp_path / "b"),
        "--metric",
        "completion_time_s",
        "--metric",
        "secondary_errors",
    )
    assert status == 0, err
    a = json.loads((tmp_path / "a" / "results.json").read_text())
    b = json.loads((tmp_path / "b" / "results.json").read_text())
    assert a == b and list(a) == ["completion_time_s", "secondary_errors"]


def test_bad_input_one_line_exit_2(tmp_path, capsys, seed):
    text = tmp_path / "notes.db"
    text.write_text("not a database at all\n" * 40)
    other = tmp_path / "other.db"
    with sqlite3.connect(other) as con:
        con.execute("create table things (id integer primary key)")
    empty = make_study_db(
        tmp_path / "empty.db",
        np.random.default_rng(seed),
        settings=replace(SETTINGS, n_participants=1, samples=10, aborted_retry=False),
    )
    with sqlite3.connect(empty) as con:
        con.execute("update trial set status = 'aborted' where phase = 'main'")
    cases = {
        tmp_path / "missing.db": "no such file",
        text: "notes.db",
        other: "not an asa-study database",
        empty: "no completed main trial",
    }
    for db, message in cases.items():
        status, out, err = run(capsys, "report", "--db", str(db), "--out", str(tmp_path / "r"))
        lines = [line for line in err.splitlines() if not line.startswith("asa report:")]
        assert status == 2, (db, err)
        assert len(lines) == 1 and lines[0].startswith("asa: error:") and message in lines[0]
        assert "Traceback" not in err
    status, _, err = run(
        capsys, "report", "--db", str(empty), "--out", str(tmp_path / "r"), "--metric", "nope"
    )
    assert status == 2 and "'nope' is not known" in err
