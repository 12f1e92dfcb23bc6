"""Semantic components from an occupancy map image: the objects and walls of thesis
appendix Alg. 4 (spec section 6), as the thesis found them in its SLAM map.

:func:`prepare_map` cleans the image (speckle dropped, gaps up to twice ``CLOSE_M``
closed), labels its 8-connected blobs, marks the cells of the morphological gradient
(the boundary cells, Alg. 4's gradient and threshold) and sorts the occupied cells into
objects (what survives an opening ``OBJECT_MIN_WIDTH_M`` across, and small blobs) and
walls (the rest of blobs at least ``WALL_MIN_LENGTH_M`` long, as ``asa scenario
from-map`` decides); cells under a table's top are the dock, neither.
:func:`map_surface_components` turns them into ``object_<k>`` (an object's contour) and
``wall_<k>`` (a straight stretch of the walls' contours, ``cv2.approxPolyDP``)
components. The doorways and gaps (Alg. 5) are :mod:`sim.semantics.map_passages`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np
from scipy import ndimage
from scipy.spatial import cKDTree

from sim.occupancy import OccupancyGrid, build_grid, clearance_map
from sim.scene import Scenario, Table

MAP_RESOLUTION_M = 0.05  # [m] the cell side a scene is rendered at without a map file
SPECKLE_CELLS = 3  # blobs of fewer occupied cells are noise (outside table footprints)
CLOSE_M = 0.1  # [m] breaks up to about twice this wide are closed (morphological closing)
OBJECT_MIN_WIDTH_M = 0.3  # [m] an opening by a disc this wide keeps objects, not walls
WALL_MIN_LENGTH_M = 1.0  # [m] a blob whose bounding box is this long is walls
WALL_TOLERANCE_M = 0.1  # [m] a wall contour's straight stretches deviate at most this
WALL_MIN_SEGMENT_M = 0.3  # [m] shorter stretches of a wall contour are no wall segment
NAME_REACH_M = 0.3  # [m] a scene element this near a map object names it
TABLE_MARGIN_M = 0.05  # [m] a table's top grown by this covers its legs (the dock)
_CROSS = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], np.uint8)


@dataclass(frozen=True, slots=True)
class MapImage:
    """A map cleaned for semantic extraction.

    ``grid`` the cleaned occupancy; ``labels`` (rows, cols) int32 its 8-connected blobs
    (0 free); ``parts`` (rows, cols) int32 what each cell is part of: an object ``k >=
    1``, a wall ``-1``, free or under a table ``0``; ``boundary`` (rows, cols) bool the
    occupied cells with a free 4-neighbour; ``clearance`` (rows, cols) [m] distance from
    a cell centre to the nearest occupied cell (0 on them).
    """

    grid: OccupancyGrid
    labels: np.ndarray
    parts: np.ndarray
    boundary: np.ndarray
    clearance: np.ndarray

    def cell_centres(self, rc: np.ndarray) -> np.ndarray:
        """Map-frame centres (k, 2) [m] of cells ``rc`` (k, 2) given as (row, col)."""
        res = self.grid.resolution
        return np.asarray(self.grid.origin) + (rc[:, ::-1] + 0.5) * res

    def cells(self, xy: np.ndarray) -> np.ndarray:
        """(row, col) (..., 2) int of the cells holding map points ``xy`` (..., 2) [m]; may
        lie outside the grid."""
        col_row = np.floor((xy - np.asarray(self.grid.origin)) / self.grid.resolution)
        return col_row[..., ::-1].astype(int)

    def occupied_at(self, xy: np.ndarray) -> np.ndarray:
        """Whether each map point ``xy`` (..., 2) [m] lies in an occupied cell (outside the
        grid: free)."""
        rc = self.cells(xy)
        rows, cols = self.grid.occupied.shape
        inside = (rc[..., 0] >= 0) & (rc[..., 0] < rows) & (rc[..., 1] >= 0) & (rc[..., 1] < cols)
        out = np.zeros(rc.shape[:-1], dtype=bool)
        out[inside] = self.grid.occupied[rc[..., 0][inside], rc[..., 1][inside]]
        return out

    def clearance_at(self, xy: np.ndarray) -> np.ndarray:
        """:attr:`clearance` at map points ``xy`` (..., 2) [m] (outside the grid: 0)."""
        rc = self.cells(xy)
        rows, cols = self.grid.occupied.shape
        inside = (rc[..., 0] >= 0) & (rc[..., 0] < rows) & (rc[..., 1] >= 0) & (rc[..., 1] < cols)
        out = np.zeros(rc.shape[:-1])
        out[inside] = self.clearance[rc[..., 0][inside], rc[..., 1][inside]]
        return out


def scenario_map(scenario: Scenario) -> OccupancyGrid:
    """The map a scenario's semantics read: ``[semantics] map`` as loaded, else the scene
    rendered at ``MAP_RESOLUTION_M`` as a laser at robot height sees it."""
    grid = scenario.semantics.map_grid
    return grid if grid is not None else build_grid(scenario, resolution=MAP_RESOLUTION_M)


def _in_table(points: np.ndarray, table: Table, margin: float) -> np.ndarray:
    """Whether each point (k, 2) [m] lies within ``table``'s top grown by ``margin``."""
    c, s = math.cos(table.yaw), math.sin(table.yaw)
    d = points - np.asarray(table.centre)
    along, across = d[:, 0] * c + d[:, 1] * s, -d[:, 0] * s + d[:, 1] * c
    return (np.abs(along) <= table.size[0] / 2 + margin) & (
        np.abs(across) <= table.size[1] / 2 + margin
    )


