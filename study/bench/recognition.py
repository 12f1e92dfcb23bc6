"""Benchmark group ``recognition``: the contextual mode's recognition in the loop against
synthetic drivers' true intention (thesis Sec. 7.2.2, 7.4; issues 16 and 40).

Synthetic participants drawn from the population model drive the main trial (A -> B -> A,
inspecting the scene's object when it has one) in the contextual-task mode in every
shipped scene with a dock (three drivers each) and in the generated floor plans of seeds
0-9 (:func:`sim.generate.generate_scene`, one driver each); every tick the driver says
which task and target it is executing, and :class:`study.engine.recognition.RecognitionTally`
scores the mode's recognised task type and target, and the assistance its blend weight
gave, against them. The generated seeds 20-29 are held out (:data:`HELD_OUT_SEEDS`: run
once, at the end, nothing tuned on them). The figures are listed in :func:`run`; other
settings of the mode (e.g. another recogniser) can be measured beside the default.
"""

from __future__ import annotations

import tempfile
from collections.abc import Callable, Mapping
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
HELD_OUT_SEEDS = tuple(range(20, 30))  # generated scenes nothing may be tuned on


def drivable_scenes() -> list[str]:
    """Shipped scenes with a dock (every shipped scene has a start): where a main trial
    A -> B -> A can be driven."""
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
    *,
    wrap_mode: Callable[[Any], Any] | None = None,
) -> tuple[RecognitionTally, list[bool]]:
    """``drivers`` synthetic drivers, one main trial each in ``scene`` in the contextual
    mode (with ``mode_settings``, e.g. another ``model_path``; ``wrap_mode`` applied to the
    built mode, as :func:`study.engine.standalone.standalone_trial`): the pooled tally and
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
            wrap_mode=wrap_mode,
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
    compare: Mapping[str, Mapping[str, Any]] | None = None,
) -> dict[str, Any]:
    """Recognition in the loop: ``drivers`` drivers (default three, ``quick`` one) in each
    of ``scenes`` (default :func:`drivable_scenes`; ``[]`` for none) and one driver in each
    generated floor plan of the seeds ``generated`` (default :data:`GENERATED_SEEDS`,
    ``quick`` the first three; ``()`` for none).

    Parameters
    ----------
    mode_settings : the contextual mode's settings of the measured run (default: its
        defaults).
    compare : further runs on the same scenes and drivers, name -> settings laid over
        ``mode_settings`` (e.g. ``{"thesis": {"recogniser": "thesis"}}``); their pooled
        figures go beside the measured run's under ``recognition_compare``.

    Returns
    -------
    dict
        ``recognition_scenes`` (names), ``recognition_drivers_per_scene``,
        ``recognition_generated_seeds``; pooled over every scene: ``loop_task_match``,
        ``loop_task_target_match``, ``loop_null_rate`` (shares of labelled ticks) and
        ``labelled_ticks``; ``assist_precision``, ``assist_precision_labelled``,
        ``assist_coverage``, ``assist_unlabelled_ticks``, ``confident_wrong_s``,
        ``confident_wrong_s_per_min`` [s per trial minute], ``confident_wrong_longest_s``
        (:func:`study.engine.recognition.assist_measures`); ``loop_per_task`` the figures
        per true task type; ``loop_deciles`` per decile of the trials' labelled time;
        ``loop_assist`` the pooled counts and seconds behind the assistance figures;
        ``loop_shipped`` and ``loop_generated`` the pooled figures of each set;
        ``loop_per_scene`` the figures per scene, with ``completed`` (the share of trials
        that completed their task); with ``compare``, ``recognition_compare`` {"default"
        and each name -> its pooled figures with ``per_task`` and ``deciles``}.
    """
    scenes = drivable_scenes() if scenes is None else list(scenes)
    drivers = drivers if drivers is not None else (1 if quick else 3)
    if generated is None:
        generated = GENERATED_SEEDS[:3] if quick else GENERATED_SEEDS
    per_scene: dict[str, Any] = {}
    runs = {"default": dict(mode_settings or {})}
    for name, extra in (compare or {}).items():
        runs[name] = {**(mode_settings or {}), **dict(extra)}
    pooled: dict[str, RecognitionTally] = {}
    with tempfile.TemporaryDirectory(prefix="asa-bench-rec-") as tmp:
        folder = Path(tmp)
        plans = [(s, drivers) for s in scenes]
        plans += [(p, 1) for p in write_generated(folder, tuple(generated))]
        for name, settings in runs.items():
            sets = _drive(folder / name, plans, len(scenes), settings)
            if name == "default":
                shipped, made, per_scene = sets
            pooled[name] = RecognitionTally({}).merge(sets[0]).merge(sets[1])
    out = pooled["default"].summary()
    figures = {
        "recognition_scenes": list(per_scene),
        "recognition_drivers_per_scene": drivers,
        "recognition_generated_seeds": list(generated),
        **{k: v for k, v in out.items() if k not in ("per_task", "deciles", "assist")},
        "loop_per_task": out["per_task"],
        "loop_deciles": out["deciles"],
        "loop_assist": out["assist"],
        "loop_shipped": _brief(shipped),
        "loop_generated": _brief(made),
        "loop_per_scene": per_scene,
    }
    if compare:
        figures["recognition_compare"] = {n: t.summary() for n, t in pooled.items()}
    return figures


def _brief(tally: RecognitionTally) -> dict[str, Any]:
    """A tally's pooled figures, without those per task type and per decile."""
    s = tally.summary()
    for key in ("per_task", "deciles", "assist"):
        s.pop(key)
    return s


def _drive(
    folder: Path, plan: list[tuple[str, int]], n_shipped: int, settings: dict[str, Any]
) -> tuple[RecognitionTally, RecognitionTally, dict[str, Any]]:
    """Drive every (scene, drivers) of ``plan`` with the mode's ``settings``, the first
    ``n_shipped`` the shipped scenes: the pooled tallies of the shipped and the generated
    scenes and each scene's figures (keyed by the scenario's name)."""
    folder.mkdir(parents=True, exist_ok=True)
    per_scene: dict[str, Any] = {}
    shipped, made = RecognitionTally({}), RecognitionTally({})
    for k, (scene, n) in enumerate(plan):
        tally, completed = scene_recognition(folder, scene, n, _SEED, settings or None)
        s = _brief(tally)
        s["completed"] = round(sum(completed) / len(completed), 4)
        per_scene[load_scenario(scene).name] = s
        (shipped if k < n_shipped else made).merge(tally)
    return shipped, made, per_scene
