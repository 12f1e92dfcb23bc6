"""The shipped scenes: they load, are closed, and the study scene has the thesis's layout.

The study scene (``cluttered_room``, thesis Fig. 7.48, Sec. 7.6.1.1-7.6.1.2) must give
one and only one way from A to B, through narrow doorways and gaps, a corridor and
past the red cylinder. Widths are measured on the exact geometry; routes are planned
on the occupancy grid with the robot as a disc of half its width plus 2 cm.
"""

from __future__ import annotations

import math
import tomllib

import numpy as np
import pytest

from sim.occupancy import OccupancyGrid, build_grid, inflate, shortest_path
from sim.scenario import (
    SCENARIO_DIR,
    Box,
    Cylinder,
    Scenario,
    available_scenarios,
    load_scenario,
    parse_scenario,
    point_in_region,
)
from sim.types import Pose2D

SHIPPED = available_scenarios()
DEMOS = [
    "demo_doorway_crossing",
    "demo_object_inspection",
    "demo_wall_following",
    "demo_object_bypass",
    "demo_docking",
]


# ------------------------------------------------------------------ geometry


def element_distances(scenario: Scenario, points: np.ndarray) -> tuple[np.ndarray, list[str]]:
    """Exact distance [m] of points (k, 2) to every obstacle: (k, n) and the n names.

    Table legs are named ``<table>.leg<i>``."""
    boxes = scenario.obstacle_boxes()
    names = [b.name for b in boxes] + [c.name for c in scenario.cylinders]
    columns = []
    if boxes:
        centre = np.array([b.centre for b in boxes])
        cos, sin = np.cos([b.yaw for b in boxes]), np.sin([b.yaw for b in boxes])
        half = np.array([b.size for b in boxes]) / 2
        dx = points[:, None, 0] - centre[None, :, 0]
        dy = points[:, None, 1] - centre[None, :, 1]
        gx = np.maximum(np.abs(cos * dx + sin * dy) - half[:, 0], 0.0)
        gy = np.maximum(np.abs(-sin * dx + cos * dy) - half[:, 1], 0.0)
        columns.append(np.hypot(gx, gy))
    if scenario.cylinders:
        centre = np.array([c.centre for c in scenario.cylinders])
        radius = np.array([c.radius for c in scenario.cylinders])
        gap = np.hypot(points[:, None, 0] - centre[:, 0], points[:, None, 1] - centre[:, 1])
        columns.append(np.maximum(gap - radius, 0.0))
    return np.hstack(columns), names


def clear_width(scenario: Scenario, point: np.ndarray, direction: np.ndarray) -> tuple:
    """Free width [m] through ``point`` along ±``direction`` and the elements at either end."""
    steps = np.arange(0.0, 3.0, 0.005)
    ends, hits = [], []
    for sign in (1.0, -1.0):
        ray = point + sign * steps[:, None] * direction
        d, names = element_distances(scenario, ray)
        blocked = np.flatnonzero(d.min(axis=1) <= 0.0)
        k = blocked[0] if len(blocked) else len(steps) - 1
        ends.append(steps[k])
        hits.append(names[int(np.argmin(d[k]))])
    return ends[0] + ends[1], hits


def footprint_points(scenario: Scenario, pose: Pose2D) -> np.ndarray:
    """Points filling the robot's footprint at ``pose`` (k, 2) [m], map frame."""
    hx, hy = scenario.robot.length / 2, scenario.robot.width / 2
    gx, gy = np.meshgrid(np.linspace(-hx, hx, 31), np.linspace(-hy, hy, 26))
    return pose.to_map_frame(np.column_stack((gx.ravel(), gy.ravel())))


def footprint_clearance(scenario: Scenario, pose: Pose2D) -> float:
    d, _ = element_distances(scenario, footprint_points(scenario, pose))
    return float(d.min())


def robot_clearance(scenario: Scenario) -> float:
    return scenario.robot.width / 2 + 0.02


def path_length(path: np.ndarray) -> float:
    return float(np.linalg.norm(np.diff(path, axis=0), axis=1).sum())


def reachable(grid: OccupancyGrid, start_xy) -> np.ndarray:
    """4-connected flood fill of the free cells from the cell of ``start_xy`` (rows, cols) bool."""
    free = ~grid.occupied
    seen = np.zeros_like(free)
    r, c = grid.world_to_cell(np.asarray(start_xy))[0]
    seen[r, c] = free[r, c]
    while True:
        grown = seen.copy()
        grown[1:] |= seen[:-1]
        grown[:-1] |= seen[1:]
        grown[:, 1:] |= seen[:, :-1]
        grown[:, :-1] |= seen[:, 1:]
        grown &= free
        if np.array_equal(grown, seen):
            return seen
        seen = grown


