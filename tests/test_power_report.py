"""The power report of ``asa power`` (analysis/power/report.py, issue 22), on a result made
from synthetic bank rows by the resampling layer (no simulator): the files, the page's
content against the result it was made from, escaping, one inline figure per metric."""

from __future__ import annotations

import ast
import itertools
import json
import os
import re
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
from markupsafe import escape

from analysis.metrics import BY_NAME
from analysis.power import (
    OMNIBUS,
    Batch,
    PlannedTests,
    bank_effects,
    curve,
    describe_n,
    n_for_power,
    resample_batch,
    summary_lines,
    tally,
)
from analysis.power.report import write_power_report

MODES = ("manual", "reactive_bn", "contextual_task")
ORDERS = list(itertools.permutations(MODES))  # full_permutation: a cycle of 6
SHIFTS = {  # metric -> mean per level, in SDs of the noise: a clear, a small and no effect
    "score_s": (0.0, -0.9, -1.5),
    "tlx_raw": (0.0, 0.25, 0.4),
    "secondary_errors": (0.0, 0.0, 0.0, 0.0),
}
TESTS = {"score_s": "rm_anova", "tlx_raw": "rm_anova", "secondary_errors": "friedman"}


def _levels(metric: str) -> tuple[str, ...]:
    return MODES + ("baseline",) if BY_NAME[metric].baseline else MODES


def _bank(rng: np.random.Generator, b: int) -> tuple[pd.DataFrame, pd.DataFrame]:
    """``b`` bank participants, entry i driving order row i mod 6: per metric a person
    effect plus noise plus the metric's shift per level (the baseline at position -1)."""
    entries = pd.DataFrame({"entry": np.arange(b), "row": np.arange(b) % len(ORDERS)})
    rows = []
    for i in range(b):
        order = ORDERS[i % len(ORDERS)]
        for metric, shift in SHIFTS.items():
            person = rng.normal(0.0, 1.0)
            for level, s in zip(_levels(metric), shift, strict=True):
                position = order.index(level) if level in order else -1
                value = 10.0 + person + s + rng.normal(0.0, 1.0)
                rows.append((i, f"B{i:04d}", metric, level, position, value))
    columns = ["entry", "participant", "metric", "mode", "position", "value"]
    return pd.DataFrame(rows, columns=columns), entries


def _metric(metric, planned, outcomes, counts, target) -> dict:
    tests = []
    for key in planned.keys(metric):
        points = curve(counts[metric][key])
        a, b = (None, None) if key == OMNIBUS else key.split(" vs ")
        tests.append(
            {
                "test": key,
                "a": a,
                "b": b,
                "curve": points,
                "n_for_power": n_for_power(points, target),
            }
        )
    return {
        "metric": metric,
        "label": BY_NAME[metric].label,
        "levels": list(planned.metrics[metric]),
        "failed": {str(n): k for n, (k, _) in counts[metric]["_failed"].items()},
        "effects": bank_effects(outcomes, planned, metric),
        "tests": tests,
    }


def _metrics(seed: int, *, bank: int, sizes: tuple[int, ...], studies: int, alpha: float):
    """The result's ``metrics``: studies resampled from a synthetic bank, counted."""
    outcomes, entries = _bank(np.random.default_rng(seed), bank)
    planned = PlannedTests(
        metrics={m: _levels(m) for m in SHIFTS}, alpha=alpha, posthoc="lsd_paired", tests=TESTS
    )
    slots = [j % len(ORDERS) for j in range(max(sizes))]
    batches = [
        (
            n,
            resample_batch(
                outcomes, entries, planned, Batch(n, 0, studies), seed=seed, slot_rows=slots
            ),
        )
        for n in sizes
    ]
    counts = tally(batches, planned)
    return [_metric(m, planned, outcomes, counts, 0.8) for m in SHIFTS]


