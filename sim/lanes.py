"""Straight, centred lanes through the doorways and gaps of a scene (issue 19): where a
driver who heads straight through a passage, centred on its axis, starts, how far they
drive until the whole footprint is past it, and how much room the lane leaves on the way
and beyond its end. Tests drive these lanes in every mode; the geometry is the scene
checker's (:mod:`sim.check`: exact oriented rectangles and circles).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from sim.check import CheckSettings, _hits, _Obstacles, _obstacles, _sweep
from sim.scene import Scenario
from sim.semantics import derive_components, passage_extent
from sim.types import Pose2D, SemanticComponent

_MAX_LANE_CLEARANCE_M = 0.5  # [m] a lane's clearance is measured up to this
_MAX_RUN_OUT_M = 1.0  # [m] and its run-out past the end


@dataclass(frozen=True, slots=True)
class StraightLane:
    """A straight, centred drive through a doorway or gap from one side: the robot at
    rest on the passage's axis, facing through it, driven straight ahead."""

    component: str  # the passage's id
    side: float  # +1: along the component's crossing normal; -1: against it
    start: Pose2D  # ``approach_m`` before the passage's centre, facing through
    through_m: float  # [m] travel from ``start`` until the whole footprint is past it
    clearance_m: float  # [m] least gap between the footprint and any obstacle on the way
    run_out_m: float  # [m] how far it could drive on past the end (at most 1 m)


def _near(obs: _Obstacles, centre: np.ndarray, radius: float) -> _Obstacles:
    """The obstacles of ``obs`` that may reach within ``radius`` [m] of ``centre``."""
    box = np.hypot(*(obs.box_centre - centre).T) - np.hypot(*obs.box_half.T) <= radius
    cyl = np.hypot(*(obs.cyl_centre - centre).T) - obs.cyl_radius <= radius
    return _Obstacles(
        box_names=tuple(n for n, k in zip(obs.box_names, box, strict=True) if k),
        box_centre=obs.box_centre[box],
        box_axis=obs.box_axis[box],
        box_half=obs.box_half[box],
        cyl_names=tuple(n for n, k in zip(obs.cyl_names, cyl, strict=True) if k),
        cyl_centre=obs.cyl_centre[cyl],
        cyl_radius=obs.cyl_radius[cyl],
    )


def _sweep_clearance(obs: _Obstacles, poses: np.ndarray, half: np.ndarray) -> float:
    """Least gap [m] between the footprint at ``poses`` and the obstacles, to 0.1 mm and
    at most ``_MAX_LANE_CLEARANCE_M`` (the footprint grown with square corners: a lower
    bound); 0 when it overlaps one."""
    lo, hi = 0.0, _MAX_LANE_CLEARANCE_M
    if _hits(obs, poses, half).any():
        return lo
    if not _hits(obs, poses, half + hi).any():
        return hi
    while hi - lo > 1e-4:
        mid = (lo + hi) / 2
        lo, hi = (lo, mid) if _hits(obs, poses, half + mid).any() else (mid, hi)
    return lo


def straight_lanes(
    scenario: Scenario,
    *,
    approach_m: tuple[float, float] = (0.8, 1.2),
    components: tuple[SemanticComponent, ...] | None = None,
    settings: CheckSettings | None = None,
) -> list[StraightLane]:
    """Both straight, centred lanes through every doorway and gap of ``scenario``.

    A lane starts on the passage's axis before its centre and ends when the footprint's
    rear is past the passage (:func:`sim.semantics.passage_extent`); its ``clearance_m``
    is the least gap between the footprint and the scene on the way (0: no straight,
    centred pass from that side). The start is the farthest of ``approach_m`` =
    (nearest, farthest) [m], in steps of ``settings.sweep_step_m``, whose lane keeps the
    robot's protective margin, else the farthest. Components as given, the side along
    the normal first.
    """
    s = CheckSettings() if settings is None else settings
    comps = derive_components(scenario) if components is None else components
    obstacles = _obstacles(scenario)
    out = []
    for comp in comps:
        if comp.kind not in ("doorway", "gap"):
            continue
        behind, ahead = passage_extent(scenario, comp)
        for side, beyond in ((1.0, ahead), (-1.0, behind)):
            out.append(_lane(scenario, obstacles, comp, side, beyond, approach_m, s))
    return out


def _lane(
    scenario: Scenario,
    obstacles: _Obstacles,
    comp: SemanticComponent,
    side: float,
    beyond: float,
    approach_m: tuple[float, float],
    s: CheckSettings,
) -> StraightLane:
    """The lane through ``comp`` from ``side`` until the rear is ``beyond`` [m] past its
    centre (see :func:`straight_lanes`)."""
    half = np.array([scenario.robot.length, scenario.robot.width]) / 2
    normal = side * np.asarray(comp.normal, dtype=float)
    yaw = math.atan2(normal[1], normal[0])
    near, far = approach_m
    centre = np.asarray(comp.centre, dtype=float)
    end = centre + (beyond + half[0]) * normal
    poses = _sweep(centre - far * normal, end, yaw, s.sweep_step_m)
    reach = (far + beyond + half[0]) / 2 + float(np.hypot(*half)) + _MAX_LANE_CLEARANCE_M
    obs = _near(obstacles, (centre - far * normal + end) / 2, reach)
    # the farthest start in [near, far] after which the lane keeps the protective margin,
    # else the farthest
    blocked = _hits(obs, poses, half + scenario.robot.protective_margin).any(axis=1)
    ahead = (poses[:, :2] - centre) @ normal  # [m] signed, along the lane
    last = np.flatnonzero(blocked)[-1] if blocked.any() else -1
    free_from = -far if last < 0 else float(ahead[min(last + 1, len(ahead) - 1)])
    approach = -free_from if -free_from >= near - 1e-9 else far
    keep = ahead >= -approach - 1e-9
    return StraightLane(
        component=comp.id,
        side=side,
        start=Pose2D(*(centre - approach * normal).tolist(), yaw),
        through_m=float(approach + beyond + half[0]),
        clearance_m=_sweep_clearance(obs, poses[keep], half),
        run_out_m=_run_out(obstacles, end, normal, half, s.sweep_step_m),
    )


def _run_out(
    obstacles: _Obstacles, end: np.ndarray, normal: np.ndarray, half: np.ndarray, step: float
) -> float:
    """How far [m] the footprint at ``end`` heading along ``normal`` can drive straight
    on before it touches an obstacle, to ``step``, at most ``_MAX_RUN_OUT_M``."""
    yaw = math.atan2(normal[1], normal[0])
    poses = _sweep(end, end + _MAX_RUN_OUT_M * normal, yaw, step)
    reach = _MAX_RUN_OUT_M / 2 + float(np.hypot(*half))
    hit = _hits(_near(obstacles, end + _MAX_RUN_OUT_M / 2 * normal, reach), poses, half)
    first = np.flatnonzero(hit.any(axis=1))
    return _MAX_RUN_OUT_M if not len(first) else float((poses[first[0], :2] - end) @ normal)
