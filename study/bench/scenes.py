"""Benchmark group ``scenes``: the study in scenes nobody here drew (issue 17).

Generated floor plans (:func:`sim.generate.generate_scene`, fixed seeds) are checked
(:func:`sim.check.check_scene`) and driven: in each, one synthetic participant drawn from
the population model drives the pilot protocol's main trial (A -> B -> A, inspecting the
scene's object, questions in the question region, 600 s limit) once in every mode, as
three identical fresh copies so the modes are compared on the same person. The figures
are listed in :func:`run`.
"""

from __future__ import annotations

import concurrent.futures as cf
import multiprocessing
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from sim.check import check_scene
from sim.scenario import load_scenario
from study._blas import limit_blas_threads
from study.bench.recognition import write_generated
from study.engine.recognition import RecognitionTally
from study.engine.standalone import standalone_trial
from study.participants.synthetic import synthetic_participant
from tasks.secondary import SecondarySettings

MODES = ("manual", "reactive_bn", "contextual_task")
SCENE_SEEDS = tuple(range(30))  # quick: the first three
TIMEOUT_S = 600.0  # [s] simulated: the pilot protocol's main-trial limit
BLOCK_SIZE = 5  # questions per entry into the region, as the pilot protocol
_SEED = 1717


def scene_trials(seed: int) -> dict[str, Any]:
    """Generate, check and drive the scene of ``seed`` in every mode: a JSON-ready row
    with ``seed``, ``problems`` (checker lines) and per mode the trial's ``completed``,
    ``timed_out``, ``collisions``, ``completion_time_s`` and ``recognition`` (counts)."""
    with tempfile.TemporaryDirectory(prefix="asa-bench-scene-") as tmp:
        folder = Path(tmp)
        (path,) = write_generated(folder, (seed,))
        sc = load_scenario(path)
        row: dict[str, Any] = {
            "seed": seed,
            "problems": [p.line(path) for p in check_scene(sc)],
        }
        person = np.random.SeedSequence([_SEED, seed])
        for mode in MODES:
            result, engine = standalone_trial(
                folder,
                synthetic_participant(np.random.default_rng(person)),
                mode=mode,
                scenario=path,
                inspection=bool(sc.inspection_object),
                timeout_s=TIMEOUT_S,
                secondary=SecondarySettings(block_size=BLOCK_SIZE),
                seed=seed,
                database=f"{mode}.db",
            )
            engine.dispose()
            out = result.outcome
            row[mode] = {
                "completed": bool(out.get("completed")),
                "timed_out": bool(out.get("timed_out")),
                "collisions": int(out.get("collisions") or 0),
                "completion_time_s": float(out.get("completion_time_s") or 0.0),
                "recognition": out.get("recognition"),
            }
    return row


def _summary(rows: list[dict[str, Any]]) -> dict[str, Any]:
    """The figures of :func:`run` from the rows of :func:`scene_trials`."""
    completion, collisions, timeouts, failures = {}, {}, {}, []
    for mode in MODES:
        done = [r[mode]["completed"] for r in rows]
        completion[mode] = round(float(np.mean(done)), 4)
        collisions[mode] = round(float(np.mean([r[mode]["collisions"] for r in rows])), 4)
        timeouts[mode] = int(sum(r[mode]["timed_out"] for r in rows))
        failures += [f"{r['seed']}/{mode}" for r in rows if not r[mode]["completed"]]
    tally = RecognitionTally({})
    for r in rows:
        rec = r["contextual_task"]["recognition"]
        if rec is not None:
            tally.merge(RecognitionTally.from_summary(rec))
    rec = tally.summary()
    assisted = max(collisions["reactive_bn"], collisions["contextual_task"])
    return {
        "scene_seeds": [r["seed"] for r in rows],
        "scene_checker_rejects": sum(bool(r["problems"]) for r in rows),
        "scene_completion_rate": completion,
        "scene_completion_min": min(completion.values()),
        "scene_collisions_mean": collisions,
        # the larger assisted mean of collisions over manual's (None when manual has none)
        "scene_collisions_ratio": (
            round(assisted / collisions["manual"], 4) if collisions["manual"] > 0 else None
        ),
        "scene_timeouts": timeouts,
        "scene_task_match": rec.get("loop_task_match"),
        "scene_recognition_match": rec.get("loop_task_target_match"),
        "scene_recognition_per_task": rec.get("per_task"),
        "scene_failures": failures,
        "scene_problems": [line for r in rows for line in r["problems"]],
    }


def run(quick: bool, *, seeds: tuple[int, ...] | None = None, workers: int = 2) -> dict:
    """Every scene of ``seeds`` (default :data:`SCENE_SEEDS`, ``quick`` the first three)
    in every mode, ``workers`` scenes at a time (one process each).

    Returns
    -------
    dict
        ``scene_checker_rejects`` (generated scenes the checker rejects, should be 0);
        per mode ``scene_completion_rate``, ``scene_collisions_mean`` and
        ``scene_timeouts``; ``scene_completion_min`` (the lowest completion rate of a
        mode), ``scene_collisions_ratio`` (the larger assisted mean over manual's);
        the contextual mode's ``scene_task_match`` and ``scene_recognition_match`` (task
        + target) over all its labelled ticks and ``scene_recognition_per_task``;
        ``scene_failures`` ("seed/mode" of every trial that did not complete) and the
        checker's ``scene_problems``.
    """
    seeds = tuple(seeds) if seeds is not None else SCENE_SEEDS[: 3 if quick else None]
    if workers <= 1 or len(seeds) <= 1:
        rows = [scene_trials(s) for s in seeds]
    else:
        ctx = multiprocessing.get_context("spawn")
        with cf.ProcessPoolExecutor(
            max_workers=workers, mp_context=ctx, initializer=limit_blas_threads
        ) as pool:
            rows = list(pool.map(scene_trials, seeds))
    return _summary(rows)
