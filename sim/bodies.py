"""The pybullet bodies of a world: the static scene in compound bodies and the
holonomic robot (thesis Sec. 7.6.1.1)."""

from __future__ import annotations

import math

from sim._pybullet import pybullet as p
from sim.scenario import Scenario
from sim.sensors import Solid, scene_solids

# Collision filter groups: the scene collides with the robot, the robot only with the
# scene; pybullet's ray test (group 1 by default, mask SCENE_GROUP) then hits the scene
# but not the robot. The scene does not collide with itself: its static bodies would
# otherwise be checked against each other at every physics substep (walls meet at the
# corners).
_RAY_GROUP, _ROBOT_GROUP, SCENE_GROUP = 1, 2, 4
JOINTS = [0, 1, 2]  # the robot's prismatic x, prismatic y and revolute yaw joints
_FLOOR_RGBA = [0.78, 0.78, 0.75, 1.0]
_ROBOT_RGBA = [0.2, 0.3, 0.55, 1.0]
_COMPOUND_MAX = 16  # shapes per pybullet compound (more: cut silently, or a crash)


def _quat_yaw(yaw: float) -> list[float]:
    return [0.0, 0.0, math.sin(yaw / 2.0), math.cos(yaw / 2.0)]


def build_scene(scenario: Scenario, pb: dict[str, int]) -> dict[int, tuple[Solid, ...]]:
    """Static bodies of at most 16 solids each (pybullet's limit for one compound).

    Bullet revisits every body at every physics step, moving or not, so elements are
    grouped. The floor is visual only (no friction). Returns static body -> its solids.
    """
    (x0, y0), (x1, y1) = scenario.bounds
    floor = p.createVisualShape(
        p.GEOM_BOX,
        halfExtents=[(x1 - x0) / 2 + 1.0, (y1 - y0) / 2 + 1.0, 0.005],
        rgbaColor=_FLOOR_RGBA,
        **pb,
    )
    centre = [(x0 + x1) / 2, (y0 + y1) / 2, -0.005]
    p.createMultiBody(0.0, -1, floor, centre, useMaximalCoordinates=True, **pb)
    solids = scene_solids(scenario)
    groups: dict[int, tuple[Solid, ...]] = {}  # static body -> its solids
    for i in range(0, len(solids), _COMPOUND_MAX):
        group = solids[i : i + _COMPOUND_MAX]
        shape = {
            "shapeTypes": [p.GEOM_CYLINDER if e.radius else p.GEOM_BOX for e in group],
            "halfExtents": [[e.size[0] / 2, e.size[1] / 2, (e.z[1] - e.z[0]) / 2] for e in group],
            "radii": [e.radius for e in group],
            "lengths": [e.z[1] - e.z[0] for e in group],
        }
        positions = [[*e.centre, (e.z[0] + e.z[1]) / 2] for e in group]
        orientations = [_quat_yaw(e.yaw) for e in group]
        col = p.createCollisionShapeArray(
            **shape,
            collisionFramePositions=positions,
            collisionFrameOrientations=orientations,
            **pb,
        )
        vis = p.createVisualShapeArray(
            **shape,
            rgbaColors=[[*e.colour, 1.0] for e in group],
            visualFramePositions=positions,
            visualFrameOrientations=orientations,
            **pb,
        )
        # maximal coordinates: a static rigid body, skipped by the solver
        body = p.createMultiBody(0.0, col, vis, [0.0, 0.0, 0.0], useMaximalCoordinates=True, **pb)
        p.setCollisionFilterGroupMask(body, -1, SCENE_GROUP, _RAY_GROUP | _ROBOT_GROUP, **pb)
        groups[body] = group
    return groups


def build_robot(scenario: Scenario, pb: dict[str, int]) -> int:
    """The robot's multibody: prismatic x, prismatic y and revolute yaw joints (two
    massless dummy links), the last link the robot's box; no damping, no friction.

    Bullet multiplies the two bodies' friction coefficients, so the robot's zero makes
    every contact frictionless: the box slides along what it touches, and a turn that
    presses its corners against an obstacle does not lock its translation.
    """
    r = scenario.robot
    half = [r.length / 2, r.width / 2, r.height / 2]
    col = p.createCollisionShape(p.GEOM_BOX, halfExtents=half, **pb)
    vis = p.createVisualShape(p.GEOM_BOX, halfExtents=half, rgbaColor=_ROBOT_RGBA, **pb)
    ident = [0.0, 0.0, 0.0, 1.0]
    body = p.createMultiBody(
        0.0,
        -1,
        -1,
        [0.0, 0.0, 0.0],
        ident,
        linkMasses=[0.0, 0.0, r.mass],
        linkCollisionShapeIndices=[-1, -1, col],
        linkVisualShapeIndices=[-1, -1, vis],
        # the box floats 1 mm above the (visual) floor: no contact with it
        linkPositions=[[0.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, r.height / 2 + 0.001]],
        linkOrientations=[ident] * 3,
        linkInertialFramePositions=[[0.0, 0.0, 0.0]] * 3,
        linkInertialFrameOrientations=[ident] * 3,
        linkParentIndices=[0, 1, 2],
        linkJointTypes=[p.JOINT_PRISMATIC, p.JOINT_PRISMATIC, p.JOINT_REVOLUTE],
        linkJointAxis=[[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        **pb,
    )
    for j in JOINTS:
        p.changeDynamics(
            body,
            j,
            linearDamping=0.0,
            angularDamping=0.0,
            jointDamping=0.0,
            lateralFriction=0.0,
            **pb,
        )
        p.setCollisionFilterGroupMask(body, j, _ROBOT_GROUP, SCENE_GROUP, **pb)
    return body
