"""The resampling layer of the power analysis (analysis/power, issue 22), on synthetic bank
rows (no driving): a planted effect has power about 1, no effect about alpha; a study is
counterbalanced as the scheme says; results do not depend on batching; the binomial CI
and the smallest N are right."""

from __future__ import annotations

import itertools

import numpy as np
import pandas as pd
import pytest
import scipy.stats

from analysis.power import (
    OMNIBUS,
    Batch,
    PlannedTests,
    check_size,
    clopper_pearson,
    curve,
    describe_n,
    draw_study,
    n_for_power,
    resample_batch,
    slot_pools,
    study_rng,
    summary_lines,
    tally,
)

MODES = ("manual", "reactive_bn", "contextual_task")
ROWS = 6  # full_permutation of three modes


def _bank(rng: np.random.Generator, b: int, shift: tuple[float, ...]) -> tuple[pd.DataFrame, ...]:
    """``b`` bank participants, entry i driving order row i mod 6; metric "m" is a subject
    effect plus noise plus ``shift`` per mode."""
    orders = list(itertools.permutations(MODES))
    entries = pd.DataFrame({"entry": np.arange(b), "row": np.arange(b) % ROWS})
    rows = []
    for i in range(b):
        person = rng.normal(0.0, 1.0)
        order = orders[i % ROWS]
        for mode, s in zip(MODES, shift, strict=True):
            value = person + s + rng.normal(0.0, 1.0)
            rows.append((i, f"B{i:04d}", "m", mode, order.index(mode), value))
    outcomes = pd.DataFrame(
        rows, columns=["entry", "participant", "metric", "mode", "position", "value"]
    )
    return outcomes, entries


PLANNED = PlannedTests(metrics={"m": MODES}, alpha=0.05, posthoc="lsd_paired")
SLOTS = [j % ROWS for j in range(60)]


def _power(outcomes, entries, n, studies, seed):
    out = resample_batch(
        outcomes, entries, PLANNED, Batch(n, 0, studies), seed=seed, slot_rows=SLOTS
    )
    return tally([(n, out)], PLANNED)["m"]


def test_a_planted_effect_has_power_near_one(rng, seed):
    outcomes, entries = _bank(rng, 120, (0.0, 2.0, 4.0))
    counts = _power(outcomes, entries, 12, 40, seed)
    for key in PLANNED.keys("m"):
        k, total = counts[key][12]
        assert total == 40 and k >= 39, (key, k)


def test_no_effect_rejects_at_about_alpha(rng, seed):
    outcomes, entries = _bank(rng, 3000, (0.0, 0.0, 0.0))
    counts = _power(outcomes, entries, 9, 400, seed)
    k, total = counts[OMNIBUS][9]
    low, high = clopper_pearson(k, total, level=0.999)
    assert low <= PLANNED.alpha <= high, (k, total)
    # a pair is tested only after the omnibus test rejects: never more often than it
    for a, b in itertools.combinations(MODES, 2):
        assert counts[f"{a} vs {b}"][9][0] <= k


def test_holm_pairs_are_counted_without_the_omnibus_gate(rng, seed):
    """With Holm planned (posthoc_gate auto) a pair is counted on its own: with one level
    far off and two equal, the omnibus test of a small study often fails to reject while
    Holm finds the far pair; gated by the protocol ("omnibus") it never rejects more often
    than the omnibus test (about 4 % of the 300 studies are such: never none)."""
    outcomes, entries = _bank(rng, 600, (0.0, 0.0, 1.5))
    batches = {}
    for gate in ("auto", "omnibus"):
        planned = PlannedTests(metrics={"m": MODES}, posthoc="holm", posthoc_gate=gate)
        out = resample_batch(
            outcomes, entries, planned, Batch(5, 0, 300), seed=seed, slot_rows=SLOTS
        )
        batches[gate] = out["m"]
    far = f"{MODES[0]} vs {MODES[2]}"
    free, gated = batches["auto"], batches["omnibus"]
    assert np.array_equal(free[OMNIBUS], gated[OMNIBUS])
    assert not np.any(gated[far] & ~gated[OMNIBUS])
    assert np.array_equal(gated[far], free[far] & free[OMNIBUS])
    assert np.any(free[far] & ~free[OMNIBUS])