def _legs(labels: np.ndarray, grid: OccupancyGrid, tables: tuple[Table, ...]) -> np.ndarray:
    """Per label (blobs + 1,): whether the blob lies within a table's top grown by
    ``TABLE_MARGIN_M`` (a leg)."""
    res = grid.resolution
    leg = np.zeros(int(labels.max()) + 1, bool)
    for k, box in enumerate(ndimage.find_objects(labels), start=1):
        if box is None or not tables:
            continue
        rows, cols = box
        corners = np.array([[rows.start, cols.start], [rows.stop - 1, cols.stop - 1]], float)
        xy = np.asarray(grid.origin) + (corners[:, ::-1] + 0.5) * res
        leg[k] = any(bool(_in_table(xy, t, TABLE_MARGIN_M).all()) for t in tables)
    return leg


def _table_cells(grid: OccupancyGrid, tables: tuple[Table, ...]) -> np.ndarray:
    """(rows, cols) bool: the cells whose centre lies under a table's top grown by
    ``TABLE_MARGIN_M`` (the dock: neither object nor wall)."""
    out = np.zeros(grid.occupied.shape, dtype=bool)
    if not tables:
        return out
    rows, cols = grid.occupied.shape
    rc = np.stack(np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij"), axis=-1)
    xy = np.asarray(grid.origin) + (rc[..., ::-1].reshape(-1, 2) + 0.5) * grid.resolution
    for table in tables:
        out |= _in_table(xy, table, TABLE_MARGIN_M).reshape(rows, cols)
    return out


def _parts(occupied: np.ndarray, blobs: np.ndarray, dock: np.ndarray, res: float) -> np.ndarray:
    """Objects and walls of the occupied cells not under a table (``dock``), given their
    8-connected ``blobs`` (:attr:`MapImage.parts`).

    An object is what survives an opening by a disc ``OBJECT_MIN_WIDTH_M`` across,
    rounded up to an odd number of cells (a wall is thinner), with the occupied cells
    within two cells of it; the rest of a blob whose bounding box reaches
    ``WALL_MIN_LENGTH_M`` is wall, the rest of a smaller blob an object too (a thin box).
    """
    body = occupied & ~dock
    size = 2 * max(int(round(OBJECT_MIN_WIDTH_M / res / 2)), 1) + 1
    disc = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (size, size))
    thick = cv2.morphologyEx(body.astype(np.uint8), cv2.MORPH_OPEN, disc).astype(bool)
    objects, n = ndimage.label(thick, structure=np.ones((3, 3)))
    parts = np.zeros(occupied.shape, np.int32)
    if n:
        distance, (rows, cols) = ndimage.distance_transform_edt(objects == 0, return_indices=True)
        near = body & (distance <= 2.0)
        parts[near] = objects[rows[near], cols[near]]
    long_blob = np.zeros(int(blobs.max()) + 1, dtype=bool)
    for k, box in enumerate(ndimage.find_objects(blobs), start=1):
        if box is not None:
            extent = max(box[0].stop - box[0].start, box[1].stop - box[1].start) * res
            long_blob[k] = extent >= WALL_MIN_LENGTH_M - 1e-9
    rest = body & (parts == 0)
    parts[rest & long_blob[blobs]] = -1
    small, _ = ndimage.label(rest & ~long_blob[blobs], structure=np.ones((3, 3)))
    parts[small > 0] = n + small[small > 0]
    return parts


def prepare_map(grid: OccupancyGrid, tables: tuple[Table, ...] = ()) -> MapImage:
    """Clean ``grid`` and find its blobs, boundary, objects, walls and clearance (see the
    module docstring); ``tables`` (the scene's, known exactly) keep their legs from being
    dropped as speckle and mark the dock's cells."""
    res = grid.resolution
    labels, n = ndimage.label(grid.occupied, structure=np.ones((3, 3)))
    sizes = np.bincount(labels.ravel(), minlength=n + 1)
    keep = (sizes >= SPECKLE_CELLS) | _legs(labels, grid, tables)
    keep[0] = False
    occupied = keep[labels]
    close = max(int(round(CLOSE_M / res)), 0)
    if close:
        kernel = np.ones((2 * close + 1, 2 * close + 1), np.uint8)
        closed = cv2.morphologyEx(
            occupied.astype(np.uint8), cv2.MORPH_CLOSE, kernel, borderType=cv2.BORDER_REPLICATE
        )
        occupied = closed.astype(bool)
    cleaned = OccupancyGrid(occupied, grid.origin, res)
    labels, _ = ndimage.label(occupied, structure=np.ones((3, 3)))
    gradient = cv2.morphologyEx(occupied.astype(np.uint8) * 255, cv2.MORPH_GRADIENT, _CROSS)
    _, edges = cv2.threshold(gradient, 127, 255, cv2.THRESH_BINARY)
    return MapImage(
        grid=cleaned,
        labels=labels.astype(np.int32),
        parts=_parts(occupied, labels, _table_cells(cleaned, tables), res),
        boundary=(edges > 0) & occupied,
        clearance=clearance_map(cleaned),
    )


