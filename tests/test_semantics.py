"""Semantic components derived from scene geometry (sim.semantics): passages, docks,
surface points, the per-tick robot-frame transform, overrides and removals."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from sim.scenario import available_scenarios, load_scenario, parse_scenario
from sim.semantics import (
    MERGE_DISTANCE_M,
    derive_components,
    in_robot_frame,
    nearest_components,
    target_distances,
)
from sim.types import COMPONENT_KINDS, Pose2D

LO, HI = 0.6, 1.1  # the default passage_width
FEW = settings(max_examples=25, deadline=None)


def scene(**fields) -> dict:
    # A in a corner, clear of the geometry the tests place about the origin (the loader
    # refuses a start inside an obstacle; derived components do not depend on it)
    data = {"name": "t", "start": {"x": -19.9, "y": -19.9}, "bounds": [[-20, -20], [20, 20]]}
    data.update(fields)
    return data


def derive(data: dict):
    return derive_components(parse_scenario(copy.deepcopy(data), "t.toml"))


def of_kind(components, *kinds):
    return [c for c in components if c.kind in kinds]


def rot(theta: float) -> np.ndarray:
    return np.array([[math.cos(theta), -math.sin(theta)], [math.sin(theta), math.cos(theta)]])


def collinear_walls(w: float, theta: float, thickness: float = 0.1, origin=(0.0, 0.0)):
    """Two walls along direction theta with an opening of width w centred at origin."""
    d = rot(theta) @ np.array([1.0, 0.0])
    o = np.asarray(origin)
    a0, a1 = o - (w / 2 + 2.0) * d, o - (w / 2) * d
    b0, b1 = o + (w / 2) * d, o + (w / 2 + 2.5) * d
    return [
        {"name": "left", "from": a0.tolist(), "to": a1.tolist(), "thickness": thickness},
        {"name": "right", "from": b0.tolist(), "to": b1.tolist(), "thickness": thickness},
    ]


def outline_distance(p: np.ndarray, polygon: np.ndarray) -> float:
    """Distance from p to the boundary of a polygon (independent of sim.semantics)."""
    best = math.inf
    for a, b in zip(polygon, np.roll(polygon, -1, axis=0), strict=True):
        t = np.clip(np.dot(p - a, b - a) / np.dot(b - a, b - a), 0, 1)
        best = min(best, float(np.linalg.norm(a + t * (b - a) - p)))
    return best


# ---------------------------------------------------------------------------- passages


@FEW
@given(
    w=st.floats(LO, HI),
    theta=st.floats(-math.pi, math.pi),
    thickness=st.floats(0.05, 0.3),
    cx=st.floats(-5, 5),
)
def test_one_doorway_between_collinear_walls(w, theta, thickness, cx):
    comps = derive(scene(walls=collinear_walls(w, theta, thickness, (cx, 1.0))))
    doors = of_kind(comps, "doorway")
    assert len(doors) == 1 and not of_kind(comps, "gap")
    door = doors[0]
    assert door.id == "doorway_0"
    assert np.linalg.norm(door.centre - (cx, 1.0)) < 0.01
    assert abs(door.width - w) < 0.01
    assert abs(np.linalg.norm(door.ends[1] - door.ends[0]) - door.width) < 1e-9
    along = rot(theta) @ np.array([1.0, 0.0])
    assert abs(np.linalg.norm(door.normal) - 1) < 1e-9
    assert abs(door.normal @ along) < 1e-6  # perpendicular to the wall: the crossing direction
    assert sorted(door.source) == ["left", "right"]
    assert np.allclose(door.points, door.ends) and np.allclose(door.target_point(), door.centre)


@FEW
@given(
    w=st.one_of(st.floats(0.2, LO - 0.01), st.floats(HI + 0.01, 3.0)),
    theta=st.floats(-math.pi, math.pi),
)
def test_no_doorway_outside_the_passage_range(w, theta):
    comps = derive(scene(walls=collinear_walls(w, theta)))
    assert not of_kind(comps, "doorway", "gap")


@FEW
@given(lo=st.floats(0.3, 1.5), span=st.floats(0.1, 1.0), frac=st.floats(0.0, 1.0))
def test_passage_range_comes_from_the_settings(lo, span, frac):
    hi = lo + span
    w = lo + frac * span
    inside = scene(walls=collinear_walls(w, 0.3), semantics={"passage_width": [lo, hi]})
    assert len(of_kind(derive(inside), "doorway")) == 1
    outside = scene(walls=collinear_walls(hi + 0.05, 0.3), semantics={"passage_width": [lo, hi]})
    assert not of_kind(derive(outside), "doorway")


def test_doorway_between_a_wall_end_and_a_perpendicular_wall():
    w = 0.85
    e = 2.95 - w  # the stub's end face; the north wall's inner face is at y = 2.95
    comps = derive(
        scene(
            walls=[
                {"name": "north", "from": [-2.0, 3.0], "to": [4.0, 3.0]},
                {"name": "stub", "from": [1.0, 0.0], "to": [1.0, e]},
            ]
        )
    )
    (door,) = of_kind(comps, "doorway")
    assert np.allclose(door.centre, (1.0, e + w / 2), atol=1e-6)
    assert door.width == pytest.approx(w)
    assert np.allclose(door.normal, (1.0, 0.0))


@FEW
@given(d=st.floats(LO, HI), theta=st.floats(-math.pi, math.pi), yaw=st.floats(-10, 10))
def test_box_next_to_a_wall_is_a_gap(d, theta, yaw):
    # wall along x through the origin (thickness 0.1), a 0.6 x 0.4 crate d away from its face
    r = rot(theta)
    wall = {"name": "wall", "from": (r @ [-3.0, 0]).tolist(), "to": (r @ [3.0, 0]).tolist()}
    # a slightly yawed crate; its nearest corner is d from the wall's face
    half_depth = 0.3 * abs(math.sin(math.radians(yaw))) + 0.2 * abs(math.cos(math.radians(yaw)))
    centre = r @ [0.0, 0.05 + d + half_depth]
    crate = {
        "name": "crate",
        "centre": centre.tolist(),
        "size": [0.6, 0.4],
        "yaw_deg": math.degrees(theta) + yaw,
    }
    comps = derive(scene(walls=[wall], boxes=[crate]))
    (gap,) = of_kind(comps, "gap")
    assert not of_kind(comps, "doorway")
    assert gap.width == pytest.approx(d, abs=0.01)
    assert set(gap.source) == {"wall", "crate"}
    assert abs(gap.normal @ (r @ [0.0, 1.0])) < 1e-6  # crossing runs along the wall
    assert (r.T @ gap.centre)[1] == pytest.approx(0.05 + d / 2, abs=0.01)


@FEW
@given(d=st.floats(LO, HI), theta=st.floats(-math.pi, math.pi))
def test_a_dead_end_pocket_beside_furniture_is_not_a_gap(d, theta):
    # a shelf along a side wall, d short of the end wall (a gap crossed along the end
    # wall); with the side wall 0.15 m behind the shelf the slot is too narrow for the
    # robot: the opening can be entered, never crossed (cluttered_room's old gap_11)
    r = rot(theta)

    def wall(name, a, b):
        return {"name": name, "from": (r @ a).tolist(), "to": (r @ b).tolist()}

    end = wall("end", [-4.0, 0.0], [0.05, 0.0])
    shelf = {
        "name": "shelf",
        "centre": (r @ [-0.4, -0.05 - d - 1.0]).tolist(),
        "size": [0.4, 2.0],
        "yaw_deg": math.degrees(theta),
    }
    assert len(of_kind(derive(scene(walls=[end], boxes=[shelf])), "gap")) == 1
    side = wall("side", [0.0, 0.05], [0.0, -4.0])
    assert not of_kind(derive(scene(walls=[end, side], boxes=[shelf])), "gap")


@FEW
@given(d=st.floats(LO, HI), length=st.floats(1.5, 8.0), theta=st.floats(-math.pi, math.pi))
def test_a_corridor_is_not_a_passage(d, length, theta):
    r = rot(theta)
    y = d + 0.1  # centre-line distance of two 0.1-thick walls with clear width d
    walls = [
        {"name": "a", "from": (r @ [0, 0]).tolist(), "to": (r @ [length, 0]).tolist()},
        {"name": "b", "from": (r @ [0, y]).tolist(), "to": (r @ [length, y]).tolist()},
    ]
    assert not of_kind(derive(scene(walls=walls)), "doorway", "gap")


def test_a_corridor_side_made_of_pieces_is_not_a_passage():
    # one side is three touching pieces, each shorter than the probe depth
    walls = [{"name": "long", "from": [0.0, 0.0], "to": [4.0, 0.0]}]
    walls += [
        {"name": f"piece{i}", "from": [1.0 + 0.5 * i, 1.0], "to": [1.5 + 0.5 * i, 1.0]}
        for i in range(3)
    ]
    assert not of_kind(derive(scene(walls=walls)), "doorway", "gap")


def test_an_obstacle_across_the_opening_blocks_the_passage():
    walls = collinear_walls(1.0, 0.0)
    free = derive(scene(walls=walls))
    assert len(of_kind(free, "doorway")) == 1
    # a small pillar in the doorway: the walls' opening is no longer free
    blocked = derive(
        scene(walls=walls, cylinders=[{"name": "pillar", "centre": [0.0, 0.0], "radius": 0.05}])
    )
    assert not of_kind(blocked, "doorway")


def test_close_passages_are_merged_keeping_the_narrowest():
    wall = {"name": "wall", "from": [-3.0, 0.0], "to": [3.0, 0.0]}
    cylinders = [
        {"name": "c1", "centre": [0.0, 0.05 + 0.8 + 0.2], "radius": 0.2},
        {"name": "c2", "centre": [0.5, 0.05 + 0.7 + 0.2], "radius": 0.2},
    ]
    gaps = of_kind(derive(scene(walls=[wall], cylinders=cylinders)), "gap")
    assert len(gaps) == 1
    assert gaps[0].width == pytest.approx(0.7) and "c2" in gaps[0].source
    # far apart they are two gaps
    # the two raw gaps were centred 0.5 m apart, closer than MERGE_DISTANCE_M
    assert MERGE_DISTANCE_M > 0.5
    cylinders[1]["centre"] = [2.0, 0.95]  # now far apart (and no c1-c2 gap)
    far = of_kind(derive(scene(walls=[wall], cylinders=cylinders)), "gap")
    assert len(far) == 2
    assert np.linalg.norm(far[0].centre - far[1].centre) > MERGE_DISTANCE_M


# --------------------------------------------------------------------------------- dock


def test_a_table_gives_a_dock_and_its_legs_no_gap():
    table = {"name": "desk", "centre": [2.0, 2.0], "size": [1.2, 0.9], "yaw_deg": 30.0}
    other = {"name": "side", "centre": [6.0, 2.0], "size": [1.0, 0.8]}
    data = scene(
        tables=[table, other],
        walls=[{"name": "far", "from": [0.0, 5.0], "to": [8.0, 5.0]}],
        dock={"x": 2.1, "y": 1.9, "yaw_deg": 120.0, "table": "desk"},
    )
    comps = derive(data)
    assert not of_kind(comps, "doorway", "gap")  # leg-to-leg openings are the dock
    docks = {c.id: c for c in of_kind(comps, "dock")}
    assert set(docks) == {"dock_desk", "dock_side"}
    desk, side = docks["dock_desk"], docks["dock_side"]
    assert np.allclose(desk.centre, (2.1, 1.9))  # the dock pose B
    assert np.allclose(desk.normal, (math.cos(math.radians(120)), math.sin(math.radians(120))))
    assert np.allclose(side.centre, (6.0, 2.0)) and np.allclose(side.normal, (1.0, 0.0))
    assert np.allclose(desk.target_point(), desk.centre) and len(desk.points) == 0


# ------------------------------------------------------------------------ surface points


@FEW
@given(
    spacing=st.floats(0.03, 0.4),
    yaw=st.floats(-180, 180),
    sx=st.floats(0.2, 1.5),
    sy=st.floats(0.2, 1.5),
    radius=st.floats(0.05, 0.6),
)
def test_surface_points_lie_on_the_outline_at_the_spacing(spacing, yaw, sx, sy, radius):
    data = scene(
        walls=[{"name": "w", "from": [-4.0, -3.0], "to": [4.0, -2.0], "thickness": 0.15}],
        boxes=[{"name": "crate", "centre": [-1.0, 1.0], "size": [sx, sy], "yaw_deg": yaw}],
        cylinders=[{"name": "drum", "centre": [2.0, 1.5], "radius": radius}],
        semantics={"surface_spacing": spacing},
    )
    s = parse_scenario(copy.deepcopy(data), "t.toml")
    comps = {c.id: c for c in derive_components(s)}
    assert {"object_crate", "object_drum", "wall_w"} <= set(comps)

    crate = comps["object_crate"]
    corners = s.boxes[0].corners()
    assert max(outline_distance(p, corners) for p in crate.points) < 1e-3
    steps = np.linalg.norm(np.diff(np.vstack((crate.points, crate.points[:1])), axis=0), axis=1)
    assert steps.max() <= spacing + 1e-9
    assert len(crate.points) >= 2 * (sx + sy) / spacing - 1e-9
    assert np.allclose(crate.centre, (-1.0, 1.0))

    drum = comps["object_drum"]
    assert np.abs(np.linalg.norm(drum.points - (2.0, 1.5), axis=1) - radius).max() < 1e-3
    steps = np.linalg.norm(np.diff(np.vstack((drum.points, drum.points[:1])), axis=0), axis=1)
    assert steps.max() <= spacing + 1e-9

    wall = comps["wall_w"]
    box = s.walls[0]
    local = Pose2D(*box.centre, box.yaw).to_robot_frame(wall.points)  # wall's own frame
    assert np.allclose(np.abs(local[:, 1]), 0.075, atol=1e-3)  # on the two long faces
    for side in (-1, 1):
        face = np.sort(local[np.sign(local[:, 1]) == side, 0])
        assert face[0] == pytest.approx(-box.size[0] / 2) and face[-1] == pytest.approx(
            box.size[0] / 2
        )
        assert np.diff(face).max() <= spacing + 1e-9


def test_hidden_surface_points_are_dropped():
    # a crate standing against a wall hides part of the wall's face
    data = scene(
        walls=[{"name": "w", "from": [-2.0, 0.0], "to": [2.0, 0.0], "thickness": 0.1}],
        boxes=[{"name": "crate", "centre": [0.0, 0.2], "size": [0.6, 0.4]}],
    )
    comps = {c.id: c for c in derive(data)}
    wall_pts = comps["wall_w"].points
    inside = (np.abs(wall_pts[:, 0]) < 0.3 - 1e-6) & (wall_pts[:, 1] > 0)
    assert not inside.any()
    assert (wall_pts[:, 1] < 0).sum() == 41  # the hidden face is dropped, the other kept whole


# ---------------------------------------------------------------------------- transforms


def room() -> dict:
    return scene(
        walls=[
            *collinear_walls(0.9, 0.0),
            {"name": "back", "from": [-3.0, 3.0], "to": [3.0, 3.0]},
        ],
        boxes=[{"name": "crate", "centre": [1.0, 1.5], "size": [0.6, 0.4], "yaw_deg": 20}],
        cylinders=[{"name": "drum", "centre": [-1.2, 1.4], "radius": 0.2}],
        tables=[{"name": "desk", "centre": [2.0, -1.5], "size": [1.2, 0.9]}],
        semantics={"components": [{"id": "gap_extra", "kind": "gap", "centre": [0, -2],
                                   "ends": [[-0.4, -2], [0.4, -2]]}]},
    )  # fmt: skip


def test_in_robot_frame_and_back_is_the_identity(rng):
    comps = derive(room())
    for _ in range(5):
        pose = Pose2D(*rng.uniform(-3, 3, size=2), float(rng.uniform(-math.pi, math.pi)))
        robot = in_robot_frame(comps, pose)
        assert [c.id for c in robot] == [c.id for c in comps]
        back_rot = rot(pose.yaw)
        for m, r in zip(comps, robot, strict=True):
            ref = m.transformed(pose)
            for name in ("centre", "points", "ends", "normal"):
                assert np.allclose(getattr(r, name), getattr(ref, name), atol=1e-12)
            assert np.allclose(pose.to_map_frame(r.centre)[0], m.centre)
            assert np.allclose(back_rot @ r.normal, m.normal)
            if len(m.points):
                assert np.allclose(pose.to_map_frame(r.points), m.points)
            if len(m.ends):
                assert np.allclose(pose.to_map_frame(r.ends), m.ends)
            assert r.kind == m.kind and r.source == m.source
            assert (math.isnan(r.width) and math.isnan(m.width)) or r.width == m.width
            assert not r.points.flags.writeable and not r.centre.flags.writeable
        # a plain tuple gives the same answer, only slower
        plain = in_robot_frame(tuple(comps), pose)
        assert all(np.allclose(a.centre, b.centre) for a, b in zip(plain, robot, strict=True))


def test_nearest_components_are_the_k_closest_targets(rng):
    comps = derive(room())
    pose = Pose2D(*rng.uniform(-2, 2, size=2), float(rng.uniform(-math.pi, math.pi)))
    robot = in_robot_frame(comps, pose)
    brute = np.array([np.linalg.norm(c.target_point()) for c in robot])
    assert np.allclose(target_distances(robot), brute)
    assert np.allclose(target_distances(tuple(robot)), brute)
    for k in (0, 1, 3, len(robot), len(robot) + 5):
        near = nearest_components(robot, k)
        assert len(near) == min(k, len(robot))
        d = [np.linalg.norm(c.target_point()) for c in near]
        assert d == sorted(d)
        if near:
            chosen = {c.id for c in near}
            rest = [b for c, b in zip(robot, brute, strict=True) if c.id not in chosen]
            assert all(d[-1] <= b + 1e-12 for b in rest)
    with pytest.raises(ValueError):
        nearest_components(robot, -1)


# --------------------------------------------------------------- overrides and removals


def test_removals_and_overrides():
    base = scene(
        walls=collinear_walls(0.9, 0.0),
        boxes=[{"name": "crate", "centre": [0.0, 2.0], "size": [0.6, 0.4]}],
    )
    derived = {c.id: c for c in derive(base)}
    assert "doorway_0" in derived and "object_crate" in derived

    data = copy.deepcopy(base)
    data["semantics"] = {
        "remove": [{"id": "object_crate"}],
        "components": [
            {"id": "doorway_0", "kind": "doorway", "centre": [0.1, 0.0],
             "ends": [[-0.3, 0.0], [0.5, 0.0]]},
            {"id": "object_ghost", "kind": "object", "points": [[3, 3], [3, 4], [4, 4]]},
            {"id": "dock_here", "kind": "dock", "centre": [1.0, -1.0]},
        ],
    }  # fmt: skip
    comps = derive(data)
    by_id = {c.id: c for c in comps}
    assert "object_crate" not in by_id
    door = by_id["doorway_0"]
    assert np.allclose(door.centre, (0.1, 0.0)) and door.width == pytest.approx(0.8)
    assert np.allclose(np.abs(door.normal), (0.0, 1.0))
    assert len(of_kind(comps, "doorway")) == 1  # replaced, not added
    ghost = by_id["object_ghost"]
    assert np.allclose(ghost.centre, (10 / 3, 11 / 3)) and len(ghost.points) == 3
    assert by_id["dock_here"].kind == "dock"
    kinds = [COMPONENT_KINDS.index(c.kind) for c in comps]
    assert kinds == sorted(kinds)


@pytest.mark.parametrize(
    ("semantics", "field"),
    [
        ({"remove": [{"id": "gap_7"}]}, "semantics.remove[0].id"),
        (
            {"components": [{"id": "d", "kind": "doorway", "centre": [0, 0],
                             "ends": [[1, 1], [1, 1]]}]},
            "semantics.components[0].ends",
        ),
        ({"surface_spacing": 1e-6}, "semantics.surface_spacing"),
    ],
)  # fmt: skip
def test_bad_semantics_name_file_and_field(semantics, field):
    data = scene(walls=collinear_walls(0.9, 0.0), semantics=semantics)
    with pytest.raises(ValueError) as error:
        derive_components(parse_scenario(data, "room.toml"))
    message = str(error.value)
    assert message.startswith("room.toml: field '") and f"'{field}'" in message
    assert "\n" not in message


# ------------------------------------------------------------------------- determinism


def test_ids_are_deterministic_and_independent_of_element_order():
    walls = [
        *collinear_walls(0.8, 0.0, origin=(0.0, 0.0)),
        *[
            {**w, "name": w["name"] + "2"}
            for w in collinear_walls(0.95, math.pi / 2, origin=(8.0, 2.0))
        ],
    ]
    a = derive(scene(walls=walls))
    b = derive(scene(walls=walls))
    c = derive(scene(walls=list(reversed(walls))))
    assert [x.id for x in a] == [x.id for x in b]
    assert len({x.id for x in a}) == len(a)
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x.centre, y.centre) and np.array_equal(x.points, y.points)
    doors_a = {x.id: x.centre for x in of_kind(a, "doorway")}
    doors_c = {x.id: x.centre for x in of_kind(c, "doorway")}
    assert set(doors_a) == {"doorway_0", "doorway_1"} == set(doors_c)
    for key in doors_a:
        assert np.allclose(doors_a[key], doors_c[key])
    assert doors_a["doorway_0"][0] < doors_a["doorway_1"][0]  # numbered by centre x


# ------------------------------------------------------------------- shipped scenarios


@pytest.mark.parametrize("name", available_scenarios())
def test_every_shipped_scenario_derives_components(name):
    s = load_scenario(name)
    comps = derive_components(s)
    ids = [c.id for c in comps]
    assert len(set(ids)) == len(ids)
    assert {c.kind for c in comps} <= set(COMPONENT_KINDS)
    overridden = {o.id for o in s.semantics.components}
    lo, hi = s.semantics.passage_width
    for c in of_kind(comps, "doorway", "gap"):
        assert len(c.ends) == 2 and abs(np.linalg.norm(c.normal) - 1) < 1e-9
        if c.id not in overridden:
            assert lo - 1e-6 <= c.width <= hi + 1e-6
    assert len(of_kind(comps, "dock")) >= len(s.tables) - sum(
        r.startswith("dock_") for r in s.semantics.remove
    )
    assert all(len(c.points) for c in of_kind(comps, "object", "wall"))
    robot = in_robot_frame(comps, s.start)
    assert len(nearest_components(robot, 10)) == min(10, len(comps))


def test_lazy_robot_frame_components_equal_the_eager_ones(rng):
    from sim.semantics import RobotFrameComponents

    comps = derive_components(load_scenario("cluttered_room"))
    for _ in range(5):
        pose = Pose2D(*rng.uniform(0.0, 10.0, 2), float(rng.uniform(-math.pi, math.pi)))
        eager = in_robot_frame(comps, pose)
        lazy = RobotFrameComponents(comps, pose)
        assert len(lazy) == len(eager) and bool(lazy)
        assert "not yet computed" in repr(lazy)  # len and bool do not compute it
        for got, want in zip(lazy, eager, strict=True):
            assert (got.id, got.kind, got.source) == (want.id, want.kind, want.source)
            for field in ("centre", "points", "ends", "normal"):
                np.testing.assert_array_equal(getattr(got, field), getattr(want, field))
            assert got.width == want.width or (math.isnan(got.width) and math.isnan(want.width))
        assert lazy[0].id == eager[0].id and [c.id for c in lazy[-3:]] == [c.id for c in eager[-3:]]
        assert lazy.materialise() is lazy.materialise()  # computed once
        np.testing.assert_array_equal(target_distances(lazy), target_distances(eager))
        k = int(rng.integers(0, 12))
        assert [c.id for c in nearest_components(lazy, k)] == [
            c.id for c in nearest_components(eager, k)
        ]
    empty = RobotFrameComponents((), Pose2D(0.0, 0.0, 0.0))
    assert len(empty) == 0 and not empty and tuple(empty) == ()
    assert empty == () and empty == RobotFrameComponents((), Pose2D(1.0, 0.0, 0.0))


def test_target_points_equal_each_components_own(rng):
    from sim.semantics import RobotFrameComponents, target_points

    for name in available_scenarios():
        comps = derive_components(load_scenario(name))
        for _ in range(3):
            pose = Pose2D(*rng.uniform(-1.0, 12.0, 2), float(rng.uniform(-math.pi, math.pi)))
            seen = in_robot_frame(comps, pose)
            want = np.array([c.target_point() for c in seen]).reshape(-1, 2)
            # packed, lazy and plain: the same points, bit for bit (ties: the first)
            for as_given in (seen, RobotFrameComponents(comps, pose), tuple(seen)):
                np.testing.assert_array_equal(target_points(as_given), want)
            np.testing.assert_allclose(
                np.hypot(want[:, 0], want[:, 1]), target_distances(seen), rtol=1e-12
            )
    assert target_points(()).shape == (0, 2)


def test_robot_frame_components_offer_their_target_points(rng):
    from sim.semantics import RobotFrameComponents

    comps = derive_components(load_scenario("cluttered_room"))
    for _ in range(4):
        pose = Pose2D(*rng.uniform(-1.0, 12.0, 2), float(rng.uniform(-math.pi, math.pi)))
        lazy = RobotFrameComponents(comps, pose)
        want = np.array([c.target_point() for c in in_robot_frame(comps, pose)])
        got = lazy.target_points()
        assert got.shape == (len(comps), 2)
        np.testing.assert_array_equal(got, want)  # bit for bit, ties: the first point
    assert RobotFrameComponents((), Pose2D(0.0, 0.0, 0.0)).target_points().shape == (0, 2)


def test_robot_frame_components_give_single_components_and_targets_lazily(rng):
    """The contextual mode reads the target points and the ~10 chosen components of 58:
    neither builds the other components, and both equal the materialised ones."""
    from sim.semantics import RobotFrameComponents

    comps = derive_components(load_scenario("cluttered_room"))
    n = len(comps)
    for _ in range(4):
        pose = Pose2D(*rng.uniform(-1.0, 12.0, 2), float(rng.uniform(-math.pi, math.pi)))
        lazy = RobotFrameComponents(comps, pose)
        eager = in_robot_frame(comps, pose)
        np.testing.assert_array_equal(lazy.target_points(), [c.target_point() for c in eager])
        for i in [int(k) for k in rng.integers(0, n, 6)] + [-1, -n, n - 1]:
            got, want = lazy[i], eager[i]
            assert (got.id, got.kind, got.source) == (want.id, want.kind, want.source)
            for field in ("centre", "points", "ends", "normal"):
                np.testing.assert_array_equal(getattr(got, field), getattr(want, field))
        assert lazy[np.int64(3)].id == eager[3].id
        assert "not yet computed" in repr(lazy)  # no index nor the targets built them all
        with pytest.raises(IndexError):
            lazy[n]
        with pytest.raises(IndexError):
            lazy[-n - 1]
        assert [c.id for c in lazy[2:5]] == [c.id for c in eager[2:5]]  # slices: all
        assert "not yet" not in repr(lazy) and lazy[4] is lazy.materialise()[4]


def test_equal_scenarios_are_derived_once_and_as_before():
    from sim.semantics.derive import _derive

    a, b = load_scenario("cluttered_room"), load_scenario("cluttered_room")
    assert a is not b and derive_components(a) is derive_components(b)  # cached
    fresh = _derive(a)
    assert [c.id for c in fresh] == [c.id for c in derive_components(a)]
    for got, want in zip(derive_components(a), fresh, strict=True):
        for field in ("centre", "points", "ends", "normal"):
            assert np.array_equal(getattr(got, field), getattr(want, field))
        assert got.width == want.width or (math.isnan(got.width) and math.isnan(want.width))
    other = copy.deepcopy(a)
    object.__setattr__(other, "name", "cluttered_room_moved")  # any other content: derived anew
    assert derive_components(other) is not derive_components(a)
