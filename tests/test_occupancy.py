"""The occupancy grid: rasterisation, distance transform, inflation, A*, ROS map files.

Each property is checked against an independent computation: exact geometry for the
rasterisation, brute force for the distance transform and the dilation, scipy's
Dijkstra for the path length, Pillow for the PNG codec.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import dijkstra

from sim.map_files import load_ros_map, save_png, save_ros_map
from sim.occupancy import (
    OccupancyGrid,
    build_grid,
    clearance_map,
    inflate,
    shortest_path,
)
from sim.scenario import Scenario, parse_scenario
from sim.types import Pose2D

RES = 0.05


def random_scene(rng: np.random.Generator, *, closed: bool = True) -> Scenario:
    """A closed room of random size with random boxes, cylinders and a thin wall."""
    w, h = rng.uniform(2.5, 4.5, size=2)
    data: dict = {
        "name": "random",
        "bounds": [[0.0, 0.0], [float(w), float(h)]],
        "start": {"x": 0.5, "y": 0.5},
        "walls": [],
        "boxes": [],
        "cylinders": [],
    }
    if closed:
        corners = [[0.05, 0.05], [w - 0.05, 0.05], [w - 0.05, h - 0.05], [0.05, h - 0.05]]
        for i in range(4):
            data["walls"].append(
                {"name": f"outer{i}", "from": corners[i], "to": corners[(i + 1) % 4]}
            )
    for i in range(int(rng.integers(2, 6))):
        data["boxes"].append(
            {
                "name": f"box{i}",
                "centre": [float(rng.uniform(0.3, w - 0.3)), float(rng.uniform(0.3, h - 0.3))],
                "size": [float(v) for v in rng.uniform(0.04, 0.8, size=2)],
                "yaw_deg": float(rng.uniform(-180, 180)),
            }
        )
    for i in range(int(rng.integers(1, 4))):
        data["cylinders"].append(
            {
                "name": f"cyl{i}",
                "centre": [float(rng.uniform(0.3, w - 0.3)), float(rng.uniform(0.3, h - 0.3))],
                "radius": float(rng.uniform(0.02, 0.4)),
            }
        )
    # a wall much thinner than a cell, at a random angle
    a = rng.uniform([0.3, 0.3], [w - 0.3, h - 0.3])
    b = rng.uniform([0.3, 0.3], [w - 0.3, h - 0.3])
    data["walls"].append({"name": "thin", "from": a.tolist(), "to": b.tolist(), "thickness": 0.005})
    return parse_scenario(data, "random.toml")


def distance_to_obstacles(scenario: Scenario, points: np.ndarray) -> np.ndarray:
    """Exact distance [m] of points (k, 2) to the nearest wall, box, leg or cylinder (k,)."""
    d = np.full(len(points), np.inf)
    for box in scenario.obstacle_boxes():
        local = Pose2D(box.centre[0], box.centre[1], box.yaw).to_robot_frame(points)
        gap = np.maximum(np.abs(local) - np.array(box.size) / 2, 0.0)
        d = np.minimum(d, np.hypot(gap[:, 0], gap[:, 1]))
    for cyl in scenario.cylinders:
        d = np.minimum(d, np.maximum(np.hypot(*(points - cyl.centre).T) - cyl.radius, 0.0))
    return d


def inside_obstacle(scenario: Scenario, points: np.ndarray) -> np.ndarray:
    """Whether points (k, 2) lie strictly inside some obstacle (k,) bool."""
    inside = np.zeros(len(points), dtype=bool)
    for box in scenario.obstacle_boxes():
        local = Pose2D(box.centre[0], box.centre[1], box.yaw).to_robot_frame(points)
        inside |= np.all(np.abs(local) < np.array(box.size) / 2, axis=1)
    for cyl in scenario.cylinders:
        inside |= np.hypot(*(points - cyl.centre).T) < cyl.radius
    return inside


def all_centres(grid: OccupancyGrid) -> np.ndarray:
    rows, cols = grid.shape
    rc = np.stack(np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij"), -1).reshape(-1, 2)
    return grid.cell_to_world(rc)


def brute_clearance(occupied: np.ndarray, res: float) -> np.ndarray:
    occ = np.argwhere(occupied)
    rows, cols = occupied.shape
    cells = np.argwhere(np.ones((rows, cols), bool))
    if len(occ) == 0:
        return np.full((rows, cols), np.inf)
    d = np.sqrt(((cells[:, None, :] - occ[None, :, :]) ** 2).sum(-1)).min(axis=1)
    return (d * res).reshape(rows, cols)


# ---------------------------------------------------------------- rasterising


def test_grid_covers_the_bounds_and_maps_cells_both_ways(rng):
    scene = random_scene(rng)
    grid = build_grid(scene, resolution=RES)
    (x0, y0), (x1, y1) = scene.bounds
    ex = grid.extent()
    assert ex[0] == x0 and ex[2] == y0
    assert x1 <= ex[1] < x1 + RES and y1 <= ex[3] < y1 + RES
    rows, cols = grid.shape
    rc = np.column_stack((rng.integers(0, rows, 50), rng.integers(0, cols, 50)))
    assert np.array_equal(grid.world_to_cell(grid.cell_to_world(rc)), rc)
    pts = rng.uniform([x0, y0], [x1, y1], size=(200, 2))
    back = grid.cell_to_world(grid.world_to_cell(pts))
    assert np.all(np.abs(back - pts) <= RES / 2 + 1e-12)
    # row 0 is the bottom of the map
    assert grid.world_to_cell(np.array([[x0 + 0.01, y0 + 0.01]]))[0].tolist() == [0, 0]
    outside = np.array([[x0 - 0.01, y0 + 1], [x1 + RES, y0 + 1], [x0 + 1, y0 - 1e-6]])
    assert not grid.is_free(outside).any()


def test_cells_inside_obstacles_are_occupied_and_far_cells_free(rng):
    for _ in range(3):
        scene = random_scene(rng)
        grid = build_grid(scene, resolution=RES)
        centres = all_centres(grid)
        occupied = grid.occupied.ravel()
        # every cell whose centre is inside an obstacle is occupied
        assert occupied[inside_obstacle(scene, centres)].all()
        # a cell can only be occupied if the obstacle reaches into it: the centre
        # is then within half a cell diagonal of it
        near = distance_to_obstacles(scene, centres) <= RES / math.sqrt(2) + 1e-9
        assert not occupied[~near].any()
        # conservative: any point strictly inside an obstacle lies in an occupied
        # cell, so even the 5 mm wall leaves no hole
        thin = scene.walls[-1]
        t = rng.uniform(-0.5, 0.5, size=(2000, 1))
        s = rng.uniform(-0.5, 0.5, size=(2000, 1))
        local = np.hstack((t * thin.size[0], s * thin.size[1]))
        pts = Pose2D(thin.centre[0], thin.centre[1], thin.yaw).to_map_frame(local)
        assert not grid.is_free(pts).any()


def test_table_tops_are_free_and_legs_occupied():
    data = {
        "name": "t",
        "bounds": [[0, 0], [3, 3]],
        "start": {"x": 0.5, "y": 0.5},
        "tables": [{"name": "table", "centre": [1.5, 1.5], "size": [1.2, 0.9], "leg": 0.06}],
    }
    scene = parse_scenario(data, "t.toml")
    grid = build_grid(scene)
    assert grid.is_free(np.array([[1.5, 1.5], [1.0, 1.3], [2.0, 1.7]])).all()
    legs = np.array([b.centre for b in scene.tables[0].leg_boxes()])
    assert not grid.is_free(legs).any()


def test_grid_equality_and_validation():
    occ = np.zeros((3, 4), bool)
    a = OccupancyGrid(occ, (0.0, 0.0), 0.1)
    assert a == OccupancyGrid(occ.copy(), (0, 0), 0.1)
    assert a != OccupancyGrid(~occ, (0.0, 0.0), 0.1)
    assert a != OccupancyGrid(occ, (0.0, 0.1), 0.1)
    assert a.shape == (3, 4)
    with pytest.raises(ValueError, match="bool"):
        OccupancyGrid(np.zeros((3, 4)), (0.0, 0.0), 0.1)
    with pytest.raises(ValueError, match="resolution"):
        OccupancyGrid(occ, (0.0, 0.0), 0.0)


# ---------------------------------------------------- distance transform, inflation


@settings(max_examples=60, deadline=None)
@given(arrays(bool, st.tuples(st.integers(1, 17), st.integers(1, 23)), elements=st.booleans()))
def test_clearance_map_equals_brute_force(occupied):
    grid = OccupancyGrid(occupied, (0.0, 0.0), RES)
    assert np.allclose(clearance_map(grid), brute_clearance(occupied, RES), rtol=0, atol=1e-12)


def test_clearance_map_of_sparse_grids_and_of_nothing(rng):
    for shape in [(40, 7), (7, 40), (31, 29)]:
        occupied = rng.random(shape) < 0.01
        occupied[rng.integers(shape[0]), rng.integers(shape[1])] = True
        grid = OccupancyGrid(occupied, (1.0, -2.0), 0.1)
        assert np.allclose(clearance_map(grid), brute_clearance(occupied, 0.1), atol=1e-12)
    empty = OccupancyGrid(np.zeros((5, 6), bool), (0.0, 0.0), RES)
    assert np.isinf(clearance_map(empty)).all()
    assert not inflate(empty, 1.0).occupied.any()


def test_inflate_is_a_disc_dilation(rng):
    for _ in range(4):
        shape = tuple(int(v) for v in rng.integers(5, 30, size=2))
        occupied = rng.random(shape) < rng.uniform(0.005, 0.1)
        grid = OccupancyGrid(occupied, (0.0, 0.0), RES)
        brute = brute_clearance(occupied, RES)
        previous = occupied
        for k in (0.37, 1.2, 2.5, 4.81):  # radii between the discrete distances
            radius = k * RES
            inflated = inflate(grid, radius)
            assert np.array_equal(inflated.occupied, brute <= radius)
            assert np.array_equal(inflated.occupied, clearance_map(grid) <= radius)
            assert not (previous & ~inflated.occupied).any()  # grows monotonically
            previous = inflated.occupied
        assert inflate(grid, 0.0) == grid


def test_inflate_at_an_exact_distance_includes_it():
    occupied = np.zeros((11, 11), bool)
    occupied[5, 5] = True
    grid = OccupancyGrid(occupied, (0.0, 0.0), RES)
    inflated = inflate(grid, 5 * RES).occupied  # 3-4-5: (8, 9) is exactly 5 cells away
    assert inflated[5, 10] and inflated[8, 9] and inflated[9, 8] and not inflated[9, 9]


# ------------------------------------------------------------------------ A*


def reference_cost(free: np.ndarray, start: tuple[int, int], goal: tuple[int, int]) -> float:
    """Shortest 8-connected path length [cells] without corner cutting, by scipy's Dijkstra."""
    rows, cols = free.shape
    index = np.arange(rows * cols).reshape(rows, cols)
    src, dst, w = [], [], []
    for dr, dc in [(0, 1), (1, 0), (1, 1), (1, -1)]:
        r0, r1 = max(0, -dr), rows - max(0, dr)
        c0, c1 = max(0, -dc), cols - max(0, dc)
        a = free[r0:r1, c0:c1]
        b = free[r0 + dr : r1 + dr, c0 + dc : c1 + dc]
        ok = a & b
        if dr and dc:  # both orthogonal cells free
            ok &= free[r0 + dr : r1 + dr, c0:c1] & free[r0:r1, c0 + dc : c1 + dc]
        src.append(index[r0:r1, c0:c1][ok])
        dst.append(index[r0 + dr : r1 + dr, c0 + dc : c1 + dc][ok])
        w.append(np.full(ok.sum(), math.hypot(dr, dc)))
    graph = coo_matrix(
        (np.concatenate(w), (np.concatenate(src), np.concatenate(dst))), shape=(index.size,) * 2
    ).tocsr()
    return float(dijkstra(graph, directed=False, indices=index[start])[index[goal]])


