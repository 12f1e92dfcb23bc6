"""Benchmark group ``power``: the throughput of ``asa power`` (issue 22).

The bank's throughput on a local Dask cluster of one and of two worker processes (the same
bank entries of the thesis protocol, through :mod:`study.jobs.power`'s own code), and the
rate of resampled studies analysed in one process. The figures are listed in :func:`run`.
"""

from __future__ import annotations

import itertools
import tempfile
import time
from pathlib import Path

import numpy as np
import pandas as pd

from analysis.data import BASELINE
from analysis.metrics import BY_NAME
from analysis.power import Batch, PlannedTests, resample_batch
from study.engine.protocol import load_protocol
from study.jobs.power.bank import BankFile
from study.jobs.power.cluster import dask_engine
from study.jobs.power.run import PowerSettings, build_bank, slot_rows

_SEED = 7061
QUICK_PROTOCOL = """
[study]
name = "bench-power-quick"
participants = 2
seed = 5

[modes]
names = ["manual", "contextual_task"]
counterbalancing = "full_permutation"

[[phases]]
kind = "baseline"
questions = 3

[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false
timeout_s = 90.0
"""


def _bank_rate(protocol, entries: int, workers: int, folder: Path) -> dict:
    """Drive ``entries`` bank entries on a local cluster of ``workers``: wall seconds (the
    cluster's start not included), CPU seconds and main trials, simulated seconds."""
    settings = PowerSettings(sizes=(2,), studies=1, bank=entries, seed=_SEED, workers=workers)
    bank = BankFile(folder / f"bank_{workers}.sqlite", {"bench": workers}, resume=False)
    try:
        with dask_engine(None, workers) as engine:
            wall = build_bank(engine.client, bank, protocol, settings, lambda *a: None)
        table, _ = bank.frames(entries)
    finally:
        bank.close()
    return {
        "wall_s": wall,
        "cpu_s": float(table["cpu_s"].sum()),
        "trials": int(table["main_trials"].sum()),
        "simulated_s": float(table["simulated_s"].sum()),
    }


def _synthetic_bank(protocol, b: int, rng: np.random.Generator) -> tuple[pd.DataFrame, ...]:
    """A bank of ``b`` participants with random values for every planned metric of
    ``protocol`` (levels as the report's: the modes, and the baseline for secondary-task
    metrics): the shape of a real bank, for the resampling rate."""
    slots = slot_rows(protocol, b)
    entries = pd.DataFrame({"entry": np.arange(b), "row": slots if slots else [0] * b})
    rows = []
    metrics = [m for m in protocol.analysis.metrics if m in BY_NAME]
    for i, metric in itertools.product(range(b), metrics):
        levels = list(protocol.modes) + ([BASELINE] if BY_NAME[metric].baseline else [])
        for j, level in enumerate(levels):
            rows.append((i, f"B{i + 1:04d}", metric, level, j, float(rng.normal(j * 0.2, 1))))
    outcomes = pd.DataFrame(
        rows, columns=["entry", "participant", "metric", "mode", "position", "value"]
    )
    levels = {
        m: tuple(protocol.modes) + ((BASELINE,) if BY_NAME[m].baseline else ()) for m in metrics
    }
    a = protocol.analysis
    planned = PlannedTests(levels, alpha=a.alpha, gate=a.gate, posthoc=a.posthoc)
    return outcomes, entries, planned, slots


def _studies_per_s(protocol, studies: int, n: int) -> float:
    outcomes, entries, planned, slots = _synthetic_bank(protocol, 300, np.random.default_rng(_SEED))
    start = time.process_time()
    resample_batch(outcomes, entries, planned, Batch(n, 0, studies), seed=_SEED, slot_rows=slots)
    return studies / (time.process_time() - start)


def run(quick: bool) -> dict:
    """The bank on one and two workers, and the resampling rate.

    Returns
    -------
    dict
        ``power_bank_protocol`` and ``power_bank_entries`` (thesis-7-6, 6 entries; with
        ``quick`` a two-mode protocol on the practice course, 2 entries);
        ``bank_trials_per_cpu_s``: main trials of the bank per CPU second of the workers
        (one worker); ``bank_trial_cpu_factor``: their simulated seconds per CPU second
        (DESIGN.md: at least 200); ``bank_entries_per_s_1`` and ``_2``: bank entries per
        wall second on a local cluster of 1 and 2 worker processes (its start not
        included); ``scaling_2_vs_1`` their ratio (aim >= 1.8); ``power_studies_per_s``:
        resampled studies of 24 participants analysed per CPU second in one process, every
        planned metric of thesis-7-6 (a 300-participant bank of random values:
        the analysis costs the same whatever the values); ``power_thesis_estimate_s``: the
        wall time these rates give for ``asa power --protocol thesis-7-6 --bank 300
        --studies 1000 --sizes 6,12,18,24`` on 2 workers (measured runs:
        docs/results.md).
    """
    thesis = load_protocol("thesis-7-6")
    with tempfile.TemporaryDirectory(prefix="asa-bench-power-") as tmp:
        folder = Path(tmp)
        if quick:
            (folder / "quick.toml").write_text(QUICK_PROTOCOL)
            protocol, entries = load_protocol(folder / "quick.toml"), 2
        else:
            protocol, entries = thesis, 6
        one = _bank_rate(protocol, entries, 1, folder)
        two = _bank_rate(protocol, entries, 2, folder)
    rate1, rate2 = entries / one["wall_s"], entries / two["wall_s"]
    studies_per_s = _studies_per_s(thesis, 10 if quick else 60, 24)
    estimate = 300 / rate2 + 4 * 1000 / (2 * studies_per_s)  # bank, then studies on 2 workers
    return {
        "power_bank_protocol": protocol.name,
        "power_bank_entries": entries,
        "bank_trials_per_cpu_s": round(one["trials"] / one["cpu_s"], 4),
        "bank_trial_cpu_factor": round(one["simulated_s"] / one["cpu_s"], 1),
        "bank_entries_per_s_1": round(rate1, 4),
        "bank_entries_per_s_2": round(rate2, 4),
        "scaling_2_vs_1": round(rate2 / rate1, 3),
        "power_studies_per_s": round(studies_per_s, 2),
        "power_thesis_estimate_s": None if quick else round(estimate),
    }
