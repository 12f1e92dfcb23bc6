"""Recording and loading demonstrations of the contextual tasks (thesis Sec. 7.2.3, 7.3,
7.4.1-7.4.2; spec section 3; issue 3, "Demonstrations and training").

:func:`record_demonstrations` drives a :class:`~sim.world.World` in manual mode
(``v = u``) with a scripted skill (:mod:`tasks.skills`) behind a
:class:`~tasks.skills.HumanStick`, one run per demonstration: a random start pose,
a random target among the scene's components of the task's kind, a random direction
or side. Every control tick is stored with the true and estimated pose, the stick
command, the demonstrated target and its target point ``s`` in the robot frame, the
task feature ``q`` against that target, and the target points of *all* candidate
components, so that an evaluation can ask for "the right target among all
candidates". The true task type is kept for evaluation only (the learner clusters
``q`` without labels). :func:`load_demonstrations` reads a directory back, checking
every file against the manifest.

Decisions where the spec is silent:

- Ticks. Every control tick (20 Hz) up to the skill's ``done`` is stored, with a
  ``moving`` flag for ticks with translational input (``|u_xy| >= MOVING_SPEED``).
  The thesis recorded way points while the robot moved (5 Hz, the joystick's rate,
  Sec. 7.3 footnote 11); a tick without translational input has no input direction,
  so its ``theta`` carries no intention. :func:`load_demonstrations` keeps only the
  moving ticks unless ``moving_only=False``; 20 Hz rather than 5 Hz gives the learner
  four times as many (correlated) points, which subsampling can undo.
- Units. ``u`` is stored in physical units (m/s, rad/s) as sent to the world;
  ``u_norm`` is each channel divided by the robot's limit (``max_speed``,
  ``max_speed``, ``max_yaw_rate``), the (-1, 1) units of thesis Sec. 5.1, and
  ``q = task_features(s, u_norm)``.
- Frames. ``s`` and the candidate points are in the robot frame of the *estimated*
  pose, exactly what the recogniser sees at run time.
- Start poses: a free cell (clearance of at least :data:`START_CLEARANCE_M` from
  every obstacle, so the footprint is clear at any heading) in the free space
  connected to the scene's start A, ``START_DISTANCE_M`` from the target, with a
  straight, clear way to where the skill first heads (checked on the occupancy
  grid), and a uniformly random heading. For object bypass the heading points at the
  object within +-:data:`BYPASS_HEADING_NOISE_DEG` (the object must be "in the way"),
  and the start is 1.8-3 m before its circumcircle with the swerving line clear.
  For wall following the start is at most 2.5 m from the face and must leave at
  least the shortest follow length plus its distance from the wall (what the approach
  uses up) of face ahead in the chosen direction.
- Seeds. Each run's Generator and world seed come from
  ``SeedSequence([seed, crc32(task), crc32(scene), k])``: the same command gives
  identical files, and adding runs or tasks does not change the earlier ones.
- Files. One ``.npz`` per run (plain arrays, no pickle, written with fixed zip
  timestamps so the bytes are reproducible); ``manifest.json`` holds the runs and the
  SHA-256 of each file. Recording into a directory with a manifest merges: runs with
  the same file name are replaced, others kept.
"""

from __future__ import annotations

import hashlib
import io
import json
import math
import zipfile
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from autonomy.features import task_features
from sim.occupancy import OccupancyGrid, build_grid, clearance_map
from sim.scenario import Scenario
from sim.semantics import derive_components
from sim.types import Pose2D, SemanticComponent
from sim.world import World
from tasks.contextual import (
    DEFAULT_SCENES,
    DEMONSTRATED,
    DIRECTIONS,
    TARGET_KIND,
    TASK_TYPES,
    ContextualTask,
    check_task_type,
)
from tasks.skills import (
    HumanStick,
    HumanStickSettings,
    SkillSettings,
    make_skill,
    wall_face,
)

