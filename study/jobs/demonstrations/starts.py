"""Start poses for demonstrations: a free, connected cell at a distance from the target
with a straight, clear way to where the skill first heads (spec section 3; the rules are
in docs/decisions.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from sim.occupancy import OccupancyGrid, build_grid, clearance_map
from sim.scenario import Scenario
from sim.types import Pose2D, SemanticComponent
from tasks.contextual import ContextualTask
from tasks.skills import SkillSettings, wall_face

START_CLEARANCE_M = 0.55  # [m] start cell to the nearest obstacle (footprint circumradius 0.39)
CONNECT_CLEARANCE_M = 0.3  # [m] free space counts as connected through this clearance
PATH_CLEARANCE_M = 0.5  # [m] along the straight way the skill first takes
START_DISTANCE_M = (1.5, 3.5)  # [m] start to the target's reference point
BYPASS_HEADING_NOISE_DEG = 10.0
MAX_START_TRIES = 400


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


def _unit(v: np.ndarray) -> np.ndarray:
    return v / max(float(np.hypot(*v)), 1e-12)


def _radius(comp: SemanticComponent) -> float:
    """The component's circumradius [m] about its centre (0 without surface points)."""
    centre = comp.centre
    return float(np.max(np.hypot(*(comp.points - centre).T))) if len(comp.points) else 0.0


def _crossing_clear(task, comp, xy, free, s, need) -> bool:
    """Doorway and gap crossing: to the pre-pass point, and beyond the passage."""
    n = _unit(comp.normal)
    side = 1.0 if float((xy - comp.centre) @ n) >= 0 else -1.0
    pre = comp.centre + side * s.pass_distance * n
    post = comp.centre - side * s.pass_distance * n
    return (
        free.clearance(pre) >= need
        and free.segment_clear(post, post - side * 0.4 * n, need)
        and free.segment_clear(xy, pre, need)
    )


def _docking_clear(task, comp, xy, free, s, need) -> bool:
    """Docking: to the pre-dock point in front of the table."""
    n = _unit(comp.normal)
    pre = comp.centre - s.dock_pre_distance * n
    return free.clearance(pre) >= need and free.segment_clear(xy, pre, need)


def _inspection_clear(task, comp, xy, free, s, need) -> bool:
    """Object inspection: the whole ring round the object, and the way to it."""
    centre = comp.centre
    ring = _radius(comp) + s.inspection_distance[1]
    angles = np.linspace(0, 2 * math.pi, 48, endpoint=False)
    on_ring = centre + ring * np.column_stack((np.cos(angles), np.sin(angles)))
    if not all(free.clearance(p) >= need - 0.05 for p in on_ring):
        return False
    d = (centre - xy) / max(float(np.hypot(*(centre - xy))), 1e-12)
    return free.segment_clear(xy, centre - d * ring, need)


def _bypass_clear(task, comp, xy, free, s, need) -> bool:
    """Object bypass: the approach, and the swerving line past the object."""
    centre = comp.centre
    radius = _radius(comp)
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


def _wall_clear(task, comp, xy, free, s, need) -> bool:
    """Wall following: close enough to the face, enough face ahead, the way along it."""
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


# task type -> whether the skill has a clear straight way (wall following otherwise)
_CLEAR_WAY: dict[str, Callable[..., bool]] = {
    "doorway_crossing": _crossing_clear,
    "gap_crossing": _crossing_clear,
    "robot_docking": _docking_clear,
    "object_inspection": _inspection_clear,
    "object_bypass": _bypass_clear,
}


def _feasible(
    task: ContextualTask,
    comp: SemanticComponent,
    xy: np.ndarray,
    yaw: float,
    free: FreeSpace,
    s: SkillSettings,
) -> bool:
    """Whether the skill has a clear straight way from ``xy`` (docs/decisions.md)."""
    check = _CLEAR_WAY.get(task.type, _wall_clear)
    return check(task, comp, xy, free, s, PATH_CLEARANCE_M)


def sample_start(
    scenario: Scenario,
    task: ContextualTask,
    components: Sequence[SemanticComponent],
    rng: np.random.Generator,
    *,
    free: FreeSpace | None = None,
    skill: SkillSettings | None = None,
) -> Pose2D:
    """A random start pose for ``task`` in ``scenario`` (docs/decisions.md, "start poses").

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
