"""Scenarios: a room described as TOML, validated into frozen dataclasses
(:mod:`sim.scene`; thesis Sec. 7.6.1.1).

A scenario file (``sim/scenarios/*.toml``, format in ``sim/scenarios/FORMAT.md``)
holds the static geometry, the start pose A, the dock pose B under a table, the object
to inspect, the polygon that starts secondary-task questions, the robot's footprint and
sensor mounts, and optional semantic settings and overrides. Every field is checked
on load; a bad one raises ``ValueError`` naming the file, the field
(``walls[3].thickness``) and what is allowed.
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np

from sim.fields import FieldReader
from sim.limits import MAX_CELLS, MAX_EXTENT_M, check_name, loads_toml
from sim.placement import placement_problems
from sim.scene import (
    Box,
    CameraSpec,
    ComponentOverride,
    Cylinder,
    Dock,
    LaserSpec,
    RobotSpec,
    Scenario,
    SemanticSettings,
    Table,
)
from sim.types import COMPONENT_KINDS, Pose2D

__all__ = [
    "CAMERA_DEFAULTS",
    "TAIL_CAMERA_DEFAULTS",
    "DEFAULT_LASERS",
    "LASER_DEFAULTS",
    "ROBOT_DEFAULTS",
    "SCENARIO_DIR",
    "SEMANTIC_SOURCES",
    "Box",
    "CameraSpec",
    "ComponentOverride",
    "Cylinder",
    "Dock",
    "LaserSpec",
    "RobotSpec",
    "Scenario",
    "SemanticSettings",
    "Table",
    "available_scenarios",
    "load_scenario",
    "parse_scenario",
    "point_in_region",
]

SCENARIO_DIR = Path(__file__).resolve().parent / "scenarios"
MAX_RAYS = 10_000  # beams of one laser scan (fov / resolution)
MAX_PIXELS = 4096  # a camera image's width or height [px]
GRID_RESOLUTION_M = 0.05  # [m] the cell size the study's occupancy grids use
SEMANTIC_SOURCES = ("geometry", "map")  # [semantics] source: the shapes, or a map image


# ------------------------------------------------------------------------ defaults

DEFAULT_LASERS = (
    {"name": "front", "position": [0.3, 0.0], "yaw_deg": 0.0},
    {"name": "rear", "position": [-0.3, 0.0], "yaw_deg": 180.0},
)
LASER_DEFAULTS = {
    "fov_deg": 270.0,
    "resolution_deg": 1.0,
    "max_range": 8.0,
    "min_range": 0.05,
    "height": 0.2,
    "sigma": 0.01,
}
ROBOT_DEFAULTS = {
    "length": 0.6,
    "width": 0.5,
    "height": 0.4,
    "mass": 40.0,
    "max_speed": 1.0,
    "max_yaw_rate": 1.2,
    "max_accel": 2.0,
    "max_yaw_accel": 4.0,
    "protective_margin": 0.05,
    "pose_sigma": [0.005, 0.002],
    "imu_sigma": [0.01, 0.05],
}
CAMERA_DEFAULTS = {
    "position": [0.25, 0.0],
    "height": 0.9,
    "pitch_deg": -15.0,
    "fov_deg": 60.0,
    "width": 320,
    "height_px": 240,
    "far": 15.0,
}
# Sec. 7.5, Fig. 7.42: "the tail camera image displaying the back view of the robot"
TAIL_CAMERA_DEFAULTS = {**CAMERA_DEFAULTS, "position": [-0.25, 0.0], "yaw_deg": 180.0}


# -------------------------------------------------------------------------- loading


def _pose(r: FieldReader) -> Pose2D:
    return Pose2D(r.number("x"), r.number("y"), math.radians(r.number("yaw_deg", 0.0)))


def _wall(r: FieldReader) -> Box:
    a = np.array(r.vector("from", 2))
    b = np.array(r.vector("to", 2))
    thickness = r.number("thickness", 0.1, positive=True)
    length = float(np.hypot(*(b - a)))
    if length <= 0:
        raise r.fail("to", "must differ from 'from'")
    centre = (a + b) / 2
    box = Box(
        name=r.string("name"),
        kind="wall",
        centre=(float(centre[0]), float(centre[1])),
        size=(length, thickness),
        yaw=math.atan2(b[1] - a[1], b[0] - a[0]),
        height=r.number("height", 1.2, positive=True),
        colour=r.vector("colour", 3, [0.82, 0.82, 0.78], unit=True),
        group=r.string("group", ""),
    )
    r.finish()
    return box


def _box(r: FieldReader) -> Box:
    box = Box(
        name=r.string("name"),
        kind="obstacle",
        centre=r.vector("centre", 2),
        size=r.vector("size", 2, positive=True),
        yaw=math.radians(r.number("yaw_deg", 0.0)),
        height=r.number("height", 0.8, positive=True),
        colour=r.vector("colour", 3, [0.55, 0.42, 0.28], unit=True),
        group=r.string("group", ""),
    )
    r.finish()
    return box


def _cylinder(r: FieldReader) -> Cylinder:
    c = Cylinder(
        name=r.string("name"),
        centre=r.vector("centre", 2),
        radius=r.number("radius", positive=True),
        height=r.number("height", 1.0, positive=True),
        colour=r.vector("colour", 3, [0.3, 0.3, 0.35], unit=True),
    )
    r.finish()
    return c


def _table(r: FieldReader, robot: RobotSpec) -> Table:
    t = Table(
        name=r.string("name"),
        centre=r.vector("centre", 2),
        size=r.vector("size", 2, positive=True),
        yaw=math.radians(r.number("yaw_deg", 0.0)),
        height=r.number("height", 0.75, positive=True),
        leg=r.number("leg", 0.06, positive=True),
        top_thickness=r.number("top_thickness", 0.04, positive=True),
        colour=r.vector("colour", 3, [0.45, 0.3, 0.18], unit=True),
    )
    if t.height <= robot.height:
        raise r.fail("height", f"must exceed the robot's height {robot.height} m to dock under it")
    if 2 * t.leg >= min(t.size):
        raise r.fail("leg", "must be less than half the table's smaller side")
    r.finish()
    return t


def _laser(r: FieldReader, defaults: dict[str, Any]) -> LaserSpec:
    d = {**LASER_DEFAULTS, **defaults}
    spec = LaserSpec(
        name=r.string("name", d.get("name")),
        position=r.vector("position", 2, d.get("position")),
        yaw=math.radians(r.number("yaw_deg", d.get("yaw_deg", 0.0))),
        fov=math.radians(r.number("fov_deg", d["fov_deg"], positive=True)),
        resolution=math.radians(r.number("resolution_deg", d["resolution_deg"], positive=True)),
        max_range=r.number("max_range", d["max_range"], positive=True),
        min_range=r.number("min_range", d["min_range"], non_negative=True),
        height=r.number("height", d["height"], positive=True),
        sigma=r.number("sigma", d["sigma"], non_negative=True),
    )
    if spec.fov > 2 * math.pi:
        raise r.fail("fov_deg", "must be at most 360")
    if spec.fov / spec.resolution > MAX_RAYS:
        raise r.fail(
            "resolution_deg", f"gives more than {MAX_RAYS} beams per scan (fov / resolution)"
        )
    if spec.min_range >= spec.max_range:
        raise r.fail("min_range", "must be less than max_range")
    r.finish()
    return spec


def _camera(cr: FieldReader, cd: dict) -> CameraSpec:
    camera = CameraSpec(
        position=cr.vector("position", 2, cd["position"]),
        height=cr.number("height", cd["height"], positive=True),
        pitch=math.radians(cr.number("pitch_deg", cd["pitch_deg"])),
        fov=math.radians(cr.number("fov_deg", cd["fov_deg"], positive=True)),
        width=cr.integer("width", cd["width"], minimum=16, maximum=MAX_PIXELS),
        height_px=cr.integer("height_px", cd["height_px"], minimum=16, maximum=MAX_PIXELS),
        far=cr.number("far", cd["far"], positive=True),
        yaw=math.radians(cr.number("yaw_deg", cd.get("yaw_deg", 0.0))),
    )
    cr.finish()
    return camera


def _robot(r: FieldReader) -> RobotSpec:
    d = ROBOT_DEFAULTS
    lasers = r.tables("lasers")
    if lasers:
        laser_specs = tuple(_laser(lr, {}) for lr in lasers)
    else:
        laser_specs = tuple(_laser(FieldReader(r.path, {}, ""), ld) for ld in DEFAULT_LASERS)
    names = [s.name for s in laser_specs]
    if len(set(names)) != len(names):
        raise r.fail("lasers", f"names must be unique, got {names}")
    camera = _camera(r.sub("camera"), CAMERA_DEFAULTS)
    tail_camera = _camera(r.sub("tail_camera"), TAIL_CAMERA_DEFAULTS)
    spec = RobotSpec(
        length=r.number("length", d["length"], positive=True),
        width=r.number("width", d["width"], positive=True),
        height=r.number("height", d["height"], positive=True),
        mass=r.number("mass", d["mass"], positive=True),
        max_speed=r.number("max_speed", d["max_speed"], positive=True),
        max_yaw_rate=r.number("max_yaw_rate", d["max_yaw_rate"], positive=True),
        max_accel=r.number("max_accel", d["max_accel"], positive=True),
        max_yaw_accel=r.number("max_yaw_accel", d["max_yaw_accel"], positive=True),
        protective_margin=r.number("protective_margin", d["protective_margin"], non_negative=True),
        pose_sigma=r.vector("pose_sigma", 2, d["pose_sigma"]),
        imu_sigma=r.vector("imu_sigma", 2, d["imu_sigma"]),
        lasers=laser_specs,
        camera=camera,
        tail_camera=tail_camera,
    )
    if min(spec.pose_sigma) < 0 or min(spec.imu_sigma) < 0:
        raise r.fail("pose_sigma", "noise levels must be zero or positive")
    r.finish()
    return spec


def _override(r: FieldReader) -> ComponentOverride:
    kind = r.string("kind", allowed=COMPONENT_KINDS)
    ends = (
        r.points("ends", minimum=2, default=[]) if kind in ("doorway", "gap") else np.empty((0, 2))
    )
    if kind in ("doorway", "gap") and len(ends) != 2:
        raise r.fail("ends", "a doorway or gap needs exactly two end points")
    pts = (
        r.points("points", minimum=1, default=[])
        if kind in ("object", "wall")
        else np.empty((0, 2))
    )
    if kind in ("object", "wall") and len(pts) == 0:
        raise r.fail("points", "an object or wall needs at least one surface point")
    if kind in ("object", "wall"):
        centre = r.vector("centre", 2, [float(v) for v in pts.mean(axis=0)])
    else:
        centre = r.vector("centre", 2)
    o = ComponentOverride(
        id=r.string("id"),
        kind=kind,
        centre=centre,
        ends=tuple(tuple(p) for p in ends.tolist()),
        points=tuple(tuple(p) for p in pts.tolist()),
    )
    r.finish()
    return o


def _semantics(r: FieldReader, base: Path | None) -> SemanticSettings:
    width = r.vector("passage_width", 2, [0.6, 1.1], positive=True)
    if width[0] >= width[1]:
        raise r.fail("passage_width", f"must be [min, max] with min < max, got {list(width)}")
    removes = []
    for rr in r.tables("remove"):
        removes.append(rr.string("id"))
        rr.finish()
    source = r.string("source", "geometry", allowed=SEMANTIC_SOURCES)
    map_file = r.string("map", "")
    if map_file and source != "map":
        raise r.fail("map", 'names the map of source = "map"; set source = "map" or drop it')
    s = SemanticSettings(
        passage_width=width,
        surface_spacing=r.number("surface_spacing", 0.1, positive=True),
        components=tuple(_override(cr) for cr in r.tables("components")),
        remove=tuple(removes),
        source=source,
        map_file=map_file,
        map_grid=_semantic_map(r, map_file, base),
    )
    r.finish()
    return s


def _semantic_map(r: FieldReader, map_file: str, base: Path | None) -> Any:
    """The occupancy grid of ``[semantics] map`` (a ROS map_server YAML, relative to the
    scenario file's folder), or None without one."""
    if not map_file:
        return None
    from sim.map_files import load_ros_map  # sim.map_files imports this module

    path = Path(map_file)
    if not path.is_absolute() and base is not None:
        path = base / path
    try:
        return load_ros_map(path)
    except FileNotFoundError:
        raise r.fail("map", f"no such map file {str(path)!r} (a ROS map_server YAML)") from None
    except ValueError as error:
        raise r.fail("map", f"cannot use it: {error}") from None


def _inside(polygon: np.ndarray, x: float, y: float) -> bool:
    """Even-odd rule point-in-polygon."""
    inside = False
    corners = polygon.tolist()  # Python floats: the same arithmetic, without numpy scalars
    n = len(corners)
    for i in range(n):
        (x1, y1), (x2, y2) = corners[i], corners[(i + 1) % n]
        if (y1 > y) != (y2 > y) and x < x1 + (y - y1) * (x2 - x1) / (y2 - y1):
            inside = not inside
    return inside


def _elements(
    r: FieldReader,
) -> tuple[RobotSpec, tuple[Box, ...], tuple[Box, ...], tuple[Cylinder, ...], tuple[Table, ...]]:
    """The robot, walls, boxes, cylinders and tables; at least one element, unique names."""
    robot = _robot(r.sub("robot"))
    walls = tuple(_wall(w) for w in r.tables("walls"))
    boxes = tuple(_box(b) for b in r.tables("boxes"))
    cylinders = tuple(_cylinder(c) for c in r.tables("cylinders"))
    tables = tuple(_table(t, robot) for t in r.tables("tables"))
    if not (walls or boxes or cylinders or tables):
        raise r.fail("walls", "a scenario needs at least one wall, box, cylinder or table")

    names = [e.name for e in (*walls, *boxes, *cylinders, *tables)]
    seen: set[str] = set()
    for n in names:
        if n in seen:
            raise r.fail("name", f"element names must be unique; {n!r} appears twice")
        seen.add(n)
    return robot, walls, boxes, cylinders, tables


def _bounds(
    r: FieldReader,
    walls: tuple[Box, ...],
    boxes: tuple[Box, ...],
    cylinders: tuple[Cylinder, ...],
    tables: tuple[Table, ...],
) -> tuple[np.ndarray, np.ndarray]:
    """The map extent (lo (2,), hi (2,)) [m]: ``bounds``, or the geometry with a margin."""
    bounds_pts = r.points("bounds", minimum=2, default=[])
    if len(bounds_pts) == 0:  # derive from the geometry with a margin
        corners = [
            b.corners() for b in (*walls, *boxes, *(leg for t in tables for leg in t.leg_boxes()))
        ]
        corners += [
            np.array(
                [
                    [c.centre[0] - c.radius, c.centre[1] - c.radius],
                    [c.centre[0] + c.radius, c.centre[1] + c.radius],
                ]
            )
            for c in cylinders
        ]
        allc = np.vstack(corners)
        lo, hi = allc.min(axis=0) - 0.5, allc.max(axis=0) + 0.5
        field = "walls"
    else:
        if len(bounds_pts) != 2 or np.any(bounds_pts[1] <= bounds_pts[0]):
            raise r.fail("bounds", "must be [[x_min, y_min], [x_max, y_max]] with max > min")
        lo, hi = bounds_pts[0], bounds_pts[1]
        field = "bounds"
    extent = hi - lo
    cells = math.prod(math.ceil(e / GRID_RESOLUTION_M) for e in extent)
    if np.any(extent > MAX_EXTENT_M) or cells > MAX_CELLS:
        raise r.fail(
            field,
            f"the scene spans {extent[0]:g} m x {extent[1]:g} m; at most "
            f"{MAX_EXTENT_M:g} m x {MAX_EXTENT_M:g} m is allowed",
        )
    return lo, hi


def _dock(r: FieldReader, source: str, tables: tuple[Table, ...]) -> Dock | None:
    dock_table = r.table("dock")
    if dock_table is None:
        return None
    dr = FieldReader(source, dock_table, "dock.")
    table_names = [t.name for t in tables]
    dock = Dock(
        pose=_pose(dr),
        table=dr.string("table", table_names[0] if table_names else ""),
        tolerance_m=dr.number("tolerance_m", 0.15, positive=True),
        tolerance_rad=math.radians(dr.number("tolerance_deg", 15.0, positive=True)),
    )
    if dock.table and dock.table not in table_names:
        raise dr.fail(
            "table",
            f"must name a table of this scenario ({', '.join(table_names) or 'none'}), "
            f"got {dock.table!r}",
        )
    dr.finish()
    return dock


def parse_scenario(data: dict[str, Any], source: str = "<scenario>") -> Scenario:
    """Validate a scenario read from TOML into a :class:`Scenario`.

    Raises ``ValueError`` naming ``source`` and the offending field.

    The file format is described in ``sim/scenarios/FORMAT.md``.
    """
    r = FieldReader(source, data)
    name = check_name(r.string("name"), f"{source}: field 'name'")
    description = r.string("description", "")
    robot, walls, boxes, cylinders, tables = _elements(r)
    lo, hi = _bounds(r, walls, boxes, cylinders, tables)
    bounds = ((float(lo[0]), float(lo[1])), (float(hi[0]), float(hi[1])))

    start_r = r.sub("start")
    start = _pose(start_r)
    start_r.finish()
    dock = _dock(r, source, tables)

    inspection = r.string("inspection_object", "")
    inspectable = [e.name for e in (*boxes, *cylinders)]
    if inspection and inspection not in inspectable:
        raise r.fail(
            "inspection_object",
            f"must name a box or cylinder ({', '.join(inspectable)}), got {inspection!r}",
        )

    qr = r.sub("question_region")
    region = qr.points("polygon", minimum=3, default=[]) if qr.data else np.empty((0, 2))
    qr.finish()

    base = Path(source).parent if source and not source.startswith("<") else None
    semantics = _semantics(r.sub("semantics"), base)
    r.finish()

    for label, pose in (("start", start), ("dock", dock.pose if dock else None)):
        if pose is not None and not (lo[0] <= pose.x <= hi[0] and lo[1] <= pose.y <= hi[1]):
            raise ValueError(
                f"{source}: field '{label}': pose ({pose.x}, {pose.y}) lies outside "
                f"the bounds {list(map(list, bounds))}"
            )
    scenario = Scenario(
        name=name,
        description=description,
        source=source,
        bounds=bounds,
        start=start,
        dock=dock,
        walls=walls,
        boxes=boxes,
        cylinders=cylinders,
        tables=tables,
        inspection_object=inspection,
        question_region=region,
        robot=robot,
        semantics=semantics,
    )
    for field, message in placement_problems(scenario):
        raise ValueError(f"{source}: field '{field}': {message}")
    return scenario


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load a shipped scenario by name (``"cluttered_room"``) or any TOML file by path.

    Raises ``ValueError`` (naming file and field) on bad content and
    ``FileNotFoundError`` when neither a shipped scenario nor a file matches.
    """
    path = Path(name_or_path)
    if not path.suffix and not path.exists():
        candidate = SCENARIO_DIR / f"{name_or_path}.toml"
        if not candidate.exists():
            raise ValueError(
                f"{name_or_path}: not a scenario file and not a shipped scenario; "
                f"shipped: {', '.join(available_scenarios())}"
            )
        path = candidate
    if not path.is_file():
        raise FileNotFoundError(2, "No such file", str(path))
    try:
        data = loads_toml(path.read_text(encoding="utf-8"), str(path))
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a UTF-8 text file") from None
    return parse_scenario(data, str(path))


def available_scenarios() -> list[str]:
    """Names of the scenarios shipped in ``sim/scenarios``, sorted."""
    return sorted(p.stem for p in SCENARIO_DIR.glob("*.toml"))


def point_in_region(scenario: Scenario, x: float, y: float) -> bool:
    """Whether map point (x, y) lies in the scenario's question region."""
    return len(scenario.question_region) >= 3 and _inside(scenario.question_region, x, y)