FORMAT_VERSION = 1
MANIFEST = "manifest.json"
MOVING_SPEED = 0.02  # [m/s] translational input below this: the tick is not "moving"
START_CLEARANCE_M = 0.55  # [m] start cell to the nearest obstacle (footprint circumradius 0.39)
CONNECT_CLEARANCE_M = 0.3  # [m] free space counts as connected through this clearance
PATH_CLEARANCE_M = 0.5  # [m] along the straight way the skill first takes
START_DISTANCE_M = (1.5, 3.5)  # [m] start to the target's reference point
BYPASS_HEADING_NOISE_DEG = 10.0
MAX_START_TRIES = 400

# name -> (dtype kind, trailing shape); "n" ticks, "m" candidate points in total
_ARRAYS: dict[str, tuple[str, tuple[int, ...]]] = {
    "t": ("f", ()),
    "pose_true": ("f", (3,)),
    "pose_est": ("f", (3,)),
    "u": ("f", (3,)),
    "u_norm": ("f", (3,)),
    "target": ("U", ()),  # id of the demonstrated component
    "s": ("f", (2,)),
    "q": ("f", (6,)),
    "moving": ("b", ()),
    "phase": ("U", ()),
    "cand_offsets": ("i", ()),  # (n + 1,)
    "cand_points": ("f", (2,)),  # (m, 2)
    "cand_ids": ("U", ()),  # (m,)
    "cand_kinds": ("U", ()),  # (m,)
}
_RUN_FIELDS = (
    "file",
    "scene",
    "task",
    "direction",
    "target",
    "ticks",
    "completed",
    "collisions",
    "sha256",
)


# --------------------------------------------------------------------------- values


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


@dataclass(frozen=True, slots=True)
class Demonstrations:
    """Demonstrations loaded from a directory; n ticks, m candidate points in total.

    ``task`` is the true task type, for evaluation only.
    """

    q: np.ndarray  # (n, 6) task features against the demonstrated target
    s: np.ndarray  # (n, 2) [m] demonstrated target point, robot frame
    u: np.ndarray  # (n, 3) stick command [m/s, m/s, rad/s]
    u_norm: np.ndarray  # (n, 3) the same in (-1, 1) units
    t: np.ndarray  # (n,) [s] time since the run's start
    pose_true: np.ndarray  # (n, 3) [m, m, rad] map frame
    pose_est: np.ndarray  # (n, 3) [m, m, rad] map frame
    run: np.ndarray  # (n,) int index into ``runs``
    task: np.ndarray  # (n,) str true task type (evaluation only)
    target: np.ndarray  # (n,) str id of the demonstrated component
    cand_offsets: np.ndarray  # (n + 1,) int: tick i's candidates are [off[i], off[i+1])
    cand_points: np.ndarray  # (m, 2) [m] target points of all candidates, robot frame
    cand_ids: np.ndarray  # (m,) str
    cand_kinds: np.ndarray  # (m,) str
    runs: tuple[dict[str, Any], ...]  # the manifest's run entries
    directory: str

    def candidates(self, i: int) -> tuple[np.ndarray, np.ndarray]:
        """Ids (k,) and target points (k, 2) [m] of tick ``i``'s candidates."""
        a, b = int(self.cand_offsets[i]), int(self.cand_offsets[i + 1])
        return self.cand_ids[a:b], self.cand_points[a:b]

    def __len__(self) -> int:
        return len(self.q)


# --------------------------------------------------------------------------- start poses


