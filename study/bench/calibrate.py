"""Benchmark group ``calibrate``: the wall time of ``asa calibrate`` and its scaling from
one to two Dask workers (issue 39).

A target study of a few synthetic participants (the protocol cut to its baseline and main
phases, no recordings) is calibrated to twice, on a local cluster of 1 and of 2 worker
processes, each with a fresh bank (same seeds, the same bank); the figures are listed in
:func:`run`.
"""

from __future__ import annotations

import tempfile
from pathlib import Path

from study.engine.protocol import load_protocol
from study.jobs.calibrate import CalibrateSettings, run_calibration
from study.jobs.power.bank import bank_protocol
from study.jobs.synth import run_synthetic_study

_SEED = 7061
QUICK_PROTOCOL = """
[study]
name = "bench-calibrate-quick"
participants = 2
seed = 5

[modes]
names = ["manual", "reactive_bn"]
counterbalancing = "full_permutation"

[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false
timeout_s = 90.0

[phases.after_trial]
instrument = "nasa_tlx"
weights = "raw"

[analysis]
metrics = ["completion_time_s", "score_s", "tlx_raw"]
"""


def _calibrate(db: Path, folder: Path, bank: int, workers: int) -> dict:
    s = CalibrateSettings(bank=bank, replicates=20, seed=_SEED, workers=workers)
    summary = run_calibration(db, folder / f"population_{workers}.toml", s)
    return summary.result["timing"]


def run(quick: bool) -> dict:
    """One calibration on 1 and on 2 workers.

    Returns
    -------
    dict
        ``calibrate_protocol``, ``calibrate_participants`` (the target study's) and
        ``calibrate_bank`` (thesis-7-6, 6 participants, a bank of 10; with ``quick`` a
        two-mode protocol on the practice course, 4 and 10); ``calibrate_s_1`` and
        ``calibrate_s_2``: wall seconds of the calibration on 1 and 2 worker processes
        (bank, fit and 20 bootstrap replicates; the cluster's start not included);
        ``calibrate_bank_s_2``, ``calibrate_fit_s_2``: its parts on 2 workers;
        ``calibrate_scaling_2_vs_1``: ``calibrate_s_1 / calibrate_s_2`` (aim >= 1.8);
        ``calibrate_thesis_estimate_s``: the wall time these give for a bank of 300 on 2
        workers (measured runs: docs/results.md).
    """
    with tempfile.TemporaryDirectory(prefix="asa-bench-calibrate-") as tmp:
        folder = Path(tmp)
        if quick:
            (folder / "quick.toml").write_text(QUICK_PROTOCOL)
            protocol, people, bank = load_protocol(folder / "quick.toml"), 4, 10
        else:
            protocol, people, bank = load_protocol("thesis-7-6"), 6, 10
        db = folder / "target.db"
        run_synthetic_study(
            bank_protocol(protocol), db, participants=people, seed=_SEED, workers=2,
            record=False,
        )  # fmt: skip
        one = _calibrate(db, folder, bank, 1)
        two = _calibrate(db, folder, bank, 2)
    total1, total2 = one["bank_s"] + one["fit_s"], two["bank_s"] + two["fit_s"]
    return {
        "calibrate_protocol": protocol.name,
        "calibrate_participants": people,
        "calibrate_bank": bank,
        "calibrate_s_1": round(total1, 2),
        "calibrate_s_2": round(total2, 2),
        "calibrate_bank_s_2": round(two["bank_s"], 2),
        "calibrate_fit_s_2": round(two["fit_s"], 2),
        "calibrate_scaling_2_vs_1": round(total1 / total2, 3),
        "calibrate_thesis_estimate_s": None
        if quick
        else round(300 / bank * two["bank_s"] + two["fit_s"] * 5),  # 100 replicates
    }
