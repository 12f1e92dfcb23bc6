"""Recording demonstrations of the contextual tasks: a scripted skill behind a simulated
human stick drives the world in manual mode, one run per demonstration, every control
tick stored (thesis Sec. 7.2.3, 7.3; spec section 3).
"""

from __future__ import annotations

import json
import zlib
from collections.abc import Callable, Iterator, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from autonomy.features import task_features
from sim.scenario import Scenario
from sim.semantics import derive_components
from sim.types import Observation, Pose2D, SemanticComponent
from sim.world import World
from study.data.paths import file_in
from study.jobs.demonstrations.files import (
    _ARRAYS,
    FORMAT_VERSION,
    MANIFEST,
    _npz_bytes,
    _read_manifest,
    _sha256,
)
from study.jobs.demonstrations.starts import FreeSpace, sample_start
from tasks.contextual import (
    DEFAULT_SCENES,
    DEMONSTRATED,
    DIRECTIONS,
    TARGET_KIND,
    ContextualTask,
    check_task_type,
)
from tasks.skills import SkillSettings, make_skill
from tasks.stick import HumanStick, HumanStickSettings

MOVING_SPEED = 0.02  # [m/s] translational input below this: the tick is not "moving"


@dataclass(frozen=True, slots=True)
class RecordSettings:
    """How demonstrations are recorded."""

    skill: SkillSettings = field(default_factory=SkillSettings)
    stick: HumanStickSettings = field(default_factory=HumanStickSettings)
    preferred_speed: tuple[float, float] = (0.3, 0.45)  # [m/s] drawn per run (thesis ~0.3)


@dataclass(frozen=True, slots=True)
class RunRecord:
    """One recorded demonstration (all per-tick arrays have n rows)."""

    scene: str
    task: ContextualTask
    start: Pose2D
    completed: bool
    phase: str  # the skill's final phase ("done", "timeout", ...)
    collisions: int
    arrays: dict[str, np.ndarray]  # see _ARRAYS


def run_seed(seed: int, task_type: str, scene: str, k: int) -> np.random.SeedSequence:
    """The seed sequence of run ``k`` of ``task_type`` in ``scene`` under ``seed``."""
    return np.random.SeedSequence(
        [int(seed), zlib.crc32(task_type.encode()), zlib.crc32(scene.encode()), int(k)]
    )


def candidates_of(scenario: Scenario, task_type: str) -> list[SemanticComponent]:
    """The components of ``scenario`` a ``task_type`` can target (ValueError if none)."""
    kind = TARGET_KIND[check_task_type(task_type)]
    found = [c for c in derive_components(scenario) if c.kind == kind]
    if not found:
        raise ValueError(
            f"scene {scenario.name}: has no {kind} component, so no {task_type} can be recorded"
        )
    return found


def record_run(
    world: World,
    task_type: str,
    seq: np.random.SeedSequence,
    *,
    settings: RecordSettings | None = None,
    free: FreeSpace | None = None,
) -> RunRecord:
    """Record one demonstration of ``task_type`` in ``world`` from seed sequence ``seq``.

    Returns
    -------
    RunRecord
        Per-tick arrays (see :class:`~study.jobs.demonstrations.files.Demonstrations` for
        their meaning), the task and the outcome.
    """
    settings = RecordSettings() if settings is None else settings
    scenario = world.scenario
    rng = np.random.default_rng(seq)
    world_seed = int(seq.generate_state(1)[0])
    targets = candidates_of(scenario, task_type)
    free = FreeSpace(scenario) if free is None else free
    task, start = _choose_task(scenario, task_type, targets, rng, free, settings.skill)
    stick = HumanStick(
        replace(settings.stick, preferred_speed=float(rng.uniform(*settings.preferred_speed)))
    )
    skill = make_skill(task_type, settings=settings.skill)
    skill.reset(task, rng)
    stick.reset(rng)
    r = scenario.robot
    limits = np.array([r.max_speed, r.max_speed, r.max_yaw_rate])
    obs = world.reset(start, seed=world_seed)
    rows: dict[str, list] = {name: [] for name in _ARRAYS if name != "cand_offsets"}
    offsets = [0]
    step = skill.act(obs)
    while not step.done:
        u = stick.filter(step.u)
        _store_tick(rows, offsets, world, obs, task, u, limits, step.phase)
        world.apply(u)
        world.step()
        obs = world.sense()
        step = skill.act(obs)
    return RunRecord(
        scene=scenario.name,
        task=task,
        start=start,
        completed=step.phase == "done",
        phase=step.phase,
        collisions=len(world.contacts()),
        arrays=_as_arrays(rows, offsets),
    )