def random_free_point(rng, grid: OccupancyGrid) -> np.ndarray:
    cells = np.argwhere(~grid.occupied)
    return grid.cell_to_world(cells[rng.integers(len(cells))][None])[0] + rng.uniform(
        -0.02, 0.02, 2
    )


def test_shortest_path_is_free_connected_optimal_and_ends_right(rng):
    found = 0
    for _ in range(6):
        scene = random_scene(rng)
        grid = build_grid(scene)
        clearance = float(rng.uniform(0.1, 0.3))
        inflated = inflate(grid, clearance)
        start, goal = random_free_point(rng, inflated), random_free_point(rng, inflated)
        path = shortest_path(grid, start, goal, clearance_m=clearance)
        s_cell = tuple(inflated.world_to_cell(start)[0])
        g_cell = tuple(inflated.world_to_cell(goal)[0])
        best = reference_cost(~inflated.occupied, s_cell, g_cell)
        if not np.isfinite(best):
            assert path is None
            continue
        found += 1
        assert path is not None and path.ndim == 2 and path.shape[1] == 2
        assert np.allclose(path[0], grid.cell_to_world(np.array([s_cell]))[0])
        assert np.allclose(path[-1], grid.cell_to_world(np.array([g_cell]))[0])
        assert inflated.is_free(path).all()
        steps = np.linalg.norm(np.diff(path, axis=0), axis=1)
        assert np.all((steps > RES / 2) & (steps < RES * math.sqrt(2) + 1e-9))
        assert steps.sum() / RES == pytest.approx(best, rel=1e-5)
    assert found >= 1


