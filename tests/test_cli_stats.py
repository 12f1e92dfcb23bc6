"""`asa stats` and analysis.tables: the JSON object, the text summary, CSV validation and the
bad-input contract (one stderr line naming file and column, exit 2, no traceback)."""

from __future__ import annotations

import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from analysis.stats import analyse
from analysis.tables import apa_anova, format_p, format_summary, read_long_csv
from study.cli import main

BUSHTUCKER = Path(__file__).parent / "r" / "bushtucker.csv"
FIELD_ARGS = ["--dv", "retch_s", "--within", "animal", "--subject", "celebrity"]
KEYS = {
    "n_subjects",
    "levels",
    "descriptives",
    "anova",
    "sphericity",
    "greenhouse_geisser",
    "p_gate",
    "p_gate_source",
    "significant",
    "posthoc",
    "warnings",
    "dropped_subjects",
    # issue 21
    "planned",
    "posthoc_planned",
    "posthoc_warning",
    "effect_sizes",
    "pairs",
    "assumptions",
    "friedman",
    "mixed",
    "order",
    "apa",
}


def run(capsys, *args: str) -> tuple[int, str, str]:
    """Run `asa` in-process; returns (exit status, stdout, stderr)."""
    try:
        main(list(args))
        code = 0
    except SystemExit as done:
        code = done.code
    captured = capsys.readouterr()
    return code, captured.out, captured.err


def write_study(path: Path, rng: np.random.Generator, n: int = 10, effect: float = 30.0) -> Path:
    """A long CSV: participant, mode, completion_time_s, with a large mode effect."""
    modes = ["manual", "reactive", "task_aware"]
    rows = []
    for i in range(n):
        person = rng.normal(0, 5)
        for j, mode in enumerate(modes):
            rows.append((f"P{i:02d}", mode, 60 + person + effect * j + rng.normal(0, 3)))
    pd.DataFrame(rows, columns=["participant", "mode", "completion_time_s"]).to_csv(
        path, index=False
    )
    return path


STUDY_ARGS = ["--dv", "completion_time_s", "--within", "mode", "--subject", "participant"]


def test_json_has_every_key_and_nothing_else_on_stdout(tmp_path, rng, capsys):
    csv = write_study(tmp_path / "study.csv", rng)
    code, out, err = run(capsys, "stats", "--csv", str(csv), *STUDY_ARGS, "--json")
    assert code == 0, err
    result = json.loads(out)  # the whole of stdout is one object
    assert set(result) == KEYS
    assert result["levels"] == ["manual", "reactive", "task_aware"]
    assert result["significant"] is True and result["posthoc"]["ran"] is True
    for pair in result["posthoc"]["lsd_paired"] + result["posthoc"]["lsd_pooled"]:
        assert set(pair) == {"a", "b", "diff", "t", "df", "p", "ci_low", "ci_high", "significant"}
    frame = read_long_csv(csv, dv="completion_time_s", within="mode", subject="participant")
    expected = analyse(frame, dv="completion_time_s", within="mode", subject="participant")
    assert result == json.loads(json.dumps(expected))
    assert err == ""


def test_text_summary(capsys):
    code, out, err = run(capsys, "stats", "--csv", str(BUSHTUCKER), *FIELD_ARGS)
    assert code == 0, err
    assert "retch_s by animal: 8 subjects, 4 levels" in out
    assert "stick_insect" in out and "8.125" in out
    assert "F(1.60, 11.19) = 3.79, p = .063, eta_p^2 = .35 (Greenhouse-Geisser)" in out
    assert "W = 0.136, chi2(5) = 11.41, p = .047 (sphericity violated)" in out
    assert "not run" in out