class FreeSpace:
    """Clearance look-ups on a scene's occupancy grid (5 cm), and the cells a start may
    be drawn from: at least ``START_CLEARANCE_M`` clear, in the free space connected
    (through ``CONNECT_CLEARANCE_M``) to the scene's start A. Build once per scene."""

    def __init__(self, scenario: Scenario) -> None:
        self.grid: OccupancyGrid = build_grid(scenario, resolution=0.05)
        self.clear = clearance_map(self.grid)
        # connected through passages a robot fits through, starting only where roomy
        labels, _ = ndimage.label(self.clear >= CONNECT_CLEARANCE_M)
        a = self._cell(np.array([scenario.start.x, scenario.start.y]))
        label = labels[a] if a is not None else 0
        # where A itself is tight, fall back to the largest free region
        if label == 0:
            sizes = np.bincount(labels.ravel())
            sizes[0] = 0
            label = int(np.argmax(sizes))
        self.region = labels == label
        rows, cols = np.nonzero(self.region & (self.clear >= START_CLEARANCE_M))
        res = self.grid.resolution
        x0, y0 = self.grid.origin
        self.cells = np.column_stack((x0 + (cols + 0.5) * res, y0 + (rows + 0.5) * res))

    def _cell(self, xy: np.ndarray) -> tuple[int, int] | None:
        res = self.grid.resolution
        col = int(math.floor((xy[0] - self.grid.origin[0]) / res))
        row = int(math.floor((xy[1] - self.grid.origin[1]) / res))
        rows, cols = self.grid.occupied.shape
        return (row, col) if 0 <= row < rows and 0 <= col < cols else None

    def clearance(self, xy: np.ndarray) -> float:
        cell = self._cell(xy)
        return float(self.clear[cell]) if cell is not None else 0.0

    def in_region(self, xy: np.ndarray) -> bool:
        cell = self._cell(xy)
        return cell is not None and bool(self.region[cell])

    def segment_clear(self, a: np.ndarray, b: np.ndarray, need: float) -> bool:
        n = max(int(math.ceil(float(np.hypot(*(b - a))) / 0.05)), 1)
        return all(self.clearance(a + (b - a) * k / n) >= need for k in range(n + 1))


def _feasible(
    task: ContextualTask,
    comp: SemanticComponent,
    xy: np.ndarray,
    yaw: float,
    free: FreeSpace,
    s: SkillSettings,
) -> bool:
    """Whether the skill has a clear straight way from ``xy`` (decided, see module doc)."""
    need = PATH_CLEARANCE_M
    if task.type in ("doorway_crossing", "gap_crossing"):
        n = comp.normal / max(float(np.hypot(*comp.normal)), 1e-12)
        side = 1.0 if float((xy - comp.centre) @ n) >= 0 else -1.0
        pre = comp.centre + side * s.pass_distance * n
        post = comp.centre - side * s.pass_distance * n
        return (
            free.clearance(pre) >= need
            and free.segment_clear(post, post - side * 0.4 * n, need)
            and free.segment_clear(xy, pre, need)
        )
    if task.type == "robot_docking":
        n = comp.normal / max(float(np.hypot(*comp.normal)), 1e-12)
        pre = comp.centre - s.dock_pre_distance * n
        return free.clearance(pre) >= need and free.segment_clear(xy, pre, need)
    centre = comp.centre
    radius = float(np.max(np.hypot(*(comp.points - centre).T))) if len(comp.points) else 0.0
    if task.type == "object_inspection":
        ring = radius + s.inspection_distance[1]
        angles = np.linspace(0, 2 * math.pi, 48, endpoint=False)
        on_ring = centre + ring * np.column_stack((np.cos(angles), np.sin(angles)))
        if not all(free.clearance(p) >= need - 0.05 for p in on_ring):
            return False
        d = (centre - xy) / max(float(np.hypot(*(centre - xy))), 1e-12)
        return free.segment_clear(xy, centre - d * ring, need)
    if task.type == "object_bypass":
        d = (centre - xy) / max(float(np.hypot(*(centre - xy))), 1e-12)
        right = np.array([d[1], -d[0]])
        sign = 1.0 if task.direction == "left" else -1.0
        offset = sign * right * (radius + s.half_width + s.bypass_clearance[1])
        before = centre - d * (radius + 1.6)
        after = centre + d * (radius + s.half_length + 0.6)
        return (
            free.segment_clear(xy, before, need)
            and free.segment_clear(before + 0.5 * offset, centre + offset, need)
            and free.segment_clear(centre + offset, after + offset, need)
        )
    # wall following
    face = wall_face(comp.points, xy)
    n = face.normal
    heading = np.array([-n[1], n[0]]) if task.direction == "left" else np.array([n[1], -n[0]])
    sense = 1.0 if float(heading @ face.tangent) >= 0 else -1.0
    end = (face.hi if sense > 0 else -face.lo) - s.wall_end_margin
    along = sense * float((xy - face.point) @ face.tangent)
    lateral = float((xy - face.point) @ n)
    if lateral < s.wall_distance[0] or lateral > 2.5:
        return False
    # the approach runs along the wall about as far as the robot starts from it
    if end - max(along, sense * (face.lo if sense > 0 else face.hi)) < s.wall_length[0] + lateral:
        return False
    line = face.point + n * float(np.mean(s.wall_distance))
    a = line + face.tangent * sense * (along + 0.7)
    b = line + face.tangent * sense * end  # the skill may follow up to the end
    return free.segment_clear(xy, a, need) and free.segment_clear(a, b, need - 0.12)


