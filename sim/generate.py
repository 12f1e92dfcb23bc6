"""Random but plausible study scenes (DESIGN.md "The scene"; thesis Sec. 7.6.1.1-7.6.1.2,
Fig. 7.48; issue 17).

:func:`generate_scene` draws a floor plan like the thesis's cluttered room: 3-6 rooms
in a chain, so there is one way from A to B ("only one way available ... with no
alternative routes"), each pair joined by a doorway of 0.75-0.9 m clear width; the
chain turns, so doorways lie in walls of both orientations. One room has a row of
shelves and crates across its route with one gap of 0.8-0.95 m; some plans have a
corridor 1.4-2.0 m wide, narrowed by a piece of furniture to 0.8-1.0 m; clutter
stands against the walls off the route; the last room holds the table with the dock
pose B under it, open side towards the room; the inspection object stands in a room
with at least 1 m free all round; the question region covers the middle room. The
plan is then turned by a multiple of 90 degrees and maybe mirrored.

Internally the plan is built with the chain going east or north; rooms are
rectangles given by their walls' centre lines (walls 0.1 m thick), and every length
is drawn on a 1 cm grid, so the TOML (:func:`scene_toml`) holds exactly the values
used. Every scene passes :func:`sim.check.check_scene`.
"""

from __future__ import annotations

import itertools
import numbers
from dataclasses import dataclass

import numpy as np

from sim.toml_text import dumps

__all__ = ["generate_scene", "scene_toml"]

WALL_T = 0.1  # [m] wall thickness
_HALF = WALL_T / 2
DOOR_WIDTH_M = (0.75, 0.9)  # clear width of a doorway
GAP_WIDTH_M = (0.8, 0.95)  # the row's one gap
CORRIDOR_CLEAR_M = (1.4, 2.0)  # clear width of a corridor
NARROWED_M = (0.8, 1.0)  # what the corridor's furniture leaves free
INSPECTION_CLEAR_M = 1.0  # least free space round the inspection object
SPACING_M = 1.2  # clutter keeps this far from other things, or touches them
_STUB = 0.45  # [m] least wall beside a doorway (0.25 in a corridor's end wall)
_OPPOSITE = {"W": "E", "E": "W", "S": "N", "N": "S"}
_GREY, _WOOD, _GREEN = [0.45, 0.5, 0.6], [0.6, 0.45, 0.25], [0.35, 0.45, 0.4]


def _cm(x: float) -> float:
    return round(float(x), 2)


@dataclass(frozen=True, slots=True)
class _Rect:
    """An axis-aligned rectangle [m]."""

    x0: float
    y0: float
    x1: float
    y1: float

    def distance(self, o: _Rect) -> float:
        dx = max(o.x0 - self.x1, self.x0 - o.x1, 0.0)
        dy = max(o.y0 - self.y1, self.y0 - o.y1, 0.0)
        return float(np.hypot(dx, dy))

    def grown(self, m: float) -> _Rect:
        return _Rect(self.x0 - m, self.y0 - m, self.x1 + m, self.y1 + m)

    def overlaps(self, o: _Rect) -> bool:
        return (
            self.x0 < o.x1 - 1e-9
            and o.x0 < self.x1 - 1e-9
            and (self.y0 < o.y1 - 1e-9 and o.y0 < self.y1 - 1e-9)
        )

    @property
    def centre(self) -> tuple[float, float]:
        return ((self.x0 + self.x1) / 2, (self.y0 + self.y1) / 2)