# the parts of a result that the resampling does not make
PROTOCOL = {
    "name": "thesis-7-6",
    "title": "Thesis Sec. 7.6 user study",
    "sha256": "ab" * 32,
    "source": "protocols/thesis-7-6.toml",
    "modes": list(MODES),
    "counterbalancing": "full_permutation",
    "cycle": len(ORDERS),
}
POPULATION = {
    "speed_median": 0.3,
    "speed_range": [0.2, 0.45],
    "distraction_p": [0.4, 0.35, 0.25],
    "age_range": [18, 45],
}
TIMING = {
    "bank_s": 812.5,
    "resample_s": 95.25,
    "total_s": 907.75,
    "bank_trials_per_cpu_s": 2.14,
    "studies_per_s": 31.5,
}


def power_result(seed: int, *, bank: int, sizes: tuple[int, ...], studies: int, alpha: float):
    """A result object as ``asa power`` makes it (through JSON, as power.json holds it)."""
    metrics = _metrics(seed, bank=bank, sizes=sizes, studies=studies, alpha=alpha)
    settings = {
        "sizes": list(sizes),
        "studies": studies,
        "bank": bank,
        "seed": seed,
        "alpha": alpha,
        "gate": "auto",
        "posthoc": "lsd_paired",
        "tests": TESTS,
        "target_power": 0.8,
        "ci_level": 0.95,
        "engine": "LocalCluster, 2 worker processes",
    }
    bank_info = {
        "file": "bank.sqlite",
        "entries": bank,
        "statuses": {"completed": bank},
        "main_trials": 3 * bank,
        "timed_out_trials": 1,
        "simulated_s": 3 * bank * 95.0,
        "cpu_s": bank * 1.4,
        "population": POPULATION,
    }
    result = {
        "title": "Power analysis: Thesis Sec. 7.6 user study",
        "created_at": "2026-11-27T09:00:00Z",
        "platform_version": "0.22.0",
        "protocol": PROTOCOL,
        "settings": settings,
        "bank": bank_info,
        "metrics": metrics,
        "summary": summary_lines(metrics),
        "timing": TIMING,
    }
    return json.loads(json.dumps(result, allow_nan=False))


SEED = int(os.environ.get("ASA_TEST_SEED", "20261123"))  # conftest's seed, for module fixtures


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """(result, paths, html) of the default result."""
    result = power_result(SEED, bank=60, sizes=(6, 12, 18, 24), studies=8, alpha=0.05)
    paths = write_power_report(result, tmp_path_factory.mktemp("power"))
    return result, paths, paths.html.read_text(encoding="utf-8")


@pytest.fixture(scope="module")
def other(tmp_path_factory):
    """(result, paths, html) of another bank, sizes, study count and alpha, a label with
    markup and a metric without effect sizes."""
    result = power_result(SEED + 1, bank=48, sizes=(6, 9, 12), studies=5, alpha=0.1)
    result["metrics"][0]["label"] = "Time <b>&</b> score [s]"
    result["metrics"][1]["effects"] = None
    paths = write_power_report(result, tmp_path_factory.mktemp("power_other"))
    return result, paths, paths.html.read_text(encoding="utf-8")


def _methods(html: str) -> str:
    found = re.search(r'<p class="methods" id="methods-text">(.*?)</p>', html, re.S)
    assert found, "no methods paragraph"
    return found.group(1)


def test_the_files_exist_and_are_not_empty(written):
    result, paths, _ = written
    assert paths.html.name == "power.html"
    assert paths.curves_png.name == "power_curves.png"
    assert paths.curves_svg.name == "power_curves.svg"
    expected = [
        f"figures/power_{m['metric']}.{ext}" for m in result["metrics"] for ext in ("png", "svg")
    ]
    assert [p.relative_to(paths.html.parent).as_posix() for p in paths.figures] == expected
    for path in (paths.html, paths.curves_png, paths.curves_svg, *paths.figures):
        assert path.is_file() and path.stat().st_size > 0, path
    assert paths.curves_png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_the_page_names_every_metric_test_and_summary_line(written, other):
    for result, _, html in (written, other):
        for m in result["metrics"]:
            assert str(escape(m["label"])) in html, m["label"]
            for t in m["tests"]:
                assert str(escape(t["test"])) in html, t["test"]
        assert result["summary"]
        for line in result["summary"]:
            assert str(escape(line)) in html, line


