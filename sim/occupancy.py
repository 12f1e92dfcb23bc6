"""The scene's 2-D occupancy grid: rasterisation, clearance, inflation, A*, ROS map files.

The participant interface shows "the 2D occupancy grid map of the test scenario"
(thesis Sec. 7.6.1.1, Fig. 7.47 and 7.48(b)); the thesis extracted semantic
components from such a map at 0.05 m per cell (appendix, Alg. 4 and 5; spec
section 6). Here the map is rasterised from the scenario's exact geometry instead
of being built by SLAM, so it has none of the thesis map's sensor noise.

What a laser at robot height sees is occupied: walls, boxes, cylinders and the
legs of tables (not their tops: the robot drives under a table to dock). A cell
is occupied when the obstacle overlaps the cell with positive area, which
includes every cell whose centre lies inside it; this conservative rule never
misses a wall thinner than a cell. Obstacles merely touching a cell's edge do
not occupy it.

Decided here, where the spec is silent:

- Distances (:func:`clearance_map`, :func:`inflate`) are measured between cell
  centres, in metres. The exact Euclidean distance transform is computed in
  numpy alone (``sim`` may not import scipy, DESIGN.md): a 1-D distance ``g``
  along the longer axis by two sweeps, then for every cell the minimum over
  the shorter axis of ``(j - k)^2 + g(k)^2``, trying offsets ``|j - k|`` in
  increasing order until none can lower any value. The cost is
  ``O(rows * cols * D)`` for a largest distance of ``D`` cells, about 15 ms
  for the 16 m x 10 m room.
- :func:`inflate` occupies every cell whose centre is within ``radius_m`` of an
  occupied cell's centre (a disc dilation), i.e.
  ``clearance_map(grid) <= radius_m`` up to rounding.
- :func:`shortest_path` is A* on the 8-connected grid inflated by
  ``clearance_m``; a diagonal step may not cut the corner of an occupied cell.
  It returns ``None`` when the start or the goal cell is outside the grid or
  blocked in the inflated grid, or when no path joins them. Ties are broken
  towards the goal (heuristic scaled by ``1 + 1e-6``), so the returned path is
  within a factor ``1 + 1e-6`` of the shortest grid path.
- Map files follow ROS ``map_server``: occupied cells are written 0 (black),
  free cells 254 (white); reading back, a pixel is occupied when
  ``p > occupied_thresh`` and free when ``p < free_thresh`` with
  ``p = (255 - value) / 255`` (``negate: 0``); pixels in between are
  "unknown", and are loaded as occupied (not free), the safe reading for a
  planner. The map's ``origin`` yaw must be 0 (the grid is axis-aligned).
  Images may be binary or plain PGM (8 or 16 bit) or 8-bit PNG.
"""

from __future__ import annotations

import heapq
import math
import re
import struct
import zlib
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from sim.scenario import Box, Cylinder, Scenario

_EPS = 1e-9  # [m] geometric tolerance: touching is not overlapping