def test_path_to_itself_is_one_cell():
    grid = OccupancyGrid(np.zeros((10, 10), bool), (0.0, 0.0), RES)
    path = shortest_path(grid, (0.26, 0.24), (0.27, 0.22), clearance_m=0.1)
    assert path is not None and path.shape == (1, 2)
    assert np.allclose(path[0], [0.275, 0.225])


def test_unreachable_goal_gives_none(rng):
    occupied = np.zeros((40, 60), bool)
    col = int(rng.integers(10, 50))
    occupied[:, col] = True  # a wall from bottom to top
    grid = OccupancyGrid(occupied, (0.0, 0.0), RES)
    left = (0.5 * col * RES, 1.0)
    right = ((col + 0.5 * (60 - col)) * RES + 0.03, 1.0)
    assert shortest_path(grid, left, right, clearance_m=0.0) is None
    assert shortest_path(grid, left, (left[0], 1.5), clearance_m=0.0) is not None
    # a one-cell hole: passable with no clearance, not with any
    with_hole = occupied.copy()
    with_hole[20, col] = False
    hole = OccupancyGrid(with_hole, (0.0, 0.0), RES)
    assert shortest_path(hole, left, right, clearance_m=0.0) is not None
    assert shortest_path(hole, left, right, clearance_m=0.06) is None
    # diagonal neighbours do not leak through a corner
    diag = np.zeros((20, 20), bool)
    diag[np.arange(20), np.arange(20)] = True
    diag_grid = OccupancyGrid(diag, (0.0, 0.0), RES)
    assert shortest_path(diag_grid, (0.8, 0.2), (0.2, 0.8), clearance_m=0.0) is None
    # start or goal outside the grid or blocked
    assert shortest_path(grid, (-1.0, 1.0), left, clearance_m=0.0) is None
    assert shortest_path(grid, left, ((col + 0.5) * RES, 1.0), clearance_m=0.0) is None


