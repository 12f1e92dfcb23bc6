"""`asa stats --json` against the R oracle (tests/r/oracle.R): every number the R script
writes into tests/r/golden/NAME.json must agree, 1e-6 (relative or absolute), 1e-3 for the
mixed models and the order tests built on them. The default run reads the stored goldens (no
R needed); the slow test reruns R when ``Rscript`` exists and compares its fresh output.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
from pathlib import Path

import pytest

from study.cli import main

R_DIR = Path(__file__).parent / "r"
MANIFEST = json.loads((R_DIR / "datasets.json").read_text())
NAMES = [entry["name"] for entry in MANIFEST]
EXACT = 1e-6
MIXED = 1e-3
LOOSE_KEYS = {"mixed", "order"}  # fitted by numerical optimisation, here and in lme4


def run_asa(entry: dict, capsys) -> dict:
    """The JSON object of `asa stats` on one dataset, with the oracle's settings."""
    args = ["stats", "--csv", str(R_DIR / entry["csv"]), "--dv", entry["dv"]]
    args += ["--within", entry["within"], "--subject", entry["subject"], "--json"]
    if entry["order"]:
        args += ["--order", entry["order"]]
    try:
        main(args)
    except SystemExit as done:  # pragma: no cover - a failure shows in the assertion
        assert done.code == 0, capsys.readouterr().err
    return json.loads(capsys.readouterr().out)


def compare(golden, ours, path: str, tolerance: float, mismatches: list[str]) -> int:
    """Every leaf of ``golden`` (nested dicts and lists) against ``ours``; returns the number
    of numbers compared and appends a line per mismatch."""
    if isinstance(golden, dict):
        if not isinstance(ours, dict):
            mismatches.append(f"{path}: expected an object, got {ours!r}")
            return 0
        count = 0
        for key, value in golden.items():
            if key.startswith("_"):
                continue
            if key not in ours:
                mismatches.append(f"{path}.{key}: missing")
                continue
            tol = MIXED if key in LOOSE_KEYS else tolerance
            count += compare(value, ours[key], f"{path}.{key}", tol, mismatches)
        return count
    if isinstance(golden, list):
        if not isinstance(ours, list) or len(ours) != len(golden):
            mismatches.append(f"{path}: expected {len(golden)} items, got {ours!r}")
            return 0
        return sum(
            compare(g, o, f"{path}[{i}]", tolerance, mismatches)
            for i, (g, o) in enumerate(zip(golden, ours, strict=True))
        )
    if isinstance(golden, bool) or golden is None or isinstance(golden, str):
        if golden != ours:
            mismatches.append(f"{path}: R {golden!r}, asa {ours!r}")
        return 0
    if ours is None or not math.isclose(golden, ours, rel_tol=tolerance, abs_tol=tolerance):
        mismatches.append(f"{path}: R {golden!r}, asa {ours!r}")
    return 1


def check(golden: dict, ours: dict) -> int:
    mismatches: list[str] = []
    count = compare(golden, ours, "$", EXACT, mismatches)
    assert not mismatches, "\n".join(mismatches)
    return count


@pytest.mark.parametrize("name", NAMES)
def test_asa_stats_agrees_with_the_r_goldens(name, capsys):
    entry = MANIFEST[NAMES.index(name)]
    golden = json.loads((R_DIR / "golden" / f"{name}.json").read_text())
    assert golden["_meta"]["R"].startswith("R version 4.")
    assert set(golden["_meta"]["packages"]) >= {"afex", "emmeans", "lme4"}
    count = check(golden, run_asa(entry, capsys))
    assert count > 100  # the golden file is not (nearly) empty


def test_goldens_cover_the_required_cases():
    goldens = {n: json.loads((R_DIR / "golden" / f"{n}.json").read_text()) for n in NAMES}
    assert goldens["sphericity"]["sphericity"]["violated"] is True
    assert goldens["missing"]["mixed"]["incomplete_subjects"] == ["P03"]
    assert len(goldens["four_levels"]["levels"]) == 4
    assert goldens["four_levels"]["posthoc"]["ran"] is True
    zeros = goldens["zeros"]["descriptives"]
    assert min(level["mean"] for level in zeros.values()) < 0.5
    assert all(len(goldens[n]["posthoc"]["holm"]) > 0 for n in ("likert", "missing", "zeros"))


def test_comparison_catches_a_difference():
    golden = {"a": {"b": [1.0, 2.0]}, "mixed": {"x": 1.0}, "_meta": {"R": "x"}}
    assert check(golden, {"a": {"b": [1.0, 2.0 + 1e-9]}, "mixed": {"x": 1.0005}}) == 3
    mismatches: list[str] = []
    compare(golden, {"a": {"b": [1.0, 2.01]}, "mixed": {"x": 1.01}}, "$", EXACT, mismatches)
    assert len(mismatches) == 2


@pytest.mark.slow
@pytest.mark.skipif(
    shutil.which("Rscript") is None and not os.environ.get("CI"),
    reason="R is not installed (CI installs it: .ci/run)",
)
def test_r_reproduces_the_stored_goldens_and_asa_agrees(tmp_path, capsys):
    """Rerun tests/r/oracle.R; its fresh output agrees with the stored goldens and asa."""
    command = ["Rscript", str(R_DIR / "oracle.R"), str(tmp_path)]
    done = subprocess.run(command, capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stderr
    for entry in MANIFEST:
        fresh = json.loads((tmp_path / f"{entry['name']}.json").read_text())
        stored = json.loads((R_DIR / "golden" / f"{entry['name']}.json").read_text())
        check(fresh, stored)
        check(fresh, run_asa(entry, capsys))
