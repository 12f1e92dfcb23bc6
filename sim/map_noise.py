"""SLAM-like noise on an occupancy grid: a scene rendered as a map a real robot would
have built (issue 23; thesis appendix: the semantic components were found in the SLAM
map image, Alg. 4 and 5).

:func:`noisy_grid` takes an exact grid (``sim.occupancy.build_grid``) and, with the
generator passed in, thickens the obstacles' edges raggedly, breaks walls in short
stretches and sprinkles speckle over the free space. The example map
(``examples/maps/``) is made by :func:`noisy_scene_map`; the later measurement of
map-based semantic components can draw its maps the same way.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import ndimage, special

from sim.occupancy import OccupancyGrid, build_grid
from sim.scene import Scenario


@dataclass(frozen=True, slots=True)
class MapNoise:
    """How noisy a rendered map is; change with ``dataclasses.replace``.

    Probabilities are per cell; lengths in cells of the grid.
    """

    thicken_p: float = 0.35  # share of the free cells touching an obstacle that become occupied
    thicken_passes: int = 1  # rounds of thickening (each one cell deep at most)
    thicken_run_cells: float = 3.0  # [cells] correlation length: thickening comes in stretches
    break_p: float = 0.01  # an occupied edge cell starts a break (cleared stretch)
    break_cells: tuple[int, int] = (1, 2)  # [cells] side of a cleared square, min and max
    speckle_p: float = 0.0005  # a free cell becomes an isolated occupied cell

    def __post_init__(self) -> None:
        for name in ("thicken_p", "break_p", "speckle_p"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"MapNoise: field '{name}': must lie in [0, 1], got {value!r}")
        lo, hi = self.break_cells
        if not 1 <= lo <= hi:
            raise ValueError(
                f"MapNoise: field 'break_cells': must be (min, max) with 1 <= min <= max, "
                f"got {self.break_cells!r}"
            )
        if self.thicken_passes < 0:
            raise ValueError("MapNoise: field 'thicken_passes': must be 0 or more")


def _touching(occupied: np.ndarray) -> np.ndarray:
    """Free cells with an occupied 4-neighbour, (rows, cols) bool."""
    near = np.zeros_like(occupied)
    near[1:] |= occupied[:-1]
    near[:-1] |= occupied[1:]
    near[:, 1:] |= occupied[:, :-1]
    near[:, :-1] |= occupied[:, 1:]
    return near & ~occupied


def _edge_cells(occupied: np.ndarray) -> np.ndarray:
    """Occupied cells with a free 4-neighbour, (rows, cols) bool."""
    return _touching(~occupied)


def _smooth_uniform(rng: np.random.Generator, shape: tuple[int, int], length: float) -> np.ndarray:
    """Values in [0, 1], uniform in distribution, correlated over ``length`` cells: a
    Gaussian-blurred white noise mapped through its normal CDF (so ``< p`` holds for a
    share ``p`` of the cells, in patches rather than single cells)."""
    field = rng.standard_normal(shape)
    if length > 0:
        field = ndimage.gaussian_filter(field, length, mode="wrap")
        field /= max(float(field.std()), 1e-12)
    return 0.5 * (1.0 + special.erf(field / np.sqrt(2.0)))


def noisy_occupancy(
    occupied: np.ndarray, rng: np.random.Generator, noise: MapNoise = MapNoise()
) -> np.ndarray:
    """A noisy copy of ``occupied`` (rows, cols) bool: ragged thickening, then breaks in
    the edges, then speckle, each drawn from ``rng`` in that order."""
    out = np.array(occupied, dtype=bool)
    for _ in range(noise.thicken_passes):
        out |= _touching(out) & (
            _smooth_uniform(rng, out.shape, noise.thicken_run_cells) < noise.thicken_p
        )
    starts = np.argwhere(_edge_cells(out) & (rng.random(out.shape) < noise.break_p))
    lo, hi = noise.break_cells
    sides = rng.integers(lo, hi + 1, size=len(starts))
    for (r, c), side in zip(starts, sides, strict=True):
        out[r : r + side, c : c + side] = False
    out |= ~out & (rng.random(out.shape) < noise.speckle_p)
    return out


def noisy_scene_map(
    scenario: Scenario,
    rng: np.random.Generator,
    *,
    resolution: float = 0.05,
    noise: MapNoise = MapNoise(),
) -> OccupancyGrid:
    """The scene as a laser at robot height sees it (``build_grid``), with SLAM-like noise.

    Parameters
    ----------
    scenario : the scene to render.
    rng : the noise's generator (the same seed gives the same map).
    resolution : [m] cell side.
    noise : how noisy.
    """
    exact = build_grid(scenario, resolution=resolution)
    return OccupancyGrid(noisy_occupancy(exact.occupied, rng, noise), exact.origin, resolution)