FREE_VALUE = 254  # PGM/PNG pixel of a free cell (ROS map_saver)
OCCUPIED_VALUE = 0  # PGM/PNG pixel of an occupied cell


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

    ``inf`` everywhere when nothing is occupied. (rows, cols) float64.
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

    # (offset, cost, the two orthogonal cells a diagonal step passes; 0 for straight steps)
    moves = [(1, 1.0, 0, 0), (-1, 1.0, 0, 0), (width, 1.0, 0, 0), (-width, 1.0, 0, 0)]
    moves += [(dy * width + dx, _SQRT2, dy * width, dx) for dy in (-1, 1) for dx in (-1, 1)]
    cost = [math.inf] * padded.size
    parent = [-1] * padded.size
    closed = bytearray(padded.size)
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
    chain = [goal]
    while chain[-1] != start:
        chain.append(parent[chain[-1]])
    flat = np.array(chain[::-1])
    rc = np.column_stack((flat // width - 1, flat % width - 1))
    return grid.cell_to_world(rc)


# ------------------------------------------------------------------------ files


def _image_rows(grid: OccupancyGrid) -> np.ndarray:
    """(rows, cols) uint8 image, row 0 the top of the map (image convention)."""
    img = np.where(grid.occupied, OCCUPIED_VALUE, FREE_VALUE).astype(np.uint8)
    return img[::-1]


def save_ros_map(grid: OccupancyGrid, directory: str | Path, stem: str) -> tuple[Path, Path]:
    """Write the grid as a ROS ``map_server`` map: ``stem.pgm`` and ``stem.yaml``.

    Parameters
    ----------
    grid : OccupancyGrid
    directory : str or Path
        Created if missing.
    stem : str
        File name without extension.

    Returns
    -------
    (Path, Path)
        The PGM image (P5, 0 = occupied, 254 = free, first row the top of the map)
        and the YAML description, in that order.
    """
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    pgm, yaml = directory / f"{stem}.pgm", directory / f"{stem}.yaml"
    img = _image_rows(grid)
    rows, cols = img.shape
    pgm.write_bytes(f"P5\n{cols} {rows}\n255\n".encode("ascii") + img.tobytes())
    yaml.write_text(
        f"image: {pgm.name}\n"
        f"resolution: {grid.resolution!r}\n"
        f"origin: [{grid.origin[0]!r}, {grid.origin[1]!r}, 0.0]\n"
        "negate: 0\n"
        "occupied_thresh: 0.65\n"
        "free_thresh: 0.196\n",
        encoding="utf-8",
    )
    return pgm, yaml


def _png_chunk(kind: bytes, data: bytes) -> bytes:
    return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data))


def save_png(grid: OccupancyGrid, path: str | Path) -> Path:
    """Write the grid as an 8-bit greyscale PNG (0 = occupied, 254 = free, top row = max y).

    Readable by :func:`load_ros_map` when named in a map YAML.
    """
    path = Path(path)
    img = _image_rows(grid)
    rows, cols = img.shape
    raw = np.hstack((np.zeros((rows, 1), np.uint8), img)).tobytes()  # filter byte 0 per row
    header = struct.pack(">IIBBBBB", cols, rows, 8, 0, 0, 0, 0)
    path.write_bytes(
        b"\x89PNG\r\n\x1a\n"
        + _png_chunk(b"IHDR", header)
        + _png_chunk(b"IDAT", zlib.compress(raw, 9))
        + _png_chunk(b"IEND", b"")
    )
    return path


def _read_pgm(data: bytes) -> np.ndarray:
    """PGM (P5 binary or P2 plain, 8 or 16 bit) -> (rows, cols) float in [0, 255]."""
    header = re.match(rb"(P[25])((?:\s+|#[^\n]*\n)+)", data)
    if header is None:
        raise ValueError("not a PGM image (P5 or P2)")
    tokens, pos = [], header.start(2)
    token_re = re.compile(rb"(?:\s|#[^\n]*(?:\n|$))*(\d+)")
    for _ in range(3):
        m = token_re.match(data, pos)
        if m is None:
            raise ValueError("PGM header must give width, height and maxval")
        tokens.append(int(m.group(1)))
        pos = m.end()
    cols, rows, maxval = tokens
    if cols < 1 or rows < 1 or not 1 <= maxval <= 65535:
        raise ValueError(f"bad PGM size {cols}x{rows} or maxval {maxval}")
    if header.group(1) == b"P2":
        values = np.array(data[pos:].split(), dtype=np.int64)
    else:
        pos += 1  # exactly one whitespace byte before the raster
        dtype = np.dtype(">u2") if maxval > 255 else np.dtype(np.uint8)
        values = np.frombuffer(data, dtype=dtype, count=-1, offset=pos)
    if values.size < rows * cols:
        raise ValueError(f"PGM raster holds {values.size} values, needs {rows * cols}")
    return values[: rows * cols].reshape(rows, cols).astype(float) * (255.0 / maxval)


