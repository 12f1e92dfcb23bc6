"""Clearance as the thesis's Sec. 7.5 measured it: the distance "recorded by the LRF"
(Fig. 7.44b, Table 7.10).

The quadrotor of Sec. 7.5 carried one 360-degree laser scanner at its centre; its clearance
is the scan's minimum range. This platform's robot has two scanners off its centre, so the
same quantity is the minimum over both scans' hits of the distance from the robot's centre
(:func:`lrf_range`), i.e. what one centred 360-degree scanner would read; the robot's size
is not subtracted (the thesis's 0.4-0.6 m through narrow doorways with a 0.39 m radius
robot are ranges from the centre). :class:`RangeStats` accumulates it over a trial: mean and
standard deviation (Table 7.10), minimum, and a histogram on the bins of
:data:`tasks.primary.CLEARANCE_BIN_EDGES_M` (Fig. 7.44b). docs/decisions.md has the choice.
"""

from __future__ import annotations

import math

import numpy as np

from tasks._geometry_kernels import min_norm_sq
from tasks.primary import CLEARANCE_BIN_EDGES_M


def lrf_range(points: np.ndarray) -> float:
    """Minimum distance [m] from the robot's centre to the laser hits.

    Parameters
    ----------
    points : ndarray, shape (m, 2)
        Laser hits of every scanner [m] in the robot frame (``Observation.points``).

    Returns
    -------
    float
        ``min_i |p_i|``; ``inf`` without hits (nothing within range).
    """
    p = np.ascontiguousarray(points, dtype=float).reshape(-1, 2)
    if len(p) == 0:
        return math.inf
    return math.sqrt(min_norm_sq(p))


class RangeStats:
    """Running statistics of one trial's per-tick :func:`lrf_range` values."""

    def __init__(self) -> None:
        self.n_ = 0  # finite values
        self.sum_ = 0.0
        self.sum_sq_ = 0.0
        self.min_ = math.inf
        self.histogram_ = np.zeros(len(CLEARANCE_BIN_EDGES_M), dtype=int)  # last: >= 2 m

    def add(self, value: float) -> None:
        """Count one tick (``inf``, nothing in range, goes to the overflow bin only)."""
        if math.isnan(value):
            return
        k = int(np.searchsorted(CLEARANCE_BIN_EDGES_M, value, side="right")) - 1
        self.histogram_[min(max(k, 0), len(self.histogram_) - 1)] += 1
        if math.isfinite(value):
            self.n_ += 1
            self.sum_ += value
            self.sum_sq_ += value * value
            self.min_ = min(self.min_, value)

    def summary(self) -> dict[str, object]:
        """``{mean_m, std_m, min_m, samples, histogram}``; None for the statistics without
        finite values. ``std_m`` is the population SD (ddof 0), as the trial's footprint
        clearance."""
        if self.n_:
            mean = self.sum_ / self.n_
            std = math.sqrt(max(0.0, self.sum_sq_ / self.n_ - mean * mean))
            stats: tuple[float | None, ...] = (mean, std, self.min_)
        else:
            stats = (None, None, None)
        return {
            "mean_m": stats[0],
            "std_m": stats[1],
            "min_m": stats[2],
            "samples": int(self.histogram_.sum()),
            "histogram": [int(c) for c in self.histogram_],
        }
