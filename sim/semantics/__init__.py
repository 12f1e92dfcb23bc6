"""Semantic components of a scene, derived from its exact geometry (spec sections 3 and 6).

The candidate targets of the contextual tasks (thesis Sec. 5.1, 6.1, 7.6.1.2 and
Fig. 7.49) are doorways and gaps (centre point and two end points), the docking
place under a table (centre point), objects and wall segments (surface points).
The thesis found them in the SLAM map image with OpenCV (appendix, Alg. 4 and 5);
here the scene's polygons and circles are known exactly, so the same ideas are
applied to the geometry and any new scenario works without hand annotation.

Outlines. Walls, boxes and table legs are rectangles (``Box.corners()``),
cylinders circles.

Passages (Alg. 5). For every pair of outlines the closest points are found
(where the closest set is a stretch, e.g. two parallel faces, its midpoint is
taken, so a doorway between two collinear walls is centred). The pair is a
passage when

1. the clear distance lies in ``scenario.semantics.passage_width`` (Alg. 5
   line 16, inclusive, 1 nm tolerance);
2. the segment between the closest points crosses no other obstacle (the
   exact counterpart of the 95 % free-cells test, lines 21-29);
3. it is an opening, not the side of a corridor. The spec is silent on how to
   tell them apart; the rule here: lines parallel to the passage are probed
   every ``DEPTH_STEP_M`` (5 cm) along the crossing normal on both sides, each
   reaching ``width / 2 + CORRIDOR_PROBE_SLACK_M`` (0.2 m) either way from the
   passage's axis. The run of probes around the passage where both halves hit
   an obstacle is the passage's depth; deeper than ``MAX_PASSAGE_DEPTH_M``
   (0.7 m) and it is a corridor, not a passage. So a doorway in a wall, a gap
   beside a cylinder or beside a crate shorter than 0.8 m are passages, the
   two sides of a corridor are not, also when a side is made of several wall
   pieces (comparing only the two outlines would miss that);
4. its centre lies within the scenario's bounds, and the two outlines are not
   two legs of the same table (that opening is the dock).

A passage between two walls is a doorway; one with a free-standing obstacle
(box, cylinder, table leg) on at least one side is a gap. Passages whose
centres are closer than ``MERGE_DISTANCE_M`` (0.75 m, Alg. 5) are merged
(single linkage); of each group the narrowest is kept, as the binding
constriction, with its own kind and sources. Ids ``doorway_0..``/``gap_0..``
number each kind by centre x, then y. ``ends[i]`` lies on ``source[i]``;
``normal`` is the unit crossing direction, perpendicular to the ends,
oriented to +x (or +y when the passage runs along x).

Docks. One per table, ``dock_<table>``: the centre is the dock pose's position
when ``scenario.dock.table`` names the table, else the table's centre; the
normal is the approach direction (the dock pose's heading, else the table's x
axis). A dock has no surface points.

Objects (Alg. 4) and wall segments. Every box and cylinder is an object
``object_<name>`` with points along its whole outline; every wall is a wall
segment ``wall_<name>`` with points along its two long faces (both are
followable). Points are at most ``surface_spacing`` apart along each side
(corners included, so the sampling is exact at the corners). Decided here:
points strictly inside another obstacle (where a box stands against a wall,
where walls overlap at a corner) or outside the scenario bounds (the outer face
of an outer wall) are dropped, as no robot can reach them; a component left
without points is dropped.

Finally ``scenario.semantics.remove`` drops derived ids (an id that matches
nothing is an error: a typo must not pass silently) and
``scenario.semantics.components`` replace same-id components or add new ones.
Components come out ordered by kind (``COMPONENT_KINDS``), then as derived.

Speed. :func:`in_robot_frame` is called every control tick. The tuple returned
by :func:`derive_components` carries every coordinate of every component
stacked in one array, so a tick is a few vector operations plus slicing (about
0.1 ms for the 58 components of ``cluttered_room``); the arrays it hands out are
read-only views. Plain tuples are accepted too (stacked on the fly, slower). The
world does not even do that unless asked: ``Observation.components`` is a
:class:`RobotFrameComponents`, which calls :func:`in_robot_frame` when first read
(decided here: most modes never read the components, and the tick budget of a
synthetic study is about 1-2 ms).
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass

import numpy as np

from sim.scenario import Box, ComponentOverride, Scenario
from sim.types import COMPONENT_KINDS, Pose2D, SemanticComponent

MERGE_DISTANCE_M = 0.75  # Alg. 5: passages with closer centres are one passage
MAX_PASSAGE_DEPTH_M = 0.7  # a constriction deeper than this is a corridor [m]
DEPTH_STEP_M = 0.05  # resolution of the depth probe [m]
CORRIDOR_PROBE_SLACK_M = 0.2  # probe reach beyond the passage's half width [m]
_TIE_M = 1e-7  # closest-point candidates within this of the minimum are ties [m]
_EPS_M = 1e-6  # an obstacle is shrunk by this before a crossing test (grazing is free) [m]
_WIDTH_TOL_M = 1e-9
MAX_SURFACE_POINTS = 200_000  # refuse a spacing that would sample more (memory, speed)


# --------------------------------------------------------------------------- outlines


@dataclass(frozen=True, slots=True)
class _Shape:
    """One obstacle outline: a convex polygon (counter-clockwise) or a circle."""

    name: str
    is_wall: bool
    table: str  # the table a leg belongs to, "" otherwise
    polygon: np.ndarray | None  # (4, 2) [m] or None for a circle
    centre: np.ndarray  # (2,) [m]
    radius: float  # [m] circle radius, or the polygon's circumradius


def _box_shape(box: Box, table: str = "") -> _Shape:
    corners = box.corners()
    centre = np.asarray(box.centre, dtype=float)
    radius = float(np.max(np.linalg.norm(corners - centre, axis=1)))
    return _Shape(box.name, box.kind == "wall", table, corners, centre, radius)


def _shapes(scenario: Scenario) -> list[_Shape]:
    shapes = [_box_shape(b) for b in (*scenario.walls, *scenario.boxes)]
    shapes += [_box_shape(leg, t.name) for t in scenario.tables for leg in t.leg_boxes()]
    shapes += [
        _Shape(c.name, False, "", None, np.asarray(c.centre, dtype=float), c.radius)
        for c in scenario.cylinders
    ]
    return shapes


def _closest_on_edges(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Closest point on each edge of ``polygon`` (e, 2) to each point (k, 2) -> (k, e, 2)."""
    start = polygon
    edge = np.roll(polygon, -1, axis=0) - polygon
    rel = points[:, None, :] - start[None, :, :]
    t = np.clip(np.einsum("kei,ei->ke", rel, edge) / np.einsum("ei,ei->e", edge, edge), 0, 1)
    return start[None, :, :] + t[..., None] * edge[None, :, :]