def test_posthoc_gate_flag_on_bushtucker(capsys):
    """Bushtucker's GG p is .063: Holm runs on its own by default, and only with
    --posthoc-gate none for LSD; --posthoc-gate omnibus holds Holm back too."""
    args = ["stats", "--csv", str(BUSHTUCKER), *FIELD_ARGS, "--posthoc", "holm"]
    code, out, err = run(capsys, *args)
    assert code == 0, err
    assert "Paired t-tests, Holm over 6 pairs" in out and "Fisher's LSD: not run" in out
    code, out, err = run(capsys, *args, "--posthoc-gate", "omnibus", "--json")
    assert code == 0 and json.loads(out)["posthoc"]["holm"] == []
    code, out, err = run(capsys, *args[:-2], "--posthoc-gate", "none", "--json")
    result = json.loads(out)
    assert code == 0 and len(result["posthoc"]["lsd_paired"]) == 6
    assert "family-wise" in err
    code, out, err = run(capsys, *args, "--posthoc-gate", "never")
    assert code == 2 and "--posthoc-gate" in err and "auto" in err


def test_gate_and_alpha_options_reach_the_analysis(capsys):
    args = ["stats", "--csv", str(BUSHTUCKER), *FIELD_ARGS, "--json"]
    auto = json.loads(run(capsys, *args)[1])
    plain = json.loads(run(capsys, *args, "--gate", "uncorrected")[1])
    strict = json.loads(run(capsys, *args, "--gate", "uncorrected", "--alpha", "0.01")[1])
    assert auto["significant"] is False  # GG p = .063
    assert plain["significant"] is True and plain["p_gate"] == plain["anova"]["p_unc"]
    assert len(plain["posthoc"]["lsd_paired"]) == 6
    assert strict["significant"] is False  # p = .026 > .01
    code, _, err = run(capsys, *args, "--gate", "sometimes")
    assert code == 2 and len(err.strip().splitlines()) == 1 and "auto" in err


def test_warnings_go_to_stderr_with_json(tmp_path, rng, capsys):
    csv = write_study(tmp_path / "study.csv", rng)
    frame = pd.read_csv(csv)
    frame = frame[~((frame["participant"] == "P03") & (frame["mode"] == "reactive"))]
    frame.to_csv(csv, index=False)
    code, out, err = run(capsys, "stats", "--csv", str(csv), *STUDY_ARGS, "--json")
    assert code == 0
    result = json.loads(out)
    assert result["dropped_subjects"] == ["P03"] and result["n_subjects"] == 9
    assert "P03" in err and "warning" in err


def bad_files(tmp_path: Path) -> dict[str, tuple[Path, list[str], list[str]]]:
    """name -> (file, extra args, fragments the one error line must contain)."""
    good_header = "participant,mode,completion_time_s\n"
    files = {
        "not_a_number": good_header + "P1,manual,61.5\nP1,reactive,seventy\n",
        "one_level": good_header + "P1,manual,61.5\nP2,manual,58\n",
        "empty_id": good_header + "P1,manual,61.5\n,reactive,58\n",
        "one_complete_subject": good_header
        + "P1,manual,61.5\nP1,reactive,70\nP2,manual,58\nP2,reactive,\n",
        "empty": "",
        "ragged": good_header + "P1,manual,61.5,extra,fields\n",
    }
    out = {}
    for name, text in files.items():
        path = tmp_path / f"{name}.csv"
        path.write_text(text)
        out[name] = (path, [], [])
    out["not_a_number"][2].extend(["'completion_time_s'", "line 3", "'seventy'", "not a number"])
    out["one_level"][2].extend(["'mode'", "only 1 level", "'manual'"])
    out["empty_id"][2].extend(["'participant'", "line 3", "empty"])
    out["one_complete_subject"][2].extend(["only 1 subject", "'participant'", "'P2'"])
    out["empty"][2].append("empty file")
    out["ragged"][2].append("not a valid CSV")
    missing_column = tmp_path / "missing_column.csv"
    missing_column.write_text(good_header + "P1,manual,61.5\n")
    out["missing_column"] = (
        missing_column,
        ["--dv", "time_s"],
        ["'time_s'", "not found", "'participant', 'mode', 'completion_time_s'"],
    )
    out["no_such_file"] = (tmp_path / "absent.csv", [], ["no such file"])
    return out


