"""Issue 25: the robot-frame semantic components' compiled kernels (the transform of the
stacked coordinates, the target points) equal numpy's formulation before them
(tests/robot_frame_reference.py) bit for bit."""

from __future__ import annotations

import math

import numpy as np

from sim.scenario import available_scenarios, load_scenario
from sim.semantics import RobotFrameComponents, derive_components, in_robot_frame
from sim.semantics.robot_frame import _nearest_rows, _rotate_shift, _transform_stacked
from sim.types import Pose2D
from tests.robot_frame_reference import packed_target_points, transform_stacked


def _pose(rng: np.random.Generator) -> Pose2D:
    x, y = rng.uniform(-2.0, 14.0, 2)
    return Pose2D(float(x), float(y), float(rng.uniform(-4.0, 4.0)))


def test_transform_and_target_points_of_every_scene_equal_the_reference(rng):
    for name in available_scenarios():
        packed = in_robot_frame(derive_components(load_scenario(name)), Pose2D(0.0, 0.0, 0.0))
        lay = packed.layout
        if not lay.n:
            continue
        x, y = (
            np.ascontiguousarray(packed.stacked[:, 0]),
            np.ascontiguousarray(packed.stacked[:, 1]),
        )
        for _ in range(40):
            pose = _pose(rng)
            want = transform_stacked(x, y, lay.n, pose)
            got = _transform_stacked(packed, pose)
            assert np.array_equal(got, want) and not got.flags.writeable
            lazy = RobotFrameComponents(packed, pose)
            targets = packed_target_points(want, lay.target_rows, lay.target_starts)
            assert np.array_equal(lazy.target_points(), targets)


def test_kernels_equal_the_reference_on_random_rows(rng):
    for _ in range(300):
        rows = int(rng.integers(1, 400))
        stacked = rng.normal(0.0, 10.0 ** rng.uniform(-3, 3), (rows, 2))
        if rng.random() < 0.3:  # ties between the nearest rows
            stacked = np.round(stacked, 1)
        n = int(rng.integers(0, rows + 1))
        pose = _pose(rng)
        c, s = math.cos(pose.yaw), math.sin(pose.yaw)
        got = _rotate_shift(stacked, n, c, s, c * pose.x + s * pose.y, -s * pose.x + c * pose.y)
        want = transform_stacked(stacked[:, 0].copy(), stacked[:, 1].copy(), n, pose)
        assert np.array_equal(got, want)
        sizes = rng.integers(1, 20, int(rng.integers(1, 30)))
        target_rows = rng.integers(0, rows, int(sizes.sum()))
        starts = np.cumsum(np.concatenate(([0], sizes[:-1])))
        assert np.array_equal(
            _nearest_rows(got, target_rows, starts),
            packed_target_points(got, target_rows, starts),
        )


def test_a_component_built_field_by_field_equals_the_constructed_one(rng):
    import dataclasses

    from sim.semantics.robot_frame import _component_at
    from sim.types import SemanticComponent

    for name in available_scenarios():
        packed = in_robot_frame(derive_components(load_scenario(name)), Pose2D(0.0, 0.0, 0.0))
        lay = packed.layout
        out = _transform_stacked(packed, _pose(rng)) if lay.n else None
        for i in range(lay.n):
            cid, kind, width, source, pts, ends = lay.items[i]
            empty = np.empty((0, 2))
            want = SemanticComponent(
                cid,
                kind,
                out[lay.n + i],
                empty if pts is None else out[pts],
                empty if ends is None else out[ends],
                width,
                out[i],
                source,
            )
            got = _component_at(out, lay, i)
            assert type(got) is SemanticComponent
            for field in dataclasses.fields(SemanticComponent):
                g, w = getattr(got, field.name), getattr(want, field.name)
                if isinstance(w, np.ndarray):
                    assert np.array_equal(g, w) and g.shape == w.shape
                else:
                    assert g == w or (g != g and w != w)  # NaN widths


def test_ids_without_building_components(rng):
    """``ids()`` of the robot-frame components and of a plain candidate list are the ids of
    the components, in index order, and reading them computes nothing."""
    from autonomy.types import as_candidates

    for name in available_scenarios():
        packed = in_robot_frame(derive_components(load_scenario(name)), Pose2D(0.0, 0.0, 0.0))
        lazy = RobotFrameComponents(packed, _pose(rng))
        ids = lazy.ids()
        assert not lazy.prepared
        assert list(ids) == [str(c.id) for c in lazy.materialise()]
        assert as_candidates(list(lazy.materialise())).ids() == ids
        plain = RobotFrameComponents(tuple(lazy.materialise()), lazy.pose)
        assert plain.ids() == ids
