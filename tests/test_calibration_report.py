"""The calibration report of ``asa calibrate`` (analysis/calibration_report.py, issue 39),
rendered from a hand-built result (no calibration run): the page beside the population
file, each parameter's estimate and interval, every moment, balanced tags, escaping."""

from __future__ import annotations

import copy
import math
from html.parser import HTMLParser

from markupsafe import escape

from analysis.calibration_report import limitations, methods_paragraph, write_calibration_report

VOID = {"meta", "br", "img", "input", "link", "hr", "col", "area", "base", "wbr"}


def _moment(name: str, metric: str, target, se, simulated, z, fitted: bool) -> dict:
    return {"moment": name, "metric": metric, "target": target, "se": se,
            "simulated": simulated, "z": z, "fitted": fitted, "bank_ess": 41.3}  # fmt: skip


RESULT = {
    "title": "Calibration of the synthetic population to <script>alert(1)</script>",
    "created_at": "2025-01-02T03:04:05+00:00",
    "platform_version": "0.9.0",
    "study": {
        "file": "pilot.db",
        "name": "<script>alert(1)</script>",
        "protocol_sha256": "ab" * 32,
        "participants": 12,
    },  # fmt: skip
    "settings": {
        "bank": 60,
        "replicates": 30,
        "level": 0.95,
        "seed": 7,
        "engine": "local Dask cluster, 2 workers",
    },  # fmt: skip
    "method": "simulated moments, importance-weighted bank, Nelder-Mead; "
    "bootstrap of participants and bank entries",
    "blocks": ["speed"],
    "identified_by": {
        "speed": ["completion_time_s", "score_s"],
        "answer": ["secondary_answer_time_s"],
        "tlx": ["tlx_raw", "tlx_weighted"],
    },
    "not_fitted": [
        {
            "name": "tlx_bias_mean",
            "block": "tlx",
            "unit": "points",
            "meaning": "mean NASA-TLX bias",
            "base": 0.0,
        }
    ],  # fmt: skip
    "parameters": [
        {
            "name": "speed_median",
            "unit": "m/s",
            "meaning": "median preferred speed",
            "block": "speed",
            "estimate": 0.2871,
            "low": 0.2514,
            "high": 0.3228,
            "bootstrap_sd": 0.0182,
            "percentile": [0.2502, 0.3199],
            "base": 0.3,
            "search": [0.15, 0.5],
        },
        {
            "name": "speed_sigma",
            "unit": "",
            "meaning": "log-normal sigma of preferred speed",
            "block": "speed",
            "estimate": 0.0612,
            "low": 0.04,
            "high": 0.1107,
            "bootstrap_sd": 0.0253,
            "percentile": [0.04, 0.1043],
            "base": 0.2,
            "search": [0.04, 0.5],
        },
    ],  # fmt: skip
    "values": {"speed_median": 0.2871, "speed_sigma": 0.0612},
    "moments": [
        _moment(
            "completion_time_s: mean manual", "completion_time_s", 151.2, 6.1, 149.8, -0.23, True
        ),
        _moment("completion_time_s: sd manual", "completion_time_s", 21.4, 4.0, 30.2, 2.2, True),
        _moment(
            "completion_time_s: corr manual~reactive_bn",
            "completion_time_s",
            0.81,
            0.07,
            0.2,
            -8.7,
            True,
        ),
        _moment("completion_time_s: sd baseline", "completion_time_s", 0.0, 0.0, 0.0, None, False),
        _moment("secondary_errors: mean manual", "secondary_errors", 0.5, 0.2, 0.7, 1.0, False),
        _moment(
            "secondary_errors: corr manual~reactive_bn",
            "secondary_errors",
            None,
            None,
            0.1,
            math.nan,
            False,
        ),
    ],  # fmt: skip
    "timing": {"bank_s": 312.4, "fit_s": 41.0, "total_s": 360.2},
}


class _Balanced(HTMLParser):
    """Every non-void element closed, in order."""

    def __init__(self) -> None:
        super().__init__()
        self.open: list[str] = []

    def handle_starttag(self, tag, attrs) -> None:
        if tag not in VOID:
            self.open.append(tag)

    def handle_endtag(self, tag) -> None:
        assert self.open and self.open[-1] == tag, (tag, self.open[-5:])
        self.open.pop()


def _page(tmp_path, result=RESULT) -> str:
    html = write_calibration_report(copy.deepcopy(result), tmp_path / "population.toml")
    assert html == tmp_path / "population.html"
    return html.read_text(encoding="utf-8")


def test_the_page_shows_every_parameter_and_moment(tmp_path):
    page = _page(tmp_path)
    for estimate, interval in (("0.287", "[0.251, 0.323]"), ("0.061", "[0.040, 0.111]")):
        assert f'<td class="v">{estimate}</td>' in page
        assert interval in page
    assert "cut at the lower bound" in page  # speed_sigma's interval reaches 0.04
    for m in RESULT["moments"]:
        assert str(escape(m["moment"])) in page
    assert page.count("<svg") == 2
    assert '<td class="no">no</td>' in page and "n/a" in page
    assert "+2.20" in page and "-8.70" in page


def test_the_page_is_balanced_and_escaped(tmp_path):
    page = _page(tmp_path)
    parser = _Balanced()
    parser.feed(page)
    parser.close()
    assert parser.open == []
    assert "<script" not in page
    assert "&lt;script&gt;alert(1)&lt;/script&gt;" in page


def test_the_text_words_the_blocks_and_limits_from_the_result():
    text = methods_paragraph(RESULT)
    assert "the speed block (speed_median and speed_sigma, identified by the planned " in text
    assert "completion_time_s)" in text and "tlx_bias_mean" in text
    assert "R = 30 bootstrap replicates" in text and "95 % interval" in text
    limits = " ".join(limitations(RESULT))
    assert "here: secondary_errors" in limits and "speed_sigma (lower)" in limits
    older = {k: v for k, v in RESULT.items() if k not in ("identified_by", "not_fitted")}
    assert "Every other parameter keeps" in methods_paragraph(older)
