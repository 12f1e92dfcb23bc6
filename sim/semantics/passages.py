"""Passages between obstacle outlines: doorways and gaps (thesis appendix Alg. 5).

For every pair of outlines the closest points are found (the midpoint of a stretch
of closest points, so a doorway between collinear walls is centred). The pair is a
passage when its clear width lies in ``scenario.semantics.passage_width`` (line 16),
the segment between the closest points crosses no other obstacle (the exact
counterpart of the 95 % free-cells test, lines 21-29), it is an opening rather than
the side of a corridor (:func:`_passage_depth`), for a gap the robot fits on both sides
of it (:func:`_traversable`: a dead-end pocket beside furniture is no passage; a doorway
in a wall stays one even when something blocks it), its centre lies within the bounds,
and the two outlines are not two legs of one table (that opening is the dock) nor two
boxes of one group (parts of one obstacle, as a map's blob).
Between two walls it is a doorway; with a free-standing obstacle on a side, a gap.
Passages closer than ``MERGE_DISTANCE_M`` are merged, keeping the narrowest.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from sim.scenario import Scenario
from sim.semantics.outlines import (
    _EPS_M,
    _any_hit,
    _clearance,
    _closest_points,
    _Shape,
    _shapes,
)
from sim.types import SemanticComponent

MERGE_DISTANCE_M = 0.75  # Alg. 5: passages with closer centres are one passage
MAX_PASSAGE_DEPTH_M = 0.7  # a constriction deeper than this is a corridor [m]
DEPTH_STEP_M = 0.05  # resolution of the depth probe [m]
CORRIDOR_PROBE_SLACK_M = 0.2  # probe reach beyond the passage's half width [m]
SIDE_PROBE_SLACK_M = 0.1  # the side probes lie this far beyond half the robot's length [m]
_WIDTH_TOL_M = 1e-9


@dataclass(frozen=True, slots=True)
class _Passage:
    kind: str
    centre: np.ndarray  # (2,) [m]
    ends: np.ndarray  # (2, 2) [m], ends[i] on source[i]
    width: float  # [m]
    source: tuple[str, str]


def _crossing_normal(ends: np.ndarray) -> np.ndarray:
    """Unit crossing direction (2,) perpendicular to ``ends`` (2, 2) [m], oriented to +x
    (or +y when the passage runs along x); ``ends[i]`` lies on ``source[i]``."""
    d = ends[1] - ends[0]
    n = np.array([-d[1], d[0]]) / np.hypot(*d)
    if n[0] < -1e-9 or (abs(n[0]) <= 1e-9 and n[1] < 0):
        n = -n
    n[np.abs(n) < 1e-12] = 0.0  # no -0.0 or 1e-17 residues in files and prints
    return n


def _side_steps(
    shapes: Sequence[_Shape], centre: np.ndarray, ends: np.ndarray, side: float, cap: int
) -> int:
    """Probe lines parallel to the passage, ``DEPTH_STEP_M`` apart along the crossing
    normal on ``side`` (+1 or -1 times ``ends``' left normal), reaching ``width / 2 +
    CORRIDOR_PROBE_SLACK_M`` each way from the axis: how many in a row from the passage
    find an obstacle in both halves (grazing counts), at most ``cap``."""
    along = (ends[1] - ends[0]) / np.hypot(*(ends[1] - ends[0]))
    normal = np.array([-along[1], along[0]])
    reach = np.hypot(*(ends[1] - ends[0])) / 2 + CORRIDOR_PROBE_SLACK_M
    steps = 0
    while steps < cap:
        origin = centre + side * (steps + 1) * DEPTH_STEP_M * normal
        if not (
            _any_hit(shapes, origin, origin + reach * along, margin=_EPS_M)
            and _any_hit(shapes, origin, origin - reach * along, margin=_EPS_M)
        ):
            break  # the space widens here
        steps += 1
    return steps


def _passage_depth(shapes: Sequence[_Shape], centre: np.ndarray, ends: np.ndarray) -> float:
    """How far [m] along the crossing normal the opening stays hemmed in on both sides:
    the runs of :func:`_side_steps` on the two sides together. Stops once the depth
    exceeds ``MAX_PASSAGE_DEPTH_M``."""
    limit = round(MAX_PASSAGE_DEPTH_M / DEPTH_STEP_M)  # count steps: no float drift
    steps = _side_steps(shapes, centre, ends, 1.0, limit + 1)
    steps += _side_steps(shapes, centre, ends, -1.0, limit + 1 - steps)
    return steps * DEPTH_STEP_M


def passage_extent(scenario: Scenario, component: SemanticComponent) -> tuple[float, float]:
    """How far [m] a doorway or gap stays hemmed in behind and ahead of its centre along
    its crossing normal (``component.normal``, map frame): beyond ``centre + ahead *
    normal`` the space widens (to ``DEPTH_STEP_M``; the probes of :func:`_passage_depth`).
    A footprint whose rear is past that line is through the passage."""
    if component.kind not in ("doorway", "gap"):
        raise ValueError(
            f"passage_extent: component {component.id!r} is a {component.kind}, not a "
            "doorway or gap"
        )
    shapes = _shapes(scenario)
    ends = np.asarray(component.ends, dtype=float)
    centre = np.asarray(component.centre, dtype=float)
    left = np.array([-(ends[1] - ends[0])[1], (ends[1] - ends[0])[0]])
    sign = 1.0 if float(left @ np.asarray(component.normal)) >= 0 else -1.0
    cap = 10 * round(MAX_PASSAGE_DEPTH_M / DEPTH_STEP_M)
    behind = _side_steps(shapes, centre, ends, -sign, cap) + 1
    ahead = _side_steps(shapes, centre, ends, sign, cap) + 1
    return round(behind * DEPTH_STEP_M, 9), round(ahead * DEPTH_STEP_M, 9)


def _traversable(
    scenario: Scenario, shapes: Sequence[_Shape], centre: np.ndarray, ends: np.ndarray
) -> bool:
    """Whether the robot fits on both sides of the opening: a disc of half its width is
    free at half its length plus ``SIDE_PROBE_SLACK_M`` from ``centre`` along the crossing
    normal, each way (not in Alg. 5; docs/decisions.md)."""
    reach = scenario.robot.length / 2 + SIDE_PROBE_SLACK_M
    half_width = scenario.robot.width / 2
    normal = _crossing_normal(ends)
    return all(
        _clearance(centre + side * reach * normal, shapes) >= half_width for side in (1.0, -1.0)
    )


def _obstacle(shape: _Shape) -> str:
    """The obstacle a shape is part of for the closest-parts rule: its group (a map's
    blob), else the shape itself (a table's legs stay apart: an opening beside one leg is
    as it was before groups existed)."""
    return shape.part_of if shape.part_of.startswith("group ") else f"shape {shape.name}"


def _close_pairs(
    shapes: list[_Shape], hi: float
) -> tuple[list[tuple[int, int, float, np.ndarray, np.ndarray]], dict[tuple[str, str], float]]:
    """Pairs of shapes of different obstacles less than ``hi`` [m] apart, as ``(i, j,
    width, p, q)``, and the clear width between each pair of obstacles (0 if they touch):
    an obstacle of several parts (a group's boxes) counts as one, so only the closest
    parts of two obstacles bound an opening between them."""
    pairs, between = [], {}
    for i, a in enumerate(shapes):
        for j in range(i + 1, len(shapes)):
            b = shapes[j]
            if a.part_of and a.part_of == b.part_of:
                continue  # two legs of one table (the dock), two boxes of one group
            if np.hypot(*(b.centre - a.centre)) - a.radius - b.radius > hi + _WIDTH_TOL_M:
                continue
            key = tuple(sorted((_obstacle(a), _obstacle(b))))
            closest = _closest_points(a, b)
            width = 0.0 if closest is None else closest[0]
            between[key] = min(between.get(key, np.inf), width)
            if closest is not None:
                pairs.append((i, j, *closest))
    return pairs, between


def _passages(scenario: Scenario, shapes: list[_Shape]) -> list[_Passage]:
    lo, hi = scenario.semantics.passage_width
    (x_min, y_min), (x_max, y_max) = scenario.bounds
    found: list[_Passage] = []
    pairs, between = _close_pairs(shapes, hi)
    for i, j, width, p, q in pairs:
        a, b = shapes[i], shapes[j]
        if not lo - _WIDTH_TOL_M <= width <= hi + _WIDTH_TOL_M:  # Alg. 5, line 16
            continue
        if width > between[tuple(sorted((_obstacle(a), _obstacle(b))))] + _WIDTH_TOL_M:
            continue  # other parts of the two obstacles are closer
        centre = (p + q) / 2
        if not (x_min <= centre[0] <= x_max and y_min <= centre[1] <= y_max):
            continue
        others = [s for k, s in enumerate(shapes) if k not in (i, j)]
        if _any_hit(others, p, q):  # Alg. 5, lines 21-29: the opening must be free
            continue
        ends = np.vstack((p, q))
        if _passage_depth(shapes, centre, ends) > MAX_PASSAGE_DEPTH_M + 1e-9:
            continue  # the side of a corridor, not an opening
        kind = "doorway" if a.is_wall and b.is_wall else "gap"
        if kind == "gap" and not _traversable(scenario, shapes, centre, ends):
            continue  # a pocket beside furniture the robot can enter at most
        found.append(_Passage(kind, centre, ends, width, (a.name, b.name)))
    return _merge(found)


def _merge(passages: list[_Passage]) -> list[_Passage]:
    """Merge passages with centres closer than ``MERGE_DISTANCE_M`` (Alg. 5), keep the
    narrowest of each single-linkage group."""
    parent = list(range(len(passages)))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, a in enumerate(passages):
        for j in range(i + 1, len(passages)):
            if np.hypot(*(passages[j].centre - a.centre)) < MERGE_DISTANCE_M:
                parent[root(j)] = root(i)
    groups: dict[int, list[int]] = {}
    for i in range(len(passages)):
        groups.setdefault(root(i), []).append(i)
    return [passages[min(g, key=lambda k: (passages[k].width, k))] for g in groups.values()]
