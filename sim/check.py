"""The scene checker: whether the robot can drive a scenario, before anyone drives it
(DESIGN.md "The scene"; thesis Sec. 7.6.1.1-7.6.1.3; issue 17).

:func:`check_scene` runs each check only where the scene has what it needs:

- **start**: the footprint at A overlaps nothing;
- **route** (with a ``[dock]``): a path for the robot from A to B (the grid is
  undirected, so the same path leads back), on the occupancy grid inflated by half
  the robot's width plus a margin (:mod:`sim.occupancy`); with a table, the path
  leads to a point just outside the table's open side;
- **dock** (with ``[dock].table``): the table is higher than the robot, B lies under
  its top, the footprint at B overlaps no leg, and the straight approach along B's
  heading from outside the open side is collision-free;
- **inspection** (with ``inspection_object``): the robot, facing the object from
  within the inspection band, can sweep an arc of at least ``min_arc_deg`` about it
  without touching anything, somewhere it can reach from A;
- **passages**: every derived doorway and gap can be crossed by the footprint.

Footprint tests are exact 2-D geometry (oriented rectangles and circles);
reachability is labelled on the inflated grid with 4-connectivity, which is what
:func:`sim.occupancy.shortest_path`'s A* reaches (no cutting of blocked corners).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy import ndimage

from sim.occupancy import OccupancyGrid, build_grid, inflate
from sim.placement import placement_problems
from sim.scene import Box, Cylinder, Scenario, Table
from sim.semantics import derive_components
from sim.types import Pose2D, SemanticComponent

_EPS_M = 1e-9  # [m] touching is not overlapping


@dataclass(frozen=True, slots=True)
class CheckSettings:
    """Settings of :func:`check_scene`; change with ``dataclasses.replace``.

    ``inspection_distance_m`` and ``min_arc_deg`` are the inspection task's own
    (``tasks.primary.PrimarySettings``), repeated here since ``sim`` may not import
    ``tasks``; a test keeps them equal.
    """

    resolution_m: float = 0.05  # [m] occupancy cell size
    inflation_margin_m: float = 0.02  # [m] beyond half the robot's width
    snap_m: float = 0.1  # [m] A or B may sit this close to a free inflated cell
    inspection_distance_m: tuple[float, float] = (0.4, 1.6)  # [m] surface to robot centre
    min_arc_deg: float = 90.0  # [deg] arc about the object one visit must sweep
    arc_step_deg: float = 2.0  # [deg] angular sampling of the band
    band_step_m: float = 0.05  # [m] radial sampling of the band
    approach_extra_m: float = 0.1  # [m] the approach starts this far outside the table
    passage_sweep_m: float = 0.1  # [m] beyond half the robot's length, each side
    sweep_step_m: float = 0.025  # [m] between footprint poses of a sweep


@dataclass(frozen=True, slots=True)
class Problem:
    """One reason a scene is not drivable: the element concerned and what is wrong."""

    element: str  # a scene element's name, a component id, "start" or "dock"
    message: str

    def line(self, source: str) -> str:
        """The problem as one line naming the file and the element."""
        return f"{source or '<scenario>'}: {self.element}: {self.message}"


# ------------------------------------------------------------------- footprint tests


@dataclass(frozen=True, slots=True)
class _Obstacles:
    """Everything at robot height as arrays: boxes (walls, boxes, legs) and circles."""

    box_names: tuple[str, ...]
    box_centre: np.ndarray  # (n, 2) [m]
    box_axis: np.ndarray  # (n, 2) unit vector of the box's own x
    box_half: np.ndarray  # (n, 2) [m] half size along own x, own y
    cyl_names: tuple[str, ...]
    cyl_centre: np.ndarray  # (m, 2) [m]
    cyl_radius: np.ndarray  # (m,) [m]


def _obstacles(scenario: Scenario) -> _Obstacles:
    boxes = scenario.obstacle_boxes()
    cyls = scenario.cylinders
    return _Obstacles(
        box_names=tuple(b.name for b in boxes),
        box_centre=np.array([b.centre for b in boxes], dtype=float).reshape(-1, 2),
        box_axis=np.array([(math.cos(b.yaw), math.sin(b.yaw)) for b in boxes]).reshape(-1, 2),
        box_half=np.array([b.size for b in boxes], dtype=float).reshape(-1, 2) / 2,
        cyl_names=tuple(c.name for c in cyls),
        cyl_centre=np.array([c.centre for c in cyls], dtype=float).reshape(-1, 2),
        cyl_radius=np.array([c.radius for c in cyls], dtype=float),
    )


def _hits(obs: _Obstacles, poses: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Which obstacles a footprint overlaps, (P, n + m) bool.

    ``poses`` (P, 3) ``(x [m], y [m], yaw [rad])``; ``half`` (2,) [m] half length and
    half width of the footprint. Boxes by the separating-axis test, circles by the
    distance from the circle's centre to the rectangle.
    """
    poses = np.asarray(poses, dtype=float).reshape(-1, 3)
    u = np.column_stack((np.cos(poses[:, 2]), np.sin(poses[:, 2])))[:, None, :]  # (P, 1, 2)
    v = np.stack((-u[..., 1], u[..., 0]), axis=-1)
    big_u = obs.box_axis[None]  # (1, n, 2)
    big_v = np.stack((-big_u[..., 1], big_u[..., 0]), axis=-1)
    d = obs.box_centre[None] - poses[:, None, :2]  # (P, n, 2)
    hx, hy = half
    bx, by = obs.box_half[None, :, 0], obs.box_half[None, :, 1]
    overlap = np.ones(d.shape[:2], dtype=bool)
    for a in (u, v, big_u, big_v):
        reach = hx * np.abs(np.sum(u * a, -1)) + hy * np.abs(np.sum(v * a, -1))
        reach = reach + bx * np.abs(np.sum(big_u * a, -1)) + by * np.abs(np.sum(big_v * a, -1))
        overlap &= np.abs(np.sum(d * a, -1)) < reach - _EPS_M
    dc = obs.cyl_centre[None] - poses[:, None, :2]  # (P, m, 2)
    lx = np.clip(np.sum(dc * u, -1), -hx, hx) - np.sum(dc * u, -1)
    ly = np.clip(np.sum(dc * v, -1), -hy, hy) - np.sum(dc * v, -1)
    circle = np.hypot(lx, ly) < obs.cyl_radius[None] - _EPS_M
    return np.concatenate((overlap, circle), axis=1)


