"""The scene's 2-D occupancy grid: rasterisation, clearance, inflation, A*
(thesis Sec. 7.6.1.1, Fig. 7.47 and 7.48(b); appendix Alg. 4 and 5; spec section 6).

The participant interface shows "the 2D occupancy grid map of the test scenario";
here it is rasterised from the scenario's exact geometry instead of being built by
SLAM, so it has none of the thesis map's sensor noise. What a laser at robot height
sees is occupied: walls, boxes, cylinders and the legs of tables (not their tops).
A cell is occupied when an obstacle overlaps it with positive area. Distances are
between cell centres, in metres. Map files: :mod:`sim.map_files`.
"""

from __future__ import annotations

import heapq
import math
from dataclasses import dataclass

import numpy as np

from sim.limits import MAX_CELLS
from sim.scenario import Box, Cylinder, Scenario

_EPS = 1e-9  # [m] geometric tolerance: touching is not overlapping


@dataclass(frozen=True, slots=True)
class OccupancyGrid:
    """An axis-aligned occupancy grid of the map frame.

    Cell ``(row, col)`` covers ``x in [x0 + col * res, x0 + (col + 1) * res)`` and
    ``y in [y0 + row * res, y0 + (row + 1) * res)``, where ``(x0, y0) = origin``:
    row 0 is the bottom row (smallest y), as in the map frame, not as in an image.
    """

    occupied: np.ndarray  # (rows, cols) bool; row 0 is the BOTTOM row (y_min), col 0 at x_min
    origin: tuple[float, float]  # map-frame (x, y) [m] of the lower-left corner of cell (0, 0)
    resolution: float  # [m / cell]

    def __post_init__(self) -> None:
        occupied = np.asarray(self.occupied)
        if occupied.ndim != 2 or occupied.dtype != bool:
            raise ValueError(
                f"OccupancyGrid.occupied must be a 2-D bool array, got {occupied.dtype} "
                f"of shape {occupied.shape}"
            )
        if not (math.isfinite(self.resolution) and self.resolution > 0):
            raise ValueError(f"OccupancyGrid.resolution must be positive, got {self.resolution}")
        object.__setattr__(self, "occupied", occupied)
        object.__setattr__(self, "origin", (float(self.origin[0]), float(self.origin[1])))
        object.__setattr__(self, "resolution", float(self.resolution))

    def __eq__(self, other: object) -> bool:
        if not isinstance(other, OccupancyGrid):
            return NotImplemented
        return (
            self.origin == other.origin
            and self.resolution == other.resolution
            and np.array_equal(self.occupied, other.occupied)
        )

    @property
    def shape(self) -> tuple[int, int]:
        """``(rows, cols)``."""
        return self.occupied.shape

    def world_to_cell(self, xy: np.ndarray) -> np.ndarray:
        """Map points (k, 2) [m] -> the cells containing them (k, 2) int ``(row, col)``.

        Points outside the grid give indices outside ``[0, rows) x [0, cols)``.
        """
        p = np.asarray(xy, dtype=float).reshape(-1, 2)
        col = np.floor((p[:, 0] - self.origin[0]) / self.resolution)
        row = np.floor((p[:, 1] - self.origin[1]) / self.resolution)
        return np.column_stack((row, col)).astype(np.int64)

    def cell_to_world(self, rc: np.ndarray) -> np.ndarray:
        """Cells (k, 2) ``(row, col)`` -> their centres (k, 2) ``(x, y)`` [m]."""
        c = np.asarray(rc, dtype=float).reshape(-1, 2)
        return np.column_stack(
            (
                self.origin[0] + (c[:, 1] + 0.5) * self.resolution,
                self.origin[1] + (c[:, 0] + 0.5) * self.resolution,
            )
        )

    def is_free(self, xy: np.ndarray) -> np.ndarray:
        """Whether map points (k, 2) [m] lie in free cells, (k,) bool; outside is not free."""
        rc = self.world_to_cell(xy)
        rows, cols = self.shape
        inside = (rc[:, 0] >= 0) & (rc[:, 0] < rows) & (rc[:, 1] >= 0) & (rc[:, 1] < cols)
        free = np.zeros(len(rc), dtype=bool)
        free[inside] = ~self.occupied[rc[inside, 0], rc[inside, 1]]
        return free

    def extent(self) -> tuple[float, float, float, float]:
        """``(x_min, x_max, y_min, y_max)`` [m], for ``imshow(..., origin="lower", extent=)``."""
        rows, cols = self.shape
        x0, y0 = self.origin
        return (x0, x0 + cols * self.resolution, y0, y0 + rows * self.resolution)