def _unfilter_png(raw: bytes, rows: int, cols: int, bpp: int) -> np.ndarray:
    """Undo PNG's per-row filters (8-bit samples) -> (rows, cols * bpp) uint8."""
    stride = cols * bpp
    if len(raw) != rows * (stride + 1):
        raise ValueError("PNG image data has the wrong length")
    data = np.frombuffer(raw, dtype=np.uint8).reshape(rows, stride + 1)
    out = np.zeros((rows, stride), dtype=np.uint8)
    prev = np.zeros(stride, dtype=np.int64)
    for r in range(rows):
        kind, line = int(data[r, 0]), data[r, 1:].astype(np.int64)
        if kind == 0:
            cur = line
        elif kind == 1:  # Sub: cumulative sum per channel
            cur = np.cumsum(line.reshape(cols, bpp), axis=0).ravel() % 256
        elif kind == 2:  # Up
            cur = (line + prev) % 256
        elif kind in (3, 4):  # Average, Paeth: sequential along the row
            cur_l, line_l, prev_l = [0] * stride, line.tolist(), prev.tolist()
            for i in range(stride):
                a = cur_l[i - bpp] if i >= bpp else 0
                b = prev_l[i]
                if kind == 3:
                    cur_l[i] = (line_l[i] + (a + b) // 2) % 256
                else:
                    c = prev_l[i - bpp] if i >= bpp else 0
                    p = a + b - c
                    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                    pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                    cur_l[i] = (line_l[i] + pred) % 256
            cur = np.array(cur_l, dtype=np.int64)
        else:
            raise ValueError(f"unknown PNG filter type {kind}")
        out[r] = cur
        prev = cur
    return out


def _read_png(data: bytes) -> np.ndarray:
    """8-bit non-interlaced PNG (grey, RGB, grey+alpha, RGBA) -> (rows, cols) float in [0, 255].

    Colour is averaged over the colour channels; alpha is ignored.
    """
    if not data.startswith(b"\x89PNG\r\n\x1a\n"):
        raise ValueError("not a PNG image")
    pos, idat, header = 8, [], None
    while pos + 8 <= len(data):
        (length,) = struct.unpack(">I", data[pos : pos + 4])
        kind = data[pos + 4 : pos + 8]
        chunk = data[pos + 8 : pos + 8 + length]
        pos += 12 + length
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", chunk[:13])
        elif kind == b"IDAT":
            idat.append(chunk)
        elif kind == b"IEND":
            break
    if header is None or not idat:
        raise ValueError("PNG without IHDR or image data")
    cols, rows, depth, colour, _, _, interlace = header
    channels = {0: 1, 2: 3, 4: 2, 6: 4}.get(colour)
    if depth != 8 or channels is None or interlace != 0:
        raise ValueError(
            "only 8-bit, non-interlaced greyscale, RGB or RGBA PNG images are supported"
        )
    try:
        raw = zlib.decompress(b"".join(idat))
    except zlib.error as error:
        raise ValueError(f"corrupt PNG image data: {error}") from None
    pixels = _unfilter_png(raw, rows, cols, channels).reshape(rows, cols, channels)
    n_colour = 1 if channels <= 2 else 3
    return pixels[:, :, :n_colour].astype(float).mean(axis=2)


_YAML_COMMENT = re.compile(r"(?:^|\s)#.*$")  # YAML: '#' starts a comment after a blank
_YAML_KEYS = ("image", "resolution", "origin", "negate", "occupied_thresh", "free_thresh", "mode")


def _parse_map_yaml(path: Path) -> dict[str, str]:
    """The flat ``key: value`` lines of a ROS map YAML (values as text)."""
    try:
        text = path.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        raise ValueError(f"{path}: not a UTF-8 text file") from None
    fields: dict[str, str] = {}
    for number, line in enumerate(text.splitlines(), start=1):
        stripped = _YAML_COMMENT.sub("", line).strip()
        if not stripped or stripped == "---":
            continue
        key, sep, value = stripped.partition(":")
        key = key.strip().strip("'\"")
        if not sep or not key:
            raise ValueError(f"{path}: line {number}: expected 'key: value', got {line.strip()!r}")
        if key not in _YAML_KEYS:
            raise ValueError(
                f"{path}: field '{key}': is not a known field (known: {', '.join(_YAML_KEYS)})"
            )
        fields[key] = value.strip()
    return fields


def _yaml_number(path: Path, fields: dict[str, str], key: str, default: float | None) -> float:
    if key not in fields:
        if default is None:
            raise ValueError(f"{path}: field '{key}': is required")
        return default
    try:
        value = float(fields[key])
    except ValueError:
        raise ValueError(f"{path}: field '{key}': must be a number, got {fields[key]!r}") from None
    if not math.isfinite(value):
        raise ValueError(f"{path}: field '{key}': must be a finite number, got {fields[key]!r}")
    return value


def load_ros_map(yaml_path: str | Path) -> OccupancyGrid:
    """Read a ROS ``map_server`` map (YAML plus PGM or PNG image) into a grid.

    Parameters
    ----------
    yaml_path : str or Path
        The YAML file; its ``image`` is relative to the YAML's directory unless absolute.

    Returns
    -------
    OccupancyGrid
        Occupied where ``p > occupied_thresh`` or unknown; free where ``p < free_thresh``.

    Raises
    ------
    ValueError
        Naming the file and the field, on any bad content.
    FileNotFoundError
        When the YAML file does not exist.
    """
    path = Path(yaml_path)
    if not path.is_file():
        raise FileNotFoundError(2, "No such file", str(path))
    fields = _parse_map_yaml(path)

    if not fields.get("image"):
        raise ValueError(f"{path}: field 'image': is required (the map image's file name)")
    image = Path(fields["image"].strip("'\""))
    image = image if image.is_absolute() else path.parent / image

    resolution = _yaml_number(path, fields, "resolution", None)
    if resolution <= 0:
        raise ValueError(f"{path}: field 'resolution': must be positive, got {resolution}")

    origin_text = fields.get("origin")
    if origin_text is None:
        raise ValueError(f"{path}: field 'origin': is required, as [x, y, yaw]")
    m = re.fullmatch(r"\[([^\]]*)\]", origin_text)
    try:
        origin = [float(v) for v in m.group(1).split(",")] if m else []
    except ValueError:
        origin = []
    if len(origin) != 3 or not all(math.isfinite(v) for v in origin):
        raise ValueError(f"{path}: field 'origin': must be [x, y, yaw], got {origin_text!r}")
    if origin[2] != 0.0:
        raise ValueError(
            f"{path}: field 'origin': the yaw must be 0 (axis-aligned grids only), got {origin[2]}"
        )

    negate = _yaml_number(path, fields, "negate", 0.0)
    if negate not in (0.0, 1.0):
        raise ValueError(f"{path}: field 'negate': must be 0 or 1, got {fields['negate']!r}")
    occupied_thresh = _yaml_number(path, fields, "occupied_thresh", 0.65)
    free_thresh = _yaml_number(path, fields, "free_thresh", 0.196)
    if not 0.0 <= free_thresh <= occupied_thresh <= 1.0:
        raise ValueError(
            f"{path}: field 'free_thresh': must satisfy 0 <= free_thresh <= occupied_thresh "
            f"<= 1, got {free_thresh} and {occupied_thresh}"
        )
    mode = fields.get("mode", "trinary").strip("'\"")
    if mode not in ("trinary", "scale"):
        raise ValueError(f"{path}: field 'mode': must be trinary or scale, got {mode!r}")

    if not image.is_file():
        raise ValueError(f"{path}: field 'image': no such file {image}")
    data = image.read_bytes()
    try:
        pixels = _read_png(data) if data.startswith(b"\x89PNG") else _read_pgm(data)
    except ValueError as error:
        raise ValueError(f"{path}: field 'image': {image.name}: {error}") from None
    p = pixels / 255.0 if negate else (255.0 - pixels) / 255.0
    free = p < free_thresh
    return OccupancyGrid(~free[::-1].copy(), (origin[0], origin[1]), resolution)
