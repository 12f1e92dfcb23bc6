"""Compiled loop of the reactive mode's environment model (:mod:`autonomy.reactive_bn`,
Eq. 3.12): one scanner's cells marked Free and Occupied. The same comparisons and
floating-point operations as the numpy code it replaced (kept in
``tests/reactive_reference.py``), so its states are identical."""

from __future__ import annotations

import numpy as np
from numba import njit


@njit(cache=True)
def mark_scan(
    free, occupied, seen, beam, far, ranges, cos, sin, ox, oy, max_range, resolution, half, lookup
) -> None:
    """Mark the zone cells one scan sees: ``free[seen[k]]`` when the range of its nearest
    beam ``beam[k]`` exceeds ``far[k]`` [m]; ``occupied[c]`` for the cell ``c`` of every
    laser hit (a range below ``max_range`` [m]; the hit at ``(ox, oy) + range (cos, sin)``
    rounded to the grid of ``resolution`` [m] and ``2 half + 1`` cells a side, ``lookup``
    its zone cell or -1). ``free``, ``occupied`` (n,) bool, updated in place."""
    for k in range(seen.shape[0]):
        if far[k] < ranges[beam[k]]:
            free[seen[k]] = True
    size = 2 * half + 1
    for b in range(ranges.shape[0]):
        r = ranges[b]
        if r < max_range:
            ix = int(np.rint((ox + r * cos[b]) / resolution)) + half
            iy = int(np.rint((oy + r * sin[b]) / resolution)) + half
            if 0 <= ix < size and 0 <= iy < size:
                cell = lookup[ix * size + iy]
                if cell >= 0:
                    occupied[cell] = True