def _inside_polygon(point: np.ndarray, polygon: np.ndarray) -> bool:
    edge = np.roll(polygon, -1, axis=0) - polygon
    rel = point - polygon
    return bool(np.all(edge[:, 0] * rel[:, 1] - edge[:, 1] * rel[:, 0] >= 0))


def _polygons_overlap(a: np.ndarray, b: np.ndarray) -> bool:
    """Separating-axis test for two convex polygons (touching counts as overlap)."""
    for poly in (a, b):
        edge = np.roll(poly, -1, axis=0) - poly
        for axis in np.column_stack((-edge[:, 1], edge[:, 0])):
            pa, pb = a @ axis, b @ axis
            if pa.max() < pb.min() or pb.max() < pa.min():
                return False
    return True


def _closest_points(a: _Shape, b: _Shape) -> tuple[float, np.ndarray, np.ndarray] | None:
    """Clear distance [m] and the closest points on ``a`` and ``b`` (2,), (2,) [m].

    ``None`` when the outlines touch or overlap. Where the closest points form a
    stretch (parallel faces), the midpoint of the stretch is returned.
    """
    if a.polygon is None and b.polygon is None:
        between = b.centre - a.centre
        gap = float(np.hypot(*between)) - a.radius - b.radius
        if gap <= 0:
            return None
        unit = between / np.hypot(*between)
        return gap, a.centre + a.radius * unit, b.centre - b.radius * unit
    if a.polygon is None or b.polygon is None:
        poly, circle = (a, b) if b.polygon is None else (b, a)
        if _inside_polygon(circle.centre, poly.polygon):
            return None
        cands = _closest_on_edges(circle.centre[None, :], poly.polygon)[0]
        dist = np.linalg.norm(cands - circle.centre, axis=1)
        p = cands[int(np.argmin(dist))]
        gap = float(dist.min()) - circle.radius
        if gap <= 0:
            return None
        q = circle.centre + circle.radius * (p - circle.centre) / dist.min()
        return (gap, p, q) if poly is a else (gap, q, p)
    if _polygons_overlap(a.polygon, b.polygon):
        return None
    # Between non-intersecting convex polygons the distance is attained at a vertex of one
    # of them; every (vertex, closest point on the other's edge) pair is a candidate.
    on_b = _closest_on_edges(a.polygon, b.polygon).reshape(-1, 2)
    on_a = _closest_on_edges(b.polygon, a.polygon).reshape(-1, 2)
    p_all = np.vstack((np.repeat(a.polygon, len(b.polygon), axis=0), on_a))
    q_all = np.vstack((on_b, np.repeat(b.polygon, len(a.polygon), axis=0)))
    dist = np.linalg.norm(q_all - p_all, axis=1)
    best = int(np.argmin(dist))
    gap = float(dist[best])
    offset = q_all[best] - p_all[best]  # unique for convex sets
    across = np.array([-offset[1], offset[0]]) / gap
    along = p_all[dist <= gap + _TIE_M] @ across
    p = p_all[best] + across * ((along.min() + along.max()) / 2 - p_all[best] @ across)
    return gap, p, p + offset