@dataclass(frozen=True, slots=True)
class _Room:
    rect: _Rect  # wall centre lines
    corridor: bool
    entry: str  # side the doorway from the previous room is in ("" for room 0)
    exit: str  # side of the doorway to the next room ("" for the last)

    def depth(self, side: str) -> float:
        r = self.rect
        return r.x1 - r.x0 if side in "WE" else r.y1 - r.y0

    def span(self, side: str) -> float:
        return self.depth("S" if side in "WE" else "W")

    def local(self, side: str, t0: float, t1: float, u0: float, u1: float) -> _Rect:
        """The rectangle at depth [t0, t1] from wall ``side``'s centre line and
        [u0, u1] along it (from its west or south end) [m]."""
        r = self.rect
        if side == "W":
            return _Rect(r.x0 + t0, r.y0 + u0, r.x0 + t1, r.y0 + u1)
        if side == "E":
            return _Rect(r.x1 - t1, r.y0 + u0, r.x1 - t0, r.y0 + u1)
        if side == "S":
            return _Rect(r.x0 + u0, r.y0 + t0, r.x0 + u1, r.y0 + t1)
        return _Rect(r.x0 + u0, r.y1 - t1, r.x0 + u1, r.y1 - t0)

    def depth_of(self, side: str, rect: _Rect) -> tuple[float, float]:
        """Depth range [m] of ``rect`` measured from wall ``side``'s centre line."""
        r = self.rect
        return {
            "W": (rect.x0 - r.x0, rect.x1 - r.x0),
            "E": (r.x1 - rect.x1, r.x1 - rect.x0),
            "S": (rect.y0 - r.y0, rect.y1 - r.y0),
            "N": (r.y1 - rect.y1, r.y1 - rect.y0),
        }[side]


@dataclass(frozen=True, slots=True)
class _Door:
    vertical: bool  # in a wall along y (x = at)
    at: float  # [m] the wall's line
    lo: float  # [m] opening, along the wall
    hi: float

    def zone(self, depth: float, side: float) -> _Rect:
        """The floor in front of the doorway on both sides, ``side`` beyond its ends."""
        if self.vertical:
            return _Rect(self.at - depth, self.lo - side, self.at + depth, self.hi + side)
        return _Rect(self.lo - side, self.at - depth, self.hi + side, self.at + depth)


# ----------------------------------------------------------------------- the chain


def _features(rng: np.random.Generator, n: int) -> tuple[int, int]:
    """Index of the corridor (-1 for none) and of the room with the row of shelves."""
    corridor = -1
    if rng.random() < (0.6 if n >= 4 else 0.4):
        corridor = int(rng.integers(1, n - 1))
    row = int(rng.choice([k for k in range(n - 1) if k != corridor]))
    return corridor, row


def _directions(rng: np.random.Generator, n: int, straight: set[int]) -> list[str]:
    """Direction "E" or "N" of each step, the step into room k at index k - 1; the
    chain goes straight on through the rooms in ``straight``."""
    dirs = [str(rng.choice(["E", "N"]))]
    for k in range(1, n - 1):
        turn = rng.random() < 0.5 and k not in straight
        dirs.append({"E": "N", "N": "E"}[dirs[-1]] if turn else dirs[-1])
    return dirs


def _size(rng: np.random.Generator, k: int, n: int, corridor: int, row: int, d: str) -> tuple:
    """Room ``k``'s (width, height) [m] between wall centre lines; ``d`` its step direction."""
    if k == corridor:
        length = _cm(rng.uniform(4.5, 7.0))
        width = _cm(rng.uniform(*CORRIDOR_CLEAR_M)) + WALL_T
        return (length, width) if d == "E" else (width, length)
    lo, hi = {0: (4.2, 5.6), n - 1: (4.6, 5.6)}.get(k, (3.4, 5.6))
    if k == n - 1 and n == 3 and corridor >= 0:  # the inspection object goes here too
        lo, hi = 5.8, 6.8
    w, h = (_cm(rng.uniform(lo, hi)) for _ in range(2))
    if k == row:  # room for the row between the doorways
        deep = _cm(rng.uniform(4.6, 6.0))
        w, h = (deep, h) if d == "E" else (w, deep)
    return w, h


def _place(rng: np.random.Generator, prev: _Room, size: tuple, d: str, stub: float) -> _Rect:
    """Room rectangle of ``size`` beyond ``prev`` in direction ``d``, overlapping it
    along the shared wall by at least a doorway and two stubs."""
    w, h = size
    need = DOOR_WIDTH_M[1] + 2 * stub
    p = prev.rect
    if d == "E":
        off = _cm(rng.uniform(-(h - need), (p.y1 - p.y0) - need))
        return _Rect(p.x1, _cm(p.y0 + off), _cm(p.x1 + w), _cm(p.y0 + off + h))
    off = _cm(rng.uniform(-(w - need), (p.x1 - p.x0) - need))
    return _Rect(_cm(p.x0 + off), p.y1, _cm(p.x0 + off + w), _cm(p.y1 + h))