# ------------------------------------------------------------------ rasterising


def _cell_range(lo: float, hi: float, origin: float, res: float, n: int) -> tuple[int, int]:
    """Indices [first, last) of the cells along one axis that [lo, hi] [m] may overlap."""
    first = max(int(math.floor((lo - origin) / res)), 0)
    last = min(int(math.floor((hi - origin) / res)) + 1, n)
    return first, last


def _paint_box(occ: np.ndarray, box: Box, origin: tuple[float, float], res: float) -> None:
    """Occupy the cells a (rotated) box overlaps: separating-axis test, cell vs. box."""
    c, s = abs(math.cos(box.yaw)), abs(math.sin(box.yaw))
    hx, hy = box.size[0] / 2, box.size[1] / 2
    ex, ey = hx * c + hy * s, hx * s + hy * c  # half extents of the box along map x and y
    rows, cols = occ.shape
    r0, r1 = _cell_range(box.centre[1] - ey, box.centre[1] + ey, origin[1], res, rows)
    c0, c1 = _cell_range(box.centre[0] - ex, box.centre[0] + ex, origin[0], res, cols)
    if r0 >= r1 or c0 >= c1:
        return
    h = res / 2
    dx = origin[0] + (np.arange(c0, c1) + 0.5) * res - box.centre[0]  # (nc,)
    dy = origin[1] + (np.arange(r0, r1) + 0.5) * res - box.centre[1]  # (nr,)
    cos_y, sin_y = math.cos(box.yaw), math.sin(box.yaw)
    along = cos_y * dx[None, :] + sin_y * dy[:, None]  # centre offset on the box's own x
    across = -sin_y * dx[None, :] + cos_y * dy[:, None]  # ... and own y
    hit = (
        (np.abs(dx)[None, :] < h + ex - _EPS)
        & (np.abs(dy)[:, None] < h + ey - _EPS)
        & (np.abs(along) < hx + h * (c + s) - _EPS)
        & (np.abs(across) < hy + h * (c + s) - _EPS)
    )
    occ[r0:r1, c0:c1] |= hit


def _paint_cylinder(
    occ: np.ndarray, cyl: Cylinder, origin: tuple[float, float], res: float
) -> None:
    """Occupy the cells a disc overlaps (distance from the disc centre to the cell < radius)."""
    rows, cols = occ.shape
    (cx, cy), radius = cyl.centre, cyl.radius
    r0, r1 = _cell_range(cy - radius, cy + radius, origin[1], res, rows)
    c0, c1 = _cell_range(cx - radius, cx + radius, origin[0], res, cols)
    if r0 >= r1 or c0 >= c1:
        return
    h = res / 2
    dx = np.abs(origin[0] + (np.arange(c0, c1) + 0.5) * res - cyl.centre[0])
    dy = np.abs(origin[1] + (np.arange(r0, r1) + 0.5) * res - cyl.centre[1])
    gx = np.maximum(dx - h, 0.0)[None, :]
    gy = np.maximum(dy - h, 0.0)[:, None]
    occ[r0:r1, c0:c1] |= gx**2 + gy**2 < cyl.radius**2 - _EPS