def sample_start(
    scenario: Scenario,
    task: ContextualTask,
    components: Sequence[SemanticComponent],
    rng: np.random.Generator,
    *,
    free: FreeSpace | None = None,
    skill: SkillSettings | None = None,
) -> Pose2D:
    """A random start pose for ``task`` in ``scenario`` (decided; see the module doc).

    Raises ValueError naming the scene and target when no start is found.
    """
    s = SkillSettings() if skill is None else skill
    free = FreeSpace(scenario) if free is None else free
    comp = next((c for c in components if c.id == task.target_id), None)
    if comp is None:
        raise ValueError(f"scene {scenario.name}: no component {task.target_id!r}")
    cells = free.cells
    if task.type == "object_bypass":
        radius = float(np.max(np.hypot(*(comp.points - comp.centre).T)))
        lo, hi = radius + 1.8, radius + 3.0
        dist = np.hypot(*(cells - comp.centre).T)
    else:
        lo, hi = START_DISTANCE_M
        ref = comp.points if comp.kind in ("object", "wall") and len(comp.points) else None
        if ref is None:
            dist = np.hypot(*(cells - comp.centre).T)
        else:
            dist, _ = cKDTree(ref).query(cells)
    cells = cells[(dist >= lo) & (dist <= hi)]
    if not len(cells):
        raise ValueError(
            f"scene {scenario.name}: no free start {lo:.1f}-{hi:.1f} m from {task.target_id!r}"
        )
    for _ in range(MAX_START_TRIES):
        xy = cells[int(rng.integers(len(cells)))] + rng.uniform(-0.025, 0.025, 2)
        if task.type == "object_bypass":
            to = comp.centre - xy
            noise = math.radians(BYPASS_HEADING_NOISE_DEG)
            yaw = math.atan2(to[1], to[0]) + float(rng.uniform(-noise, noise))
        else:
            yaw = float(rng.uniform(-math.pi, math.pi))
        if _feasible(task, comp, xy, yaw, free, s):
            return Pose2D(float(xy[0]), float(xy[1]), yaw)
    raise ValueError(
        f"scene {scenario.name}: no feasible start for {task.type} at {task.target_id!r} "
        f"after {MAX_START_TRIES} tries"
    )


