"""Issue 21's non-parametric path (Friedman, Kendall's W, Wilcoxon-Holm, the auto rule) and
mixed models (MixedLM, LRTs, order effects). Checked against scipy and by properties here;
tests/test_stats_oracle.py checks them against R."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest
import scipy.stats

from analysis.stats import analyse, choose_test
from analysis.stats.mixed import cells, mixed_model, order_effects
from analysis.stats.nonparametric import friedman, wilcoxon, wilcoxon_holm

COLUMNS = {"dv": "y", "within": "mode", "subject": "pid"}


def crossover(rng: np.random.Generator, n: int, k: int, effect: float = 2.0) -> pd.DataFrame:
    """Long frame with pid, mode, position, y: cyclic orders, a mode and a position effect."""
    rows = []
    for i in range(n):
        person = rng.normal(0, 3)
        for position in range(k):
            j = (i + position) % k
            y = 20 + person + effect * j + 0.5 * position + rng.normal()
            rows.append((f"P{i:02d}", f"L{j}", position + 1, y))
    return pd.DataFrame(rows, columns=["pid", "mode", "position", "y"])


def test_friedman_matches_scipy_with_ties(rng):
    for n, k in [(10, 3), (7, 4), (15, 5)]:
        y = np.round(rng.normal(size=(n, k)) * 1.5)  # many ties within rows
        ours = friedman(y)
        expected = scipy.stats.friedmanchisquare(*y.T)
        assert ours["chi2"] == pytest.approx(expected.statistic, rel=1e-10)
        assert ours["p"] == pytest.approx(expected.pvalue, rel=1e-9)
        assert 0.0 <= ours["kendall_w"] <= 1.0


def test_kendalls_w_is_one_for_perfect_agreement_and_undefined_for_all_ties():
    y = np.tile(np.arange(4.0), (6, 1)) + np.arange(6.0)[:, None]
    assert friedman(y)["kendall_w"] == pytest.approx(1.0)
    assert friedman(np.ones((5, 3)))["chi2"] is None


def test_wilcoxon_matches_scipy_exact_and_normal(rng):
    d = rng.normal(size=14)
    exact = scipy.stats.wilcoxon(d, method="exact")
    ours = wilcoxon(d)
    assert ours["method"] == "exact" and ours["p"] == pytest.approx(exact.pvalue, rel=1e-12)
    assert min(ours["V"], 14 * 15 / 2 - ours["V"]) == exact.statistic
    tied = np.round(rng.normal(size=20) * 2)  # ties and zeros: normal approximation
    approx = scipy.stats.wilcoxon(tied, zero_method="wilcox", correction=True, method="approx")
    ours = wilcoxon(tied)
    assert ours["method"] == "normal" and ours["p"] == pytest.approx(approx.pvalue, rel=1e-10)
    assert wilcoxon(np.zeros(5))["p"] is None


def test_wilcoxon_pairs_are_holm_adjusted(rng):
    y = rng.normal(size=(12, 4)) + np.array([0.0, 0.5, 1.0, 1.5])
    rows = wilcoxon_holm(y, ("a", "b", "c", "d"))
    raw = np.array([r["p_unc"] for r in rows])
    order = np.argsort(raw)
    adjusted = np.maximum.accumulate(np.minimum(1, (6 - np.arange(6)) * raw[order]))
    assert np.array([r["p"] for r in rows])[order] == pytest.approx(adjusted)


@pytest.mark.parametrize(
    ("values", "planned"),
    [
        (np.r_[np.zeros(20), [1, 2, 1, 3]], "friedman"),  # counts, mostly zero
        (np.tile([1.0, 2, 3, 4, 5, 6, 7], 3), "friedman"),  # a 7-point item, 21 answers
        (np.linspace(30.5, 90.2, 24), "rm_anova"),  # times
        (np.arange(24.0), "rm_anova"),  # whole numbers, no ties
    ],
)
def test_auto_rule(values, planned):
    test, reason = choose_test(values)
    assert test == planned and reason.startswith("auto: ")
    assert choose_test(values, requested="rm_anova") == ("rm_anova", "requested")
    with pytest.raises(ValueError, match="test 'anova' is not allowed"):
        choose_test(values, requested="anova")


def test_planned_friedman_leads_and_rm_anova_follows(rng):
    frame = crossover(rng, 12, 3).drop(columns="position")
    frame["y"] = np.round(frame["y"] / 10)  # few distinct values: auto picks Friedman
    out = analyse(frame, **COLUMNS, test="auto", mixed=False)
    assert out["planned"]["test"] == "friedman" and out["planned"]["other"] == "rm_anova"
    assert out["planned"]["p"] == out["friedman"]["p"]
    assert out["apa"]["planned"] == out["apa"]["friedman"]
    assert out["anova"]["F"] is not None  # the other test is still there


def test_mixed_model_keeps_a_participant_with_a_missing_level(rng):
    frame = crossover(rng, 10, 3)
    frame = frame[~((frame["pid"] == "P04") & (frame["mode"] == "L1"))]
    data = cells(frame, **COLUMNS, order="position")
    out = mixed_model(data, ["L0", "L1", "L2"])
    assert out["n_obs"] == 29 and out["n_subjects"] == 10
    assert out["incomplete_subjects"] == ["P04"]
    assert out["lrt"]["df"] == 2 and out["lrt"]["p"] < 0.05
    terms = [f["term"] for f in out["fixed"]]
    assert terms == ["(Intercept)", "modeL1", "modeL2", "position"]
    assert out["fixed"][2]["estimate"] == pytest.approx(4.0, abs=1.5)
    assert "anti-conservative" in out["caveat"]
    full = analyse(frame, **COLUMNS, order="position")
    assert full["n_subjects"] == 9 and full["mixed"]["n_subjects"] == 10


def test_a_constant_per_participant_changes_no_likelihood_ratio(rng):
    frame = crossover(rng, 9, 3)
    shifted = frame.assign(y=frame["y"] + frame["pid"].str[1:].astype(int) * 7.0)
    a = mixed_model(cells(frame, **COLUMNS, order="position"), ["L0", "L1", "L2"])
    b = mixed_model(cells(shifted, **COLUMNS, order="position"), ["L0", "L1", "L2"])
    assert b["lrt"]["chi2"] == pytest.approx(a["lrt"]["chi2"], rel=1e-4, abs=1e-6)


def test_order_effects_and_aliased_positions(rng):
    frame = crossover(rng, 12, 3)
    out = order_effects(cells(frame, **COLUMNS, order="position"), ["L0", "L1", "L2"])
    assert out["position"]["df"] == 2 and out["mode_x_position"]["df"] == 4
    assert set(out["position_means"]) == {"1", "2", "3"}
    # everyone in the same order: position is mode, nothing left to test
    same = frame.assign(position=frame["mode"].str[1:].astype(int) + 1)
    aliased = order_effects(cells(same, **COLUMNS, order="position"), ["L0", "L1", "L2"])
    assert aliased["position"]["df"] == 0 and aliased["position"]["chi2"] is None


def test_an_exact_fit_has_no_mixed_model():
    y = 5.0 + np.arange(3)[None, :] + np.arange(4)[:, None] * 2.0
    rows = [(f"P{i}", f"L{j}", y[i, j]) for i in range(4) for j in range(3)]
    out = analyse(pd.DataFrame(rows, columns=["pid", "mode", "y"]), **COLUMNS)
    assert out["mixed"]["lrt"]["chi2"] is None and out["mixed"]["fixed"] == []


def test_bad_order_columns_are_one_line_errors(rng):
    frame = crossover(rng, 4, 3)
    with pytest.raises(ValueError, match=r"^column 'pos' \(order\) not found"):
        cells(frame, **COLUMNS, order="pos")
    text = frame.astype({"position": object})
    text.loc[2, "position"] = "third"
    with pytest.raises(ValueError, match=r"^column 'position': row 2: 'third' is not a position"):
        cells(text, **COLUMNS, order="position")
    twice = pd.concat([frame, frame.iloc[[0]].assign(position=3)])
    with pytest.raises(ValueError, match="has rows with different positions"):
        cells(twice, **COLUMNS, order="position")
