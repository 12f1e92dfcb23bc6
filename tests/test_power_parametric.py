"""The parametric bootstrap of a pilot (analysis.power.parametric, issue 39) against the
closed forms: pingouin's ``power_rm_anova`` for a one-way within design whose covariance is
spherical (compound symmetry), and R's ``pwr.t.test(type = "paired")`` for two levels.

The pilot is built with exactly the chosen sample mean and covariance, so its fitted model is
the closed form's population; the simulated power must then lie within the Monte Carlo
interval of the closed form (4 binomial standard errors: the test fails by chance about
once in 15,000 seeds)."""

from __future__ import annotations

import json
import os
import shutil
import subprocess

import numpy as np
import pingouin
import pytest

from analysis.power import OMNIBUS, Batch, PlannedTests, tally
from analysis.power.parametric import (
    PilotModel,
    at_effect,
    fit_moments,
    replicate_powers,
    simulate_batch,
    variant_key,
)

Z = 4.0  # binomial standard errors of Monte Carlo tolerance


def exact_pilot(rng: np.random.Generator, mean: np.ndarray, cov: np.ndarray, n: int) -> np.ndarray:
    """(n, k) rows whose sample mean is ``mean`` and sample covariance (ddof 1) ``cov``."""
    z = rng.normal(size=(n, len(mean)))
    z -= z.mean(axis=0)
    white = z @ np.linalg.inv(np.linalg.cholesky(np.cov(z, rowvar=False)).T)
    return mean + white @ np.linalg.cholesky(cov).T


def compound(k: int, sd: float, rho: float) -> np.ndarray:
    return sd**2 * ((1 - rho) * np.eye(k) + rho * np.ones((k, k)))


def simulated_power(models, planned, n, studies, seed, draws=20):
    batches = [(n, simulate_batch(models, planned, Batch(n, 0, studies), seed=seed, draws=draws))]
    return tally(batches, planned)


def within_mc(k: int, total: int, expected: float) -> bool:
    se = np.sqrt(expected * (1 - expected) / total)
    return abs(k / total - expected) <= Z * se + 0.5 / total


def test_exact_pilot_has_the_chosen_moments(rng):
    mean, cov = np.array([10.0, 11.0, 12.5]), compound(3, 2.0, 0.5)
    wide = exact_pilot(rng, mean, cov, 12)
    got_mean, got_cov = fit_moments(wide)
    assert np.allclose(got_mean, mean) and np.allclose(got_cov, cov)
    # the random-intercept model of compound-symmetric data is the same covariance
    assert np.allclose(fit_moments(wide, "lmm")[1], cov, atol=0.6)


@pytest.mark.parametrize(("n", "rho"), [(8, 0.5), (12, 0.2)])
def test_rm_anova_power_matches_pingouin(rng, seed, n, rho):
    k, sd = 3, 2.0
    mean = np.array([10.0, 10.8, 11.9])
    wide = exact_pilot(rng, mean, compound(k, sd, rho), 15)
    models = {"m": PilotModel("m", ("a", "b", "c"), wide)}
    planned = PlannedTests({"m": ("a", "b", "c")}, gate="uncorrected")
    studies = 500
    counts = simulated_power(models, planned, n, studies, seed)["m"]
    f_sq = np.sum((mean - mean.mean()) ** 2) / (k * sd**2)
    expected = pingouin.power_rm_anova(eta_squared=f_sq / (1 + f_sq), m=k, n=n, corr=rho)
    hits, total = counts[OMNIBUS][n]
    assert total == studies and 0.15 < expected < 0.95
    assert within_mc(hits, total, expected), (hits / total, expected)


PWR = """
suppressPackageStartupMessages(library(pwr))
cat(pwr.t.test(n = {n}, d = {d}, sig.level = 0.05, type = "paired")$power)
"""


@pytest.mark.skipif(
    shutil.which("Rscript") is None and not os.environ.get("CI"),
    reason="R is not installed (CI installs it: .ci/run)",
)
def test_paired_pair_power_matches_r_pwr(rng, seed):
    n, diff, sd_a, sd_b, rho = 10, 1.0, 1.5, 1.2, 0.4
    cov = np.array([[sd_a**2, rho * sd_a * sd_b], [rho * sd_a * sd_b, sd_b**2]])
    wide = exact_pilot(rng, np.array([5.0, 5.0 + diff]), cov, 9)
    d = diff / np.sqrt(sd_a**2 + sd_b**2 - 2 * rho * sd_a * sd_b)
    done = subprocess.run(
        ["Rscript", "-e", PWR.format(n=n, d=repr(float(d)))],
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 0, done.stderr
    expected = float(done.stdout)
    models = {"m": PilotModel("m", ("a", "b"), wide)}
    planned = PlannedTests({"m": ("a", "b")}, posthoc="holm")
    counts = simulated_power(models, planned, n, 500, seed)["m"]
    for test in (OMNIBUS, "a vs b"):  # with two levels the F test is the paired t test
        hits, total = counts[test][n]
        assert within_mc(hits, total, expected), (test, hits / total, expected)
    assert json.dumps(expected)  # a plain number came back


def test_effect_of_interest_scales_the_means_and_lowers_the_power(rng, seed):
    mean = np.array([10.0, 12.0, 16.0])
    scaled = at_effect(mean, 3.0)
    assert np.ptp(scaled) == pytest.approx(3.0) and scaled.mean() == pytest.approx(mean.mean())
    assert np.allclose((scaled - scaled.mean()) / (mean - mean.mean()), 0.5)
    with pytest.raises(ValueError, match="all equal"):
        at_effect(np.array([1.0, 1.0]), 2.0)
    wide = exact_pilot(rng, mean, compound(3, 4.0, 0.5), 12)
    models = {"m": PilotModel("m", ("a", "b", "c"), wide, interest=0.0 + 2.0)}
    keys = {variant_key("m", v): ("a", "b", "c") for v in ("pilot", "interest")}
    counts = simulated_power(models, PlannedTests(keys), 10, 200, seed)
    assert counts["m@interest"][OMNIBUS][10][0] < counts["m"][OMNIBUS][10][0]


def test_pilot_uncertainty_spreads_the_replicates(rng, seed):
    """Bootstrap replicates of a small pilot differ: their powers spread, and the expected
    power is the mean of the replicates' powers."""
    wide = exact_pilot(rng, np.array([10.0, 11.0, 12.0]), compound(3, 2.0, 0.5), 6)
    models = {"m": PilotModel("m", ("a", "b", "c"), wide)}
    planned = PlannedTests({"m@uncertain": ("a", "b", "c")})
    draws, studies, n = 10, 200, 8
    batches = [
        (n, a, simulate_batch(models, planned, Batch(n, a, a + 50), seed=seed, draws=draws))
        for a in range(0, studies, 50)
    ]
    powers = replicate_powers(batches, "m@uncertain", OMNIBUS, draws)[n]
    counts = tally([(n, b) for n, _, b in batches], planned)["m@uncertain"][OMNIBUS][n]
    assert powers.mean() == pytest.approx(counts[0] / counts[1])
    assert np.ptp(powers) > 0.2
    # the same studies whatever the batching
    whole = simulate_batch(models, planned, Batch(n, 0, studies), seed=seed, draws=draws)
    joined = np.concatenate([b["m@uncertain"][OMNIBUS] for _, _, b in batches])
    assert np.array_equal(whole["m@uncertain"][OMNIBUS], joined)