def _near_miss(rect: _Rect, rooms: list[_Room]) -> bool:
    """Whether ``rect`` nearly lines up with a room it does not join: edges off by less
    than ``SPACING_M`` leave a notch between wall ends, which reads as a doorway."""
    for room in rooms:
        r = room.rect
        if rect.distance(r) >= SPACING_M + 0.1:
            continue
        for a, b in itertools.chain(
            itertools.product((rect.x0, rect.x1), (r.x0, r.x1)),
            itertools.product((rect.y0, rect.y1), (r.y0, r.y1)),
        ):
            if 1e-6 < abs(a - b) < SPACING_M + 0.1:
                return True
    return False


def _door(rng: np.random.Generator, a: _Rect, b: _Rect, d: str, stub: float) -> _Door:
    width = _cm(rng.uniform(*DOOR_WIDTH_M))
    lo, hi = (max(a.y0, b.y0), min(a.y1, b.y1)) if d == "E" else (max(a.x0, b.x0), min(a.x1, b.x1))
    start = _cm(rng.uniform(lo + stub, hi - stub - width))
    return _Door(d == "E", a.x1 if d == "E" else a.y1, start, _cm(start + width))


def _chain(rng: np.random.Generator, n: int) -> tuple[list[_Room], list[_Door], int, int]:
    corridor, row = _features(rng, n)
    dirs = _directions(rng, n, {corridor, row} - {0})
    rooms = [_Room(_Rect(0.0, 0.0, *_size(rng, 0, n, corridor, row, dirs[0])), False, "", "")]
    doors: list[_Door] = []
    for k in range(1, n):
        d = dirs[k - 1]
        stub = 0.25 if corridor in (k, k - 1) else _STUB
        for _ in range(50):  # a rectangle clear of every earlier room
            rect = _place(rng, rooms[-1], _size(rng, k, n, corridor, row, d), d, stub)
            if not any(rect.overlaps(r.rect) for r in rooms) and not _near_miss(rect, rooms[:-1]):
                break
        else:
            raise RuntimeError(f"generate_scene: no place for room {k} (a generator bug)")
        prev = rooms[-1]
        rooms[-1] = _Room(prev.rect, prev.corridor, prev.entry, "E" if d == "E" else "N")
        rooms.append(_Room(rect, k == corridor, "W" if d == "E" else "S", ""))
        doors.append(_door(rng, prev.rect, rect, d, stub))
    return rooms, doors, corridor, row


# ------------------------------------------------------------------------- walls


def _merge(intervals: list[tuple[float, float]]) -> list[list[float]]:
    out: list[list[float]] = []
    for lo, hi in sorted(intervals):
        if out and lo <= out[-1][1] + 1e-9:
            out[-1][1] = max(out[-1][1], hi)
        else:
            out.append([lo, hi])
    return out


def _walls(rooms: list[_Room], doors: list[_Door]) -> list[dict]:
    """Wall segments along every room edge (shared edges once), cut at the doorways;
    horizontal walls run half a thickness past their ends to close the corners."""
    lines: dict[tuple[bool, float], list[tuple[float, float]]] = {}
    for room in rooms:
        r = room.rect
        for vertical, at, lo, hi in (
            (False, r.y0, r.x0, r.x1),
            (False, r.y1, r.x0, r.x1),
            (True, r.x0, r.y0, r.y1),
            (True, r.x1, r.y0, r.y1),
        ):
            lines.setdefault((vertical, round(at, 6)), []).append((lo, hi))
    walls = []
    for (vertical, at), spans in sorted(lines.items()):
        for lo, hi in _merge(spans):
            cuts = sorted(
                (d.lo, d.hi) for d in doors if d.vertical == vertical and round(d.at, 6) == at
            )
            ext = 0.0 if vertical else _HALF
            edges = [lo - ext, *(x for c in cuts if lo < c[0] < hi for x in c), hi + ext]
            for a, b in zip(edges[::2], edges[1::2], strict=True):
                frm, to = ([at, a], [at, b]) if vertical else ([a, at], [b, at])
                walls.append({"name": f"wall_{len(walls)}", "from": frm, "to": to})
    return walls