def _segment_hits(shape: _Shape, p: np.ndarray, q: np.ndarray, margin: float) -> bool:
    """Whether segment p-q meets ``shape`` grown by ``margin`` [m] (negative: shrunk, so
    that grazing does not count)."""
    if shape.polygon is None:
        d = q - p
        t = np.clip((shape.centre - p) @ d / (d @ d), 0.0, 1.0)
        return bool(np.hypot(*(p + t * d - shape.centre)) < shape.radius + margin)
    poly = shape.polygon
    edge = np.roll(poly, -1, axis=0) - poly
    inward = np.column_stack((-edge[:, 1], edge[:, 0])) / np.linalg.norm(edge, axis=1)[:, None]
    t_lo, t_hi = 0.0, 1.0  # Liang-Barsky clip against each half-plane
    for n, v in zip(inward, poly, strict=True):
        a0 = float(n @ (p - v)) + margin
        b0 = float(n @ (q - p))
        if abs(b0) < 1e-15:
            if a0 < 0:
                return False
            continue
        t0 = -a0 / b0
        if b0 > 0:
            t_lo = max(t_lo, t0)
        else:
            t_hi = min(t_hi, t0)
        if t_lo > t_hi:
            return False
    return True


def _any_hit(
    shapes: Sequence[_Shape], p: np.ndarray, q: np.ndarray, *, margin: float = -_EPS_M
) -> bool:
    mid, half = (p + q) / 2, float(np.hypot(*(q - p))) / 2
    return any(
        float(np.hypot(*(s.centre - mid))) <= s.radius + half + margin
        and _segment_hits(s, p, q, margin)
        for s in shapes
    )


# --------------------------------------------------------------------------- passages


@dataclass(frozen=True, slots=True)
class _Passage:
    kind: str
    centre: np.ndarray  # (2,) [m]
    ends: np.ndarray  # (2, 2) [m], ends[i] on source[i]
    width: float  # [m]
    source: tuple[str, str]


def _crossing_normal(ends: np.ndarray) -> np.ndarray:
    d = ends[1] - ends[0]
    n = np.array([-d[1], d[0]]) / np.hypot(*d)
    if n[0] < -1e-9 or (abs(n[0]) <= 1e-9 and n[1] < 0):
        n = -n
    n[np.abs(n) < 1e-12] = 0.0  # no -0.0 or 1e-17 residues in files and prints
    return n


def _passage_depth(shapes: Sequence[_Shape], centre: np.ndarray, ends: np.ndarray) -> float:
    """How far [m] along the crossing normal the opening stays hemmed in on both sides.

    Probe lines parallel to the passage at offsets of ``DEPTH_STEP_M`` along the
    normal, reaching ``width / 2 + CORRIDOR_PROBE_SLACK_M`` each way from the axis;
    the depth is the run of offsets around the passage where both halves hit an
    obstacle (grazing counts). Stops once the depth exceeds ``MAX_PASSAGE_DEPTH_M``.
    """
    along = (ends[1] - ends[0]) / np.hypot(*(ends[1] - ends[0]))
    normal = np.array([-along[1], along[0]])
    reach = np.hypot(*(ends[1] - ends[0])) / 2 + CORRIDOR_PROBE_SLACK_M
    limit = round(MAX_PASSAGE_DEPTH_M / DEPTH_STEP_M)  # count steps: no float drift
    steps = 0
    for side in (1.0, -1.0):
        k = 1
        while steps <= limit:
            origin = centre + side * k * DEPTH_STEP_M * normal
            if not (
                _any_hit(shapes, origin, origin + reach * along, margin=_EPS_M)
                and _any_hit(shapes, origin, origin - reach * along, margin=_EPS_M)
            ):
                break  # the space widens here
            k += 1
            steps += 1
    return steps * DEPTH_STEP_M