def build_grid(scenario: Scenario, *, resolution: float = 0.05) -> OccupancyGrid:
    """Rasterise the scene as a laser at robot height sees it.

    Parameters
    ----------
    scenario : Scenario
        Walls, boxes, cylinders and table legs are obstacles; table tops are not.
    resolution : float
        Cell side [m]. The grid covers ``scenario.bounds`` (rounded up to whole cells).

    Returns
    -------
    OccupancyGrid
        ``origin`` is the bounds' lower-left corner.
    """
    if not (math.isfinite(resolution) and resolution > 0):
        raise ValueError(f"resolution must be a positive number of metres, got {resolution}")
    (x0, y0), (x1, y1) = scenario.bounds
    cols = max(int(math.ceil((x1 - x0) / resolution - 1e-9)), 1)
    rows = max(int(math.ceil((y1 - y0) / resolution - 1e-9)), 1)
    if rows * cols > MAX_CELLS:
        raise ValueError(
            f"{scenario.source or '<scenario>'}: a grid of {x1 - x0:g} m x {y1 - y0:g} m at "
            f"{resolution:g} m per cell has {rows * cols} cells, more than {MAX_CELLS}; "
            f"use a coarser resolution"
        )
    occ = np.zeros((rows, cols), dtype=bool)
    origin = (float(x0), float(y0))
    for box in scenario.obstacle_boxes():
        _paint_box(occ, box, origin, resolution)
    for cyl in scenario.cylinders:
        _paint_cylinder(occ, cyl, origin, resolution)
    return OccupancyGrid(occupied=occ, origin=origin, resolution=resolution)


# -------------------------------------------------------------- distance transform


def _squared_edt(occupied: np.ndarray) -> np.ndarray:
    """Exact squared Euclidean distance [cells^2] of each cell to the nearest occupied cell.

    ``inf`` everywhere when nothing is occupied. (rows, cols) float64. A 1-D distance
    ``g`` along the longer axis by two sweeps, then for every cell the minimum over the
    shorter axis of ``(j - k)^2 + g(k)^2``, trying offsets ``|j - k|`` in increasing
    order until none can lower any value: ``O(rows * cols * D)`` for a largest
    distance of ``D`` cells.
    """
    if not occupied.any():
        return np.full(occupied.shape, np.inf)
    transpose = occupied.shape[0] < occupied.shape[1]
    occ = occupied.T if transpose else occupied  # (n_long, n_short)
    n_long, n_short = occ.shape
    # 1-D distance along the long axis: a forward and a backward sweep
    g = np.empty(occ.shape)
    run = np.full(n_short, np.inf)
    for i in range(n_long):
        run = np.where(occ[i], 0.0, run + 1.0)
        g[i] = run
    run = np.full(n_short, np.inf)
    for i in range(n_long - 1, -1, -1):
        run = np.where(occ[i], 0.0, run + 1.0)
        np.minimum(g[i], run, out=g[i])
    g2 = g * g
    # along the short axis: d2(i, j) = min_k (j - k)^2 + g(i, k)^2, exactly, by trying
    # offsets o = |j - k| in increasing order; none can improve once o^2 >= max(d2)
    d2 = g2.copy()
    for o in range(1, n_short):
        if o * o >= d2.max():
            break
        np.minimum(d2[:, o:], g2[:, :-o] + o * o, out=d2[:, o:])
        np.minimum(d2[:, :-o], g2[:, o:] + o * o, out=d2[:, :-o])
    return d2.T if transpose else d2


def clearance_map(grid: OccupancyGrid) -> np.ndarray:
    """Distance of each cell centre to the nearest occupied cell's centre.

    Returns
    -------
    numpy.ndarray
        (rows, cols) [m]; 0 on occupied cells, ``inf`` everywhere if no cell is occupied.
    """
    return np.sqrt(_squared_edt(grid.occupied)) * grid.resolution


def inflate(grid: OccupancyGrid, radius_m: float) -> OccupancyGrid:
    """Disc dilation: occupy every cell whose centre is within ``radius_m`` [m] of an occupied one.

    ``radius_m <= 0`` returns the grid's cells unchanged.
    """
    if radius_m <= 0:
        return OccupancyGrid(grid.occupied.copy(), grid.origin, grid.resolution)
    r_cells2 = (radius_m / grid.resolution) ** 2
    occupied = _squared_edt(grid.occupied) <= r_cells2 * (1 + 1e-12)
    return OccupancyGrid(occupied, grid.origin, grid.resolution)


# --------------------------------------------------------------------------- A*

_SQRT2 = math.sqrt(2.0)