def _wall_rects(walls: list[dict]) -> list[_Rect]:
    out = []
    for w in walls:
        (x0, y0), (x1, y1) = w["from"], w["to"]
        out.append(
            _Rect(
                min(x0, x1) - _HALF, min(y0, y1) - _HALF, max(x0, x1) + _HALF, max(y0, y1) + _HALF
            )
        )
    return out


# ---------------------------------------------------------------------- furniture


class _Layout:
    """What has been placed so far: elements for the file, rectangles for spacing."""

    def __init__(self, walls: list[dict]) -> None:
        self.walls = walls
        self.wall_rects = _wall_rects(walls)
        self.boxes: list[dict] = []
        self.cylinders: list[dict] = []
        self.tables: list[dict] = []
        self.solid: list[_Rect] = []  # footprints of everything but walls
        self.keep_out: list[_Rect] = []  # floor the route or a task needs

    def box(self, name: str, rect: _Rect, height: float, colour: list[float]) -> None:
        self.boxes.append(
            {
                "name": name,
                "centre": [round((rect.x0 + rect.x1) / 2, 3), round((rect.y0 + rect.y1) / 2, 3)],
                "size": [round(rect.x1 - rect.x0, 3), round(rect.y1 - rect.y0, 3)],
                "height": height,
                "colour": colour,
            }
        )
        self.solid.append(rect)

    def cylinder(self, name: str, centre: tuple[float, float], radius: float, **kw) -> None:
        self.cylinders.append(
            {"name": name, "centre": [round(c, 3) for c in centre], "radius": radius, **kw}
        )
        self.solid.append(
            _Rect(centre[0] - radius, centre[1] - radius, centre[0] + radius, centre[1] + radius)
        )

    def spaced(self, rect: _Rect) -> bool:
        """Clutter rule: off the keep-out floor, overlapping nothing, and either close to
        (< 0.45 m, so no passage even for a disc measured by its square) or at least
        ``SPACING_M`` from every wall and element."""
        if any(rect.overlaps(k) for k in self.keep_out):
            return False
        for o in self.wall_rects + self.solid:
            if rect.overlaps(o) or 0.45 <= rect.distance(o) < SPACING_M:
                return False
        return True


def _row(rng: np.random.Generator, lay: _Layout, room: _Room, k: int) -> None:
    """Shelves and crates across the room from wall to wall, one gap, parallel to the
    wall the route enters by (for room 0: the wall behind the start)."""
    side = room.entry or _OPPOSITE[room.exit]
    thick = _cm(rng.uniform(0.4, 0.6))
    t_min = 1.6 if k == 0 else 1.3
    t = _cm(rng.uniform(t_min, room.depth(side) - thick - 1.3))
    span = room.span(side)
    u_lo, u_hi = _HALF - 0.03, span - _HALF + 0.03  # into the walls: no slot at the ends
    gap = _cm(rng.uniform(*GAP_WIDTH_M))
    g0 = _cm(rng.uniform(_HALF + 0.5, span - _HALF - 0.5 - gap))
    parts = 0
    for a, b in ((u_lo, g0), (_cm(g0 + gap), u_hi)):
        cuts = 1 if b - a < 0.8 else int(rng.integers(1, 3 if b - a < 1.5 else 4))
        edges = [a]
        for x in (
            sorted(_cm(x) for x in rng.uniform(a + 0.3, b - 0.3, cuts - 1)) if cuts > 1 else ()
        ):
            if x - edges[-1] >= 0.2 and b - x >= 0.2:  # pieces touch: no slot between them
                edges.append(x)
        edges.append(b)
        for e0, e1 in itertools.pairwise(edges):
            shelf = parts % 2 == 0
            lay.box(
                f"{'shelf' if shelf else 'crate'}_row_{parts}",
                room.local(side, t, t + thick, e0, e1),
                1.6 if shelf else 0.8,
                _GREY if shelf else _WOOD,
            )
            parts += 1
    lay.keep_out.append(room.local(side, t - SPACING_M, t + thick + SPACING_M, 0.0, span))