# --------------------------------------------------------------------------- recording


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
        Per-tick arrays (see :class:`Demonstrations` for their meaning), the task and
        the outcome.
    """
    settings = RecordSettings() if settings is None else settings
    scenario = world.scenario
    rng = np.random.default_rng(seq)
    world_seed = int(seq.generate_state(1)[0])
    targets = candidates_of(scenario, task_type)
    directions = DIRECTIONS[task_type]
    free = FreeSpace(scenario) if free is None else free
    start = None
    # a random target; another one if no start works for it (e.g. a gap in a tight corner)
    for i in rng.permutation(len(targets)):
        direction = directions[int(rng.integers(len(directions)))]
        task = ContextualTask(task_type, targets[int(i)].id, direction)
        try:
            start = sample_start(scenario, task, targets, rng, free=free, skill=settings.skill)
            break
        except ValueError:
            continue
    if start is None:
        raise ValueError(
            f"scene {scenario.name}: no {TARGET_KIND[task_type]} has a feasible start for "
            f"{task_type} (see study.jobs.demonstrations.sample_start)"
        )
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
        rows["phase"].append(step.phase)
        for c in obs.components:
            rows["cand_points"].append(c.target_point())
            rows["cand_ids"].append(c.id)
            rows["cand_kinds"].append(c.kind)
        offsets.append(offsets[-1] + len(obs.components))
        world.apply(u)
        world.step()
        obs = world.sense()
        step = skill.act(obs)
    arrays = {
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
    return RunRecord(
        scene=scenario.name,
        task=task,
        start=start,
        completed=step.phase == "done",
        phase=step.phase,
        collisions=len(world.contacts()),
        arrays=arrays,
    )


def _npz_bytes(arrays: dict[str, np.ndarray]) -> bytes:
    """An .npz archive with fixed timestamps (np.savez stamps the current time)."""
    buffer = io.BytesIO()
    with zipfile.ZipFile(buffer, "w", compression=zipfile.ZIP_DEFLATED) as archive:
        for name in sorted(arrays):
            info = zipfile.ZipInfo(f"{name}.npy", date_time=(1980, 1, 1, 0, 0, 0))
            info.compress_type = zipfile.ZIP_DEFLATED
            data = io.BytesIO()
            np.lib.format.write_array(data, np.ascontiguousarray(arrays[name]), allow_pickle=False)
            archive.writestr(info, data.getvalue())
    return buffer.getvalue()


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def plan_recording(task: str, scene: str | None) -> list[tuple[str, str]]:
    """``[(task type, scene)]`` for a ``--task`` value (a type or ``"all"``) and ``--scene``."""
    if task == "all":
        types = list(DEMONSTRATED)
    else:
        types = [check_task_type(task, field="--task")]
    return [(t, scene if scene else DEFAULT_SCENES[t]) for t in types]


def resolve_plan(plan: Sequence[tuple[str, str | Scenario]]) -> list[tuple[str, Scenario]]:
    """Load every scene of ``plan`` and check it has a target for its task type.

    Raises ValueError naming the option, scene or file before anything is recorded.
    """
    from study.jobs.scenes import load

    jobs = []
    for task_type, scene in plan:
        check_task_type(task_type, field="--task")
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
        ``manifest.json``.
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
        raise ValueError(f"--runs: must be a whole number >= 1, got {runs!r}")
    settings = RecordSettings() if settings is None else settings
    out = Path(out)
    if out.exists() and not out.is_dir():
        raise ValueError(f"{out}: --out must be a directory")
    jobs = resolve_plan(plan)  # fail before recording anything
    manifest_path = out / MANIFEST
    entries: dict[str, dict[str, Any]] = {}
    if manifest_path.is_file():
        for entry in _read_manifest(out)["runs"]:
            entries[entry["file"]] = entry
    seeds = {entry.get("seed") for entry in entries.values()}
    for task_type, scenario in jobs:
        (out / task_type).mkdir(parents=True, exist_ok=True)
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
                rel = f"{task_type}/{scenario.name}_run_{k}.npz"
                path = out / rel
                path.write_bytes(_npz_bytes(rec.arrays))
                moving = rec.arrays["moving"]
                entries[rel] = {
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
    seeds.add(int(seed))
    seeds.discard(None)
    manifest = {
        "version": FORMAT_VERSION,
        "seed": int(seed) if seeds == {int(seed)} else None,
        "arrays": sorted(_ARRAYS),
        "runs": [entries[key] for key in sorted(entries)],
    }
    manifest_path.write_text(json.dumps(manifest, indent=1) + "\n")
    return manifest


# --------------------------------------------------------------------------- loading


def _read_manifest(directory: Path) -> dict[str, Any]:
    path = directory / MANIFEST
    if not directory.is_dir():
        raise ValueError(f"{directory}: not a directory of demonstrations")
    if not path.is_file():
        raise ValueError(f"{path}: no manifest (record with `asa demonstrations record`)")
    try:
        manifest = json.loads(path.read_text())
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as error:
        raise ValueError(f"{path}: not a readable JSON manifest ({error})") from None
    if not isinstance(manifest, dict):
        raise ValueError(f"{path}: the manifest must be a JSON object")
    if manifest.get("version") != FORMAT_VERSION:
        raise ValueError(
            f"{path}: field 'version': {manifest.get('version')!r} not supported "
            f"(this platform reads {FORMAT_VERSION})"
        )
    runs = manifest.get("runs")
    if not isinstance(runs, list):
        raise ValueError(f"{path}: field 'runs': must be a list of run entries")
    for i, entry in enumerate(runs):
        if not isinstance(entry, dict):
            raise ValueError(f"{path}: field 'runs[{i}]': must be an object")
        for name in _RUN_FIELDS:
            if name not in entry:
                raise ValueError(f"{path}: field 'runs[{i}].{name}': missing")
        if entry["task"] not in TASK_TYPES:
            raise ValueError(
                f"{path}: field 'runs[{i}].task': {entry['task']!r} unknown; "
                f"allowed: {', '.join(TASK_TYPES)}"
            )
        rel = Path(str(entry["file"]))
        if rel.is_absolute() or ".." in rel.parts:
            raise ValueError(f"{path}: field 'runs[{i}].file': must be a path inside {directory}")
    return manifest


def _load_run(path: Path, entry: dict[str, Any]) -> dict[str, np.ndarray]:
    if not path.is_file():
        raise ValueError(f"{path}: missing (listed in the manifest)")
    digest = _sha256(path)
    if digest != entry["sha256"]:
        raise ValueError(
            f"{path}: field 'sha256': file hash {digest[:12]}... does not match the "
            f"manifest's {str(entry['sha256'])[:12]}... (file changed or corrupted)"
        )
    try:
        with np.load(path, allow_pickle=False) as data:
            arrays = {name: data[name] for name in data.files}
    except Exception as error:  # zipfile, format or pickle errors all mean a bad file
        raise ValueError(f"{path}: not a readable .npz file ({error})") from None
    for name in _ARRAYS:
        if name not in arrays:
            raise ValueError(f"{path}: field '{name}': missing array")
    n = len(arrays["t"])
    m = len(arrays["cand_points"])
    for name, (kind, trailing) in _ARRAYS.items():
        a = arrays[name]
        rows = n + 1 if name == "cand_offsets" else m if name.startswith("cand_") else n
        if a.shape != (rows, *trailing) or a.dtype.kind not in (kind, "u" if kind == "i" else kind):
            raise ValueError(
                f"{path}: field '{name}': expected shape {(rows, *trailing)} of kind "
                f"'{kind}', got {a.shape} {a.dtype}"
            )
        if kind == "f" and not np.all(np.isfinite(a)):
            raise ValueError(f"{path}: field '{name}': must be finite")
    off = arrays["cand_offsets"]
    if off[0] != 0 or off[-1] != m or np.any(np.diff(off) < 0):
        raise ValueError(
            f"{path}: field 'cand_offsets': must rise from 0 to {m} (the candidate count)"
        )
    if n and not np.all(arrays["target"] == entry["target"]):
        raise ValueError(
            f"{path}: field 'target': does not match the manifest's {entry['target']!r}"
        )
    if n != entry["ticks"]:
        raise ValueError(
            f"{path}: field 'ticks': manifest says {entry['ticks']}, file has {n} ticks"
        )
    return arrays


def load_demonstrations(directory: str | Path, *, moving_only: bool = True) -> Demonstrations:
    """Load and validate a directory written by :func:`record_demonstrations`.

    Parameters
    ----------
    directory : path
        The ``--out`` directory of ``asa demonstrations record``.
    moving_only : bool
        Keep only ticks with translational input (the way points, see the module doc).

    Returns
    -------
    Demonstrations
        All runs concatenated in manifest order.

    Raises
    ------
    ValueError
        Naming the file and field: missing manifest, missing file, hash mismatch,
        unreadable file, missing array, wrong shape.
    """
    directory = Path(directory)
    manifest = _read_manifest(directory)
    parts: dict[str, list[np.ndarray]] = {name: [] for name in (*_ARRAYS, "run", "task")}
    offset_base = 0
    for i, entry in enumerate(manifest["runs"]):
        a = _load_run(directory / entry["file"], entry)
        keep = a["moving"] if moving_only else np.ones(len(a["t"]), dtype=bool)
        off = a["cand_offsets"]
        idx = np.nonzero(keep)[0]
        counts = off[idx + 1] - off[idx]
        picks = (
            np.concatenate([np.arange(off[j], off[j + 1]) for j in idx])
            if len(idx)
            else np.zeros(0, dtype=int)
        )
        for name in _ARRAYS:
            if name == "cand_offsets":
                continue
            parts[name].append(a[name][picks] if name.startswith("cand_") else a[name][keep])
        parts["cand_offsets"].append(offset_base + np.cumsum(counts))
        offset_base += int(counts.sum())
        k = len(idx)
        parts["run"].append(np.full(k, i, dtype=np.int64))
        parts["task"].append(np.full(k, entry["task"]))

    def cat(name: str, shape: tuple[int, ...], dtype: Any) -> np.ndarray:
        return np.concatenate(parts[name]) if parts[name] else np.zeros(shape, dtype=dtype)

    offsets = np.concatenate(([0], cat("cand_offsets", (0,), np.int64))).astype(np.int64)
    return Demonstrations(
        q=cat("q", (0, 6), float),
        s=cat("s", (0, 2), float),
        u=cat("u", (0, 3), float),
        u_norm=cat("u_norm", (0, 3), float),
        t=cat("t", (0,), float),
        pose_true=cat("pose_true", (0, 3), float),
        pose_est=cat("pose_est", (0, 3), float),
        run=cat("run", (0,), np.int64),
        task=cat("task", (0,), str),
        target=cat("target", (0,), str),
        cand_offsets=offsets,
        cand_points=cat("cand_points", (0, 2), float),
        cand_ids=cat("cand_ids", (0,), str),
        cand_kinds=cat("cand_kinds", (0,), str),
        runs=tuple(manifest["runs"]),
        directory=str(directory),
    )


def summarise(directory: str | Path) -> dict[str, Any]:
    """Counts per task type from the manifest (files are checked by hash too).

    Returns
    -------
    dict
        ``{"directory", "runs", "ticks", "tasks": {task: {"runs", "ticks",
        "moving_ticks", "completed", "completion_rate", "collisions", "scenes"}}}``.
    """
    directory = Path(directory)
    manifest = _read_manifest(directory)
    tasks: dict[str, dict[str, Any]] = {}
    for entry in manifest["runs"]:
        path = directory / entry["file"]
        if not path.is_file():
            raise ValueError(f"{path}: missing (listed in the manifest)")
        if _sha256(path) != entry["sha256"]:
            raise ValueError(f"{path}: field 'sha256': does not match the manifest")
        t = tasks.setdefault(
            entry["task"],
            {
                "runs": 0,
                "ticks": 0,
                "moving_ticks": 0,
                "completed": 0,
                "collisions": 0,
                "scenes": [],
            },
        )
        t["runs"] += 1
        t["ticks"] += int(entry["ticks"])
        t["moving_ticks"] += int(entry.get("moving_ticks", entry["ticks"]))
        t["completed"] += int(bool(entry["completed"]))
        t["collisions"] += int(entry["collisions"])
        if entry["scene"] not in t["scenes"]:
            t["scenes"].append(entry["scene"])
    for t in tasks.values():
        t["completion_rate"] = round(t["completed"] / t["runs"], 4)
    return {
        "directory": str(directory),
        "version": manifest["version"],
        "seed": manifest.get("seed"),
        "runs": sum(t["runs"] for t in tasks.values()),
        "ticks": sum(t["ticks"] for t in tasks.values()),
        "tasks": {k: tasks[k] for k in sorted(tasks)},
    }