# ------------------------------------------------------------------ map files


def test_ros_map_round_trip(rng, tmp_path):
    scene = random_scene(rng)
    grid = build_grid(scene)
    pgm, yaml = save_ros_map(grid, tmp_path / "maps", "room")
    assert (pgm.name, yaml.name) == ("room.pgm", "room.yaml")
    rows, cols = grid.shape
    data = pgm.read_bytes()
    header = f"P5\n{cols} {rows}\n255\n".encode()
    assert data.startswith(header)
    image = np.frombuffer(data[len(header) :], np.uint8).reshape(rows, cols)
    assert set(np.unique(image)) <= {0, 254}
    assert np.array_equal(image[0] == 0, grid.occupied[-1])  # image top = map top
    text = yaml.read_text()
    for line in ("image: room.pgm", "negate: 0", "occupied_thresh: 0.65", "free_thresh: 0.196"):
        assert line in text
    assert load_ros_map(yaml) == grid


def test_png_written_by_us_reads_in_pillow_and_back(rng, tmp_path):
    pil = pytest.importorskip("PIL.Image")
    grid = build_grid(random_scene(rng))
    png = save_png(grid, tmp_path / "room.png")
    with pil.open(png) as img:
        assert img.mode == "L"
        pixels = np.asarray(img)
    assert np.array_equal(pixels == 0, grid.occupied[::-1])
    yaml = tmp_path / "room.yaml"
    yaml.write_text(
        f"image: room.png\nresolution: {grid.resolution}\n"
        f"origin: [{grid.origin[0]}, {grid.origin[1]}, 0.0]\n"
    )
    assert load_ros_map(yaml) == grid