def _narrowing(rng: np.random.Generator, lay: _Layout, room: _Room) -> None:
    """A cabinet against one side of the corridor, leaving 0.8-1.0 m free."""
    side = room.entry
    clear = room.span(side) - WALL_T
    length = _cm(rng.uniform(0.5, 0.9))
    t0 = _cm(rng.uniform(1.3, room.depth(side) - 1.3 - length))
    protrude = _cm(clear - rng.uniform(*NARROWED_M))
    if rng.random() < 0.5:
        rect = room.local(side, t0, t0 + length, _HALF - 0.02, _HALF + protrude)
    else:
        span = room.span(side)
        rect = room.local(side, t0, t0 + length, span - _HALF - protrude, span - _HALF + 0.02)
    lay.box("cabinet_corridor", rect, 1.3, _GREEN)
    lay.keep_out.append(room.rect)


def _table(rng: np.random.Generator, lay: _Layout, room: _Room) -> dict:
    """The table against a wall other than the entry's, open side to the room; returns
    the dock pose (internal frame) under it, facing the wall."""
    side = str(rng.choice([s for s in "WESN" if s != room.entry]))
    deep, wide = _cm(rng.uniform(1.0, 1.4)), _cm(rng.uniform(0.9, 1.1))
    t0 = _HALF + _cm(rng.uniform(0.05, 0.15))
    span = room.span(side)
    u0 = _cm(rng.uniform(_HALF + SPACING_M, span - _HALF - SPACING_M - wide))
    top = room.local(side, t0, t0 + deep, u0, u0 + wide)
    cx, cy = top.centre
    lay.tables.append(
        {
            "name": "table",
            "centre": [round(cx, 3), round(cy, 3)],
            "size": [round(top.x1 - top.x0, 3), round(top.y1 - top.y0, 3)],
            "height": _cm(rng.uniform(0.7, 0.8)),
            "leg": 0.06,
        }
    )
    lay.solid.append(top)
    lay.keep_out.append(room.local(side, 0.0, t0 + deep + 1.6, u0 - 0.6, u0 + wide + 0.6))
    yaw = {"W": 180.0, "E": 0.0, "S": 270.0, "N": 90.0}[side]
    return {"x": round(cx, 3), "y": round(cy, 3), "yaw_deg": yaw}


def _start(rng: np.random.Generator, lay: _Layout, room: _Room) -> dict:
    """Pose A in room 0 by the wall opposite its doorway, facing into the room."""
    side = _OPPOSITE[room.exit]
    u = _cm(rng.uniform(1.0, room.span(side) - 1.0))
    spot = room.local(side, 0.75, 0.75, u, u)
    lay.keep_out.append(spot.grown(0.8))
    yaw = {"W": 0.0, "E": 180.0, "S": 90.0, "N": 270.0}[side]
    return {"x": round(spot.x0, 3), "y": round(spot.y0, 3), "yaw_deg": yaw}