def _passages(scenario: Scenario, shapes: list[_Shape]) -> list[_Passage]:
    lo, hi = scenario.semantics.passage_width
    (x_min, y_min), (x_max, y_max) = scenario.bounds
    found: list[_Passage] = []
    for i, a in enumerate(shapes):
        for j in range(i + 1, len(shapes)):
            b = shapes[j]
            if a.table and a.table == b.table:
                continue  # between two legs of one table: the dock, not a gap
            if np.hypot(*(b.centre - a.centre)) - a.radius - b.radius > hi + _WIDTH_TOL_M:
                continue
            closest = _closest_points(a, b)
            if closest is None:
                continue
            width, p, q = closest
            if not lo - _WIDTH_TOL_M <= width <= hi + _WIDTH_TOL_M:  # Alg. 5, line 16
                continue
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


# --------------------------------------------------------------------- surface points


def _sample_edges(
    starts: np.ndarray, stops: np.ndarray, spacing: float, *, closed: bool = False
) -> np.ndarray:
    """Points along each segment, at most ``spacing`` apart (k, 2) [m].

    Both ends of each segment are included, unless ``closed`` (consecutive
    segments of an outline): then each segment's end is the next one's start.
    """
    out = []
    for a, b in zip(starts, stops, strict=True):
        n = max(1, math.ceil(float(np.hypot(*(b - a))) / spacing - 1e-9))
        t = np.linspace(0.0, 1.0, n + 1)
        out.append(a + (t[:-1] if closed else t)[:, None] * (b - a))
    return np.vstack(out)


def _outline_points(shape: _Shape, spacing: float) -> np.ndarray:
    if shape.polygon is None:
        n = max(8, math.ceil(2 * math.pi * shape.radius / spacing - 1e-9))
        angle = np.linspace(0.0, 2 * math.pi, n, endpoint=False)
        return shape.centre + shape.radius * np.column_stack((np.cos(angle), np.sin(angle)))
    poly = shape.polygon
    return _sample_edges(poly, np.roll(poly, -1, axis=0), spacing, closed=True)


def _wall_points(shape: _Shape, spacing: float) -> np.ndarray:
    poly = shape.polygon
    lengths = np.linalg.norm(np.roll(poly, -1, axis=0) - poly, axis=1)
    first = 0 if lengths[0] >= lengths[1] else 1  # the two long faces: edges first, first+2
    starts = poly[[first, first + 2]]
    stops = poly[[(first + 1) % 4, (first + 3) % 4]]
    return _sample_edges(starts, stops, spacing)


def _reachable(
    points: np.ndarray, own: _Shape, shapes: Sequence[_Shape], scenario: Scenario
) -> np.ndarray:
    """Drop points strictly inside another obstacle or outside the bounds."""
    (x_min, y_min), (x_max, y_max) = scenario.bounds
    keep = (
        (points[:, 0] >= x_min - 1e-9)
        & (points[:, 0] <= x_max + 1e-9)
        & (points[:, 1] >= y_min - 1e-9)
        & (points[:, 1] <= y_max + 1e-9)
    )
    for s in shapes:
        if s is own:
            continue
        near = np.linalg.norm(points - s.centre, axis=1) < s.radius + 1e-9
        if not near.any():
            continue
        if s.polygon is None:
            inside = np.linalg.norm(points - s.centre, axis=1) < s.radius - _EPS_M
        else:
            edge = np.roll(s.polygon, -1, axis=0) - s.polygon
            inward = np.column_stack((-edge[:, 1], edge[:, 0]))
            inward /= np.linalg.norm(edge, axis=1)[:, None]
            depth = np.einsum("kei,ei->ke", points[:, None, :] - s.polygon[None], inward)
            inside = np.all(depth > _EPS_M, axis=1)
        keep &= ~(near & inside)
    return points[keep]


# ------------------------------------------------------------------------ derivation


def _readonly(a: np.ndarray) -> np.ndarray:
    a = np.array(a, dtype=float)
    a.flags.writeable = False
    return a


def _component(
    id: str,
    kind: str,
    centre: np.ndarray,
    points: np.ndarray,
    *,
    ends: np.ndarray | None = None,
    width: float = math.nan,
    normal: np.ndarray | None = None,
    source: tuple[str, ...] = (),
) -> SemanticComponent:
    return SemanticComponent(
        id=id,
        kind=kind,
        centre=_readonly(centre),
        points=_readonly(np.asarray(points, dtype=float).reshape(-1, 2)),
        ends=_readonly(np.empty((0, 2)) if ends is None else ends),
        width=float(width),
        normal=_readonly(np.zeros(2) if normal is None else normal),
        source=source,
    )


