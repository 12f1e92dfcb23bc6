"""The reactive mode's cell states as numpy computed them before issue 25 (the oracle of
tests/test_reactive_kernels.py; autonomy.reactive_bn.cell_states now runs a kernel)."""

from __future__ import annotations

from typing import Any

import numpy as np

from autonomy.reactive_bn import FREE, OCCUPIED, UNKNOWN, SectorGrid, _scan_geometry


def cell_states(scans: Any, grid: SectorGrid) -> np.ndarray:
    free = np.zeros(len(grid.cells), dtype=bool)
    occupied = np.zeros(len(grid.cells), dtype=bool)
    size = 2 * grid.half + 1
    for scan in scans:
        angles = np.asarray(scan.angles, dtype=float)
        ranges = np.asarray(scan.ranges, dtype=float)
        origin = np.asarray(scan.origin, dtype=float)
        if len(angles) < 2:
            continue
        seen, beam, far, cos, sin = _scan_geometry(grid, angles, origin)
        free[seen] |= far < ranges[beam]
        hit = ranges < scan.max_range
        r = ranges[hit]
        hx = origin[0] + r * cos[hit]
        hy = origin[1] + r * sin[hit]
        ix = np.rint(hx / grid.resolution).astype(int) + grid.half
        iy = np.rint(hy / grid.resolution).astype(int) + grid.half
        inside = (ix >= 0) & (ix < size) & (iy >= 0) & (iy < size)
        cell = grid.lookup[ix[inside] * size + iy[inside]]
        occupied[cell[cell >= 0]] = True
    return np.where(occupied, OCCUPIED, np.where(free, FREE, UNKNOWN))