def _inspection(
    rng: np.random.Generator, lay: _Layout, rooms: list[_Room], order: list[int]
) -> str:
    """The object to inspect, in the first room of ``order`` with space for it: at
    least ``INSPECTION_CLEAR_M`` from everything (more on the other sides)."""
    cylinder = bool(rng.random() < 0.6)
    size = _cm(rng.uniform(0.15, 0.3)) if cylinder else [_cm(rng.uniform(0.3, 0.6)) for _ in "xy"]
    half = (size, size) if cylinder else (size[0] / 2, size[1] / 2)
    for k in order:
        r = rooms[k].rect.grown(-(_HALF + INSPECTION_CLEAR_M + 0.05))
        if r.x1 - r.x0 < 2 * half[0] or r.y1 - r.y0 < 2 * half[1]:
            continue
        for _ in range(200):
            cx = _cm(rng.uniform(r.x0 + half[0], r.x1 - half[0]))
            cy = _cm(rng.uniform(r.y0 + half[1], r.y1 - half[1]))
            rect = _Rect(cx - half[0], cy - half[1], cx + half[0], cy + half[1])
            near = rect.grown(INSPECTION_CLEAR_M + 0.05)
            if any(near.overlaps(o) for o in lay.solid) or any(
                rect.grown(0.3).overlaps(o) for o in lay.keep_out
            ):
                continue
            if cylinder:
                lay.cylinder("inspect_cylinder", (cx, cy), size, height=1.0, colour=[0.9, 0.1, 0.1])
                name = "inspect_cylinder"
            else:
                lay.box("inspect_box", rect, 0.9, [0.9, 0.1, 0.1])
                name = "inspect_box"
            lay.keep_out.append(near)
            return name
    raise RuntimeError("generate_scene: no room with space for the inspection object (a bug)")


def _clutter(rng: np.random.Generator, lay: _Layout, room: _Room, k: int) -> None:
    """One to three boxes and cylinders against the walls, away from the route."""
    for j in range(int(rng.integers(1, 4))):
        for _ in range(25):
            side = str(rng.choice(list("WESN")))
            span = room.span(side)
            t0 = _HALF + 0.02
            if rng.random() < 0.5:
                depth, along = _cm(rng.uniform(0.3, 0.6)), _cm(rng.uniform(0.4, 0.9))
                u0 = _cm(rng.uniform(_HALF, span - _HALF - along))
                rect = room.local(side, t0, t0 + depth, u0, u0 + along)
                if lay.spaced(rect):
                    lay.box(f"crate_{k}_{j}", rect, _cm(rng.uniform(0.5, 1.2)), _WOOD)
                    break
            else:
                radius = _cm(rng.uniform(0.15, 0.3))
                u = _cm(rng.uniform(_HALF + radius, span - _HALF - radius))
                rect = room.local(side, t0, t0 + 2 * radius, u - radius, u + radius)
                if lay.spaced(rect):
                    lay.cylinder(
                        f"bin_{k}_{j}", rect.centre, radius, height=_cm(rng.uniform(0.4, 0.9))
                    )
                    break


def _inner(rect: _Rect) -> list[list[float]]:
    r = rect.grown(-_HALF)
    return [[r.x0, r.y0], [r.x1, r.y0], [r.x1, r.y1], [r.x0, r.y1]]


# --------------------------------------------------------------------- the plan


