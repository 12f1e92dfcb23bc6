"""analysis.stats: repeated-measures ANOVA, Mauchly, Greenhouse-Geisser and Fisher's LSD.

Numbers are checked against computations written here (explicit loops, R's mauchly.test
algorithm transcribed, Box's scalar epsilon formula), statsmodels' AnovaRM, scipy's ttest_rel,
pingouin 0.7 and the published SPSS output of Field's Bushtucker example (tests/r/ keeps the
data and the R script that reproduces them); the rest are properties that hold for any data.
"""

from __future__ import annotations

import itertools
import json
import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest
import scipy.stats
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from analysis.stats import (
    GATES,
    POSTHOC,
    analyse,
    descriptives,
    gate_p,
    greenhouse_geisser,
    lsd_paired,
    lsd_pooled,
    mauchly,
    repeated_measures,
    rm_anova,
)

HERE = Path(__file__).parent
COLUMNS = {"dv": "y", "within": "mode", "subject": "pid"}
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
}
# issue 21's additions (tests/test_stats_effects.py and the others test them)
NEW_KEYS = {
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
PAIR_KEYS = {"a", "b", "diff", "t", "df", "p", "ci_low", "ci_high", "significant"}
FEW = settings(
    max_examples=25, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)


def to_long(y: np.ndarray, levels=None, subjects=None) -> pd.DataFrame:
    """(n, k) wide array -> long frame, subject-major row order."""
    n, k = y.shape
    levels = levels if levels is not None else [f"L{j}" for j in range(k)]
    subjects = subjects if subjects is not None else [f"P{i:02d}" for i in range(n)]
    rows = [(subjects[i], levels[j], y[i, j]) for i in range(n) for j in range(k)]
    return pd.DataFrame(rows, columns=["pid", "mode", "y"])


def random_design(rng: np.random.Generator, n: int, k: int, effect: float = 1.0) -> np.ndarray:
    """Subject effect + condition effect + heteroscedastic errors (not spherical)."""
    subject = rng.normal(0.0, 3.0, size=(n, 1))
    condition = effect * rng.normal(0.0, 1.0, size=(1, k))
    scale = rng.uniform(0.5, 2.0, size=(1, k))
    return 10.0 + subject + condition + scale * rng.normal(size=(n, k))


def field_bushtucker() -> pd.DataFrame:
    return pd.read_csv(HERE / "r" / "bushtucker.csv", dtype={"celebrity": str})


FIELD = {"dv": "retch_s", "within": "animal", "subject": "celebrity"}


def close(a, b, rel=1e-9, abs_=1e-12) -> bool:
    if a is None or b is None:
        return a is b
    return math.isclose(a, b, rel_tol=rel, abs_tol=abs_)


# ------------------------------------------------------------------------------------------
# Independent computations
# ------------------------------------------------------------------------------------------


def sums_of_squares_by_loops(y: np.ndarray) -> dict:
    n, k = y.shape
    grand = 0.0
    for i in range(n):
        for j in range(k):
            grand += y[i, j]
    grand /= n * k
    row = [sum(y[i, j] for j in range(k)) / k for i in range(n)]
    col = [sum(y[i, j] for i in range(n)) / n for j in range(k)]
    ss_total = sum((y[i, j] - grand) ** 2 for i in range(n) for j in range(k))
    ss_effect = sum(n * (col[j] - grand) ** 2 for j in range(k))
    ss_subjects = sum(k * (row[i] - grand) ** 2 for i in range(n))
    ss_error = ss_total - ss_effect - ss_subjects
    return {
        "ss_total": ss_total,
        "ss_effect": ss_effect,
        "ss_subjects": ss_subjects,
        "ss_error": ss_error,
    }


def mauchly_as_r(y: np.ndarray) -> tuple[float, float, float]:
    """R's mauchly.test.SSD with X = ~1, transcribed: T = Thin.row(proj(M) - proj(X)) with
    M = I, so T is k - 1 independent rows of the centring matrix (not orthonormal), Psi = T T',
    U = Psi^-1 T SSD T'. Returns W, z (R's chi-square) and p."""
    n, k = y.shape
    centred = y - y.mean(axis=0)
    ssd = centred.T @ centred  # object$SSD of lm(Y ~ 1), df = n - 1
    projection = np.eye(k) - np.ones((k, k)) / k  # proj(M) - proj(X)
    T = projection[:-1]  # Thin.row keeps k - 1 linearly independent rows
    psi = T @ T.T
    B = T @ ssd @ T.T
    U = np.linalg.solve(psi, B)
    pp, nu, p = k - 1, n - 1, k
    log_w = math.log(np.linalg.det(U)) - pp * math.log(np.trace(U / pp))
    rho = 1 - (2 * pp**2 + pp + 2) / (6 * pp * nu)
    w2 = (
        (pp + 2)
        * (pp - 1)
        * (pp - 2)
        * (2 * pp**3 + 6 * pp**2 + 3 * p + 2)
        / (288 * (nu * pp * rho) ** 2)
    )
    z = -nu * rho * log_w
    f = pp * (pp + 1) / 2 - 1
    pr1 = scipy.stats.chi2.sf(z, f)
    pr2 = scipy.stats.chi2.sf(z, f + 4)
    return math.exp(log_w), z, pr1 + w2 * (pr2 - pr1)


def box_epsilon_scalar(y: np.ndarray) -> float:
    """Box's (1954) scalar formula: k^2 (mean diag - mean all)^2 / ((k - 1) (sum s_ij^2 -
    2 k sum row_mean^2 + k^2 mean_all^2))."""
    k = y.shape[1]
    s = np.cov(y, rowvar=False)
    mean_all = s.mean()
    mean_diag = np.trace(s) / k
    row_means = s.mean(axis=1)
    num = k**2 * (mean_diag - mean_all) ** 2
    den = (k - 1) * (np.sum(s**2) - 2 * k * np.sum(row_means**2) + k**2 * mean_all**2)
    return float(num / den)


# ------------------------------------------------------------------------------------------
# ANOVA
# ------------------------------------------------------------------------------------------


@pytest.mark.parametrize("shape", [(2, 2), (5, 3), (12, 4), (7, 6)])
def test_sums_of_squares_f_p_and_effect_sizes_by_hand(rng, shape):
    y = random_design(rng, *shape)
    n, k = shape
    ss = sums_of_squares_by_loops(y)
    out = rm_anova(to_long(y), **COLUMNS)
    df1, df2 = k - 1, (n - 1) * (k - 1)
    assert (out["df_effect"], out["df_error"]) == (df1, df2)
    assert out["ss_effect"] == pytest.approx(ss["ss_effect"], rel=1e-10)
    assert out["ss_error"] == pytest.approx(ss["ss_error"], rel=1e-8)
    assert out["ms_error"] == pytest.approx(ss["ss_error"] / df2, rel=1e-8)
    F = (ss["ss_effect"] / df1) / (ss["ss_error"] / df2)
    assert out["F"] == pytest.approx(F, rel=1e-8)
    assert out["p_unc"] == pytest.approx(scipy.stats.f.sf(F, df1, df2), rel=1e-7)
    assert out["np2"] == pytest.approx(ss["ss_effect"] / (ss["ss_effect"] + ss["ss_error"]))
    assert out["ng2"] == pytest.approx(ss["ss_effect"] / ss["ss_total"])


def test_f_and_p_match_statsmodels_anovarm(rng):
    from statsmodels.stats.anova import AnovaRM

    for n, k in [(4, 2), (9, 3), (18, 3), (11, 5)]:
        y = random_design(rng, n, k)
        frame = to_long(y)
        table = AnovaRM(frame, depvar="y", subject="pid", within=["mode"]).fit().anova_table
        out = rm_anova(frame, **COLUMNS)
        assert out["F"] == pytest.approx(table["F Value"].iloc[0], rel=1e-9)
        assert out["p_unc"] == pytest.approx(table["Pr > F"].iloc[0], rel=1e-7)
        assert out["df_effect"] == table["Num DF"].iloc[0]
        assert out["df_error"] == table["Den DF"].iloc[0]


@pytest.mark.filterwarnings("ignore:The inplace keyword")  # pingouin 0.7 on pandas 3
def test_matches_pingouin_rm_anova_sphericity_and_epsilon(rng):
    import pingouin

    for n, k in [(10, 3), (15, 4), (25, 5)]:
        y = random_design(rng, n, k)
        frame = to_long(y)
        table = pingouin.rm_anova(
            frame, dv="y", within="mode", subject="pid", detailed=True, correction=True
        )
        out = analyse(frame, **COLUMNS)
        assert out["anova"]["F"] == pytest.approx(table["F"].iloc[0], rel=1e-9)
        # pingouin 0.7 names the columns p_unc / p_GG_corr; 0.5 had p-unc / p-GG-corr
        table.columns = [str(c).replace("-", "_") for c in table.columns]
        assert out["anova"]["p_unc"] == pytest.approx(table["p_unc"].iloc[0], rel=1e-7)
        assert out["anova"]["ng2"] == pytest.approx(table["ng2"].iloc[0], rel=1e-9)
        assert out["greenhouse_geisser"]["eps"] == pytest.approx(table["eps"].iloc[0], rel=1e-9)
        assert out["greenhouse_geisser"]["p"] == pytest.approx(table["p_GG_corr"].iloc[0], rel=1e-7)
        spher = pingouin.sphericity(frame, dv="y", within="mode", subject="pid")
        assert out["sphericity"]["W"] == pytest.approx(spher.W, rel=1e-9)
        assert out["sphericity"]["chi2"] == pytest.approx(spher.chi2, rel=1e-9)
        assert out["sphericity"]["dof"] == spher.dof
        assert out["sphericity"]["p"] == pytest.approx(spher.pval, rel=1e-7)


def test_field_bushtucker_published_values():
    # Field, Discovering Statistics Using SPSS, repeated-measures chapter (SPSS output);
    # tests/r/rm_stats.R reproduces these from R on tests/r/bushtucker.csv.
    out = analyse(field_bushtucker(), **FIELD)
    assert out["levels"] == ["stick_insect", "kangaroo_testicle", "fish_eye", "witchetty_grub"]
    assert out["n_subjects"] == 8
    means = [out["descriptives"][level]["mean"] for level in out["levels"]]
    sds = [out["descriptives"][level]["sd"] for level in out["levels"]]
    assert means == pytest.approx([8.125, 4.25, 4.125, 5.75])
    assert sds == pytest.approx([2.23, 1.83, 2.75, 2.92], abs=0.005)
    anova = out["anova"]
    assert (anova["df_effect"], anova["df_error"]) == (3, 21)
    assert anova["ss_effect"] == pytest.approx(83.125)
    assert anova["ss_error"] == pytest.approx(153.375)
    assert anova["F"] == pytest.approx(3.794, abs=5e-4)
    assert anova["p_unc"] == pytest.approx(0.026, abs=5e-4)
    sph = out["sphericity"]
    assert sph["W"] == pytest.approx(0.136, abs=5e-4)
    assert sph["chi2"] == pytest.approx(11.41, abs=5e-3)
    assert sph["dof"] == 5
    assert sph["p"] == pytest.approx(0.047, abs=5e-4)
    assert sph["violated"] is True
    assert out["greenhouse_geisser"]["eps"] == pytest.approx(0.533, abs=5e-4)
    assert out["greenhouse_geisser"]["p"] == pytest.approx(0.063, abs=5e-4)
    # auto gate: sphericity violated -> GG p = .063 -> no LSD (Holm and Bonferroni run)
    assert out["p_gate"] == out["greenhouse_geisser"]["p"]
    assert out["significant"] is False
    posthoc = out["posthoc"]
    assert (posthoc["ran"], posthoc["gated"], posthoc["posthoc_gate"]) == (False, True, "auto")
    assert posthoc["lsd_paired"] == posthoc["lsd_pooled"] == []
    assert len(posthoc["holm"]) == len(posthoc["bonferroni"]) == 6


def test_constant_per_subject_changes_nothing(seed):
    @FEW
    @given(
        data_seed=st.integers(0, 2**32 - 1),
        k=st.integers(2, 5),
        shift=st.floats(-1e3, 1e3, allow_nan=False),
    )
    def check(data_seed, k, shift):
        rng = np.random.default_rng([seed, data_seed])
        y = random_design(rng, 6, k)
        shifted = y.copy()
        shifted[rng.integers(6)] += shift
        a = analyse(to_long(y), **COLUMNS, gate="uncorrected", alpha=0.999, mixed=False)
        b = analyse(to_long(shifted), **COLUMNS, gate="uncorrected", alpha=0.999, mixed=False)
        assert b["anova"]["F"] == pytest.approx(a["anova"]["F"], rel=1e-6)
        assert b["anova"]["ss_error"] == pytest.approx(a["anova"]["ss_error"], rel=1e-6)
        assert b["sphericity"]["W"] == pytest.approx(a["sphericity"]["W"], rel=1e-6)
        assert b["greenhouse_geisser"]["eps"] == pytest.approx(
            a["greenhouse_geisser"]["eps"], rel=1e-6
        )
        for pa, pb in zip(a["posthoc"]["lsd_paired"], b["posthoc"]["lsd_paired"], strict=True):
            assert pb["t"] == pytest.approx(pa["t"], rel=1e-6)

    check()


def assert_same_result(a: dict, b: dict, *, rel: float = 1e-9) -> None:
    """Equal objects, floats up to rounding (summation order differs)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and set(a) == set(b)
        for key in a:
            assert_same_result(a[key], b[key], rel=rel)
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            assert_same_result(x, y, rel=rel)
    elif isinstance(a, float):
        assert b == pytest.approx(a, rel=rel, abs=1e-12)
    else:
        assert a == b


def test_permuting_participants_changes_nothing(rng):
    for k in (2, 3, 4):
        y = random_design(rng, 9, k, effect=3.0)
        order = rng.permutation(9)
        subjects = [f"P{i:02d}" for i in range(9)]
        a = analyse(to_long(y, subjects=subjects), **COLUMNS, mixed=False)
        b = analyse(
            to_long(y[order], subjects=[subjects[i] for i in order]), **COLUMNS, mixed=False
        )
        assert_same_result(a, b)
        # anonymous relabelling too (outliers name their subject: compare without names)
        c = analyse(to_long(y[order], subjects=[f"X{i}" for i in range(9)]), **COLUMNS, mixed=False)
        for result in (a, c):
            result["warnings"] = [w for w in result["warnings"] if "outlier" not in w]
            for item in result["assumptions"]["outliers"]["items"]:
                item["subject"] = "?"
            result["apa"] = None
        assert_same_result(a, c)


def test_reordering_and_relabelling_rows_changes_nothing_but_level_order(rng):
    y = random_design(rng, 8, 4, effect=3.0)
    frame = to_long(y)
    a = analyse(frame, **COLUMNS, gate="uncorrected", alpha=0.999)
    shuffled = frame.sample(frac=1.0, random_state=rng.integers(2**31)).reset_index(drop=True)
    renamed = {f"L{j}": f"mode_{j}" for j in range(4)}
    shuffled["mode"] = shuffled["mode"].map(renamed)
    b = analyse(shuffled, **COLUMNS, gate="uncorrected", alpha=0.999)
    assert b["levels"] == list(pd.unique(shuffled["mode"]))
    for key in ("anova", "sphericity", "greenhouse_geisser"):
        assert_same_result(a[key], b[key])
    for level, stats in a["descriptives"].items():
        assert_same_result(stats, b["descriptives"][renamed[level]])
    for kind in ("lsd_paired", "lsd_pooled"):
        by_pair = {(p["a"], p["b"]): p for p in b["posthoc"][kind]}
        for pair in a["posthoc"][kind]:
            key = (renamed[pair["a"]], renamed[pair["b"]])
            sign = 1.0 if key in by_pair else -1.0
            other = by_pair[key if sign > 0 else key[::-1]]
            assert other["diff"] == pytest.approx(sign * pair["diff"], rel=1e-9)
            assert other["t"] == pytest.approx(sign * pair["t"], rel=1e-9)
            assert other["p"] == pytest.approx(pair["p"], rel=1e-9)
            low, high = (pair["ci_low"], pair["ci_high"])
            expected = (low, high) if sign > 0 else (-high, -low)
            assert (other["ci_low"], other["ci_high"]) == pytest.approx(expected, rel=1e-9)


# ------------------------------------------------------------------------------------------
# Sphericity and Greenhouse-Geisser
# ------------------------------------------------------------------------------------------


def test_mauchly_matches_r_algorithm(rng):
    for n, k in [(5, 3), (8, 4), (12, 5), (30, 6), (7, 7)]:
        y = random_design(rng, n, k)
        W, z, p = mauchly_as_r(y)
        out = mauchly(to_long(y), **COLUMNS)
        assert out["W"] == pytest.approx(W, rel=1e-8)
        assert out["chi2"] == pytest.approx(z, rel=1e-8)
        assert out["p"] == pytest.approx(p, rel=1e-7, abs=1e-15)
        assert out["dof"] == (k - 1) * k // 2 - 1
        assert out["violated"] == (out["p"] < 0.05)
        assert 0.0 < out["W"] <= 1.0


def test_gg_epsilon_matches_box_formula_and_bounds(seed):
    @FEW
    @given(data_seed=st.integers(0, 2**32 - 1), n=st.integers(2, 15), k=st.integers(3, 6))
    def check(data_seed, n, k):
        rng = np.random.default_rng([seed, data_seed])
        y = random_design(rng, n, k)
        frame = to_long(y)
        gg = greenhouse_geisser(frame, **COLUMNS)
        anova = rm_anova(frame, **COLUMNS)
        assert 1.0 / (k - 1) - 1e-12 <= gg["eps"] <= 1.0 + 1e-12
        assert gg["eps"] == pytest.approx(
            min(1.0, max(1 / (k - 1), box_epsilon_scalar(y))), rel=1e-7
        )
        scaled = scipy.stats.f.sf(anova["F"], gg["eps"] * (k - 1), gg["eps"] * (n - 1) * (k - 1))
        assert gg["p"] == pytest.approx(scaled, rel=1e-9)
        assert 0.0 <= gg["p"] <= 1.0

    check()


def test_two_levels_sphericity_trivial_and_f_is_paired_t_squared(seed):
    @FEW
    @given(data_seed=st.integers(0, 2**32 - 1), n=st.integers(2, 30))
    def check(data_seed, n):
        rng = np.random.default_rng([seed, data_seed])
        y = random_design(rng, n, 2)
        out = analyse(to_long(y), **COLUMNS, alpha=0.999, mixed=False)
        assert out["sphericity"] == {"W": 1.0, "chi2": 0.0, "dof": 0, "p": 1.0, "violated": False}
        assert out["greenhouse_geisser"]["eps"] == 1.0
        assert out["greenhouse_geisser"]["p"] == pytest.approx(out["anova"]["p_unc"])
        t = scipy.stats.ttest_rel(y[:, 0], y[:, 1])
        assert out["anova"]["F"] == pytest.approx(t.statistic**2, rel=1e-8)
        assert out["anova"]["p_unc"] == pytest.approx(t.pvalue, rel=1e-6)
        if out["posthoc"]["ran"]:
            (paired,) = out["posthoc"]["lsd_paired"]
            (pooled,) = out["posthoc"]["lsd_pooled"]
            assert paired["t"] == pytest.approx(pooled["t"], rel=1e-8)
            assert paired["df"] == pooled["df"] == n - 1

    check()


def test_gate_rules():
    anova = {"p_unc": 0.01}
    gg = {"eps": 0.6, "p": 0.08}
    violated = {"violated": True}
    fine = {"violated": False}
    assert gate_p(anova, violated, gg) == 0.08
    assert gate_p(anova, fine, gg) == 0.01
    assert gate_p(anova, violated, gg, gate="uncorrected") == 0.01
    assert gate_p(anova, fine, gg, gate="greenhouse_geisser") == 0.08
    with pytest.raises(ValueError, match="auto"):
        gate_p(anova, fine, gg, gate="huynh_feldt")


def test_gate_consistency_on_data(rng):
    for k in (3, 4):
        y = random_design(rng, 10, k, effect=0.8)
        for gate in GATES:
            out = analyse(to_long(y), **COLUMNS, gate=gate, mixed=False)
            expected = {
                "uncorrected": out["anova"]["p_unc"],
                "greenhouse_geisser": out["greenhouse_geisser"]["p"],
                "auto": out["greenhouse_geisser"]["p"]
                if out["sphericity"]["violated"]
                else out["anova"]["p_unc"],
            }[gate]
            assert out["p_gate"] == expected
            gg_used = gate == "greenhouse_geisser" or (
                gate == "auto" and out["sphericity"]["violated"]
            )
            assert out["p_gate_source"] == ("greenhouse_geisser" if gg_used else "uncorrected")
            assert out["significant"] == (out["p_gate"] < 0.05)
            assert out["posthoc"]["ran"] == out["significant"]
            n_pairs = k * (k - 1) // 2 if out["significant"] else 0
            assert len(out["posthoc"]["lsd_paired"]) == len(out["posthoc"]["lsd_pooled"])
            assert len(out["posthoc"]["lsd_paired"]) == n_pairs


def test_posthoc_gate_runs_holm_and_bonferroni_on_their_own(rng):
    """Whatever the omnibus p: under "auto" the LSD forms run only when the gate passes and
    Holm, Bonferroni and Friedman's Wilcoxon-Holm pairs always; "omnibus" gates every family,
    "none" none (with a warning for unprotected LSD). Equal level means (F = 0: the gate
    fails) and a large effect (it passes), so both outcomes occur."""
    seen = set()
    noise = random_design(rng, 8, 3, effect=0.0)
    null = noise - noise.mean(axis=0) + noise.mean()
    strong = null + np.array([0.0, 10.0, 20.0]) * noise.std()
    for y in (null, strong):
        for planned in POSTHOC:
            out = analyse(to_long(y), **COLUMNS, posthoc=planned, mixed=False)
            sig, ph = out["significant"], out["posthoc"]
            seen.add(sig)
            assert len(ph["lsd_paired"]) == len(ph["lsd_pooled"]) == (3 if sig else 0)
            assert len(ph["holm"]) == len(ph["bonferroni"]) == 3
            assert ph["gated"] == planned.startswith("lsd")
            assert ph["ran"] == (sig or not ph["gated"])
            assert len(out["friedman"]["posthoc"]["wilcoxon_holm"]) == 3
            gated = analyse(to_long(y), **COLUMNS, posthoc=planned, posthoc_gate="omnibus")
            assert all(len(gated["posthoc"][f]) == (3 if sig else 0) for f in POSTHOC)
            f_sig = gated["friedman"]["significant"]
            assert len(gated["friedman"]["posthoc"]["wilcoxon_holm"]) == (3 if f_sig else 0)
            free = analyse(to_long(y), **COLUMNS, posthoc=planned, posthoc_gate="none")
            assert all(len(free["posthoc"][f]) == 3 for f in POSTHOC)
            assert any("family-wise" in w for w in free["warnings"]) == planned.startswith("lsd")
            fast = analyse(to_long(y), **COLUMNS, posthoc=planned, decisions_only=True)
            assert fast["posthoc"][planned] == out["posthoc"][planned]
    assert seen == {True, False}
    with pytest.raises(ValueError, match="posthoc_gate 'sometimes'.*auto, omnibus, none"):
        analyse(to_long(y), **COLUMNS, posthoc_gate="sometimes")


def test_spherical_data_gives_w_and_eps_one(rng):
    y = spherical_design(rng, 10, 4)
    out = analyse(to_long(y), **COLUMNS)
    assert out["sphericity"]["W"] == pytest.approx(1.0)
    assert out["sphericity"]["p"] == pytest.approx(1.0)
    assert out["greenhouse_geisser"]["eps"] == pytest.approx(1.0)


# ------------------------------------------------------------------------------------------
# Fisher's LSD
# ------------------------------------------------------------------------------------------


def test_lsd_paired_matches_ttest_rel(rng):
    y = random_design(rng, 11, 4, effect=2.0)
    table = lsd_paired(to_long(y), **COLUMNS, alpha=0.1)
    assert list(table.columns) == ["a", "b", "diff", "t", "df", "p", "ci_low", "ci_high",
                                   "significant"]  # fmt: skip
    pairs = list(itertools.combinations(range(4), 2))
    assert [(r.a, r.b) for r in table.itertuples()] == [(f"L{i}", f"L{j}") for i, j in pairs]
    for row, (i, j) in zip(table.itertuples(), pairs, strict=True):
        ref = scipy.stats.ttest_rel(y[:, i], y[:, j])
        ci = ref.confidence_interval(confidence_level=0.9)
        assert row.diff == pytest.approx(y[:, i].mean() - y[:, j].mean())
        assert row.t == pytest.approx(ref.statistic, rel=1e-9)
        assert row.p == pytest.approx(ref.pvalue, rel=1e-8)
        assert row.df == 10
        assert (row.ci_low, row.ci_high) == pytest.approx((ci.low, ci.high), rel=1e-9)
        assert row.significant == (ref.pvalue < 0.1)


def test_lsd_pooled_formula(rng):
    n, k = 9, 3
    y = random_design(rng, n, k, effect=2.0)
    frame = to_long(y)
    table = lsd_pooled(frame, **COLUMNS)
    ss = sums_of_squares_by_loops(y)
    df_error = (n - 1) * (k - 1)
    se = math.sqrt(2 * (ss["ss_error"] / df_error) / n)
    t_crit = scipy.stats.t.ppf(0.975, df_error)
    for row, (i, j) in zip(table.itertuples(), itertools.combinations(range(k), 2), strict=True):
        diff = y[:, i].mean() - y[:, j].mean()
        t = diff / se
        p = 2 * scipy.stats.t.cdf(-abs(t), df_error)
        assert (row.a, row.b) == (f"L{i}", f"L{j}")
        assert row.diff == pytest.approx(diff)
        assert row.t == pytest.approx(t, rel=1e-8)
        assert row.df == df_error
        assert row.p == pytest.approx(p, rel=1e-7)
        assert row.ci_low == pytest.approx(diff - t_crit * se, rel=1e-8)
        assert row.ci_high == pytest.approx(diff + t_crit * se, rel=1e-8)
        assert row.significant == (p < 0.05)


def spherical_design(rng: np.random.Generator, n: int, k: int) -> np.ndarray:
    """Subject effect + condition effect + errors E = Z C' with Z centred and Z'Z = c I and
    C orthonormal contrasts, so the sample covariance of the levels, double-centred, is
    proportional to the centring matrix: every pair's difference variance is equal."""
    z = rng.normal(size=(n, k - 1))
    z -= z.mean(axis=0)
    q, _ = np.linalg.qr(z)  # orthonormal, still centred (columns are combinations of z's)
    contrasts, _ = np.linalg.qr(np.eye(k)[:, :-1] - 1.0 / k)  # (k, k-1), orthogonal to 1
    errors = rng.uniform(1.0, 5.0) * q @ contrasts.T
    subject = rng.normal(0.0, 4.0, size=(n, 1))
    condition = np.linspace(0.0, 2.0, k)[None, :]
    return 20.0 + subject + condition + errors


def test_pooled_and_paired_lsd_coincide_when_difference_variances_equal(rng):
    n, k = 12, 4
    y = spherical_design(rng, n, k)
    variances = [np.var(y[:, i] - y[:, j], ddof=1) for i, j in itertools.combinations(range(k), 2)]
    assert np.allclose(variances, variances[0], rtol=1e-9)  # the construction works
    frame = to_long(y)
    anova = rm_anova(frame, **COLUMNS)
    assert variances[0] == pytest.approx(2 * anova["ms_error"], rel=1e-9)
    paired = lsd_paired(frame, **COLUMNS)
    pooled = lsd_pooled(frame, **COLUMNS)
    assert np.allclose(paired["diff"], pooled["diff"], rtol=1e-12)
    assert np.allclose(paired["t"], pooled["t"], rtol=1e-9)
    # Same t, more df: the pooled p is smaller and its CI narrower.
    assert (pooled["df"] == (n - 1) * (k - 1)).all() and (paired["df"] == n - 1).all()
    assert (pooled["p"] < paired["p"]).all()
    assert ((pooled["ci_high"] - pooled["ci_low"]) < (paired["ci_high"] - paired["ci_low"])).all()


def test_pooled_standard_error_is_the_mean_of_paired_difference_variances(rng):
    # In any data the pair-averaged difference variance equals 2 MS_error.
    n, k = 10, 5
    y = random_design(rng, n, k)
    variances = [np.var(y[:, i] - y[:, j], ddof=1) for i, j in itertools.combinations(range(k), 2)]
    assert np.mean(variances) == pytest.approx(2 * rm_anova(to_long(y), **COLUMNS)["ms_error"])


# ------------------------------------------------------------------------------------------
# analyse: shape of the object, missing cells, duplicates, degenerate data, errors
# ------------------------------------------------------------------------------------------


def test_analyse_object_is_json_and_complete(rng):
    y = random_design(rng, 12, 3, effect=30.0)  # the effect is sure to pass the gate
    out = analyse(to_long(y, levels=["manual", "reactive", "task_aware"]), **COLUMNS)
    assert json.loads(json.dumps(out, allow_nan=False)) == out
    assert set(out) == KEYS | NEW_KEYS
    assert out["levels"] == ["manual", "reactive", "task_aware"]
    assert out["n_subjects"] == 12
    assert set(out["anova"]) == {
        "F", "df_effect", "df_error", "p_unc", "ss_effect", "ss_error", "ms_error", "np2", "ng2"
    }  # fmt: skip
    assert set(out["sphericity"]) == {"W", "chi2", "dof", "p", "violated"}
    assert set(out["greenhouse_geisser"]) == {"eps", "p"}
    for level, stats in out["descriptives"].items():
        assert set(stats) == {"mean", "sd", "se", "n"}
        column = y[:, out["levels"].index(level)]
        assert stats["mean"] == pytest.approx(column.mean())
        assert stats["sd"] == pytest.approx(column.std(ddof=1))
        assert stats["se"] == pytest.approx(column.std(ddof=1) / math.sqrt(12))
        assert stats["n"] == 12
    assert out["significant"] and out["posthoc"]["ran"]
    for kind in ("lsd_paired", "lsd_pooled"):
        assert len(out["posthoc"][kind]) == 3
        for pair in out["posthoc"][kind]:
            assert set(pair) == PAIR_KEYS
            assert isinstance(pair["df"], int) and isinstance(pair["significant"], bool)
    assert out["dropped_subjects"] == []
    assert not [w for w in out["warnings"] if "Shapiro" not in w and "outlier" not in w]


def test_descriptives_frame(rng):
    y = random_design(rng, 6, 3)
    table = descriptives(to_long(y), **COLUMNS)
    assert list(table.index) == ["L0", "L1", "L2"] and table.index.name == "mode"
    assert np.allclose(table["mean"], y.mean(axis=0))
    assert np.allclose(table["sd"], y.std(axis=0, ddof=1))
    assert np.allclose(table["se"], y.std(axis=0, ddof=1) / math.sqrt(6))
    assert (table["n"] == 6).all()


def test_missing_cells_drop_the_subject_with_a_named_warning(rng):
    y = random_design(rng, 7, 3)
    frame = to_long(y)
    # P02 lacks L1 (no row), P05 has an empty (NaN) value for L2
    holed = frame[~((frame["pid"] == "P02") & (frame["mode"] == "L1"))].copy()
    holed.loc[(holed["pid"] == "P05") & (holed["mode"] == "L2"), "y"] = np.nan
    out = analyse(holed, **COLUMNS)
    assert out["dropped_subjects"] == ["P02", "P05"]
    assert out["n_subjects"] == 5
    (warning,) = [w for w in out["warnings"] if "listwise" in w]
    assert "P02" in warning and "P05" in warning and "'L1'" in warning
    keep = [0, 1, 3, 4, 6]
    reference = analyse(to_long(y[keep], subjects=[f"P{i:02d}" for i in keep]), **COLUMNS)
    assert_same_result(out["anova"], reference["anova"])
    assert_same_result(out["descriptives"], reference["descriptives"])


def test_duplicate_cells_are_averaged_with_a_warning(rng):
    y = random_design(rng, 5, 3)
    frame = to_long(y)
    # P01/L2 measured three times around its value: the cell mean is the original value
    cell = (frame["pid"] == "P01") & (frame["mode"] == "L2")
    extra = pd.DataFrame({"pid": "P01", "mode": "L2", "y": [y[1, 2] + 1.0, y[1, 2] + 2.0]})
    doubled = pd.concat([frame.assign(y=frame["y"].where(~cell, y[1, 2] - 3.0)), extra])
    out = analyse(doubled, **COLUMNS)
    (warning,) = [w for w in out["warnings"] if "cell" in w]
    assert "1 (subject, level) cell" in warning and "P01" in warning and "3 rows" in warning
    assert_same_result(out["anova"], analyse(frame, **COLUMNS)["anova"])


def test_zero_error_variance_is_undefined_not_nan(rng):
    subject = rng.normal(0, 5, size=(6, 1))
    y = 100.0 + subject + np.array([[0.0, 1.0, 3.0]])  # perfectly additive: SS_error = 0
    out = analyse(to_long(y), **COLUMNS)
    json.dumps(out, allow_nan=False)
    assert out["anova"]["F"] is None and out["anova"]["p_unc"] is None
    assert out["anova"]["ss_error"] == 0.0 and out["anova"]["np2"] == 1.0
    assert out["greenhouse_geisser"] == {"eps": None, "p": None}
    assert out["sphericity"]["W"] is None and out["sphericity"]["violated"] is False
    assert out["p_gate"] is None and out["significant"] is False
    assert any("SS_error is 0" in w for w in out["warnings"])
    # all values equal: nothing is defined but it is still valid JSON
    flat = analyse(to_long(np.full((4, 3), 2.5)), **COLUMNS)
    assert flat["anova"]["np2"] is None and flat["anova"]["ng2"] is None
    json.dumps(flat, allow_nan=False)


def test_zero_sd_pair_has_undefined_t(rng):
    n = 8
    base = rng.normal(10, 2, size=n)
    # L0 - L1 is exactly 5 for everyone; L2 is noisy and far away (gate passes)
    y = np.column_stack([base + 5.0, base, base + 40.0 + rng.normal(0, 1, size=n)])
    out = analyse(to_long(y), **COLUMNS, gate="uncorrected")
    assert out["significant"]
    first = out["posthoc"]["lsd_paired"][0]
    assert (first["a"], first["b"]) == ("L0", "L1")
    assert first["t"] is None and first["p"] is None and first["significant"] is False
    assert first["ci_low"] == pytest.approx(5.0) and first["ci_high"] == pytest.approx(5.0)
    assert any("SD 0" in w for w in out["warnings"])


def test_fewer_subjects_than_levels_gives_w_zero(rng):
    y = random_design(rng, 3, 5)  # covariance of 4 contrasts from 3 subjects: rank 2
    out = analyse(to_long(y), **COLUMNS)
    assert out["sphericity"]["W"] == 0.0 and out["sphericity"]["p"] == 0.0
    assert out["sphericity"]["chi2"] is None and out["sphericity"]["violated"] is True
    assert 1 / 4 - 1e-12 <= out["greenhouse_geisser"]["eps"] <= 1.0
    assert out["p_gate"] == out["greenhouse_geisser"]["p"]
    assert any("singular" in w for w in out["warnings"])


def test_numeric_labels_become_strings(rng):
    y = random_design(rng, 4, 3)
    frame = to_long(y, levels=[1, 2, 3], subjects=[101, 102, 103, 104])
    out = analyse(frame, **COLUMNS)
    assert out["levels"] == ["1", "2", "3"]
    assert list(out["descriptives"]) == ["1", "2", "3"]


def test_errors_are_clear(rng):
    y = random_design(rng, 5, 3)
    frame = to_long(y)
    with pytest.raises(ValueError, match=r"column 'time_s' \(dv\) not found.*'pid', 'mode', 'y'"):
        analyse(frame, dv="time_s", within="mode", subject="pid")
    with pytest.raises(ValueError, match="only 1 level"):
        analyse(frame[frame["mode"] == "L0"], **COLUMNS)
    with pytest.raises(ValueError, match="only 1 subject"):
        analyse(frame[frame["pid"] == "P00"], **COLUMNS)
    holed = frame[~((frame["pid"] != "P00") & (frame["mode"] == "L2"))]
    with pytest.raises(ValueError, match=r"only 1 subject.*dropped: 'P01'"):
        analyse(holed, **COLUMNS)
    bad = frame.astype({"y": object})
    bad.loc[7, "y"] = "fast"
    with pytest.raises(ValueError, match="column 'y': row 7: 'fast' is not a number"):
        analyse(bad, **COLUMNS)
    with pytest.raises(ValueError, match="not finite"):
        analyse(frame.assign(y=frame["y"].where(frame.index != 3, np.inf)), **COLUMNS)
    with pytest.raises(ValueError, match="three different columns"):
        analyse(frame, dv="y", within="y", subject="pid")
    with pytest.raises(ValueError, match="row 2 is empty"):
        analyse(frame.assign(pid=frame["pid"].where(frame.index != 2, None)), **COLUMNS)
    with pytest.raises(ValueError, match="same label"):
        analyse(frame.assign(mode=[1, "1", 2] * 5), **COLUMNS)
    with pytest.raises(ValueError, match="gate 'hf' is not allowed"):
        analyse(frame, **COLUMNS, gate="hf")
    with pytest.raises(ValueError, match="alpha"):
        analyse(frame, **COLUMNS, alpha=1.5)
    with pytest.raises(TypeError, match="DataFrame"):
        analyse(y, **COLUMNS)


def test_repeated_measures_orders_by_first_appearance(rng):
    y = random_design(rng, 4, 3)
    frame = to_long(y, levels=["c", "a", "b"], subjects=["z", "y", "x", "w"])
    data = repeated_measures(frame.iloc[::-1], **COLUMNS)
    assert data.levels == ("b", "a", "c")
    assert data.subjects == ("w", "x", "y", "z")
    assert np.allclose(data.y, y[::-1, ::-1])


def test_repeated_cells_are_averaged_and_named_in_the_note(rng):
    y = random_design(rng, 4, 3)
    frame = to_long(y, levels=["a", "b", "c"], subjects=["p1", "p2", "p3", "p4"])
    extra = frame.iloc[[0]].assign(y=frame["y"].iloc[0] + 2.0)
    data = repeated_measures(pd.concat([frame, extra], ignore_index=True), **COLUMNS)
    who, level = extra["pid"].iloc[0], extra["mode"].iloc[0]
    assert np.isclose(data.y[0, 0], y[0, 0] + 1.0)  # the mean of the cell's two rows
    (note,) = [n for n in data.warnings if "more than one row" in n]
    assert f"subject {who!r}, level {level!r}: 2 rows" in note