def test_one_inline_svg_per_metric_and_nothing_fetched(written, other):
    for result, _, html in (written, other):
        assert html.count("<svg") == len(result["metrics"])
        assert not re.search(r"""(src|href)=["']?(https?:)?//""", html)
        assert "<script" not in html and "<link" not in html


def test_the_power_table_shows_every_point_and_the_n_for_the_target(written):
    result, _, html = written
    for m in result["metrics"]:
        for t in m["tests"]:
            for p in t["curve"]:
                assert f"{p['power']:.2f} [{p['ci_low']:.2f}, {p['ci_high']:.2f}]" in html
            assert str(escape(describe_n(t["n_for_power"]))) in html
    found = [t["n_for_power"]["n"] for m in result["metrics"] for t in m["tests"]]
    reached = [n for n in found if n is not None]
    assert reached and html.count('class="n reached"') == len(reached)
    cycle = result["protocol"]["cycle"]
    for n in reached:  # an N between complete counterbalancing cycles is also given rounded up
        if n % cycle:
            assert f"{-(-n // cycle) * cycle} in full cycles" in html


def test_the_methods_paragraph_follows_the_result(written, other):
    texts = []
    for result, _, html in (written, other):
        s = result["settings"]
        text = _methods(html)
        sizes = ", ".join(str(n) for n in s["sizes"][:-1]) + f" and {s['sizes'][-1]}"
        for part in (
            f"B = {s['bank']}",
            f"S = {s['studies']}",
            f"N = {sizes}",
            f"\u03b1 = {s['alpha']:g}",
            result["protocol"]["name"],
        ):
            assert part in text, part
        texts.append((text, s))
    (first, s1), (second, s2) = texts
    assert f"B = {s1['bank']}" not in second and f"S = {s2['studies']}" not in first
    assert f"\u03b1 = {s1['alpha']:g}" not in second


def test_a_curve_that_never_reaches_the_target_says_n_greater_than_the_largest_size(written):
    result, _, html = written
    largest = max(result["settings"]["sizes"])
    short = [t for m in result["metrics"] for t in m["tests"] if t["n_for_power"]["n"] is None]
    assert short, "the fixture's null metric should never reach the target"
    assert html.count(f'<td class="n short">N &gt; {largest}</td>') == len(short)


def test_markup_in_a_label_is_escaped_and_missing_effects_are_said(other):
    result, paths, html = other
    assert "Time &lt;b&gt;&amp;&lt;/b&gt; score [s]" in html
    assert "<b>&</b>" not in html
    svg = (
        paths.html.parent / "figures" / f"power_{result['metrics'][0]['metric']}.svg"
    ).read_text()
    assert "Time &lt;b&gt;&amp;&lt;/b&gt; score [s]" in svg
    assert "the analysis could not run on the bank" in html


def test_every_setting_is_shown(written):
    result, _, html = written
    for section in ("settings", "bank", "timing", "protocol"):
        for key in result[section]:
            assert f"<td>{key}</td>" in html, (section, key)
    for key in result["bank"]["population"]:
        assert f"<td>{key}</td>" in html, key


def test_the_report_imports_no_simulator_layer():
    """Layering: analysis never imports study, sim or autonomy (DESIGN.md)."""
    source = Path(__file__).parents[1] / "analysis" / "power" / "report.py"
    tree = ast.parse(source.read_text(encoding="utf-8"))
    names = [a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names]
    names += [n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module]
    assert not [n for n in names if n.split(".")[0] in ("study", "sim", "autonomy")]