def _plan(rng: np.random.Generator, n: int) -> dict:
    """The scene in the internal frame (chain going east and north), as a TOML dict."""
    rooms, doors, corridor, row = _chain(rng, n)
    lay = _Layout(_walls(rooms, doors))
    lay.keep_out += [d.zone(1.4, 0.4) for d in doors]
    start = _start(rng, lay, rooms[0])
    _row(rng, lay, rooms[row], row)
    if corridor >= 0:
        _narrowing(rng, lay, rooms[corridor])
    dock = _table(rng, lay, rooms[-1])
    free = [k for k in range(n) if k not in (row, corridor)]
    order = [k for k in free if 0 < k < n - 1] + [k for k in free if k in (0, n - 1)]
    inspect = _inspection(rng, lay, rooms, order)
    for k, room in enumerate(rooms):
        if k != corridor:
            _clutter(rng, lay, room, k)
    lo = np.min([[r.rect.x0, r.rect.y0] for r in rooms], axis=0) - 0.3
    hi = np.max([[r.rect.x1, r.rect.y1] for r in rooms], axis=0) + 0.3
    turns = sum(
        a.entry in "WE" and a.exit in "SN" or a.entry in "SN" and a.exit in "WE"
        for a in rooms[1:-1]
    )
    return {
        "name": "generated",
        "description": (
            f"Generated floor plan: {n} rooms in a chain ({turns} turns), "
            f"{'a corridor, ' if corridor >= 0 else ''}a row with one gap, a table to dock under"
        ),
        "bounds": [[round(float(x), 3) for x in lo], [round(float(x), 3) for x in hi]],
        "inspection_object": inspect,
        "start": start,
        "dock": {**dock, "table": "table"},
        "question_region": {"polygon": _inner(rooms[(n - 1) // 2].rect)},
        "walls": lay.walls,
        "boxes": lay.boxes,
        "cylinders": lay.cylinders,
        "tables": lay.tables,
    }


# ------------------------------------------------------------------- orientation


def _turned(data: dict, quarter_turns: int, mirror: bool) -> dict:
    """The plan turned by ``quarter_turns`` x 90 deg counter-clockwise after mirroring
    x if ``mirror``, shifted so the bounds start at (-0.3, -0.3). Exact on the 1 cm grid."""
    m = np.array([[-1, 0], [0, 1]]) if mirror else np.eye(2, dtype=int)
    rot = np.linalg.matrix_power(np.array([[0, -1], [1, 0]]), quarter_turns % 4) @ m
    corners = np.array(data["bounds"]) @ rot.T
    shift = -0.3 - corners.min(axis=0)

    def pt(p: list[float]) -> list[float]:
        q = rot @ np.asarray(p, dtype=float) + shift
        return [round(float(v), 3) + 0.0 for v in q]

    def heading(yaw: float) -> float:
        yaw = (180.0 - yaw) if mirror else yaw
        return float((yaw + 90.0 * quarter_turns) % 360.0)

    def size(s: list[float]) -> list[float]:
        return [s[1], s[0]] if quarter_turns % 2 else list(s)

    out = dict(data)
    hi = np.abs(corners.max(axis=0) - corners.min(axis=0)) - 0.3
    out["bounds"] = [[-0.3, -0.3], [round(float(v), 3) for v in hi]]
    for key in ("start", "dock"):
        x, y = pt([data[key]["x"], data[key]["y"]])
        out[key] = {**data[key], "x": x, "y": y, "yaw_deg": heading(data[key]["yaw_deg"])}
    out["question_region"] = {"polygon": [pt(p) for p in data["question_region"]["polygon"]]}
    out["walls"] = [{**w, "from": pt(w["from"]), "to": pt(w["to"])} for w in data["walls"]]
    for key in ("boxes", "tables"):
        out[key] = [{**b, "centre": pt(b["centre"]), "size": size(b["size"])} for b in data[key]]
    out["cylinders"] = [{**c, "centre": pt(c["centre"])} for c in data["cylinders"]]
    return out


def generate_scene(rng: np.random.Generator, *, rooms: int | None = None) -> dict:
    """A random study scene as a TOML-ready dict (format: ``sim/scenarios/FORMAT.md``).

    Parameters
    ----------
    rng : numpy.random.Generator
        The only source of randomness: the same generator state gives the same scene.
    rooms : int, optional
        Number of rooms in the chain, 3-6; drawn uniformly when omitted.

    Returns
    -------
    dict
        Keys ``name``, ``description``, ``bounds``, ``inspection_object``, ``start``,
        ``dock``, ``question_region``, ``walls``, ``boxes``, ``cylinders``, ``tables``;
        lengths [m], angles [deg]. :func:`sim.scenario.parse_scenario` accepts it and
        :func:`sim.check.check_scene` finds no problem.
    """
    if rooms is not None and (
        isinstance(rooms, bool) or not isinstance(rooms, numbers.Integral) or not 3 <= rooms <= 6
    ):
        raise ValueError(f"rooms: must be an integer from 3 to 6, got {rooms!r}")
    n = int(rng.integers(3, 7)) if rooms is None else int(rooms)
    plan = _plan(rng, n)
    return _turned(plan, int(rng.integers(0, 4)), bool(rng.random() < 0.5))


def scene_toml(data: dict, *, header: str = "") -> str:
    """A scene dict (:func:`generate_scene`) as TOML text, ``header`` as leading comments."""
    lines = "".join(f"# {line}\n" if line else "#\n" for line in header.splitlines())
    return lines + ("\n" if lines else "") + dumps(data)