BAD = [
    "not_a_number",
    "one_level",
    "empty_id",
    "one_complete_subject",
    "empty",
    "ragged",
    "missing_column",
    "no_such_file",
]


@pytest.mark.parametrize("name", BAD)
def test_bad_csv_is_one_line_exit_2(tmp_path, capsys, name):
    path, extra, fragments = bad_files(tmp_path)[name]
    args = dict(zip(STUDY_ARGS[::2], STUDY_ARGS[1::2], strict=True))
    args.update(dict(zip(extra[::2], extra[1::2], strict=True)))
    flat = [item for pair in args.items() for item in pair]
    code, out, err = run(capsys, "stats", "--csv", str(path), *flat, "--json")
    assert code == 2
    assert out == ""
    lines = err.strip().splitlines()
    assert len(lines) == 1, err
    assert lines[0].startswith("asa: error: ") and str(path) in lines[0]
    for fragment in fragments:
        assert fragment in lines[0]
    assert "Traceback" not in err


def test_bad_csv_through_the_console_script_has_no_traceback(tmp_path):
    path = tmp_path / "times.csv"
    path.write_text("participant,mode,completion_time_s\nP1,manual,1\nP1,reactive,x\n")
    command = [sys.executable, "-m", "study.cli", "stats", "--csv", str(path), *STUDY_ARGS]
    result = subprocess.run(command, capture_output=True, text=True, timeout=120)
    assert result.returncode == 2
    assert result.stdout == ""
    assert len(result.stderr.strip().splitlines()) == 1
    assert "Traceback" not in result.stderr
    assert str(path) in result.stderr and "'completion_time_s'" in result.stderr


# ------------------------------------------------------------------------------------------
# analysis.tables
# ------------------------------------------------------------------------------------------


def test_read_long_csv_keeps_ids_as_text_and_numbers_lines(tmp_path):
    path = tmp_path / "data.csv"
    path.write_text("pid, mode, y\n007, a, 1.5\n\n007, b, NA\n010, a,\n010, b, 2e1\n")
    frame = read_long_csv(path, dv="y", within="mode", subject="pid")
    assert list(frame.columns) == ["pid", "mode", "y"]
    assert list(frame["pid"]) == ["007", "007", "010", "010"]
    assert list(frame["mode"]) == ["a", "b", "a", "b"]
    assert list(frame.index) == [2, 4, 5, 6]  # the blank line 3 is skipped
    assert frame["y"].iloc[0] == 1.5 and frame["y"].iloc[3] == 20.0
    assert frame["y"].iloc[1:3].isna().all()
    bad = tmp_path / "bad.csv"
    bad.write_text("pid,mode,y\n1,a,1\n\n1,b,inf\n")
    with pytest.raises(ValueError, match=r"bad.csv: column 'y' line 4: 'inf' is not finite"):
        read_long_csv(bad, dv="y", within="mode", subject="pid")
    with pytest.raises(ValueError, match="is a directory"):
        read_long_csv(tmp_path, dv="y", within="mode", subject="pid")


@pytest.mark.parametrize(
    ("p", "text"),
    [
        (None, "n/a"),
        (math.nan, "n/a"),
        (0.0, "< .001"),
        (0.000999, "< .001"),
        (0.001, "= .001"),
        (0.02557, "= .026"),
        (0.5, "= .500"),
        (1.0, "= 1.000"),
    ],
)
def test_format_p(p, text):
    assert format_p(p) == text


def test_apa_line_follows_the_gate():
    frame = read_long_csv(BUSHTUCKER, dv="retch_s", within="animal", subject="celebrity")
    columns = {"dv": "retch_s", "within": "animal", "subject": "celebrity"}
    auto = analyse(frame, **columns)
    assert apa_anova(auto) == "F(1.60, 11.19) = 3.79, p = .063, eta_p^2 = .35 (Greenhouse-Geisser)"
    plain = analyse(frame, **columns, gate="uncorrected")
    assert apa_anova(plain) == "F(3, 21) = 3.79, p = .026, eta_p^2 = .35"
    text = format_summary(plain, dv="retch_s", within="animal", gate="uncorrected")
    assert "Fisher's LSD, paired" in text and "Fisher's LSD, pooled" in text
    assert "df = 7; 95% CI" in text and "df = 21; 95% CI" in text