def _check_budget(scenario: Scenario) -> None:
    spacing = scenario.semantics.surface_spacing
    length = sum(2 * max(w.size) for w in scenario.walls)
    length += sum(2 * (b.size[0] + b.size[1]) for b in scenario.boxes)
    length += sum(2 * math.pi * c.radius for c in scenario.cylinders)
    if length / spacing > MAX_SURFACE_POINTS:
        raise ValueError(
            f"{scenario.source or '<scenario>'}: field 'semantics.surface_spacing': "
            f"{spacing} m would give about {length / spacing:.0f} surface points, more than "
            f"{MAX_SURFACE_POINTS}; use at least {length / MAX_SURFACE_POINTS:.3g} m"
        )


def _derived(scenario: Scenario) -> list[SemanticComponent]:
    shapes = _shapes(scenario)
    _check_budget(scenario)
    spacing = scenario.semantics.surface_spacing
    out: list[SemanticComponent] = []

    passages = _passages(scenario, shapes)
    for kind in ("doorway", "gap"):
        mine = sorted(
            (p for p in passages if p.kind == kind),
            key=lambda p: (round(float(p.centre[0]), 9), round(float(p.centre[1]), 9)),
        )
        for k, p in enumerate(mine):
            out.append(
                _component(
                    f"{kind}_{k}",
                    kind,
                    p.centre,
                    p.ends,
                    ends=p.ends,
                    width=p.width,
                    normal=_crossing_normal(p.ends),
                    source=p.source,
                )
            )

    dock = scenario.dock
    for table in scenario.tables:
        if dock is not None and dock.table == table.name:
            centre, heading = (dock.pose.x, dock.pose.y), dock.pose.yaw
        else:
            centre, heading = table.centre, table.yaw
        normal = np.array([math.cos(heading), math.sin(heading)])
        out.append(
            _component(
                f"dock_{table.name}",
                "dock",
                np.asarray(centre),
                np.empty((0, 2)),
                normal=normal,
                source=(table.name,),
            )
        )

    by_name = {s.name: s for s in shapes}
    for element in (*scenario.boxes, *scenario.cylinders):
        shape = by_name[element.name]
        points = _reachable(_outline_points(shape, spacing), shape, shapes, scenario)
        if len(points):
            out.append(
                _component(
                    f"object_{element.name}",
                    "object",
                    shape.centre,
                    points,
                    source=(element.name,),
                )
            )
    for wall in scenario.walls:
        shape = by_name[wall.name]
        points = _reachable(_wall_points(shape, spacing), shape, shapes, scenario)
        if len(points):
            out.append(
                _component(f"wall_{wall.name}", "wall", shape.centre, points, source=(wall.name,))
            )
    return out


def _from_override(
    o: ComponentOverride, index: int, scenario: Scenario, replaced: SemanticComponent | None
) -> SemanticComponent:
    centre = np.asarray(o.centre, dtype=float)
    if o.kind in ("doorway", "gap"):
        ends = np.asarray(o.ends, dtype=float).reshape(2, 2)
        width = float(np.hypot(*(ends[1] - ends[0])))
        if width <= 0:
            raise ValueError(
                f"{scenario.source or '<scenario>'}: field 'semantics.components[{index}].ends': "
                f"the two end points must differ, got {ends.tolist()}"
            )
        return _component(
            o.id, o.kind, centre, ends, ends=ends, width=width, normal=_crossing_normal(ends)
        )
    if o.kind == "dock":
        if replaced is not None and replaced.kind == "dock":
            normal = replaced.normal
        elif scenario.dock is not None:
            normal = np.array([math.cos(scenario.dock.pose.yaw), math.sin(scenario.dock.pose.yaw)])
        else:
            normal = np.zeros(2)
        return _component(o.id, o.kind, centre, np.empty((0, 2)), normal=normal)
    return _component(o.id, o.kind, centre, np.asarray(o.points, dtype=float))


