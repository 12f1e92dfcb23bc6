"""The moments ``asa calibrate`` matches (issue 39): per planned metric, over the people
who have every level, the mean and the standard deviation of each level and the
correlation of every pair of levels (the participants' covariance across modes, which is
what a repeated-measures test sees), weighted.

A pilot's moments are its sample's (weights 1, or a bootstrap's counts); a candidate
population's are the bank's under importance weights (:mod:`study.jobs.calibrate.model`).
"""

from __future__ import annotations

import itertools
import warnings
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np
import pandas as pd


@dataclass(frozen=True, slots=True)
class Wide:
    """One metric's complete people: values (n, k) and each row's person index."""

    metric: str
    levels: tuple[str, ...]
    values: np.ndarray  # (n, k) [metric units]
    rows: np.ndarray  # (n,) int: index of the person (pilot participant or bank entry)


def wide_frames(long: pd.DataFrame, people: list, levels: Mapping[str, tuple[str, ...]]):
    """Metric -> :class:`Wide` from long rows (metric, person, mode, value); ``people`` the
    person labels in index order, ``levels`` the levels of each metric in report order."""
    index = {p: i for i, p in enumerate(people)}
    out = {}
    for metric, lv in levels.items():
        part = long[long["metric"] == metric]
        table = part.pivot_table(index="person", columns="mode", values="value", aggfunc="first")
        table = table.reindex(columns=list(lv)).dropna()
        rows = np.array([index[p] for p in table.index], dtype=int)
        out[metric] = Wide(metric, tuple(lv), table.to_numpy(dtype=float), rows)
    return out


def moment_names(w: Wide) -> list[str]:
    """``metric: mean LEVEL``, ``... sd LEVEL``, ``... corr A~B`` in :func:`moments` order."""
    pairs = itertools.combinations(w.levels, 2)
    return (
        [f"{w.metric}: mean {lv}" for lv in w.levels]
        + [f"{w.metric}: sd {lv}" for lv in w.levels]
        + [f"{w.metric}: corr {a}~{b}" for a, b in pairs]
    )


def moments(values: np.ndarray, weights: np.ndarray, *, frequency: bool) -> np.ndarray:
    """Means (k), sds (k), correlations (k(k-1)/2) of ``values`` (n, k) under ``weights``.

    ``frequency``: weights are counts (a sample or a bootstrap's), the variance divides by
    ``sum(w) - 1``; otherwise importance weights, normalised, the variance divided by
    ``1 - sum(w_norm^2)`` (unbiased for reliability weights; both equal ddof = 1 for equal
    weights). A correlation of a level without spread is NaN.
    """
    w = np.asarray(weights, dtype=float)
    total = w.sum()
    if total <= 0:
        k = values.shape[1]
        return np.full(2 * k + k * (k - 1) // 2, np.nan)
    p = w / total
    mean = p @ values
    d = values - mean
    if frequency:
        scale = total / (total - 1.0) if total > 1 else np.nan
    else:
        rest = 1.0 - float(p @ p)
        scale = 1.0 / rest if rest > 1e-12 else np.nan
    cov = (d * p[:, None]).T @ d * scale
    sd = np.sqrt(np.clip(np.diag(cov), 0.0, None))
    k = values.shape[1]
    iu = np.triu_indices(k, 1)
    with np.errstate(invalid="ignore", divide="ignore"):
        corr = cov[iu] / (sd[iu[0]] * sd[iu[1]])
    corr = np.where((sd[iu[0]] > 0) & (sd[iu[1]] > 0), corr, np.nan)
    return np.concatenate([mean, sd, corr])


def sample_moments(wides: Mapping[str, Wide], counts: np.ndarray) -> dict[str, np.ndarray]:
    """Metric -> moments of the sample with person counts ``counts`` (n_people,)."""
    return {m: moments(w.values, counts[w.rows], frequency=True) for m, w in wides.items()}


def bootstrap_se(wides: Mapping[str, Wide], people: int, draws: int, rng) -> dict:
    """Metric -> (m,) standard error of each moment: the sd over ``draws`` bootstraps of the
    people (drawn with replacement, jointly over metrics); 0 for a moment that never varies,
    NaN where it is undefined."""
    reps = {m: [] for m in wides}
    for _ in range(draws):
        counts = np.bincount(rng.integers(0, people, people), minlength=people).astype(float)
        for m, v in sample_moments(wides, counts).items():
            reps[m].append(v)
    with warnings.catch_warnings():  # a moment undefined in every draw: NaN, said above
        warnings.simplefilter("ignore", RuntimeWarning)
        return {m: np.nanstd(np.array(r), axis=0, ddof=1) for m, r in reps.items()}