def _names_hit(obs: _Obstacles, hit_row: np.ndarray) -> str:
    names = [n for n, h in zip(obs.box_names + obs.cyl_names, hit_row, strict=True) if h]
    return ", ".join(repr(n) for n in names[:3]) + (" ..." if len(names) > 3 else "")


def _sweep(a: np.ndarray, b: np.ndarray, yaw: float, step: float) -> np.ndarray:
    """Poses (k, 3) from point ``a`` to ``b`` [m] at most ``step`` apart, heading ``yaw``."""
    n = max(1, math.ceil(float(np.hypot(*(b - a))) / step))
    t = np.linspace(0.0, 1.0, n + 1)[:, None]
    xy = a + t * (b - a)
    return np.column_stack((xy, np.full(len(xy), yaw)))


# ------------------------------------------------------------------- reachability


@dataclass(frozen=True, slots=True)
class _Reach:
    grid: OccupancyGrid  # the inflated grid
    labels: np.ndarray  # (rows, cols) int, 0 on blocked cells
    clearance_m: float  # [m] the inflation radius

    def near(self, xy: np.ndarray, snap_m: float) -> set[int]:
        """Labels of the free inflated cells within ``snap_m`` [m] of map point ``xy``."""
        res = self.grid.resolution
        k = int(math.ceil(snap_m / res))
        offsets = np.arange(-k, k + 1) * res
        pts = np.asarray(xy, dtype=float)[None] + np.stack(
            np.meshgrid(offsets, offsets), axis=-1
        ).reshape(-1, 2)
        pts = pts[np.hypot(*(pts - xy).T) <= snap_m + 1e-9]
        return self.at(pts) - {0}

    def at(self, pts: np.ndarray) -> set[int]:
        return set(self.labels_at(pts).tolist())

    def labels_at(self, pts: np.ndarray) -> np.ndarray:
        """Label of each map point (k, 2) [m], 0 outside the grid or on blocked cells."""
        rc = self.grid.world_to_cell(pts)
        rows, cols = self.labels.shape
        inside = (rc[:, 0] >= 0) & (rc[:, 0] < rows) & (rc[:, 1] >= 0) & (rc[:, 1] < cols)
        out = np.zeros(len(rc), dtype=np.int64)
        out[inside] = self.labels[rc[inside, 0], rc[inside, 1]]
        return out


