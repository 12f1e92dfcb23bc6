"""Alg. 4 and 5 of the thesis's appendix taken literally, on occupancy grids (issue 23):
how well do they find the doorways and gaps that the exact geometry gives?

Objects: morphological gradient (3 x 3), binary threshold, contours (OpenCV), contours
closer than 1.0 m merged. Gaps: each object split into 24 azimuth parts about its centre;
pairs of parts whose closest points are within the scene's passage widths; the connecting
line more than 95 % free; centres closer than 0.75 m merged, the narrowest kept. Scored
against ``sim.semantics.derive_components`` (doorways and gaps; a match within 0.3 m) on
the exact rendering and two noisy ones (``sim.map_noise``, seeds 1-2).

Needs ``pip install opencv-python-headless``. Run from the repository root:

    python docs/experiments/map_semantics_literal.py cluttered_room practice_course

Result (2026-11-27, docs/results.md "Issue 23"): precision and recall at most 0.5 and
0.33, mostly 0: merging contours closer than 1.0 m joins the walls on both sides of every
doorway (0.6-1.1 m wide in these scenes), so a doorway lies inside one object and the
azimuth split about that object's centre rarely puts its two edges in different parts.
The adapted algorithm the platform uses is ``sim.semantics.map_passages`` (its module
docstring; measured by ``asa bench --only map_semantics``).
"""

import itertools
import sys

import cv2
import numpy as np
from scipy.spatial import cKDTree

from sim.map_noise import noisy_scene_map
from sim.occupancy import OccupancyGrid, build_grid
from sim.scenario import load_scenario
from sim.semantics import derive_components


def _groups(n: int, close) -> list[list[int]]:
    """Single-linkage groups of ``0 .. n-1`` under ``close(i, j)``."""
    parent = list(range(n))

    def root(i: int) -> int:
        while parent[i] != i:
            parent[i] = parent[parent[i]]
            i = parent[i]
        return i

    for i, j in itertools.combinations(range(n), 2):
        if close(i, j):
            parent[root(j)] = root(i)
    out: dict[int, list[int]] = {}
    for i in range(n):
        out.setdefault(root(i), []).append(i)
    return list(out.values())


def objects(grid: OccupancyGrid, merge_m: float = 1.0) -> list[np.ndarray]:
    """Alg. 4: contour points (k, 2) [m] per object, contours closer than ``merge_m``
    merged."""
    img = np.where(grid.occupied, 0, 254).astype(np.uint8)
    grad = cv2.morphologyEx(img, cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8))
    _, bw = cv2.threshold(grad, 127, 255, cv2.THRESH_BINARY)
    contours, _ = cv2.findContours(bw, cv2.RETR_LIST, cv2.CHAIN_APPROX_NONE)
    res, (x0, y0) = grid.resolution, grid.origin
    pts = [(c[:, 0, :] + 0.5) * res + (x0, y0) for c in contours]
    trees = [cKDTree(p) for p in pts]

    def close(i: int, j: int) -> bool:
        d, _ = trees[j].query(pts[i], k=1, distance_upper_bound=merge_m)
        return bool(np.any(d < merge_m))

    return [np.vstack([pts[i] for i in g]) for g in _groups(len(pts), close)]


def _free_ratio(grid: OccupancyGrid, p: np.ndarray, q: np.ndarray) -> float:
    """Share of free cells along the segment p-q (Alg. 5, lines 23-29)."""
    res, origin = grid.resolution, np.asarray(grid.origin)
    m = max(2, int(np.ceil(np.hypot(*(q - p)) / res * 2)))
    line = p + np.linspace(0, 1, m)[:, None] * (q - p)
    cells = ((line - origin) / res).astype(int)
    rows = np.clip(cells[:, 1], 0, grid.occupied.shape[0] - 1)
    cols = np.clip(cells[:, 0], 0, grid.occupied.shape[1] - 1)
    return float(np.mean(~grid.occupied[rows, cols]))


def _parts(objs: list[np.ndarray], n: int) -> list[np.ndarray]:
    """Each object split into ``n`` azimuth parts about its centre (Alg. 5, lines 3-12)."""
    parts = []
    for o in objs:
        c = o.mean(axis=0)
        az = np.arctan2(o[:, 1] - c[1], o[:, 0] - c[0]) % (2 * np.pi)
        idx = np.minimum((az / (2 * np.pi) * n).astype(int), n - 1)
        parts += [o[idx == i] for i in range(n) if np.any(idx == i)]
    return parts


def gaps(grid, objs, n=24, dmin=1.1, dmax=1.4, tau=0.95, merge=0.75) -> np.ndarray:
    """Alg. 5: gap centres (g, 2) [m]."""
    parts = _parts(objs, n)
    trees = [cKDTree(p) for p in parts]
    found = []
    for i, j in itertools.combinations(range(len(parts)), 2):
        d, k = trees[j].query(parts[i], k=1, distance_upper_bound=dmax + 1e-9)
        a = int(np.argmin(d))
        if not dmin <= d[a] <= dmax:
            continue
        p, q = parts[i][a], parts[j][k[a]]
        if _free_ratio(grid, p, q) > tau:
            found.append(((p + q) / 2, d[a]))
    keep: list[np.ndarray] = []
    for centre, _width in sorted(found, key=lambda t: t[1]):  # the narrowest first
        if all(np.hypot(*(centre - c)) >= merge for c in keep):
            keep.append(centre)
    return np.array(keep).reshape(-1, 2)


def score(found: np.ndarray, truth: np.ndarray, tol: float = 0.3) -> tuple[float, float]:
    """(precision, recall): a found centre within ``tol`` [m] of a true one matches."""
    if len(truth) == 0 or len(found) == 0:
        return float(len(found) == 0), float(len(truth) == 0)
    d = np.linalg.norm(found[:, None, :] - truth[None, :, :], axis=2)
    return float((d.min(axis=1) <= tol).mean()), float((d.min(axis=0) <= tol).mean())


def main(names: list[str]) -> None:
    for name in names:
        sc = load_scenario(name)
        comps = derive_components(sc)
        truth = np.array([c.centre for c in comps if c.kind in ("doorway", "gap")])
        lo, hi = sc.semantics.passage_width
        for seed in range(3):
            grid = noisy_scene_map(sc, np.random.default_rng(seed)) if seed else build_grid(sc)
            objs = objects(grid)
            found = gaps(grid, objs, dmin=lo, dmax=hi)
            prec, rec = score(found, truth.reshape(-1, 2))
            kind = "exact" if seed == 0 else f"noisy {seed}"
            print(
                f"{name} ({kind}): {len(objs)} objects, {len(found)} passages found, "
                f"{len(truth)} true; precision {prec:.2f}, recall {rec:.2f}"
            )


if __name__ == "__main__":
    main(sys.argv[1:] or ["cluttered_room", "practice_course", "demo_doorway_crossing"])
