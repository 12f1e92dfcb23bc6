"""Doorways and gaps found in an occupancy map image (thesis appendix Alg. 5, adapted;
spec section 6). The parts Alg. 5 pairs are boundary cells, not 24 azimuth sectors, and a
pair is kept as the exact-geometry derivation (:mod:`sim.semantics.passages`) keeps a pair
of shapes; the rules and why are in docs/decisions.md ("Semantic components from a map
image"). In order: candidate pairs a passage width apart (:func:`_candidates`), closest
points within ``NEIGHBOUR_M``, a line at least ``FREE_SHARE`` free, not two legs of one
table, stretches (``STRETCH_LINK_M``), the geometry's checks (centre clearance,
``MAX_PASSAGE_DEPTH_M``, room for the robot on both sides), then near passages merged
as the geometry merges them (:func:`sim.semantics.passages._merge`). Between two wall
blobs it is a doorway, else a gap.
"""

from __future__ import annotations

import numpy as np
from scipy.spatial import cKDTree

from sim.scene import Scenario
from sim.semantics.map_image import TABLE_MARGIN_M, MapImage, _in_table
from sim.semantics.passages import (
    CORRIDOR_PROBE_SLACK_M,
    DEPTH_STEP_M,
    MAX_PASSAGE_DEPTH_M,
    SIDE_PROBE_SLACK_M,
    _crossing_normal,
    _merge,
    _Passage,
)

FREE_SHARE = 0.95  # Alg. 5: the share of free cells on the line between the two parts
END_CELLS = 1.5  # [cells] of the line next to each end left out of the free share
NEIGHBOUR_M = 0.15  # [m] an end is the nearest boundary cell to the other within this
STRETCH_LINK_M = 0.3  # [m] candidates whose ends (as one 4-vector) are this close: a stretch
GRAZE_M = 1e-6  # [m] a depth probe this close to an occupied cell touches it
CENTRE_TOLERANCE_M = 0.1  # [m] the centre's clearance may fall this short of width / 2


def _candidates(image: MapImage, lo: float, hi: float) -> tuple[np.ndarray, np.ndarray]:
    """Steps 1-3: the boundary cells' centres ``xy`` (n, 2) [m] and the kept pairs (k, 2)
    of indices into it."""
    res = image.grid.resolution
    xy = image.cell_centres(np.argwhere(image.boundary).astype(float))
    if len(xy) < 2:
        return xy, np.empty((0, 2), dtype=int)
    tree = cKDTree(xy)
    pairs = tree.query_pairs(hi + 1e-9, output_type="ndarray")
    width = np.linalg.norm(xy[pairs[:, 0]] - xy[pairs[:, 1]], axis=1)
    pairs, width = pairs[width >= lo - 1e-9], width[width >= lo - 1e-9]
    for radius in (1.5 * res, NEIGHBOUR_M):  # the 8 neighbours first: cheap, drops most
        pairs, width = _closest(tree, xy, pairs, width, radius)
    return xy, pairs[_free(image, xy[pairs[:, 0]], xy[pairs[:, 1]]) >= FREE_SHARE - 1e-12]


def _closest(
    tree: cKDTree, xy: np.ndarray, pairs: np.ndarray, width: np.ndarray, radius: float
) -> tuple[np.ndarray, np.ndarray]:
    """Step 2: the pairs (and widths) whose ends are each the other's nearest boundary
    cell among those within ``radius`` [m] of it."""
    ends = np.unique(pairs)
    near = tree.query_ball_point(xy[ends], radius + 1e-9)
    table = np.full((len(xy), max(map(len, near), default=1)), -1)
    for i, row in zip(ends, near, strict=True):
        table[i, : len(row)] = row
    keep = np.ones(len(pairs), dtype=bool)
    for mine, other in ((0, 1), (1, 0)):
        around = table[pairs[:, mine]]  # (k, m): cells near one end
        gap = np.linalg.norm(xy[np.maximum(around, 0)] - xy[pairs[:, other]][:, None], axis=2)
        keep &= np.where(around >= 0, gap, np.inf).min(axis=1) >= width - 1e-9
    return pairs[keep], width[keep]


