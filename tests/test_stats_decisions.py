"""``analyse(..., decisions_only=True)`` (issue 22, the resampling of power analyses): the
same decisions as the full analysis, by the same code, for every planned test and post-hoc
family, with the extra keys left out."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

from analysis.stats import POSTHOC, analyse


def _frame(rng: np.random.Generator, n: int, k: int, effect: float, whole: bool) -> pd.DataFrame:
    y = rng.normal(0.0, 1.0, (n, 1)) + rng.normal(0.0, 1.0, (n, k)) + effect * np.arange(k)
    if whole:
        y = np.clip(np.round(y), 0, None)
    return pd.DataFrame(
        [(f"s{i}", f"m{j}", float(y[i, j])) for i in range(n) for j in range(k)],
        columns=["participant", "mode", "value"],
    )


@pytest.mark.parametrize("posthoc", POSTHOC)
@pytest.mark.parametrize("test", ["rm_anova", "friedman", "auto"])
def test_decisions_equal_those_of_the_full_analysis(rng, posthoc, test):
    for trial in range(6):
        n, k = int(rng.integers(3, 20)), int(rng.integers(2, 5))
        df = _frame(rng, n, k, effect=float(rng.choice([0.0, 0.4, 1.5])), whole=trial % 2 == 0)
        options = dict(dv="value", within="mode", subject="participant", posthoc=posthoc, test=test)
        full = analyse(df, mixed=False, **options)
        lean = analyse(df, decisions_only=True, **options)
        assert lean["planned"] == full["planned"]
        assert lean["p_gate"] == full["p_gate"] and lean["significant"] == full["significant"]
        assert lean["posthoc"][posthoc] == full["posthoc"][posthoc]
        if full["planned"]["test"] == "friedman":
            assert lean["friedman"] == full["friedman"]
        else:
            assert lean["friedman"] is None
        assert lean["descriptives"] == full["descriptives"]
        others = [f for f in POSTHOC if f != posthoc]
        assert all(lean["posthoc"][f] == [] for f in others)
        assert lean["pairs"] is None and lean["apa"] is None and lean["mixed"] is None


def test_the_direct_table_and_the_cell_means_give_the_same_bits(rng):
    """One row per cell fills the table directly; a repeated row takes the groupby path
    (cell means). Both must give bit-identical statistics (the layout of the table
    matters to numpy's sums in the last bit)."""
    df = _frame(rng, 40, 3, effect=0.3, whole=False)
    df["value"] *= 37.1
    doubled = pd.concat([df, df.iloc[[0]]], ignore_index=True)  # one cell twice, same value
    a = analyse(df, dv="value", within="mode", subject="participant", mixed=False)
    b = analyse(doubled, dv="value", within="mode", subject="participant", mixed=False)
    for key in ("descriptives", "anova", "sphericity", "greenhouse_geisser", "posthoc", "pairs"):
        assert a[key] == b[key], key