def test_apa_line_when_f_is_undefined():
    frame = pd.DataFrame(
        {"s": ["1", "1", "2", "2"], "w": ["a", "b", "a", "b"], "y": [1.0, 2.0, 5.0, 6.0]}
    )
    result = analyse(frame, dv="y", within="w", subject="s")
    assert apa_anova(result) == "F(1, 1) undefined (SS_error = 0)"
    assert "SS_error is 0" in format_summary(result)


# ------------------------------------------------------------------------------------------
# issue 21: --test, --posthoc, --order
# ------------------------------------------------------------------------------------------

R_DIR = Path(__file__).parent / "r"
LIKERT_ARGS = ["--dv", "rating", "--within", "mode", "--subject", "participant"]


def test_friedman_holm_and_order_reach_the_json(capsys):
    csv = str(R_DIR / "likert.csv")
    args = ["stats", "--csv", csv, *LIKERT_ARGS, "--json"]
    code, out, err = run(capsys, *args, "--test", "friedman", "--posthoc", "holm")
    assert code == 0, err
    result = json.loads(out)
    assert result["planned"]["test"] == "friedman" and result["posthoc_planned"] == "holm"
    assert result["order"] is None and result["mixed"]["formula"] == "y ~ mode + (1 | subject)"
    code, out, err = run(capsys, *args, "--test", "auto", "--order", "position")
    result = json.loads(out)
    assert result["planned"]["requested"] == "auto" and result["planned"]["test"] == "friedman"
    assert result["mixed"]["formula"] == "y ~ mode + position + (1 | subject)"
    assert set(result["order"]) >= {"position", "mode_x_position", "position_means"}


def test_text_summary_shows_the_additions(capsys):
    csv = str(R_DIR / "four_levels.csv")
    code, out, err = run(
        capsys, "stats", "--csv", csv, "--dv", "y", "--within", "mode", "--subject",
        "participant", "--order", "position",
    )  # fmt: skip
    assert code == 0, err
    for heading in ("Effect sizes", "Friedman test", "Assumptions", "Mixed model", "Order"):
        assert heading in out
    assert "90% CI" in out and "d_z" in out
    assert "protects the family-wise error rate only for three levels" in out  # LSD, 4 levels


@pytest.mark.parametrize(
    ("extra", "fragments"),
    [
        (["--test", "anova"], ["'anova'", "rm_anova"]),
        (["--posthoc", "tukey"], ["'tukey'", "holm"]),
        (["--order", "slot"], ["'slot'", "not found", "'position'"]),
        (["--order", "rating"], ["order column 'rating'"]),
    ],
)
def test_bad_options_are_one_line_exit_2(capsys, extra, fragments):
    csv = str(R_DIR / "likert.csv")
    code, out, err = run(capsys, "stats", "--csv", csv, *LIKERT_ARGS, "--json", *extra)
    assert code == 2 and out == ""
    assert len(err.strip().splitlines()) == 1 and "Traceback" not in err
    for fragment in fragments:
        assert fragment in err


def test_a_position_that_is_not_a_number_names_its_line(tmp_path, capsys):
    path = tmp_path / "ordered.csv"
    path.write_text("participant,mode,position,y\nP1,a,1,3\nP1,b,second,4\nP2,a,2,5\nP2,b,1,6\n")
    args = ["--dv", "y", "--within", "mode", "--subject", "participant", "--order", "position"]
    code, out, err = run(capsys, "stats", "--csv", str(path), *args)
    assert code == 2 and len(err.strip().splitlines()) == 1
    assert str(path) in err and "'position' line 3: 'second' is not a position" in err
