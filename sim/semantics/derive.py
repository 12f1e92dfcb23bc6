"""The semantic components of a scenario, derived from its exact geometry
(thesis Sec. 5.1, 6.1, 7.6.1.2, Fig. 7.49; appendix Alg. 4 and 5).

Passages (:mod:`sim.semantics.passages`) become doorways and gaps; every table a
dock ``dock_<table>``; every box and cylinder an object ``object_<name>`` with points
along its outline; every wall a wall segment ``wall_<name>`` with points along its
two long faces, at most ``surface_spacing`` apart (corners included). Then
``scenario.semantics.remove`` and ``scenario.semantics.components`` apply.
"""

from __future__ import annotations

import dataclasses
import math
import pickle
from collections.abc import Sequence

import numpy as np

from sim.scenario import ComponentOverride, Scenario
from sim.semantics.map_image import map_surface_components, prepare_map, scenario_map
from sim.semantics.map_passages import map_passages
from sim.semantics.outlines import _EPS_M, _Shape, _shapes
from sim.semantics.passages import _crossing_normal, _Passage, _passages
from sim.semantics.robot_frame import _pack
from sim.types import COMPONENT_KINDS, SemanticComponent

MAX_SURFACE_POINTS = 200_000  # refuse a spacing that would sample more (memory, speed)
# derived components by the scenario's content (its pickle): the engine, the scene check
# and each synthetic participant derive the same scenes, about 0.3-0.5 s each
_DERIVED: dict[bytes, tuple[SemanticComponent, ...]] = {}
_MAX_DERIVED = 32


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


def _passage_components(passages: list[_Passage]) -> list[SemanticComponent]:
    """Doorways, then gaps; ids ``doorway_0..``/``gap_0..`` numbered by centre x, then y."""
    out: list[SemanticComponent] = []
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
    return out


def _dock_components(scenario: Scenario) -> list[SemanticComponent]:
    """One dock per table, without surface points.

    The centre is the dock pose's position when ``scenario.dock.table`` names the
    table, else the table's centre; the normal is the approach direction (the dock
    pose's heading, else the table's x axis).
    """
    out: list[SemanticComponent] = []
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
    return out


def _surface_components(scenario: Scenario, shapes: list[_Shape]) -> list[SemanticComponent]:
    """Objects (boxes, cylinders: the whole outline), then walls (the two long faces);
    a component left without reachable points is dropped."""
    spacing = scenario.semantics.surface_spacing
    out: list[SemanticComponent] = []
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


def _map_components(scenario: Scenario) -> list[SemanticComponent]:
    """Doorways, gaps, docks, objects and walls with ``[semantics] source = "map"``: all
    but the docks (the tables, known exactly) from the map image."""
    image = prepare_map(scenario_map(scenario), scenario.tables)
    out = _passage_components(map_passages(image, scenario)) + _dock_components(scenario)
    counts = {"object": 0, "wall": 0}
    for kind, points, names in map_surface_components(image, scenario):
        centre = points.mean(axis=0)
        out.append(_component(f"{kind}_{counts[kind]}", kind, centre, points, source=names))
        counts[kind] += 1
    return out


def _derived(scenario: Scenario) -> list[SemanticComponent]:
    if scenario.semantics.source == "map":
        return _map_components(scenario)
    shapes = _shapes(scenario)
    _check_budget(scenario)
    return (
        _passage_components(_passages(scenario, shapes))
        + _dock_components(scenario)
        + _surface_components(scenario, shapes)
    )


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
    docstring for the rules). ``scenario.semantics.remove`` drops derived ids (an
    id that matches nothing is an error: a typo must not pass silently);
    ``scenario.semantics.components`` replace same-id components or add new ones.

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
        returned (``tuple(...)`` of it still works, only slower). Derived once per
        process for equal scenarios (the same pickle): later calls return that tuple.

    Raises
    ------
    ValueError
        When ``semantics.remove`` names an id that was not derived, or an
        override's two end points coincide; the message names the file and field.
    """
    try:
        key = pickle.dumps(scenario, protocol=pickle.HIGHEST_PROTOCOL)
    except (pickle.PicklingError, TypeError, AttributeError):  # not cached then
        return _derive(scenario)
    if key not in _DERIVED:
        if len(_DERIVED) >= _MAX_DERIVED:
            _DERIVED.pop(next(iter(_DERIVED)))
        _DERIVED[key] = _derive(scenario)
    return _DERIVED[key]


def with_semantic_source(scenario: Scenario, source: str) -> Scenario:
    """``scenario`` with ``[semantics] source`` set to ``source`` ("geometry" or "map",
    the scene rendered without a map file); unchanged when it has that source already.
    Switching drops the hand overrides and removals (they name the other source's ids)."""
    if scenario.semantics.source == source:
        return scenario
    semantics = dataclasses.replace(
        scenario.semantics, source=source, map_file="", map_grid=None, components=(), remove=()
    )
    return dataclasses.replace(scenario, semantics=semantics)


def _derive(scenario: Scenario) -> tuple[SemanticComponent, ...]:
    """:func:`derive_components`, computed."""
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