def derive_components(scenario: Scenario) -> tuple[SemanticComponent, ...]:
    """Every semantic component of ``scenario``, in the map frame.

    Deterministic: the same scenario always gives the same components, ids and
    order (by kind as in ``COMPONENT_KINDS``, then as derived; see the module
    docstring for the rules).

    Parameters
    ----------
    scenario : Scenario
        The validated scene; its ``semantics`` settings give the passage widths
        [m], the surface-point spacing [m], removals and overrides.

    Returns
    -------
    tuple of SemanticComponent
        Map-frame components with read-only arrays. The tuple also carries the
        stacked coordinates that make :func:`in_robot_frame` fast; keep it as
        returned (``tuple(...)`` of it still works, only slower).

    Raises
    ------
    ValueError
        When ``semantics.remove`` names an id that was not derived, or an
        override's two end points coincide; the message names the file and field.
    """
    components = _derived(scenario)
    ids = [c.id for c in components]
    source = scenario.source or "<scenario>"
    for k, rid in enumerate(scenario.semantics.remove):
        if rid not in ids:
            raise ValueError(
                f"{source}: field 'semantics.remove[{k}].id': no derived component has id "
                f"{rid!r}; derived: {', '.join(ids) or 'none'}"
            )
    removed = set(scenario.semantics.remove)
    components = [c for c in components if c.id not in removed]
    for k, override in enumerate(scenario.semantics.components):
        at = next((i for i, c in enumerate(components) if c.id == override.id), None)
        new = _from_override(override, k, scenario, None if at is None else components[at])
        if at is None:
            components.append(new)
        else:
            components[at] = new
    rank = {kind: i for i, kind in enumerate(COMPONENT_KINDS)}
    components.sort(key=lambda c: rank[c.kind])  # stable: derived order within a kind
    return _pack(components)


# ---------------------------------------------------------------- per-tick transform


_EMPTY = np.empty((0, 2))
_EMPTY.flags.writeable = False


@dataclass(frozen=True, slots=True)
class _Layout:
    """Where each component's coordinates sit in the stacked rows.

    Rows ``[0, n)`` hold the normals (rotated, never shifted), rows ``[n, 2n)``
    the centres, then every component's points and ends (a passage's points are
    its ends and share their rows).
    """

    n: int
    # per component: (id, kind, width, source, points rows or None, ends rows or None)
    items: tuple[tuple[str, str, float, tuple[str, ...], slice | None, slice | None], ...]
    target_rows: np.ndarray  # (m,) rows whose nearest is each component's target point
    target_starts: np.ndarray  # (n,) start of each component's run in target_rows


class _Packed(tuple):
    """A tuple of components that also carries their stacked coordinates.

    ``stacked`` (rows, 2) [m] holds every coordinate in the components' frame,
    ``x`` and ``y`` (rows,) [m] are its columns, contiguous; ``layout`` says
    which rows belong to which component. A tuple subclass, rather than a side
    table keyed by ``id()``, so the pack lives and dies with the tuple.
    """

    stacked: np.ndarray
    x: np.ndarray
    y: np.ndarray
    layout: _Layout


def _pack(components: Sequence[SemanticComponent]) -> _Packed:
    n = len(components)
    blocks = [np.asarray(c.normal, dtype=float).reshape(1, 2) for c in components]
    blocks += [np.asarray(c.centre, dtype=float).reshape(1, 2) for c in components]
    items, targets, starts = [], [], []
    row = 2 * n
    for i, c in enumerate(components):
        pts = np.asarray(c.points, dtype=float).reshape(-1, 2)
        ends = np.asarray(c.ends, dtype=float).reshape(-1, 2)
        pts_rows = ends_rows = None
        if len(ends):
            ends_rows = slice(row, row + len(ends))
            blocks.append(ends)
            row += len(ends)
        if len(pts) and ends_rows is not None and np.array_equal(pts, ends):
            pts_rows = ends_rows
        elif len(pts):
            pts_rows = slice(row, row + len(pts))
            blocks.append(pts)
            row += len(pts)
        starts.append(len(targets))
        if c.kind in ("object", "wall") and pts_rows is not None:
            targets.extend(range(pts_rows.start, pts_rows.stop))
        else:
            targets.append(n + i)
        items.append((c.id, c.kind, float(c.width), tuple(c.source), pts_rows, ends_rows))
    stacked = np.vstack(blocks) if blocks else np.empty((0, 2))
    layout = _Layout(
        n=n,
        items=tuple(items),
        target_rows=np.asarray(targets, dtype=np.intp),
        target_starts=np.asarray(starts, dtype=np.intp),
    )
    return _with_pack(_Packed(components), stacked, layout)


def _with_pack(packed: _Packed, stacked: np.ndarray, layout: _Layout) -> _Packed:
    stacked.flags.writeable = False
    packed.stacked, packed.layout = stacked, layout
    packed.x = np.ascontiguousarray(stacked[:, 0])
    packed.y = np.ascontiguousarray(stacked[:, 1])
    return packed