def _a_star(
    free: list[bool], heuristic: list[float], start: int, goal: int, width: int
) -> list[int] | None:
    """A* over the flat padded grid (``free`` per cell, rows ``width`` long): each
    cell's parent on the cheapest path found, or ``None`` when ``goal`` is unreachable."""
    # (offset, cost, the two orthogonal cells a diagonal step passes; 0 for straight steps)
    moves = [(1, 1.0, 0, 0), (-1, 1.0, 0, 0), (width, 1.0, 0, 0), (-width, 1.0, 0, 0)]
    moves += [(dy * width + dx, _SQRT2, dy * width, dx) for dy in (-1, 1) for dx in (-1, 1)]
    cost = [math.inf] * len(free)
    parent = [-1] * len(free)
    closed = bytearray(len(free))
    cost[start] = 0.0
    heap = [(heuristic[start], start)]
    pop, push = heapq.heappop, heapq.heappush
    while heap:
        _, node = pop(heap)
        if closed[node]:
            continue
        if node == goal:
            break
        closed[node] = 1
        base = cost[node]
        for offset, step, ortho_a, ortho_b in moves:
            nb = node + offset
            if not free[nb] or closed[nb]:
                continue
            if ortho_a and not (free[node + ortho_a] and free[node + ortho_b]):
                continue  # no cutting the corner of a blocked cell
            new = base + step
            if new < cost[nb]:
                cost[nb] = new
                parent[nb] = node
                push(heap, (new + heuristic[nb], nb))
    else:
        return None
    return parent


def shortest_path(
    grid: OccupancyGrid,
    start_xy: np.ndarray,
    goal_xy: np.ndarray,
    *,
    clearance_m: float,
) -> np.ndarray | None:
    """Shortest 8-connected path between two points, keeping ``clearance_m`` from obstacles.

    Parameters
    ----------
    grid : OccupancyGrid
        The raw (uninflated) map.
    start_xy, goal_xy : array_like
        (2,) map-frame points [m].
    clearance_m : float
        [m] the grid is inflated by this radius first (:func:`inflate`), so every
        cell centre on the path is farther than ``clearance_m`` from every
        occupied cell centre; for a robot, half its width plus a margin.

    Returns
    -------
    numpy.ndarray or None
        (k, 2) [m] centres of the path's cells, the first the start's cell and the
        last the goal's; ``None`` when either cell is outside the grid or blocked,
        or when the goal cannot be reached.

    Notes
    -----
    A* on the 8-connected inflated grid; a diagonal step may not cut the corner of an
    occupied cell. Ties are broken towards the goal (heuristic scaled by ``1 + 1e-6``),
    so the path is within a factor ``1 + 1e-6`` of the shortest grid path.
    """
    blocked = inflate(grid, clearance_m).occupied
    rows, cols = blocked.shape
    cells = grid.world_to_cell(np.array([start_xy, goal_xy], dtype=float).reshape(2, 2))
    for r, c in cells:
        if not (0 <= r < rows and 0 <= c < cols) or blocked[r, c]:
            return None
    # a frame of blocked cells, so that neighbours never need a bounds check
    width = cols + 2
    padded = np.ones((rows + 2, width), dtype=bool)
    padded[1:-1, 1:-1] = blocked
    free = (~padded).ravel().tolist()
    start = int((cells[0, 0] + 1) * width + cells[0, 1] + 1)
    goal = int((cells[1, 0] + 1) * width + cells[1, 1] + 1)
    # octile-distance heuristic, precomputed, nudged to break ties towards the goal
    rr, cc = np.divmod(np.arange(padded.size), width)
    dr, dc = np.abs(rr - (goal // width)), np.abs(cc - (goal % width))
    lo, hi = np.minimum(dr, dc), np.maximum(dr, dc)
    heuristic = ((hi - lo + _SQRT2 * lo) * (1.0 + 1e-6)).tolist()

    parent = _a_star(free, heuristic, start, goal, width)
    if parent is None:
        return None
    chain = [goal]
    while chain[-1] != start:
        chain.append(parent[chain[-1]])
    flat = np.array(chain[::-1])
    rc = np.column_stack((flat // width - 1, flat % width - 1))
    return grid.cell_to_world(rc)
