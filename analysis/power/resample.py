"""Studies resampled from a bank of synthetic participants, and the planned tests'
decisions on each (issue 22; thesis Sec. 7.6.2 for the tests).

A *bank* is two frames: ``entries`` (one row per bank participant: ``entry``, ``row``, the
counterbalancing row of the order it drove) and ``outcomes`` (the long frames of
:func:`analysis.metrics.long_frame`, one row per bank participant, metric and level:
``entry``, ``participant``, ``metric``, ``mode``, ``position``, ``value``). A study of N
draws N distinct bank participants; with a deterministic counterbalancing scheme, the
participant in slot j of the study is drawn from those who drove slot j's order, so the
study is counterbalanced as the protocol's scheme would have it and carries whatever
position effects the bank has. Each study is analysed with :func:`analysis.stats.analyse`
(the report's function, ``decisions_only``) with the protocol's alpha, gate, planned test and
post-hoc family. Every study's draw comes from its own generator, seeded from (seed, N,
study index), so the decisions do not depend on how studies are batched or where they run.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

import numpy as np
import pandas as pd

from analysis.stats import analyse

OMNIBUS = "omnibus"
OUTCOME_COLUMNS: tuple[str, ...] = ("entry", "participant", "metric", "mode", "position", "value")


@dataclass(frozen=True, slots=True)
class PlannedTests:
    """The planned analysis of every metric, as the protocol says (``[analysis]``).

    Attributes
    ----------
    metrics : metric -> its levels in report order (modes in protocol order, then the
        baseline for secondary-task metrics).
    alpha, gate, posthoc, posthoc_gate : as :func:`analysis.stats.analyse`.
    tests : metric -> planned omnibus test ("rm_anova", "friedman" or "auto").
    """

    metrics: Mapping[str, tuple[str, ...]]
    alpha: float = 0.05
    gate: str = "auto"
    posthoc: str = "lsd_paired"
    tests: Mapping[str, str] = field(default_factory=dict)
    posthoc_gate: str = "auto"

    def analyse(self, frame: pd.DataFrame, metric: str, **options) -> dict:
        """:func:`analysis.stats.analyse` of a long frame of ``metric`` (columns
        ``participant``, ``mode``, ``value``) as planned; ``options`` add to it
        (``decisions_only``, ``mixed``)."""
        return analyse(
            frame,
            dv="value",
            within="mode",
            subject="participant",
            alpha=self.alpha,
            gate=self.gate,
            test=self.tests.get(metric, "rm_anova"),
            posthoc=self.posthoc,
            posthoc_gate=self.posthoc_gate,
            **options,
        )

    def keys(self, metric: str) -> tuple[str, ...]:
        """The tests of ``metric``: :data:`OMNIBUS`, then ``"a vs b"`` per pair of levels."""
        levels = self.metrics[metric]
        return (OMNIBUS, *(pair_key(a, b) for a, b in itertools.combinations(levels, 2)))


def pair_key(a: str, b: str) -> str:
    """The name of the contrast of levels ``a`` and ``b`` (``"a vs b"``)."""
    return f"{a} vs {b}"


def slot_pools(entries: pd.DataFrame, slot_rows: Sequence[int] | None) -> dict[int, np.ndarray]:
    """Counterbalancing row -> the bank entries that drove it (sorted); {-1: every entry}
    when ``slot_rows`` is None (a random scheme: any entry fits any slot)."""
    if slot_rows is None:
        return {-1: np.sort(entries["entry"].to_numpy(dtype=np.int64))}
    return {
        int(r): np.sort(entries.loc[entries["row"] == r, "entry"].to_numpy(dtype=np.int64))
        for r in sorted(set(int(r) for r in slot_rows))
    }


def check_size(pools: Mapping[int, np.ndarray], slot_rows: Sequence[int] | None, n: int) -> None:
    """ValueError when the bank has too few participants for a study of ``n``."""
    need = _needed(slot_rows, n)
    for row, count in need.items():
        have = len(pools.get(row, ()))
        if have < count:
            which = "participants" if row == -1 else f"participants driving order row {row}"
            raise ValueError(
                f"sizes: N = {n} needs {count} bank {which}, the bank has {have}; "
                f"use a larger --bank or smaller sizes"
            )


def _needed(slot_rows: Sequence[int] | None, n: int) -> dict[int, int]:
    if slot_rows is None:
        return {-1: n}
    counts: dict[int, int] = {}
    for row in slot_rows[:n]:
        counts[int(row)] = counts.get(int(row), 0) + 1
    return counts


def draw_study(
    pools: Mapping[int, np.ndarray],
    slot_rows: Sequence[int] | None,
    n: int,
    rng: np.random.Generator,
) -> np.ndarray:
    """The bank entries of one study of ``n`` (distinct), slot by slot.

    Parameters
    ----------
    pools : from :func:`slot_pools`.
    slot_rows : the counterbalancing row of each study slot (at least ``n``), or None.
    n : participants.
    rng : the study's generator.

    Returns
    -------
    numpy.ndarray
        (n,) entry numbers.
    """
    chosen = [
        rng.choice(pools[row], size=count, replace=False)
        for row, count in sorted(_needed(slot_rows, n).items())
    ]
    return np.concatenate(chosen)


def study_rng(seed: int, n: int, study: int) -> np.random.Generator:
    """The generator of study number ``study`` of size ``n``."""
    return np.random.default_rng([int(seed), int(n), int(study)])


def decisions(result: dict, planned: PlannedTests, metric: str) -> dict[str, bool]:
    """Test name -> rejected, from one :func:`analysis.stats.analyse` object: the planned
    omnibus test, and each pair by the planned family (behind the omnibus test when the
    family is gated: Fisher's LSD by default, thesis Sec. 7.6.2; Holm and Bonferroni on
    their own, see :func:`analysis.stats.posthoc_gated`)."""
    plan = result["planned"]
    if plan["test"] == "rm_anova":
        rows = result["posthoc"][result["posthoc_planned"]]
    else:
        rows = result["friedman"]["posthoc"]["wilcoxon_holm"]
    rejected = {frozenset((r["a"], r["b"])) for r in rows if r["significant"]}
    out = {OMNIBUS: bool(plan["significant"])}
    for a, b in itertools.combinations(planned.metrics[metric], 2):
        out[pair_key(a, b)] = frozenset((a, b)) in rejected
    return out


def analyse_study(
    frame: pd.DataFrame, planned: PlannedTests, metric: str
) -> dict[str, bool] | None:
    """The decisions of one study's long frame of ``metric``; None when the analysis
    cannot run (too few complete participants): counted as no rejection."""
    try:
        result = planned.analyse(frame, metric, decisions_only=True)
    except ValueError:
        return None
    return decisions(result, planned, metric)


@dataclass(frozen=True, slots=True)
class Batch:
    """One batch of resampled studies: sizes and study numbers ``start`` .. ``stop - 1``."""

    n: int
    start: int
    stop: int


def resample_batch(
    outcomes: pd.DataFrame,
    entries: pd.DataFrame,
    planned: PlannedTests,
    batch: Batch,
    *,
    seed: int,
    slot_rows: Sequence[int] | None,
) -> dict[str, dict[str, np.ndarray]]:
    """Draw and analyse the studies of ``batch``.

    Returns
    -------
    dict
        metric -> test name -> (stop - start,) bool array of rejections, plus metric ->
        ``"_failed"`` the studies whose analysis could not run.
    """
    pools = slot_pools(entries, slot_rows)
    by_metric = {
        m: frame.set_index("entry", drop=False).sort_index()
        for m, frame in outcomes.groupby("metric", sort=False)
        if m in planned.metrics
    }
    count = batch.stop - batch.start
    out = {
        m: {key: np.zeros(count, dtype=bool) for key in (*planned.keys(m), "_failed")}
        for m in planned.metrics
    }
    for i, study in enumerate(range(batch.start, batch.stop)):
        chosen = draw_study(pools, slot_rows, batch.n, study_rng(seed, batch.n, study))
        for metric, frame in by_metric.items():
            got = analyse_study(frame.loc[np.sort(chosen)], planned, metric)
            if got is None:
                out[metric]["_failed"][i] = True
                continue
            for key, rejected in got.items():
                out[metric][key][i] = rejected
    return out