def _reach(scenario: Scenario, s: CheckSettings) -> _Reach:
    clearance = scenario.robot.width / 2 + s.inflation_margin_m
    inflated = inflate(build_grid(scenario, resolution=s.resolution_m), clearance)
    labels, _ = ndimage.label(~inflated.occupied)  # 4-connected: A*'s reach
    return _Reach(inflated, labels, clearance)


def _xy(x: float, y: float) -> str:
    return f"({x:.2f}, {y:.2f})"


# ------------------------------------------------------------------------- checks


@dataclass(frozen=True, slots=True)
class _Context:
    scenario: Scenario
    settings: CheckSettings
    obstacles: _Obstacles
    reach: _Reach
    half: np.ndarray  # (2,) [m] half length, half width of the footprint
    start_labels: set[int]  # labels of the cells the robot can leave A by


def _check_start(c: _Context) -> list[Problem]:
    a = c.scenario.start
    hit = _hits(c.obstacles, np.array([[a.x, a.y, a.yaw]]), c.half)[0]
    if hit.any():
        return [
            Problem(
                "start",
                f"the robot's footprint at A {_xy(a.x, a.y)} overlaps "
                + _names_hit(c.obstacles, hit),
            )
        ]
    if not c.start_labels:
        return [
            Problem(
                "start",
                f"A {_xy(a.x, a.y)} lies within {c.reach.clearance_m:.2f} m of an obstacle "
                f"everywhere within {c.settings.snap_m:g} m, so the robot cannot leave it",
            )
        ]
    return []


def _table_corners(table: Table) -> np.ndarray:
    """The table top's corners in the map frame (4, 2) [m]."""
    hx, hy = table.size[0] / 2, table.size[1] / 2
    local = np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]])
    return Pose2D(table.centre[0], table.centre[1], table.yaw).to_map_frame(local)


def _under(table: Table, xy: np.ndarray) -> bool:
    """Whether map point ``xy`` [m] lies under the table's top."""
    local = Pose2D(table.centre[0], table.centre[1], table.yaw).to_robot_frame(xy[None])[0]
    return bool(np.all(np.abs(local) <= np.array(table.size) / 2 + _EPS_M))


def _approach_point(table: Table, pose: np.ndarray, half: np.ndarray, extra: float) -> np.ndarray:
    """Where the straight approach into dock ``pose`` (3,) starts [m]: back along its
    heading until the whole footprint is ``extra`` outside the table's top."""
    heading = np.array([math.cos(pose[2]), math.sin(pose[2])])
    behind = float(np.min((_table_corners(table) - pose[:2]) @ heading))  # <= 0 under it
    return pose[:2] + (min(behind, 0.0) - half[0] - extra) * heading


def _check_route(c: _Context) -> list[Problem]:
    """A path from A to B (or to the point outside the table's open side)."""
    dock = c.scenario.dock
    if dock is None or not c.start_labels:
        return []
    pose = dock.pose.as_array()
    goal, what = pose[:2], f"B {_xy(*pose[:2])}"
    if dock.table:
        table = c.scenario.element(dock.table)
        goal = _approach_point(table, pose, c.half, c.settings.approach_extra_m)
        what = f"the approach point {_xy(*goal)} outside table {dock.table!r}'s open side"
    if c.start_labels & c.reach.near(goal, c.settings.snap_m):
        return []
    return [
        Problem(
            "dock",
            f"no path for the robot (clearance {c.reach.clearance_m:.2f} m) from A "
            f"{_xy(c.scenario.start.x, c.scenario.start.y)} to {what}",
        )
    ]