def in_robot_frame(
    components: Sequence[SemanticComponent], pose: Pose2D
) -> tuple[SemanticComponent, ...]:
    """The components as seen from a robot at ``pose`` (robot frame: x forward, y left).

    Equal to ``tuple(c.transformed(pose) for c in components)``, but all
    coordinates are transformed at once when ``components`` came from
    :func:`derive_components` (plain sequences are stacked first, slower).

    Parameters
    ----------
    components : sequence of SemanticComponent
        Components in the map frame.
    pose : Pose2D
        Robot pose in the map frame ([m], [m], [rad]).

    Returns
    -------
    tuple of SemanticComponent
        Robot-frame components, same order; their arrays are read-only views of
        one array. Feed it to :func:`nearest_components`.
    """
    components = _packed_or_plain(components)
    packed = components if isinstance(components, _Packed) else _pack(components)
    lay = packed.layout
    if lay.n == 0:
        return packed
    return _components_of(_transform_stacked(packed, pose), lay)


def _transform_stacked(packed: _Packed, pose: Pose2D) -> np.ndarray:
    """The stacked coordinates of ``packed`` (a layout with ``n > 0``) seen from ``pose``:
    (rows, 2) [m], read-only (the arithmetic of :func:`in_robot_frame`)."""
    n = packed.layout.n
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    x, y = packed.x, packed.y
    out = np.empty((len(x), 2))
    ox, oy = out[:, 0], out[:, 1]
    np.multiply(x, c, out=ox)  # the rotation of Pose2D.to_robot_frame
    ox += s * y
    np.multiply(y, c, out=oy)
    oy -= s * x
    ox[n:] -= c * pose.x + s * pose.y  # positions are shifted, normals (rows < n) are not
    oy[n:] -= -s * pose.x + c * pose.y
    out.flags.writeable = False
    return out


def _component_at(out: np.ndarray, lay: _Layout, i: int) -> SemanticComponent:
    """Component ``i`` of the layout ``lay`` on the stacked coordinates ``out`` (views)."""
    cid, kind, width, source, pts, ends = lay.items[i]
    return SemanticComponent(
        cid,
        kind,
        out[lay.n + i],
        _EMPTY if pts is None else out[pts],
        _EMPTY if ends is None else out[ends],
        width,
        out[i],
        source,
    )


def _components_of(out: np.ndarray, lay: _Layout) -> _Packed:
    """Every component of ``lay`` on ``out``, packed (see :func:`in_robot_frame`)."""
    result = _Packed(_component_at(out, lay, i) for i in range(lay.n))
    result.stacked, result.layout = out, lay
    result.x, result.y = out[:, 0], out[:, 1]
    return result


class RobotFrameComponents(Sequence[SemanticComponent]):
    """Map-frame components seen from a pose, put into the robot frame on first use.

    What ``World.sense`` hands out as ``Observation.components``: a read-only sequence
    equal to ``in_robot_frame(components, pose)``, but only computed (once) when an
    element is read or the sequence iterated. ``len`` does not compute it. Manual and
    reactive modes never look at the components, and a tick then does not pay for
    58 transformed components (about 0.1-0.2 ms). The contextual mode reads
    :meth:`target_points` and the ~10 components it chooses by index: both come from the
    transformed coordinates alone (one array operation), an integer index builds just
    that component (equal to the materialised one, a new object per call), so such a
    tick builds 11 components instead of 58. Iteration, slices and equality materialise.

    Parameters
    ----------
    components : sequence of SemanticComponent
        Components in the map frame (packed by :func:`derive_components` for speed).
    pose : Pose2D
        Robot pose in the map frame ([m], [m], [rad]).
    """

    __slots__ = ("_map", "_pose", "_seen", "_out")
    __hash__ = None  # type: ignore[assignment]  # like a tuple of array-holding components

    def __init__(self, components: Sequence[SemanticComponent], pose: Pose2D) -> None:
        self._map = components
        self._pose = pose
        self._seen: tuple[SemanticComponent, ...] | None = None
        self._out: np.ndarray | None = None  # the transformed stacked coordinates

    @property
    def pose(self) -> Pose2D:
        """The pose the components are seen from."""
        return self._pose

    def materialise(self) -> tuple[SemanticComponent, ...]:
        """The robot-frame components (computed on the first call)."""
        if self._seen is None:
            out = self._stacked()
            if out is None:
                self._seen = in_robot_frame(self._map, self._pose)
            else:
                self._seen = _components_of(out, self._map.layout)
        return self._seen

    def _stacked(self) -> np.ndarray | None:
        """The stacked robot-frame coordinates when the map components are packed with
        at least one component (else None), computed once."""
        if self._out is None:
            packed = self._map
            if not (isinstance(packed, _Packed) and packed.layout.n):
                return None
            self._out = _transform_stacked(packed, self._pose)
        return self._out

    def target_points(self) -> np.ndarray:
        """Every component's intentional target point ``s`` (n, 2) [m] in the robot frame.

        Equal to ``np.array([c.target_point() for c in self])`` (the module's
        :func:`target_points`, a few vector operations); for the contextual mode, which
        may not import ``sim`` and finds this method by duck typing.
        """
        if self._seen is None:
            out = self._stacked()
            if out is not None:  # no component objects needed (58 of them in a room)
                return _packed_target_points(out, self._map.layout)
        return target_points(self.materialise())

    def __len__(self) -> int:
        return len(self._map)

    def __getitem__(self, index):  # type: ignore[no-untyped-def]
        if self._seen is None and isinstance(index, int | np.integer):
            out = self._stacked()
            if out is not None:  # one component, equal to the materialised one
                n = self._map.layout.n
                i = int(index)
                if not -n <= i < n:
                    raise IndexError("RobotFrameComponents index out of range")
                return _component_at(out, self._map.layout, i % n)
        return self.materialise()[index]

    def __iter__(self) -> Iterator[SemanticComponent]:
        return iter(self.materialise())

    def __eq__(self, other: object) -> bool:
        if isinstance(other, RobotFrameComponents):
            other = other.materialise()
        if not isinstance(other, tuple):
            return NotImplemented
        return self.materialise() == other

    def __repr__(self) -> str:
        state = "computed" if self._seen is not None else "not yet computed"
        return f"RobotFrameComponents({len(self)} components seen from {self._pose}, {state})"


