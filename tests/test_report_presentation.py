"""The report as a reader sees it (issue 21): the synthetic-data banner, Table 1, levels
0 by construction left out of the tests, APA p-values near alpha, the terms explained,
whiskers that do not go below zero and a paths figure large enough to read."""

from __future__ import annotations

import json
import os
import re
import shutil
import subprocess

import pandas as pd
import pytest
from markupsafe import escape

from analysis.figures import metric_figure, paths_figure
from analysis.metrics import BY_NAME
from analysis.presentation import GLOSSARY, synthetic_banner, table_one, without_constant_levels
from analysis.tables import format_p


@pytest.fixture(scope="module")
def built(generated_report):
    """The report of every metric that test_report.py reads too (tests/conftest.py)."""
    _, paths, out, _ = generated_report
    return paths, out, paths.html.read_text(encoding="utf-8")


def test_synthetic_participants_carry_a_banner(built):
    _, _, html = built
    assert 'class="banner"' in html and "Model output, not data about people" in html
    assert synthetic_banner({"human": 12}) == ""
    text = synthetic_banner({"human": 10, "synthetic": 2})
    assert "2 of the 12 participants" in text


def test_table_one_gives_every_planned_metric_as_m_sd_per_mode(built):
    paths, out, html = built
    table = pd.read_csv(out / "tables" / "table1.csv", keep_default_na=False)
    assert 'id="table1"' in html
    # assist_share's manual level is 0 by construction: described, not "without any value"
    assert "assist_share: manual left out of the test: 0 by construction" in html
    assert "assist_share: levels without any value left out" not in html
    assert {"completion_time_s", "collisions", "score_s"} <= set(table["metric"])
    for mode in ("manual", "reactive_bn", "contextual_task"):
        cells = table[mode]
        assert all(re.fullmatch(r"-?\d+\.\d+ \((\d+\.\d+|n/a)\)", c) for c in cells if c)


def test_levels_zero_by_construction_are_described_not_tested():
    long = pd.DataFrame(
        {
            "participant": [f"P{i}" for i in range(5) for _ in range(3)],
            "mode": ["manual", "reactive_bn", "contextual_task"] * 5,
            "position": [0, 1, 2] * 5,
            "value": [0.0, 0.4, 0.6, 0.0, 0.5, 0.7, 0.0, 0.3, 0.5, 0.0, 0.6, 0.9, 0.0, 0.2, 0.4],
        }
    )
    tested, out = without_constant_levels(BY_NAME["assist_share"], long)
    assert out == ["manual"] and set(tested["mode"]) == {"reactive_bn", "contextual_task"}
    kept, none = without_constant_levels(BY_NAME["collisions"], long)  # an outcome, never left out
    assert none == [] and len(kept) == len(long)
    table = table_one({"assist_share": (BY_NAME["assist_share"], long)}, ["manual", "reactive_bn"])
    assert table.loc[0, "manual"] == "0.000 (0.000)"
    assert table.loc[0, "note"] == "0 by construction in manual"


@pytest.mark.parametrize(
    ("p", "text"),
    [(0.0496, "= .0496"), (0.04951, "= .0495"), (0.05004, "= .050"), (0.2345, "= .234"),
     (0.0004, "< .001"), (float("nan"), "n/a")],
)  # fmt: skip
def test_p_near_alpha_never_reads_on_the_wrong_side(p, text):
    assert format_p(p, alpha=0.05) == text
    shown = float("0" + text[2:]) if text.startswith("= ") else None
    if shown is not None:
        assert (shown < 0.05) == (p < 0.05)


def test_no_raw_p_values_and_every_term_explained(built):
    _, _, html = built
    text = re.sub(r"<svg.*?</svg>", "", html, flags=re.S)
    # every p in APA form: no leading zero, no exponent ("p = 0.000", "p 1.2e-05")
    assert not re.search(r"\bp (= |< )?0\.\d", text)
    assert not re.search(r"\bp (= )?\d(\.\d+)?e-\d+", text)
    assert re.search(r"\bp (= \.\d{3}|< \.001)", text)
    assert 'id="terms"' in html
    for term, _ in GLOSSARY:
        assert f"<dt>{term}</dt>" in html