def _check_dock(c: _Context) -> list[Problem]:
    """The robot fits under the dock's table, and drives straight in from outside it."""
    dock, robot = c.scenario.dock, c.scenario.robot
    if dock is None:
        return []
    pose = dock.pose.as_array()
    if not dock.table:  # a goal pose without a table: the footprint must fit there
        hit = _hits(c.obstacles, pose[None], c.half)[0]
        if hit.any():
            msg = f"the robot's footprint at B {_xy(*pose[:2])} overlaps "
            return [Problem("dock", msg + _names_hit(c.obstacles, hit))]
        return []
    table = c.scenario.element(dock.table)
    if table.height <= robot.height:
        return [
            Problem(
                table.name,
                f"the underside of its top ({table.height:g} m) is not above the robot "
                f"({robot.height:g} m high), so the robot cannot dock under it",
            )
        ]
    if not _under(table, pose[:2]):
        return [Problem("dock", f"B {_xy(*pose[:2])} does not lie under table {table.name!r}")]
    start = _approach_point(table, pose, c.half, c.settings.approach_extra_m)
    poses = _sweep(start, pose[:2], float(pose[2]), c.settings.sweep_step_m)
    hit = _hits(c.obstacles, poses, c.half)
    if hit.any():
        first = int(np.argmax(hit.any(axis=1)))
        where = "at B" if first == len(poses) - 1 else f"at {_xy(*poses[first, :2])}"
        return [
            Problem(
                "dock",
                f"the straight approach into B along its heading "
                f"({math.degrees(pose[2]):.0f} deg) from outside table {table.name!r} "
                f"hits {_names_hit(c.obstacles, hit[first])} {where}",
            )
        ]
    return []


def _band_poses(obj: Box | Cylinder, s: CheckSettings) -> tuple[np.ndarray, np.ndarray]:
    """Robot poses facing the object over a polar grid about its centre.

    Returns poses (n_phi, n_rho, 3) and whether each lies in the inspection band
    (n_phi, n_rho) bool: its centre's distance to the object's surface within
    ``inspection_distance_m``.
    """
    near, far = s.inspection_distance_m
    centre = np.asarray(obj.centre, dtype=float)
    if isinstance(obj, Cylinder):
        rho = obj.radius + np.arange(near, far + 1e-9, s.band_step_m)
    else:
        half = np.array(obj.size) / 2
        rho = np.arange(half.min() + near, float(np.hypot(*half)) + far + 1e-9, s.band_step_m)
    phi = np.radians(np.arange(0.0, 360.0, s.arc_step_deg))
    u = np.column_stack((np.cos(phi), np.sin(phi)))
    xy = centre + u[:, None, :] * rho[None, :, None]  # (n_phi, n_rho, 2)
    if isinstance(obj, Cylinder):
        surface = np.broadcast_to(rho - obj.radius, xy.shape[:2])
    else:  # distance to the box: the point in the box's frame, outside the half extents
        local = Pose2D(*obj.centre, obj.yaw).to_robot_frame(xy.reshape(-1, 2))
        surface = np.hypot(*np.maximum(np.abs(local) - half, 0.0).T).reshape(xy.shape[:2])
    yaw = np.broadcast_to((phi + math.pi)[:, None], xy.shape[:2])
    in_band = (surface >= near - 1e-9) & (surface <= far + 1e-9)
    return np.concatenate((xy, yaw[..., None]), axis=-1), in_band


def inspection_arc_deg(scenario: Scenario, *, settings: CheckSettings | None = None) -> float:
    """The largest arc [deg] the robot can sweep about the inspection object.

    Facing the object's centre, its own centre within the inspection band, its
    footprint touching nothing, and connected (over neighbouring angles and band
    distances) to poses it can reach from A; 360 for a full circle, 0 without an
    inspection object.
    """
    s = CheckSettings() if settings is None else settings
    return _arc_deg(_context(scenario, s))


def _arc_deg(c: _Context) -> float:
    name = c.scenario.inspection_object
    if not name:
        return 0.0
    poses, ok = _band_poses(c.scenario.element(name), c.settings)
    shape = ok.shape
    flat = poses.reshape(-1, 3)
    ok = ok.ravel() & ~_hits(c.obstacles, flat, c.half).any(axis=1)
    if c.start_labels:
        reachable = np.isin(c.reach.labels_at(flat[:, :2]), list(c.start_labels))
        ok &= reachable
    ok = ok.reshape(shape)
    if not ok.any():
        return 0.0
    labels, n = ndimage.label(np.concatenate((ok, ok)))  # twice round: arcs across 0 deg
    n_phi = shape[0]
    best = 0
    for k in range(1, n + 1):
        rows = np.nonzero((labels == k).any(axis=1))[0]
        best = max(best, len(np.unique(rows % n_phi)))
    return min(best, n_phi) * c.settings.arc_step_deg if best < n_phi else 360.0