@pytest.mark.parametrize("mode", ["L", "RGB", "RGBA"])
def test_png_written_by_pillow_reads_here(rng, tmp_path, mode):
    pil = pytest.importorskip("PIL.Image")
    values = rng.choice(np.array([0, 100, 205, 254, 255], np.uint8), size=(23, 31))
    img = pil.fromarray(values, "L").convert(mode)
    img.save(tmp_path / "m.png", optimize=True)  # Pillow picks its own row filters
    (tmp_path / "m.yaml").write_text(
        "image: m.png  # map image\nresolution: 0.1\norigin: [-1.0, 2.0, 0]\nmode: trinary\n"
    )
    grid = load_ros_map(tmp_path / "m.yaml")
    # ROS trinary reading: p = (255 - v) / 255; free when p < 0.196, else not free
    assert np.array_equal(grid.occupied, (values <= 205)[::-1])
    assert grid.origin == (-1.0, 2.0) and grid.resolution == 0.1


def test_negated_and_plain_pgm_maps(tmp_path):
    values = np.array([[0, 254, 255], [10, 205, 240]])
    (tmp_path / "m.pgm").write_text("P2\n# plain\n3 2\n255\n" + " ".join(map(str, values.ravel())))
    (tmp_path / "m.yaml").write_text("image: m.pgm\nresolution: 0.5\norigin: [0, 0, 0]\n")
    plain = load_ros_map(tmp_path / "m.yaml")
    assert plain.occupied[::-1].tolist() == [[True, False, False], [True, True, False]]
    (tmp_path / "n.yaml").write_text(
        "image: m.pgm\nresolution: 0.5\norigin: [0, 0, 0]\nnegate: 1\n"
    )
    negated = load_ros_map(tmp_path / "n.yaml")
    assert negated.occupied[::-1].tolist() == [[False, True, True], [False, True, True]]


BAD_YAML = [
    ("image: m.pgm\norigin: [0, 0, 0]\n", "resolution"),
    ("image: m.pgm\nresolution: fine\norigin: [0, 0, 0]\n", "resolution"),
    ("image: m.pgm\nresolution: -0.05\norigin: [0, 0, 0]\n", "resolution"),
    ("image: m.pgm\nresolution: 0.05\n", "origin"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0]\n", "origin"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0.5]\n", "origin"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nnegate: 2\n", "negate"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nfree_thresh: 0.9\n", "free_thresh"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nmode: blend\n", "mode"),
    ("image: m.pgm\nresolution: 0.05\norigin: [0, 0, 0]\nresolutoin: 1\n", "resolutoin"),
    ("resolution: 0.05\norigin: [0, 0, 0]\n", "image"),
    ("image: nowhere.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n", "image"),
    ("image: bad.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n", "image"),
    ("image: short.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n", "image"),
    ("image: bad.png\nresolution: 0.05\norigin: [0, 0, 0]\n", "image"),
]


@pytest.mark.parametrize(("text", "field"), BAD_YAML)
def test_bad_map_files_name_file_and_field(tmp_path, text, field):
    save_ros_map(OccupancyGrid(np.zeros((3, 4), bool), (0.0, 0.0), RES), tmp_path, "m")
    (tmp_path / "bad.pgm").write_bytes(b"P7\n1 1\n255\n\x00")
    (tmp_path / "short.pgm").write_bytes(b"P5\n4 3\n255\n\x00\x00")
    (tmp_path / "bad.png").write_bytes(b"\x89PNG\r\n\x1a\nnot really")
    path = tmp_path / "map.yaml"
    path.write_text(text)
    with pytest.raises(ValueError) as error:
        load_ros_map(path)
    message = str(error.value)
    assert message.startswith(f"{path}: field '{field}'")
    assert "\n" not in message


def test_missing_map_file(tmp_path):
    with pytest.raises(FileNotFoundError):
        load_ros_map(tmp_path / "none.yaml")