def _choose_task(
    scenario: Scenario,
    task_type: str,
    targets: list[SemanticComponent],
    rng: np.random.Generator,
    free: FreeSpace,
    skill: SkillSettings,
) -> tuple[ContextualTask, Pose2D]:
    """A random target among ``targets``, direction and start; another target if no start
    works for one (e.g. a gap in a tight corner)."""
    directions = DIRECTIONS[task_type]
    for i in rng.permutation(len(targets)):
        direction = directions[int(rng.integers(len(directions)))]
        task = ContextualTask(task_type, targets[int(i)].id, direction)
        try:
            return task, sample_start(scenario, task, targets, rng, free=free, skill=skill)
        except ValueError:
            continue
    raise ValueError(
        f"scene {scenario.name}: no {TARGET_KIND[task_type]} has a feasible start for "
        f"{task_type} (see study.jobs.demonstrations.sample_start)"
    )


def _store_tick(
    rows: dict[str, list],
    offsets: list[int],
    world: World,
    obs: Observation,
    task: ContextualTask,
    u: np.ndarray,
    limits: np.ndarray,
    phase: str,
) -> None:
    """Append one tick: poses, stick command ``u`` (3,) [m/s, m/s, rad/s], the target
    point ``s`` and feature ``q`` (robot frame of the estimated pose), every candidate."""
    target = next(c for c in obs.components if c.id == task.target_id)
    s = target.target_point()
    u_norm = u / limits
    true = world.true_pose()
    rows["t"].append(obs.t)
    rows["pose_true"].append(true.as_array())
    rows["pose_est"].append(obs.pose.as_array())
    rows["u"].append(u)
    rows["u_norm"].append(u_norm)
    rows["target"].append(task.target_id)
    rows["s"].append(s)
    rows["q"].append(task_features(s, u_norm)[0])
    rows["moving"].append(bool(np.hypot(u[0], u[1]) >= MOVING_SPEED))
    rows["phase"].append(phase)
    for c in obs.components:
        rows["cand_points"].append(c.target_point())
        rows["cand_ids"].append(c.id)
        rows["cand_kinds"].append(c.kind)
    offsets.append(offsets[-1] + len(obs.components))


def _as_arrays(rows: dict[str, list], offsets: list[int]) -> dict[str, np.ndarray]:
    """The stored arrays of a run (shapes in ``files._ARRAYS``)."""
    return {
        "t": np.asarray(rows["t"], dtype=float).reshape(-1),
        "pose_true": np.asarray(rows["pose_true"], dtype=float).reshape(-1, 3),
        "pose_est": np.asarray(rows["pose_est"], dtype=float).reshape(-1, 3),
        "u": np.asarray(rows["u"], dtype=float).reshape(-1, 3),
        "u_norm": np.asarray(rows["u_norm"], dtype=float).reshape(-1, 3),
        "target": np.asarray(rows["target"], dtype=str).reshape(-1),
        "s": np.asarray(rows["s"], dtype=float).reshape(-1, 2),
        "q": np.asarray(rows["q"], dtype=float).reshape(-1, 6),
        "moving": np.asarray(rows["moving"], dtype=bool).reshape(-1),
        "phase": np.asarray(rows["phase"], dtype=str).reshape(-1),
        "cand_offsets": np.asarray(offsets, dtype=np.int64),
        "cand_points": np.asarray(rows["cand_points"], dtype=float).reshape(-1, 2),
        "cand_ids": np.asarray(rows["cand_ids"], dtype=str).reshape(-1),
        "cand_kinds": np.asarray(rows["cand_kinds"], dtype=str).reshape(-1),
    }


def plan_recording(task: str, scene: str | None) -> list[tuple[str, str]]:
    """``[(task type, scene)]`` for ``task`` (a type or ``"all"``, the four the thesis
    demonstrated) and ``scene`` (``None``: each type's demonstration scene)."""
    if task == "all":
        types = list(DEMONSTRATED)
    else:
        types = [check_task_type(task, field="task")]
    return [(t, scene if scene else DEFAULT_SCENES[t]) for t in types]