def _packed_or_plain(components: Sequence[SemanticComponent]) -> Sequence[SemanticComponent]:
    return components.materialise() if isinstance(components, RobotFrameComponents) else components


def target_points(components: Sequence[SemanticComponent]) -> np.ndarray:
    """Every component's intentional target point ``s`` (n, 2) [m], in their frame.

    Equal to ``np.array([c.target_point() for c in components])`` (the same nearest
    surface point, the first one on ties), in a few vector operations when the
    components came from :func:`in_robot_frame` or ``World.sense``: about 3 times
    faster for the 58 components (2,562 candidate points) of ``cluttered_room`` than
    one call per component (50 vs 170 us).
    """
    if isinstance(components, RobotFrameComponents):
        return components.target_points()
    if isinstance(components, _Packed) and components.layout.n:
        return _packed_target_points(components.stacked, components.layout)
    return np.array([c.target_point() for c in components], dtype=float).reshape(-1, 2)


def _packed_target_points(stacked: np.ndarray, lay: _Layout) -> np.ndarray:
    """:func:`target_points` of packed components from their stacked coordinates."""
    candidates = stacked[lay.target_rows]  # (m, 2)
    sq = np.einsum("ij,ij->i", candidates, candidates)
    lowest = np.minimum.reduceat(sq, lay.target_starts)
    counts = np.diff(np.append(lay.target_starts, len(sq)))
    at_min = np.flatnonzero(sq == np.repeat(lowest, counts))
    first = at_min[np.searchsorted(at_min, lay.target_starts)]  # first minimum per run
    return candidates[first]


def target_distances(components: Sequence[SemanticComponent]) -> np.ndarray:
    """Distance from the frame's origin to each component's target point (n,) [m].

    In the robot frame this is the distance from the robot's centre to the
    intentional target point ``s`` (spec section 3): a passage's or dock's centre,
    an object's or wall's nearest surface point.
    """
    components = _packed_or_plain(components)
    if isinstance(components, _Packed) and components.layout.n:
        lay = components.layout
        sq = np.einsum("ij,ij->i", components.stacked, components.stacked)
        return np.sqrt(np.minimum.reduceat(sq[lay.target_rows], lay.target_starts))
    return np.array([float(np.hypot(*c.target_point())) for c in components], dtype=float)


def nearest_components(
    components_robot_frame: Sequence[SemanticComponent], k: int
) -> tuple[SemanticComponent, ...]:
    """The ``k`` components whose target points are closest to the robot.

    Used to keep the recogniser's candidate budget (10 components per tick in
    DESIGN.md's benchmark).

    Parameters
    ----------
    components_robot_frame : sequence of SemanticComponent
        Components in the robot frame, e.g. from :func:`in_robot_frame`.
    k : int
        How many to keep, >= 0; all of them when there are fewer.

    Returns
    -------
    tuple of SemanticComponent
        At most ``k`` components, nearest first (ties keep the input order).
    """
    if k < 0:
        raise ValueError(f"k: must be zero or positive, got {k}")
    if not len(components_robot_frame):
        return ()
    components_robot_frame = _packed_or_plain(components_robot_frame)
    order = np.argsort(target_distances(components_robot_frame), kind="stable")[:k]
    return tuple(components_robot_frame[int(i)] for i in order)