def _free(image: MapImage, p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Step 3: the share (k,) of free samples on each segment ``p``-``q`` (k, 2) [m],
    sampled every quarter cell, leaving out ``END_CELLS`` at each end."""
    if len(p) == 0:
        return np.empty(0)
    res = image.grid.resolution
    length = np.linalg.norm(q - p, axis=1)
    t = np.linspace(0.0, 1.0, int(np.ceil(length.max() / res * 4)) + 2)
    along = t[None, :] * length[:, None]
    inner = (along >= END_CELLS * res) & (along <= length[:, None] - END_CELLS * res)
    hit = image.occupied_at(p[:, None, :] + t[None, :, None] * (q - p)[:, None, :]) & inner
    return 1.0 - hit.sum(axis=1) / np.maximum(inner.sum(axis=1), 1)


def _not_legs(scenario: Scenario, xy: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """Step 4: the pairs whose two ends are not both under one table's top."""
    keep = np.ones(len(pairs), dtype=bool)
    for table in scenario.tables:
        inside = _in_table(xy, table, TABLE_MARGIN_M)
        keep &= ~(inside[pairs[:, 0]] & inside[pairs[:, 1]])
    return pairs[keep]


def _stretches(xy: np.ndarray, pairs: np.ndarray) -> list[np.ndarray]:
    """Step 5: the pairs grouped into stretches, each (k, 2) [indices into ``xy``] with
    its ends in a consistent order (column 0 on one side)."""
    n = len(pairs)
    if n == 0:
        return []
    p, q = xy[pairs[:, 0]], xy[pairs[:, 1]]
    both = cKDTree(np.vstack((np.hstack((p, q)), np.hstack((q, p)))))
    parent = np.arange(n)

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for a, b in both.query_pairs(STRETCH_LINK_M + 1e-9):
        parent[root(a % n)] = root(b % n)
    groups: dict[int, list[int]] = {}
    for i in range(n):
        groups.setdefault(root(i), []).append(i)
    out = []
    for members in groups.values():
        g = pairs[members]
        first = xy[g[0, 0]]
        swap = np.linalg.norm(xy[g[:, 1]] - first, axis=1) < np.linalg.norm(
            xy[g[:, 0]] - first, axis=1
        )
        g[swap] = g[swap][:, ::-1]
        out.append(g)
    return out


def _depth_steps(image: MapImage, centre: np.ndarray, ends: np.ndarray, cap: int) -> int:
    """Like :func:`sim.semantics.passages._passage_depth` in steps of ``DEPTH_STEP_M``:
    how many probe lines parallel to the passage, on both sides of it, find an occupied
    cell within ``width / 2 + CORRIDOR_PROBE_SLACK_M`` each way (at most ``cap``)."""
    along = (ends[1] - ends[0]) / np.linalg.norm(ends[1] - ends[0])
    normal = np.array([-along[1], along[0]])
    reach = np.linalg.norm(ends[1] - ends[0]) / 2 + CORRIDOR_PROBE_SLACK_M
    t = np.linspace(0.0, reach, int(np.ceil(reach / image.grid.resolution * 4)) + 1)
    offsets = np.arange(1, cap + 1) * DEPTH_STEP_M
    total = 0
    for side in (1.0, -1.0):
        origins = centre + side * offsets[:, None] * normal  # (cap, 2)
        # a probe grazing a cell's edge counts, as in the geometry: look a hair each way
        shift = (GRAZE_M * np.array([-1.0, 1.0]))[:, None] * normal  # (2, 2)
        lines = origins[:, None, None, :] + shift[None, :, None, :]  # (cap, 2, 1, 2)
        ray = t[:, None] * along  # (m, 2)
        ahead = image.occupied_at(lines + ray).any(axis=(1, 2))
        both = ahead & image.occupied_at(lines - ray).any(axis=(1, 2))
        total += cap if both.all() else int(np.argmin(both))
    return min(total, cap)


def _passage(
    image: MapImage, scenario: Scenario, xy: np.ndarray, stretch: np.ndarray
) -> _Passage | None:
    """Step 6: the passage of one stretch, or None when it fails a check."""
    res = image.grid.resolution
    width = np.linalg.norm(xy[stretch[:, 0]] - xy[stretch[:, 1]], axis=1)
    best = stretch[width <= width.min() + res / 2]
    ends = np.vstack((xy[best[:, 0]].mean(axis=0), xy[best[:, 1]].mean(axis=0)))
    centre, w = ends.mean(axis=0), float(width.min())
    (x_min, y_min), (x_max, y_max) = scenario.bounds
    if not (x_min <= centre[0] <= x_max and y_min <= centre[1] <= y_max):
        return None
    if float(image.clearance_at(centre)) < w / 2 - CENTRE_TOLERANCE_M:
        return None  # a third obstacle is nearer than the two ends
    limit = round(MAX_PASSAGE_DEPTH_M / DEPTH_STEP_M)
    if _depth_steps(image, centre, ends, limit + 1) > limit:
        return None  # the side of a corridor, not an opening
    reach = scenario.robot.length / 2 + SIDE_PROBE_SLACK_M
    sides = centre + np.array([[1.0], [-1.0]]) * reach * _crossing_normal(ends)
    if float(image.clearance_at(sides).min()) < scenario.robot.width / 2:
        return None  # a pocket beside furniture the robot can enter at most
    cells = tuple(image.cells(ends).T)
    kind = "doorway" if bool((image.parts[cells] == -1).all()) else "gap"
    blobs = image.labels[cells]
    return _Passage(kind, centre, ends, w, (f"blob_{blobs[0]}", f"blob_{blobs[1]}"))


def map_passages(image: MapImage, scenario: Scenario) -> list[_Passage]:
    """The doorways and gaps of ``image`` (steps 1-7 of the module docstring), with the
    scenario's passage widths, bounds, tables and robot size."""
    lo, hi = scenario.semantics.passage_width
    xy, pairs = _candidates(image, lo, hi)
    pairs = _not_legs(scenario, xy, pairs)
    found = [_passage(image, scenario, xy, s) for s in _stretches(xy, pairs)]
    return _merge([p for p in found if p is not None])
