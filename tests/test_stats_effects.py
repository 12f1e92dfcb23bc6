"""Issue 21's additions to analysis.stats: effect sizes with CIs, Holm and Bonferroni pairs,
assumption checks and the APA text. Properties and independent computations (scipy,
statsmodels); tests/test_stats_oracle.py checks the same numbers against R."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pandas as pd
import pytest
import scipy.stats
from statsmodels.stats.multitest import multipletests

from analysis.stats import analyse, lsd_paired, lsd_warning, paired_adjusted
from analysis.stats.apa import format_p
from analysis.stats.assumptions import normality, outliers, studentised_residuals
from analysis.stats.effects import ncp_interval_f, ncp_interval_t, pair_effects
from analysis.stats.posthoc import bonferroni, holm

COLUMNS = {"dv": "y", "within": "mode", "subject": "pid"}


def to_long(y: np.ndarray) -> pd.DataFrame:
    n, k = y.shape
    rows = [(f"P{i:02d}", f"L{j}", y[i, j]) for i in range(n) for j in range(k)]
    return pd.DataFrame(rows, columns=["pid", "mode", "y"])


def design(rng: np.random.Generator, n: int, k: int, effect: float) -> np.ndarray:
    return (
        10 + rng.normal(0, 3, (n, 1)) + effect * rng.normal(size=(1, k)) + rng.normal(size=(n, k))
    )


def test_eta_interval_solves_its_equations_and_excludes_zero_iff_the_f_test_rejects(rng):
    for n, k, effect in [(8, 3, 0.3), (12, 4, 1.0), (20, 3, 0.0), (6, 2, 2.0), (10, 5, 0.5)]:
        out = analyse(to_long(design(rng, n, k, effect)), **COLUMNS, mixed=False)
        anova, np2 = out["anova"], out["effect_sizes"]["np2"]
        assert np2["value"] == pytest.approx(anova["np2"], rel=1e-12)
        assert np2["ci_level"] == pytest.approx(0.90)
        assert 0.0 <= np2["ci_low"] <= np2["value"] <= np2["ci_high"] < 1.0
        # Steiger (2004): the 1 - 2 alpha interval excludes 0 iff p < alpha
        assert (np2["ci_low"] > 0.0) == (anova["p_unc"] < 0.05)
        F, df1, df2 = anova["F"], anova["df_effect"], anova["df_error"]
        low, high = ncp_interval_f(F, df1, df2, 0.90)
        assert scipy.stats.ncf.cdf(F, df1, df2, high) == pytest.approx(0.05, abs=1e-9)
        if low > 0.0:
            assert scipy.stats.ncf.cdf(F, df1, df2, low) == pytest.approx(0.95, abs=1e-9)


def test_dz_interval_is_the_noncentral_t_inversion_and_agrees_with_the_t_test(rng):
    y = design(rng, 9, 4, 1.5)
    levels = ("a", "b", "c", "d")
    effects = pair_effects(y, levels, level=0.95)
    tests = lsd_paired(to_long(y), **COLUMNS)
    for effect, test, (i, j) in zip(
        effects, tests.to_dict("records"), itertools.combinations(range(4), 2), strict=True
    ):
        d = y[:, i] - y[:, j]
        assert effect["dz"] == pytest.approx(d.mean() / d.std(ddof=1))
        assert (effect["ci_low"], effect["ci_high"]) == pytest.approx(
            (test["ci_low"], test["ci_high"])
        )
        t, df = effect["dz"] * 3.0, 8  # sqrt(9) = 3
        assert scipy.stats.nct.cdf(t, df, effect["dz_ci_low"] * 3.0) == pytest.approx(0.975)
        assert scipy.stats.nct.cdf(t, df, effect["dz_ci_high"] * 3.0) == pytest.approx(0.025)
        # at delta = 0 the noncentral t is the central one: the CI excludes 0 iff p < .05
        assert (effect["dz_ci_low"] > 0 or effect["dz_ci_high"] < 0) == (test["p"] < 0.05)


def test_swapping_a_pair_mirrors_the_dz_interval():
    low, high = ncp_interval_t(2.3, 11, 0.95)
    assert ncp_interval_t(-2.3, 11, 0.95) == pytest.approx((-high, -low))
    assert ncp_interval_t(0.0, 11, 0.95)[0] == pytest.approx(-ncp_interval_t(0.0, 11, 0.95)[1])
    big = ncp_interval_t(40.0, 5, 0.95)  # far tails, where scipy's nct returns NaN
    assert all(math.isfinite(b) for b in big) and big[0] < 40.0 < big[1]


def test_holm_and_bonferroni_match_statsmodels(rng):
    for m in (1, 3, 6, 10):
        p = rng.uniform(0, 0.2, size=m)
        assert holm(p) == pytest.approx(multipletests(p, method="holm")[1], rel=1e-12)
        assert bonferroni(p) == pytest.approx(multipletests(p, method="bonferroni")[1])
    with_nan = np.array([0.01, np.nan, 0.04])
    assert np.isnan(holm(with_nan)[1]) and holm(with_nan)[[0, 2]] == pytest.approx([0.02, 0.04])


def test_adjusted_pairs_keep_t_and_widen_the_interval(rng):
    frame = to_long(design(rng, 10, 4, 1.0))
    plain = lsd_paired(frame, **COLUMNS)
    for method in ("holm", "bonferroni"):
        adjusted = paired_adjusted(frame, **COLUMNS, method=method)
        assert adjusted["t"].to_numpy() == pytest.approx(plain["t"].to_numpy())
        assert adjusted["p_unc"].to_numpy() == pytest.approx(plain["p"].to_numpy())
        assert (adjusted["p"] >= adjusted["p_unc"] - 1e-15).all()
        half = (adjusted["ci_high"] - adjusted["ci_low"]) / 2
        se = (plain["ci_high"] - plain["ci_low"]) / 2 / scipy.stats.t.ppf(0.975, 9)
        assert half.to_numpy() == pytest.approx(se * scipy.stats.t.ppf(1 - 0.05 / 12, 9))
    with pytest.raises(ValueError, match="holm or bonferroni"):
        paired_adjusted(frame, **COLUMNS, method="tukey")


def test_lsd_with_more_than_three_levels_warns(rng):
    assert lsd_warning("lsd_paired", 3) is None and lsd_warning("holm", 6) is None
    assert "three levels" in lsd_warning("lsd_pooled", 4)
    y = design(rng, 8, 4, 1.0)
    out = analyse(to_long(y), **COLUMNS, posthoc="lsd_paired", mixed=False)
    assert out["posthoc_warning"] in out["warnings"]
    holm_out = analyse(to_long(y), **COLUMNS, posthoc="holm", mixed=False)
    assert holm_out["posthoc_warning"] is None
    assert holm_out["posthoc_planned"] == "holm"
    with pytest.raises(ValueError, match="posthoc 'tukey' is not allowed"):
        analyse(to_long(y), **COLUMNS, posthoc="tukey")


def test_normality_and_outliers(rng):
    y = design(rng, 15, 3, 0.5)
    checks = normality(y, ("a", "b", "c"))
    for pair, (i, j) in zip(checks["pairs"], itertools.combinations(range(3), 2), strict=True):
        expected = scipy.stats.shapiro(y[:, i] - y[:, j])
        assert (pair["W"], pair["p"]) == pytest.approx((expected.statistic, expected.pvalue))
    y[4, 1] += 25.0  # one wild value
    found = outliers(y, ("a", "b", "c"), tuple(f"P{i}" for i in range(15)))
    assert found["count"] >= 1 and found["items"][0]["subject"] == "P4"
    assert found["items"][0]["level"] == "b" and found["items"][0]["t"] > 3.0


def test_studentised_residuals_match_statsmodels_ols(rng):
    import statsmodels.formula.api as smf

    y = design(rng, 7, 4, 1.0)
    frame = to_long(y)
    fit = smf.ols("y ~ C(pid) + C(mode)", frame).fit()
    expected = fit.get_influence().resid_studentized_external
    assert studentised_residuals(y).ravel() == pytest.approx(np.asarray(expected), rel=1e-8)
    additive = 5.0 + np.arange(3)[None, :] + np.arange(4)[:, None]
    assert studentised_residuals(additive.astype(float)) is None  # SS_error = 0


def test_assumption_failures_are_warnings_of_the_planned_anova(rng):
    y = design(rng, 12, 3, 0.5)
    y[0, 0] += 40.0
    anova = analyse(to_long(y), **COLUMNS, mixed=False)
    assert any("outlier" in w for w in anova["warnings"])
    ranks = analyse(to_long(y), **COLUMNS, test="friedman", mixed=False)
    assert not any("outlier" in w for w in ranks["warnings"])  # not an assumption of Friedman
    assert ranks["assumptions"]["outliers"]["count"] >= 1  # but still reported


@pytest.mark.parametrize(
    ("p", "alpha", "text"),
    [
        (0.04996, 0.05, "= .04996"),
        (0.0504, 0.05, "= .050"),
        (0.05, 0.05, "= .050"),
        (0.0099, 0.01, "= .0099"),
        (0.0004, 0.05, "< .001"),
        (None, 0.05, "n/a"),
    ],
)
def test_a_rounded_p_never_lands_on_alpha_from_below(p, alpha, text):
    assert format_p(p, alpha=alpha) == text


def test_apa_lines(rng):
    out = analyse(to_long(design(rng, 12, 3, 3.0)), **COLUMNS, posthoc="holm")
    apa = out["apa"]
    assert apa["planned"] == apa["rm_anova"]
    assert "eta_p^2 = " in apa["rm_anova"] and "90% CI [" in apa["rm_anova"]
    assert "eta_G^2" in apa["rm_anova"] and "0." not in apa["rm_anova"].split("eta_p^2")[1][:6]
    assert apa["friedman"].startswith("chi2(2) = ") and ", W = ." in apa["friedman"]
    assert len(apa["pairs"]) == 3 and all("d_z = " in line for line in apa["pairs"])
    assert "(likelihood ratio, ML; 36 observations of 12 participants)" in apa["mixed"]
    assert apa["order"] is None