def test_count_whiskers_stop_at_zero():
    long = pd.DataFrame(
        {
            "participant": ["a", "b", "c", "a", "b", "c"],
            "mode": ["manual"] * 3 + ["reactive_bn"] * 3,
            "position": [0, 0, 0, 1, 1, 1],
            "value": [0.0, 0.0, 3.0, 0.0, 0.0, 0.0],
        }
    )
    fig = metric_figure(long, BY_NAME["collisions"], ("manual", "reactive_bn"))
    ax = fig.axes[0]
    low = min(seg[:, 1].min() for c in ax.collections for seg in getattr(c, "get_segments", list)())
    assert low >= 0.0


def test_paths_figure_has_readable_panels_and_distinct_markers():
    samples = pd.DataFrame(
        {"trial_id": [1] * 5, "tick": range(5), "x": [0, 1, 2, 1, 0.0], "y": [0, 1, 0, 1, 0.0]}
    )
    trials = pd.DataFrame({"trial_id": [1], "mode": ["manual"]})
    fig = paths_figure(samples, trials, ("manual", "reactive_bn", "contextual_task"))
    width, height = fig.get_size_inches()
    visible = [ax for ax in fig.axes if ax.get_visible()]
    assert len(visible) == 3 and width / 2 >= 6.0  # two 6-inch panels a row
    labels = {line.get_label(): line for line in fig.axes[0].get_lines()}
    assert labels["start"].get_marker() != labels["end"].get_marker()
    assert labels["start"].get_color() != labels["end"].get_color()


def test_every_planned_metric_has_effect_sizes_and_the_design_checks(built):
    paths, _, html = built
    results = json.loads(paths.results_json.read_text())
    text = re.sub(r"<svg.*?</svg>", "", html, flags=re.S)
    assert 'id="design"' in text and "mode x position" in text
    for name, r in results.items():
        if name == "recognition":
            continue
        assert "90% CI" in r["apa"]["rm_anova"]  # eta_p^2 with its interval
        for line in r["apa"]["pairs"]:
            assert "d_z" in line and "95% CI" in line
            assert str(escape(line)) in text
        if r["order"]:  # order effects where every level is a position in the order
            assert re.search(rf"<td>{name}</td><td>chi2\(\d+\) = ", text)


def test_the_report_writes_its_planned_tests_as_an_r_script(built):
    paths, out, _ = built
    script = (out / "analysis.R").read_text(encoding="utf-8")
    results = json.loads(paths.results_json.read_text())
    planned = [m for m in ("completion_time_s", "collisions", "score_s") if m in results]
    assert planned and 'read.csv("tables/trials.csv"' in script
    for name in planned:
        assert f'"{name}"' in script
        assert f'{name} = "{results[name]["planned"]["test"]}"' in script


@pytest.mark.slow
@pytest.mark.skipif(
    shutil.which("Rscript") is None and not os.environ.get("CI"),
    reason="R is not installed (CI installs it: .ci/run)",
)
def test_the_r_script_runs_and_agrees_with_the_report(built):
    paths, out, _ = built
    run = subprocess.run(
        ["Rscript", "analysis.R"], cwd=out, capture_output=True, text=True, timeout=600
    )
    assert run.returncode == 0, run.stderr
    results = json.loads(paths.results_json.read_text())
    for name in ("completion_time_s", "collisions", "score_s"):
        block = run.stdout.split(f"===== {name} ")[1].split("=====")[0]
        row = re.search(r"^mode\s+\S+\s+\S+\s+\S+\s+\S+\s+(\S+)", block, flags=re.M)
        assert row and float(row[1]) == pytest.approx(results[name]["anova"]["F"], rel=1e-4)
        ran = results[name]["posthoc"]["ran"]  # the same post-hoc decision as the report
        assert re.search(r"^post hoc \S+ " + ("ran" if ran else "not run"), block, flags=re.M)