def resolve_plan(plan: Sequence[tuple[str, str | Scenario]]) -> list[tuple[str, Scenario]]:
    """Load every scene of ``plan`` and check it has a target for its task type.

    Raises ValueError naming the task type, scene or file before anything is recorded.
    """
    from study.jobs.scenes import load

    jobs = []
    for task_type, scene in plan:
        check_task_type(task_type, field="task")
        scenario = scene if isinstance(scene, Scenario) else load(scene)
        candidates_of(scenario, task_type)
        jobs.append((task_type, scenario))
    return jobs


def record_demonstrations(
    out: str | Path,
    plan: Sequence[tuple[str, str | Scenario]],
    runs: int,
    *,
    seed: int = 0,
    settings: RecordSettings | None = None,
    progress: Callable[[int], None] | None = None,
) -> dict[str, Any]:
    """Record ``runs`` demonstrations of each ``(task type, scene)`` into ``out``.

    Parameters
    ----------
    out : path
        Output directory (created); files ``<task>/<scene>_run_<k>.npz`` and
        ``manifest.json``. An existing manifest is merged: runs with the same file name
        are replaced, others kept.
    plan : sequence of (str, str or Scenario)
        Task types and the scene (a shipped name, a TOML path or a Scenario) each is
        recorded in; see :func:`plan_recording`.
    runs : int
        Runs per entry of ``plan``, >= 1.
    seed : int
        Master seed; per-run seeds are derived from it (:func:`run_seed`).
    progress : callable, optional
        Called with 1 after each run (a progress bar's ``update``).

    Returns
    -------
    dict
        The manifest written.
    """
    if not (isinstance(runs, int) and runs >= 1):
        raise ValueError(f"runs: must be a whole number >= 1, got {runs!r}")
    settings = RecordSettings() if settings is None else settings
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: out must be a directory")
    jobs = resolve_plan(plan)  # fail before recording anything
    entries: dict[str, dict[str, Any]] = {}
    if (out / MANIFEST).is_file():
        for entry in _read_manifest(out)["runs"]:
            entries[entry["file"]] = entry
    seeds = {entry.get("seed") for entry in entries.values()}
    for task_type, scenario in jobs:
        (out / task_type).mkdir(parents=True, exist_ok=True)
        for entry in _record_scene(out, task_type, scenario, runs, seed, settings, progress):
            entries[entry["file"]] = entry
    seeds.add(int(seed))
    seeds.discard(None)
    manifest = {
        "version": FORMAT_VERSION,
        "seed": int(seed) if seeds == {int(seed)} else None,
        "arrays": sorted(_ARRAYS),
        "runs": [entries[key] for key in sorted(entries)],
    }
    (out / MANIFEST).write_text(json.dumps(manifest, indent=1) + "\n")
    return manifest


def _record_scene(
    out: Path,
    task_type: str,
    scenario: Scenario,
    runs: int,
    seed: int,
    settings: RecordSettings,
    progress: Callable[[int], None] | None,
) -> Iterator[dict[str, Any]]:
    """Record and write runs 0..runs-1 of ``task_type`` in ``scenario``; yields each
    run's manifest entry once its file is written."""
    free = FreeSpace(scenario)
    with World(scenario, seed=int(seed)) as world:
        for k in range(runs):
            rec = record_run(
                world,
                task_type,
                run_seed(seed, task_type, scenario.name, k),
                settings=settings,
                free=free,
            )
            name = f"{scenario.name}_run_{k}"  # under out/<task>/, whatever the name says
            path = file_in(out / task_type, name, ".npz", what=f"{scenario.source}: field 'name'")
            rel = f"{task_type}/{name}.npz"
            path.write_bytes(_npz_bytes(rec.arrays))
            moving = rec.arrays["moving"]
            yield {
                "file": rel,
                "scene": scenario.name,
                "task": task_type,
                "direction": rec.task.direction,
                "target": rec.task.target_id,
                "ticks": int(len(moving)),
                "moving_ticks": int(moving.sum()),
                "completed": rec.completed,
                "final_phase": rec.phase,
                "collisions": rec.collisions,
                "duration_s": round(len(moving) * world.settings.dt, 3),
                "start": [round(v, 6) for v in rec.start.as_array().tolist()],
                "seed": int(seed),
                "run": k,
                "sha256": _sha256(path),
            }
            if progress is not None:
                progress(1)
