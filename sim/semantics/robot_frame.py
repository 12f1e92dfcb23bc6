"""The semantic components in the robot frame, every control tick.

:func:`derive_components` returns a tuple that also carries every coordinate of
every component stacked in one array, so putting them into the robot frame is a
few vector operations plus slicing; ``Observation.components`` is a
:class:`RobotFrameComponents`, which does that only when first read.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, fields

import numpy as np
from numba import njit

from sim.types import Pose2D, SemanticComponent

_EMPTY = np.empty((0, 2))
_EMPTY.flags.writeable = False
_INDEX = (int, np.integer)  # what indexes one component


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
    ids: tuple[str, ...]  # (n,) the components' ids


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
        ids=tuple(str(item[0]) for item in items),
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
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    # positions are shifted by the pose's position seen from the robot, normals are not
    shift_x = c * pose.x + s * pose.y
    shift_y = -s * pose.x + c * pose.y
    out = _rotate_shift(packed.stacked, packed.layout.n, c, s, shift_x, shift_y)
    out.flags.writeable = False
    return out


@njit(cache=True)
def _rotate_shift(
    stacked: np.ndarray, n: int, c: float, s: float, shift_x: float, shift_y: float
) -> np.ndarray:
    """The rows (x, y) [m] of ``stacked`` (rows, 2) rotated into the robot frame,
    ``(x c + s y, y c - s x)``, the rows from ``n`` on then less (shift_x, shift_y):
    (rows, 2) [m]. The floating-point operations of numpy's in-place form
    (``x * c``, ``+= s * y``, ``-= shift``) in the same order."""
    out = np.empty((stacked.shape[0], 2))
    for r in range(stacked.shape[0]):
        x, y = stacked[r, 0], stacked[r, 1]
        ox = x * c + s * y
        oy = y * c - s * x
        if r >= n:
            ox -= shift_x
            oy -= shift_y
        out[r, 0], out[r, 1] = ox, oy
    return out


# SemanticComponent's fields in order and their slots' setters: a component is filled in
# field by field, as its frozen dataclass __init__ does, without that __init__'s
# object.__setattr__ per field (11 components a tick in the contextual mode)
_FIELDS = ("id", "kind", "centre", "points", "ends", "width", "normal", "source")
if tuple(f.name for f in fields(SemanticComponent)) != _FIELDS:  # pragma: no cover
    raise ImportError("sim.semantics.robot_frame: SemanticComponent's fields changed")
_SETTERS = tuple(SemanticComponent.__dict__[name].__set__ for name in _FIELDS)


def _component_at(out: np.ndarray, lay: _Layout, i: int) -> SemanticComponent:
    """Component ``i`` of the layout ``lay`` on the stacked coordinates ``out`` (views)."""
    cid, kind, width, source, pts, ends = lay.items[i]
    set_id, set_kind, set_centre, set_points, set_ends, set_width, set_normal, set_source = _SETTERS
    component = object.__new__(SemanticComponent)
    set_id(component, cid)
    set_kind(component, kind)
    set_centre(component, out[lay.n + i])
    set_points(component, _EMPTY if pts is None else out[pts])
    set_ends(component, _EMPTY if ends is None else out[ends])
    set_width(component, width)
    set_normal(component, out[i])
    set_source(component, source)
    return component


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
    element is read or the sequence iterated; ``len`` does not compute it.
    :meth:`target_points` and an integer index use the transformed coordinates alone
    (an index builds just that component, equal to the materialised one, a new object
    per call); iteration, slices and equality materialise.

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

    @property
    def prepared(self) -> bool:
        """Whether the robot-frame coordinates were computed (the sequence was read)."""
        return self._out is not None or self._seen is not None

    def ids(self) -> tuple[str, ...]:
        """The components' ids in index order (nothing is transformed or built)."""
        if isinstance(self._map, _Packed):
            return self._map.layout.ids
        return tuple(str(c.id) for c in self._map)

    def kinds(self) -> tuple[str, ...]:
        """The components' kinds in index order (nothing is transformed or built)."""
        if isinstance(self._map, _Packed):
            return tuple(item[1] for item in self._map.layout.items)
        return tuple(str(c.kind) for c in self._map)

    def normals(self) -> np.ndarray:
        """Every component's passage normal (n, 2) in the robot frame (zeros for kinds
        without one), from the stacked coordinates when packed."""
        out = self._stacked() if self._seen is None else None
        if out is not None:
            return out[: self._map.layout.n]
        return np.array([np.asarray(c.normal, dtype=float) for c in self.materialise()]).reshape(
            -1, 2
        )

    def prepare(self) -> RobotFrameComponents:
        """Compute the robot-frame coordinates now rather than when first read (the
        per-stage clock of the trial loop times them apart from their reader)."""
        if self._stacked() is None:
            self.materialise()
        return self

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
        if self._seen is None and isinstance(index, _INDEX):
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
    components came from :func:`in_robot_frame` or ``World.sense``.
    """
    if isinstance(components, RobotFrameComponents):
        return components.target_points()
    if isinstance(components, _Packed) and components.layout.n:
        return _packed_target_points(components.stacked, components.layout)
    return np.array([c.target_point() for c in components], dtype=float).reshape(-1, 2)


def _packed_target_points(stacked: np.ndarray, lay: _Layout) -> np.ndarray:
    """:func:`target_points` of packed components from their stacked coordinates."""
    return _nearest_rows(stacked, lay.target_rows, lay.target_starts)


@njit(cache=True)
def _nearest_rows(stacked: np.ndarray, rows: np.ndarray, starts: np.ndarray) -> np.ndarray:
    """Per run of ``rows`` (the runs begin at ``starts``, (n,)), the row of ``stacked``
    (m, 2) [m] nearest the origin, the first on ties: (n, 2) [m]. Squared distances are
    ``x * x + y * y``, what ``numpy.einsum("ij,ij->i", ...)`` computes of two columns."""
    n = starts.shape[0]
    out = np.empty((n, 2))
    for k in range(n):
        stop = starts[k + 1] if k + 1 < n else rows.shape[0]
        best, low = rows[starts[k]], math.inf
        for j in range(starts[k], stop):
            x, y = stacked[rows[j], 0], stacked[rows[j], 1]
            sq = x * x + y * y
            if sq < low:
                best, low = rows[j], sq
        out[k, 0], out[k, 1] = stacked[best, 0], stacked[best, 1]
    return out


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