def _check_inspection(c: _Context) -> list[Problem]:
    name = c.scenario.inspection_object
    if not name:
        return []
    arc = _arc_deg(c)
    s = c.settings
    if arc + 1e-9 >= s.min_arc_deg:
        return []
    near, far = s.inspection_distance_m
    return [
        Problem(
            name,
            f"the robot, facing it from {near:g}-{far:g} m off its surface, can sweep only "
            f"{arc:.0f} deg about it without touching anything (needs {s.min_arc_deg:g} deg)",
        )
    ]


def _passable(c: _Context, comp: SemanticComponent) -> bool:
    """Whether the footprint, heading along the crossing normal, can drive into the
    opening from at least one side (at some sideways offset within it).

    Through is not required: Alg. 5 also finds dead-end pockets (a shelf a little off
    a wall, its end near a corner), which the robot can enter but not leave on the far
    side; whether the route's own passages lead through is the route check's question.
    """
    normal = np.asarray(comp.normal, dtype=float)
    along = np.array([-normal[1], normal[0]])
    s = c.settings
    slack = max((comp.width - 2 * c.half[1]) / 2, 0.0)
    offsets = np.arange(-slack, slack + 1e-9, s.sweep_step_m)
    offsets = offsets[np.argsort(np.abs(offsets), kind="stable")] if len(offsets) else np.zeros(1)
    reach = c.half[0] + s.passage_sweep_m
    yaw = math.atan2(normal[1], normal[0])
    for off in offsets:
        centre = np.asarray(comp.centre) + off * along
        for side in (-1.0, 1.0):  # from one side into the opening
            poses = _sweep(centre + side * reach * normal, centre, yaw, s.sweep_step_m)
            if not _hits(c.obstacles, poses, c.half).any():
                return True
    return False


def _check_passages(c: _Context, components: tuple[SemanticComponent, ...]) -> list[Problem]:
    """Doorways and gaps the footprint cannot enter. A passage whose opening has free
    inflated cells none of which the robot can reach from A is skipped: nobody drives
    there (a pocket walled in by clutter), and a route through it fails the route check."""
    out = []
    for comp in components:
        if comp.kind not in ("doorway", "gap"):
            continue
        labels = c.reach.near(np.asarray(comp.centre), c.settings.snap_m)
        if c.start_labels and labels and not labels & c.start_labels:
            continue
        if not _passable(c, comp):
            out.append(
                Problem(
                    comp.id,
                    f"{comp.kind} between {' and '.join(repr(n) for n in comp.source) or '?'} "
                    f"at {_xy(*comp.centre)}, {comp.width:.2f} m clear, is not passable for "
                    f"the robot's {2 * c.half[1]:g} m x {2 * c.half[0]:g} m footprint",
                )
            )
    return out


def _context(scenario: Scenario, s: CheckSettings) -> _Context:
    reach = _reach(scenario, s)
    start = np.array([scenario.start.x, scenario.start.y])
    return _Context(
        scenario=scenario,
        settings=s,
        obstacles=_obstacles(scenario),
        reach=reach,
        half=np.array([scenario.robot.length, scenario.robot.width]) / 2,
        start_labels=reach.near(start, s.snap_m),
    )


def check_scene(
    scenario: Scenario,
    *,
    settings: CheckSettings | None = None,
    components: tuple[SemanticComponent, ...] | None = None,
) -> list[Problem]:
    """Every reason the robot could not drive ``scenario``; ``[]`` when it can.

    Parameters
    ----------
    scenario : Scenario
        The validated scene; checks needing a dock, a table or an inspection object
        are skipped when it has none.
    settings : CheckSettings, optional
        Grid resolution, margins and the inspection band and arc.
    components : tuple of SemanticComponent, optional
        ``derive_components(scenario)``, when the caller has them already.

    Returns
    -------
    list of Problem
        In order: impossible placements (:func:`sim.placement.placement_problems`:
        a pose inside an obstacle, a question region of zero area or off the map),
        start, route, dock, inspection, passages. ``Problem.line(source)``
        gives the one-line message naming the file and the element.
    """
    s = CheckSettings() if settings is None else settings
    c = _context(scenario, s)
    comps = derive_components(scenario) if components is None else components
    placed = [Problem(field, message) for field, message in placement_problems(scenario)]
    return (
        placed
        + _check_start(c)
        + _check_route(c)
        + _check_dock(c)
        + _check_inspection(c)
        + _check_passages(c, comps)
    )
