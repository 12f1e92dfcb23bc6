"""Benchmark group ``synth``: synthetic participants and whole synthetic studies (issue 6).

One thesis main trial driven by a synthetic participant in the contextual-task mode, then
a synthetic study of the thesis protocol with 2 workers. The figures are listed in
:func:`run`.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from study.engine.protocol import load_protocol
from study.engine.standalone import standalone_trial
from study.jobs.synth import run_synthetic_study
from study.participants.synthetic import Population, SyntheticParticipant

_SEED = 7061


def _trial(
    folder: Path, timeout_s: float, *, record: bool = True, database: str = "bench.db"
) -> dict:
    """One thesis main trial, contextual mode, synthetic participant, into a new
    ``folder / database``: its figures (with the ``synthetic_trial_`` prefix; ``record``:
    with the rerun recording)."""
    protocol = load_protocol("thesis-7-6")
    main = protocol.main
    rng = np.random.default_rng(_SEED)
    person = SyntheticParticipant(Population().sample(rng), rng)
    first: list[float] = []  # clocks at the first tick: the setup is not the trial's

    def on_tick(tick: int, writer: object) -> None:
        if not first:
            first.extend((time.perf_counter(), time.process_time()))

    result, engine = standalone_trial(
        folder,
        person,
        mode="contextual_task",
        scenario=main.scenario,
        inspection=True,
        timeout_s=timeout_s,
        secondary=protocol.secondary_settings,
        seed=_SEED,
        mode_settings=protocol.mode_settings.get("contextual_task", {}),
        database=database,
        on_tick=on_tick,
        record=record,
        durable=False,  # as asa synth writes each participant's scratch database
    )
    wall, cpu = time.perf_counter() - first[0], time.process_time() - first[1]
    engine.dispose()
    return {
        "synthetic_trial_realtime_factor": round(result.duration_s / wall, 2),
        "synthetic_trial_cpu_factor": round(result.duration_s / max(cpu, 1e-9), 2),
        "synthetic_trial_simulated_s": round(result.duration_s, 2),
        "synthetic_trial_completed": bool(result.outcome.get("completed")),
    }


def run(quick: bool) -> dict:
    """One synthetic main trial, then a synthetic study (2 participants with ``quick``).

    Returns
    -------
    dict
        ``synthetic_warmup_s``: wall seconds of a 10 s trial run first, in which the
        process loads the compiled kernels and makes their first calls (once per
        process: every ``asa synth`` worker pays it once);
        ``synthetic_trial_realtime_factor``: simulated seconds per wall second of one
        thesis main trial (cluttered room, A -> B -> A with the inspection, secondary
        questions) in the contextual-task mode, with SQLite logging (into a scratch
        database without fsync, as ``asa synth`` writes) and the rerun recording, in
        this one process; ``synthetic_trial_cpu_factor`` the same per CPU
        second of this process; ``synthetic_trial_simulated_s`` the trial's simulated
        length (with ``quick`` the trial is cut at 30 s); ``synthetic_trial_completed``;
        ``synthetic_trial_fast_factor`` and ``synthetic_trial_fast_cpu_factor`` the same
        trial without its recording (``asa synth --no-recordings``: the power bank's
        path); or ``synthetic_trial_error``. ``synthetic_study_s``: wall seconds of
        :func:`study.jobs.synth.run_synthetic_study` of the thesis protocol with 2
        workers, recordings included, for ``synthetic_study_participants`` participants
        (18, or 2 with ``quick``); ``synthetic_study_protocol``.
    """
    figures: dict = {}
    with tempfile.TemporaryDirectory(prefix="asa-bench-synth-") as tmp:
        folder = Path(tmp)
        try:
            start = time.perf_counter()  # the compiled kernels' first calls, once a process
            _trial(folder, 10.0, record=False, database="warmup.db")
            figures["synthetic_warmup_s"] = round(time.perf_counter() - start, 2)
            figures.update(_trial(folder, 30.0 if quick else 900.0))
            fast = _trial(folder, 30.0 if quick else 900.0, record=False, database="fast.db")
            figures["synthetic_trial_fast_factor"] = fast["synthetic_trial_realtime_factor"]
            figures["synthetic_trial_fast_cpu_factor"] = fast["synthetic_trial_cpu_factor"]
        except ValueError as error:  # e.g. a shipped model the mode cannot read
            figures["synthetic_trial_error"] = str(error)
        n = 2 if quick else 18
        summary = run_synthetic_study(
            "thesis-7-6", folder / "study.db", participants=n, seed=_SEED, workers=2
        )
        figures["synthetic_study_s"] = round(summary.wall_s, 1)
        figures["synthetic_study_participants"] = n
        figures["synthetic_study_protocol"] = "thesis-7-6"
    return figures