def block_disc(grid: OccupancyGrid, centre: np.ndarray, radius: float) -> OccupancyGrid:
    rows, cols = grid.shape
    rc = np.stack(np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij"), -1).reshape(-1, 2)
    near = np.hypot(*(grid.cell_to_world(rc) - centre).T) <= radius
    return OccupancyGrid(grid.occupied | near.reshape(rows, cols), grid.origin, grid.resolution)


def free_ring(scenario: Scenario, name: str, width: float) -> bool:
    """Whether nothing but ``name`` lies within ``width`` [m] of its outline (a circle
    around a cylinder, the circumscribed circle around a box)."""
    element = scenario.element(name)
    if isinstance(element, Cylinder):
        radius = element.radius
    else:
        radius = math.hypot(*element.size) / 2
    rr, aa = np.meshgrid(np.linspace(radius, radius + width, 31), np.linspace(0, 2 * np.pi, 180))
    pts = np.asarray(element.centre) + np.column_stack(
        (rr.ravel() * np.cos(aa.ravel()), rr.ravel() * np.sin(aa.ravel()))
    )
    d, names = element_distances(scenario, pts)
    others = [i for i, n in enumerate(names) if n != name]
    return bool(d[:, others].min() > 0.0)


# ----------------------------------------------------------- every shipped scene


def test_the_shipped_scenes_are_there():
    assert {"cluttered_room", *DEMOS} <= set(SHIPPED)


@pytest.mark.parametrize("name", SHIPPED)
def test_shipped_scene_loads_closed_with_a_clear_start(name):
    scenario = load_scenario(name)
    assert scenario.name == name and scenario.description
    assert scenario.source == str(SCENARIO_DIR / f"{name}.toml")
    grid = build_grid(scenario)
    # closed: the free space around the start never reaches the edge of the map
    inside = reachable(grid, (scenario.start.x, scenario.start.y))
    assert inside.sum() > 100
    assert not (inside[0].any() or inside[-1].any() or inside[:, 0].any() or inside[:, -1].any())
    # the robot stands clear at A, with its protective field
    assert footprint_clearance(scenario, scenario.start) >= scenario.robot.protective_margin
    # every element lies inside the map
    (x0, y0), (x1, y1) = scenario.bounds
    for box in scenario.obstacle_boxes():
        c = box.corners()
        assert c[:, 0].min() >= x0 and c[:, 0].max() <= x1
        assert c[:, 1].min() >= y0 and c[:, 1].max() <= y1


@pytest.mark.parametrize(
    "name", [n for n in SHIPPED if (d := load_scenario(n).dock) is not None and d.table]
)
def test_dock_is_under_its_table_and_reachable(name):
    scenario = load_scenario(name)
    dock = scenario.dock
    table = scenario.element(dock.table)
    assert scenario.robot.height < table.height
    # the whole footprint is under the table top, clear of the legs
    top = Box("top", "obstacle", table.centre, table.size, table.yaw, 0.0, (0, 0, 0))
    local = Pose2D(*top.centre, top.yaw).to_robot_frame(footprint_points(scenario, dock.pose))
    assert np.all(np.abs(local) <= np.array(top.size) / 2)
    assert footprint_clearance(scenario, dock.pose) >= scenario.robot.protective_margin
    # facing into the table: it drives in straight, backing out 1.2 m is clear
    heading = np.array([math.cos(dock.pose.yaw), math.sin(dock.pose.yaw)])
    for back in np.linspace(0.0, 1.2, 13):
        x, y = np.array([dock.pose.x, dock.pose.y]) - back * heading
        assert footprint_clearance(scenario, Pose2D(x, y, dock.pose.yaw)) > 0.05
    path = shortest_path(
        build_grid(scenario),
        (scenario.start.x, scenario.start.y),
        (dock.pose.x, dock.pose.y),
        clearance_m=robot_clearance(scenario),
    )
    assert path is not None


# ------------------------------------------------------------ the study scene


@pytest.fixture(scope="module")
def room() -> Scenario:
    return load_scenario("cluttered_room")


@pytest.fixture(scope="module")
def room_grid(room) -> OccupancyGrid:
    return build_grid(room)


@pytest.fixture(scope="module")
def route(room, room_grid) -> np.ndarray:
    path = shortest_path(
        room_grid,
        (room.start.x, room.start.y),
        (room.dock.pose.x, room.dock.pose.y),
        clearance_m=robot_clearance(room),
    )
    assert path is not None, "no way from A to B for the robot"
    return path


def chord_widths(scenario: Scenario, points: np.ndarray) -> tuple[np.ndarray, list]:
    """The narrowest free chord through each point (k, 2), searched within 30 degrees of
    the direction to the nearest obstacle: its width [m] (k,) and the names of the
    elements at its two ends (k lists of 2). Rays are marched by sphere tracing on the
    exact distance to the obstacles."""
    eps = 1e-4
    d0 = element_distances(scenario, points)[0].min(axis=1)
    grad = np.column_stack(
        [
            element_distances(scenario, points + step)[0].min(axis=1) - d0
            for step in ((eps, 0.0), (0.0, eps))
        ]
    )
    base = np.arctan2(grad[:, 1], grad[:, 0])
    offsets = np.radians(np.linspace(-30.0, 30.0, 13))
    theta = (base[:, None] + offsets[None, :]).ravel()  # (k * m,)
    unit = np.column_stack((np.cos(theta), np.sin(theta)))
    origin = np.repeat(points, len(offsets), axis=0)
    t = np.zeros((2, len(theta)))
    for side, sign in enumerate((1.0, -1.0)):
        for _ in range(100):
            d, _ = element_distances(scenario, origin + sign * t[side][:, None] * unit)
            t[side] = np.minimum(t[side] + d.min(axis=1), 3.0)
    chords = t.sum(axis=0).reshape(len(points), len(offsets))
    best = np.argmin(chords, axis=1) + np.arange(len(points)) * len(offsets)
    ends = np.vstack(
        (origin[best] + t[0, best, None] * unit[best], origin[best] - t[1, best, None] * unit[best])
    )
    d, element_names = element_distances(scenario, ends)
    nearest = np.argmin(d, axis=1).reshape(2, len(points))
    names = [
        [element_names[nearest[0, i]], element_names[nearest[1, i]]] for i in range(len(points))
    ]
    return chords.min(axis=1), names


def narrow_places(scenario: Scenario, route: np.ndarray) -> list[tuple[np.ndarray, float, list]]:
    """Where the route passes an opening of at most 1.1 m: (point, width, the elements
    either side), one per opening, at its narrowest point."""
    d, _ = element_distances(scenario, route)
    candidates = np.flatnonzero(d.min(axis=1) <= 0.6)  # a chord <= 1.1 m has an end near
    widths = np.full(len(route), np.inf)
    names: list = [None] * len(route)
    if len(candidates):
        w, n = chord_widths(scenario, route[candidates])
        widths[candidates] = w
        for i, c in enumerate(candidates):
            names[c] = n[i]
    narrow = widths <= 1.1
    places, i = [], 0
    while i < len(route):
        if not narrow[i]:
            i += 1
            continue
        j = i
        while j + 1 < len(route) and narrow[j + 1]:
            j += 1
        k = i + int(np.argmin(widths[i : j + 1]))
        places.append((route[k], float(widths[k]), names[k]))
        i = j + 1
    return places


@pytest.fixture(scope="module")
def openings(room, route) -> list[tuple[np.ndarray, float, list]]:
    goal = np.array([room.dock.pose.x, room.dock.pose.y])
    # the table's own legs, around the dock, are the dock, not an opening on the way
    return [o for o in narrow_places(room, route) if np.linalg.norm(o[0] - goal) > 1.0]


def test_study_scene_has_its_parts(room):
    (x0, y0), (x1, y1) = room.bounds
    assert 15.0 <= x1 - x0 <= 17.5 and 9.0 <= y1 - y0 <= 11.5
    assert room.dock is not None and room.dock.table == "table"
    table = room.element("table")
    assert table.size == pytest.approx((1.2, 0.9)) and table.height == pytest.approx(0.75)
    assert room.inspection_object == "red_cylinder"
    cylinder = room.element("red_cylinder")
    assert isinstance(cylinder, Cylinder)
    assert 0.2 <= cylinder.radius <= 0.3
    assert cylinder.colour == pytest.approx((0.9, 0.1, 0.1))
    assert len(room.question_region) >= 3
    assert room.semantics.passage_width == (0.6, 1.1)


def test_red_cylinder_has_room_to_be_inspected_and_is_passed_by(room, route):
    assert free_ring(room, "red_cylinder", 1.5)
    centre = np.asarray(room.element("red_cylinder").centre)
    assert np.hypot(*(route - centre).T).min() < 2.0


def test_route_a_to_b_and_back_is_passable_and_of_study_length(room, room_grid, route):
    length = path_length(route)
    assert 18.0 <= length <= 25.0
    back = shortest_path(
        room_grid,
        (room.dock.pose.x, room.dock.pose.y),
        (room.start.x, room.start.y),
        clearance_m=robot_clearance(room),
    )
    assert back is not None
    assert path_length(back) == pytest.approx(length, rel=0.02)


def test_route_has_narrow_doorways_and_gaps_inside_the_passage_range(room, openings):
    low, high = room.semantics.passage_width
    walls = {w.name for w in room.walls}
    doorways = [o for o in openings if set(o[2]) <= walls]
    gaps = [o for o in openings if not set(o[2]) <= walls]
    assert len(doorways) >= 3 and len(gaps) >= 2
    for _, width, _ in openings:
        assert low <= width <= high
    # doorways: robot width + protective field both sides + about 15 cm (footnote 29)
    robot = room.robot
    for _, width, _ in doorways:
        assert width - robot.width - 2 * robot.protective_margin == pytest.approx(0.15, abs=0.06)
    for _, width, _ in gaps:
        assert 0.75 <= width <= 1.0


def test_route_has_a_corridor_wider_than_any_passage(room, route):
    """A stretch of at least 4 m whose width is outside ``passage_width`` yet under 1.6 m."""
    samples = route[::4]
    run, best = 0.0, 0.0
    for a, b in zip(samples[:-1], samples[1:], strict=True):
        direction = (b - a) / np.linalg.norm(b - a)
        width, _ = clear_width(room, a, np.array([-direction[1], direction[0]]))
        run = run + np.linalg.norm(b - a) if 1.1 < width <= 1.6 else 0.0
        best = max(best, run)
    assert best >= 4.0


def test_there_is_no_alternative_route(room, room_grid, openings):
    """Blocking any one opening on the route leaves no way from A to B."""
    start, goal = (room.start.x, room.start.y), (room.dock.pose.x, room.dock.pose.y)
    for point, width, _ in openings:
        blocked = block_disc(room_grid, point, width / 2 + 0.1)
        assert shortest_path(blocked, start, goal, clearance_m=robot_clearance(room)) is None
    # and a control: the same disc put in an open room does not cut the route
    centre = np.asarray(room.element("red_cylinder").centre) + (0.0, 1.2)
    blocked = block_disc(room_grid, centre, 0.5)
    assert shortest_path(blocked, start, goal, clearance_m=robot_clearance(room)) is not None


def test_question_region_lies_on_the_route_both_ways(room, route):
    inside = np.array([point_in_region(room, x, y) for x, y in route])
    assert not inside[0] and not inside[-1]  # starts after A, ends before B
    # crossed once each way, over a good stretch of the route
    assert np.count_nonzero(np.diff(inside.astype(int)) != 0) == 2
    assert path_length(route[inside]) >= 8.0


# ------------------------------------------------------------ demonstration scenes


def test_doorway_scene_has_two_doorways(rng):
    scenario = load_scenario("demo_doorway_crossing")
    grid = build_grid(scenario)
    clearance = robot_clearance(scenario)
    start = (scenario.start.x, scenario.start.y)
    goal = (float(rng.uniform(4.5, 6.3)), float(rng.uniform(1.0, 6.0)))
    first = shortest_path(grid, start, goal, clearance_m=clearance)
    assert first is not None
    cuts = narrow_places(scenario, first)
    assert len(cuts) == 1 and 0.6 <= cuts[0][1] <= 1.1
    grid = block_disc(grid, cuts[0][0], cuts[0][1] / 2 + 0.1)
    second = shortest_path(grid, start, goal, clearance_m=clearance)
    assert second is not None  # the other doorway
    cuts += narrow_places(scenario, second)
    assert len(cuts) == 2 and np.linalg.norm(cuts[0][0] - cuts[1][0]) > 1.5
    grid = block_disc(grid, cuts[1][0], cuts[1][1] / 2 + 0.1)
    assert shortest_path(grid, start, goal, clearance_m=clearance) is None


def test_inspection_scene_has_several_objects_with_room_around():
    scenario = load_scenario("demo_object_inspection")
    names = [e.name for e in (*scenario.boxes, *scenario.cylinders)]
    assert len(names) >= 2 and scenario.inspection_object in names
    for name in names:
        assert free_ring(scenario, name, 1.5)


def test_bypass_scene_has_several_objects_with_room_on_every_side():
    scenario = load_scenario("demo_object_bypass")
    names = [e.name for e in (*scenario.boxes, *scenario.cylinders)]
    assert len(names) >= 2
    for name in names:
        assert free_ring(scenario, name, 1.2)


def test_wall_following_scene_has_two_walls_followable_on_both_sides():
    scenario = load_scenario("demo_wall_following")
    (x0, y0), (x1, y1) = scenario.bounds
    inner = [
        w
        for w in scenario.walls
        if np.all(w.corners() > (x0 + 0.5, y0 + 0.5)) and np.all(w.corners() < (x1 - 0.5, y1 - 0.5))
    ]
    assert len(inner) >= 2
    half = scenario.robot.width / 2
    for wall in inner:
        # the robot's centre line 0.25 m off either face, along the whole wall
        offset = wall.size[1] / 2 + 0.25 + half
        t = np.linspace(-wall.size[0] / 2, wall.size[0] / 2, 40)
        for side in (-1.0, 1.0):
            local = np.column_stack((t, np.full_like(t, side * offset)))
            track = Pose2D(*wall.centre, wall.yaw).to_map_frame(local)
            d, _ = element_distances(scenario, track)
            assert d.min() >= half + 0.05


def test_docking_scene_has_more_than_one_table():
    scenario = load_scenario("demo_docking")
    assert scenario.dock is not None and len(scenario.tables) >= 2
    grid = inflate(build_grid(scenario), robot_clearance(scenario))
    assert grid.is_free(np.array([[scenario.dock.pose.x, scenario.dock.pose.y]])).all()


# -------------------------------------------------------------- malformed files


def study_data() -> dict:
    return tomllib.loads((SCENARIO_DIR / "cluttered_room.toml").read_text(encoding="utf-8"))


def index_of(items: list[dict], name: str) -> int:
    return next(i for i, item in enumerate(items) if item["name"] == name)


def set_field(path: tuple, value) -> object:
    """A mutation setting ``data[path[0]][path[1]]...`` to ``value``; returns the field name."""

    def mutate(data: dict) -> str:
        target = data
        for key in path[:-1]:
            target = target[key]
        target[path[-1]] = value
        name = ""
        for key in path:
            name += f"[{key}]" if isinstance(key, int) else (f".{key}" if name else key)
        return name

    return mutate


def bad_cylinder_radius(data: dict) -> str:
    i = index_of(data["cylinders"], "red_cylinder")
    data["cylinders"][i]["radius"] = -0.25
    return f"cylinders[{i}].radius"


def no_start(data: dict) -> str:
    data.pop("start")
    return "start.x"


def start_off_the_map(data: dict) -> str:
    data["start"]["x"] = 40.0
    return "start"


MALFORMED = [
    bad_cylinder_radius,
    no_start,
    start_off_the_map,
    set_field(("walls", 3, "colour_rgb"), [1, 0, 0]),
    set_field(("boxes", 0, "size"), ["wide", 0.5]),
    set_field(("dock", "yaw_deg"), "west"),
    set_field(("tables", 0, "height"), True),
    set_field(("bounds",), [[16.3, 10.3], [-0.3, -0.3]]),
    set_field(("bounds",), [[-0.3, -0.3]]),
    set_field(("bounds",), [[-0.3, -0.3], [math.inf, 10.3]]),
    set_field(("question_region", "polygon"), [[4, 0], [11, math.nan], [11, 6]]),
    set_field(("inspection_object",), "blue_cylinder"),
]


@pytest.mark.parametrize("mutate", MALFORMED)
def test_malformed_study_scene_names_file_and_field(mutate):
    data = study_data()
    field = mutate(data)
    with pytest.raises(ValueError) as error:
        parse_scenario(data, "cluttered_room.toml")
    message = str(error.value)
    assert message.startswith("cluttered_room.toml: field '")
    assert f"'{field}'" in message
    assert "\n" not in message


def test_malformed_file_on_disk_names_the_path(tmp_path):
    text = (SCENARIO_DIR / "cluttered_room.toml").read_text(encoding="utf-8")
    bad = tmp_path / "my_room.toml"
    bad.write_text(text.replace("radius = 0.25", "radius = -0.25", 1), encoding="utf-8")
    with pytest.raises(ValueError) as error:
        load_scenario(bad)
    assert str(error.value).startswith(f"{bad}: field 'cylinders[")
    assert ".radius'" in str(error.value)