# ---------------------------------------------------------------- objects and walls


def _contours(mask: np.ndarray) -> list[np.ndarray]:
    """Every contour (outer and holes) of ``mask`` as (k, 2) (row, col) cells, in order."""
    found, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    return [c[:, 0, ::-1] for c in found]


def _in_bounds(points: np.ndarray, scenario: Scenario) -> np.ndarray:
    (x0, y0), (x1, y1) = scenario.bounds
    return points[
        (points[:, 0] >= x0) & (points[:, 0] <= x1) & (points[:, 1] >= y0) & (points[:, 1] <= y1)
    ]


def _object_points(image: MapImage, mask: np.ndarray, box: tuple, step: int) -> np.ndarray:
    """Points (k, 2) [m] along the outer contour of the object cells ``mask`` (within the
    slices ``box``), every ``step``-th cell."""
    outer, _ = cv2.findContours(mask.astype(np.uint8), cv2.RETR_EXTERNAL, cv2.CHAIN_APPROX_NONE)
    rc = max(outer, key=len)[:, 0, ::-1] + (box[0].start, box[1].start)
    return image.cell_centres(rc[::step].astype(float))


def _wall_segments(image: MapImage, mask: np.ndarray, box: tuple, spacing: float) -> list:
    """Points (k, 2) [m] along each straight stretch of the contours of the wall cells
    ``mask`` (within the slices ``box``) at least ``WALL_MIN_SEGMENT_M`` long, at most
    ``spacing`` apart (ends included)."""
    res = image.grid.resolution
    offset = np.array([box[0].start, box[1].start])
    out = []
    for contour in _contours(mask):
        poly = cv2.approxPolyDP(
            contour[:, None, ::-1].astype(np.int32), WALL_TOLERANCE_M / res, True
        )[:, 0, ::-1]
        corners = image.cell_centres((poly + offset).astype(float))
        for a, b in zip(corners, np.roll(corners, -1, axis=0), strict=True):
            length = float(np.hypot(*(b - a)))
            if length < WALL_MIN_SEGMENT_M:
                continue
            t = np.linspace(0.0, 1.0, max(1, math.ceil(length / spacing - 1e-9)) + 1)
            out.append(a + t[:, None] * (b - a))
    return out


def _element_names(image: MapImage, scenario: Scenario) -> dict[int, tuple[str, ...]]:
    """The scene's boxes and cylinders by the map object they lie on: the object at the
    element's centre, else the nearest object cell within ``NAME_REACH_M`` of it."""
    objects = np.argwhere(image.parts > 0)
    if len(objects) == 0:
        return {}
    tree = cKDTree(image.cell_centres(objects.astype(float)))
    names: dict[int, list[str]] = {}
    for element in (*scenario.boxes, *scenario.cylinders):
        distance, i = tree.query(np.asarray(element.centre, dtype=float))
        if distance <= NAME_REACH_M:
            names.setdefault(int(image.parts[tuple(objects[i])]), []).append(element.name)
    return {k: tuple(v) for k, v in names.items()}


def map_surface_components(
    image: MapImage, scenario: Scenario
) -> list[tuple[str, np.ndarray, tuple[str, ...]]]:
    """The objects, then the wall segments of the map, as ``(kind, points (k, 2) [m],
    source)`` within the scenario's bounds, each kind ordered by centre x, then y
    (components without points inside the bounds are dropped). An object's ``source``
    names the scene's boxes and cylinders on it (so the inspection object is known),
    a wall's is empty."""
    spacing = scenario.semantics.surface_spacing
    step = max(1, int(spacing / image.grid.resolution + 1e-9))
    names = _element_names(image, scenario)
    objects, walls = [], []
    for k, box in enumerate(ndimage.find_objects(np.maximum(image.parts, 0)), start=1):
        if box is not None:
            points = _in_bounds(_object_points(image, image.parts[box] == k, box, step), scenario)
            objects.append(("object", points, names.get(k, ())))
    wall_blobs, _ = ndimage.label(image.parts == -1, structure=np.ones((3, 3)))
    for k, box in enumerate(ndimage.find_objects(wall_blobs), start=1):
        for points in _wall_segments(image, wall_blobs[box] == k, box, spacing):
            walls.append(("wall", _in_bounds(points, scenario), ()))

    def order(found: list) -> list:
        kept = [c for c in found if len(c[1])]
        return sorted(kept, key=lambda c: (round(float(c[1][:, 0].mean()), 9), c[1][:, 1].mean()))

    return order(objects) + order(walls)
