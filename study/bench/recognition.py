"""Benchmark group ``recognition``: the contextual mode's recognition in the loop against
synthetic drivers' true intention (thesis Sec. 7.2.2, 7.4; issue 16).

Synthetic participants drawn from the population model drive the main trial (A -> B -> A,
inspecting the scene's object when it has one) in the contextual-task mode in every
shipped scene with a start and a dock and in generated floor plans
(:func:`sim.generate.generate_scene`, fixed seeds); every tick the driver says which task
and target it is executing, and :class:`study.engine.recognition.RecognitionTally`
scores the mode's recognised task type and target against them. The figures are listed
in :func:`run`.
"""

from __future__ import annotations

import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from sim.generate import generate_scene, scene_toml
from sim.scenario import available_scenarios, load_scenario
from study.engine.recognition import RecognitionTally
from study.engine.standalone import standalone_trial
from study.participants.synthetic import synthetic_participant

_SEED = 1616
TIMEOUT_S = 300.0  # [s] simulated; a trial that has not finished by then is cut there
GENERATED_SEEDS = tuple(range(10))  # the generated scenes (quick: the first three)


def drivable_scenes() -> list[str]:
    """Shipped scenes with a start pose and a dock: where a main trial can be driven."""
    out = []
    for name in available_scenarios():
        sc = load_scenario(name)
        if sc.dock is not None:
            out.append(name)
    return out


def write_generated(folder: Path, seeds: tuple[int, ...]) -> list[str]:
    """Generated floor plans ``generated_<seed>.toml`` written to ``folder``; their paths."""
    paths = []
    for seed in seeds:
        path = folder / f"generated_{seed}.toml"
        data = generate_scene(np.random.default_rng(seed))
        data["name"] = f"generated_{seed}"
        path.write_text(scene_toml(data), encoding="utf-8")
        paths.append(str(path))
    return paths


def scene_recognition(
    folder: Path,
    scene: str,
    drivers: int,
    seed: int,
    mode_settings: dict[str, Any] | None = None,
) -> tuple[RecognitionTally, list[bool]]:
    """``drivers`` synthetic drivers, one main trial each in ``scene`` in the contextual
    mode (with ``mode_settings``, e.g. another ``model_path``): the pooled tally and
    whether each trial completed its task."""
    sc = load_scenario(scene)
    tally: RecognitionTally | None = None
    completed = []
    rngs = np.random.default_rng([seed, len(sc.name)]).spawn(drivers)
    for k, rng in enumerate(rngs):
        result, engine = standalone_trial(
            folder,
            synthetic_participant(rng),
            mode="contextual_task",
            mode_settings=mode_settings,
            scenario=scene,
            inspection=bool(sc.inspection_object),
            timeout_s=TIMEOUT_S,
            seed=seed + k,
            database=f"{sc.name}_{k}.db",
        )
        engine.dispose()
        completed.append(bool(result.outcome.get("completed")))
        rec = result.outcome.get("recognition")
        if rec is None:
            continue
        one = RecognitionTally.from_summary(rec)
        tally = one if tally is None else tally.merge(one)
    return (tally if tally is not None else RecognitionTally({})), completed


def run(
    quick: bool,
    scenes: list[str] | None = None,
    *,
    drivers: int | None = None,
    generated: tuple[int, ...] | None = None,
    mode_settings: dict[str, Any] | None = None,
) -> dict[str, Any]:
    """Recognition in the loop: ``drivers`` drivers (default three, ``quick`` one) in each
    of ``scenes`` (default :func:`drivable_scenes`) and one driver in each generated floor
    plan of the seeds ``generated`` (default :data:`GENERATED_SEEDS`, ``quick`` the first
    three; ``()`` for none).

    Returns
    -------
    dict
        ``recognition_scenes`` (names), ``recognition_drivers_per_scene``,
        ``recognition_generated_seeds``; pooled over every scene: ``loop_task_match``,
        ``loop_task_target_match``, ``loop_null_rate`` (shares of labelled ticks) and
        ``labelled_ticks``; ``loop_per_task`` the same per true task type;
        ``loop_shipped`` and ``loop_generated`` the pooled figures of each set;
        ``loop_per_scene`` the figures per scene, with ``completed`` (the share of trials
        that completed their task).
    """
    scenes = list(scenes) if scenes else drivable_scenes()
    drivers = drivers if drivers is not None else (1 if quick else 3)
    if generated is None:
        generated = GENERATED_SEEDS[:3] if quick else GENERATED_SEEDS
    per_scene: dict[str, Any] = {}
    with tempfile.TemporaryDirectory(prefix="asa-bench-rec-") as tmp:
        folder = Path(tmp)
        shipped = _pooled(folder, [(s, drivers) for s in scenes], per_scene, mode_settings)
        plans = [(p, 1) for p in write_generated(folder, tuple(generated))]
        made = _pooled(folder, plans, per_scene, mode_settings)
    out = RecognitionTally({}).merge(shipped).merge(made).summary()
    return {
        "recognition_scenes": list(per_scene),
        "recognition_drivers_per_scene": drivers,
        "recognition_generated_seeds": list(generated),
        **{k: v for k, v in out.items() if k != "per_task"},
        "loop_per_task": out["per_task"],
        "loop_shipped": _brief(shipped),
        "loop_generated": _brief(made),
        "loop_per_scene": per_scene,
    }


def _brief(tally: RecognitionTally) -> dict[str, Any]:
    s = tally.summary()
    s.pop("per_task")
    return s


def _pooled(
    folder: Path,
    plan: list[tuple[str, int]],
    per_scene: dict[str, Any],
    mode_settings: dict[str, Any] | None,
) -> RecognitionTally:
    """Drive every (scene, drivers) of ``plan``; each scene's figures into ``per_scene``
    (keyed by the scenario's name); the pooled tally."""
    total = RecognitionTally({})
    for scene, n in plan:
        tally, completed = scene_recognition(folder, scene, n, _SEED, mode_settings)
        s = _brief(tally)
        s["completed"] = round(sum(completed) / len(completed), 4)
        per_scene[load_scenario(scene).name] = s
        total.merge(tally)
    return total