def test_a_study_is_counterbalanced_and_draws_distinct_participants(rng, seed):
    _, entries = _bank(rng, 60, (0.0, 0.0, 0.0))
    pools = slot_pools(entries, SLOTS)
    for study in range(20):
        chosen = draw_study(pools, SLOTS, 12, study_rng(seed, 12, study))
        assert len(set(chosen.tolist())) == 12
        assert sorted((chosen % ROWS).tolist()) == sorted(SLOTS[:12])
    chosen = draw_study(slot_pools(entries, None), None, 12, study_rng(seed, 12, 0))
    assert len(set(chosen.tolist())) == 12


def test_batches_do_not_change_the_decisions(rng, seed):
    outcomes, entries = _bank(rng, 60, (0.0, 0.3, 0.6))
    whole = resample_batch(outcomes, entries, PLANNED, Batch(6, 0, 30), seed=seed, slot_rows=SLOTS)
    parts = [
        resample_batch(outcomes, entries, PLANNED, Batch(6, a, b), seed=seed, slot_rows=SLOTS)
        for a, b in ((0, 11), (11, 30))
    ]
    for key, flags in whole["m"].items():
        joined = np.concatenate([p["m"][key] for p in parts])
        assert np.array_equal(flags, joined), key


def test_a_bank_too_small_for_a_size_is_refused(rng):
    _, entries = _bank(rng, 13, (0.0, 0.0, 0.0))  # rows 0 and 1 three times, the rest twice
    pools = slot_pools(entries, SLOTS)
    check_size(pools, SLOTS, 12)
    with pytest.raises(ValueError, match=r"sizes: N = 18 needs 3 bank participants"):
        check_size(pools, SLOTS, 18)


def test_clopper_pearson_matches_the_beta_quantiles(rng):
    for _ in range(20):
        n = int(rng.integers(1, 500))
        k = int(rng.integers(0, n + 1))
        low, high = clopper_pearson(k, n)
        assert 0.0 <= low <= k / n <= high <= 1.0
        if 0 < k < n:  # the two tails each hold 2.5 %
            assert scipy.stats.binom.sf(k - 1, n, low) == pytest.approx(0.025, rel=1e-6)
            assert scipy.stats.binom.cdf(k, n, high) == pytest.approx(0.025, rel=1e-6)
    assert clopper_pearson(0, 10)[0] == 0.0 and clopper_pearson(10, 10)[1] == 1.0


def test_the_smallest_n_is_interpolated_between_sizes():
    points = curve({6: (500, 1000), 12: (900, 1000), 18: (990, 1000)})
    found = n_for_power(points)
    assert found["simulated"] == 12
    assert found["n"] == 11  # 6 + (0.8 - 0.5) / (0.9 - 0.5) * 6 = 10.5
    assert found["low"] <= found["n"] <= found["high"]
    assert describe_n(found).startswith("N = 11 [")
    first = n_for_power(curve({6: (950, 1000), 12: (999, 1000)}))
    assert first["at_most"] == 6 and describe_n(first) == "N <= 6"  # not simulated below 6
    assert found["at_most"] is None
    never = n_for_power(curve({6: (10, 100), 12: (20, 100)}))
    assert never["n"] is None and never["beyond"] == 12 and describe_n(never) == "N > 12"
    test = {"test": "a vs b", "curve": points, "n_for_power": found}
    lines = summary_lines([{"metric": "score_s", "tests": [test]}])
    assert lines == [f"score_s: a vs b reaches 0.8 at {describe_n(found)}"]
