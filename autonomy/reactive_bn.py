"""Reactive shared autonomy by situation recognition with a Bayesian network
(thesis Ch. 3.2, eqs. 3.5-3.21; evaluated in 7.5; spec section 2).

Three situations, one assistive action each (situated-action paradigm): FT, Free Travel,
``g = u`` (3.5); OA, Object Approach, ``g = alpha u`` with ``alpha = exp(-1 / (d -
d_safe))`` if ``d > d_safe`` else 0 (3.6, 3.7); GOA, General Obstacle Avoidance,
``g = DWA(u, z)`` (3.8, :mod:`autonomy.dwa`). The environment model is a local occupancy
grid split into sectors (3.12-3.14, :func:`cell_states`); the user input model a wrapped
normal over the input direction (3.15-3.18); the posteriors (3.19-3.21) are normalised
over the situations and the MAP situation gives ``g`` (3.10). The command sent follows
the setting ``arbitration``: ``"exclusive"`` (default) executes the MAP situation's action
alone, ``v = g`` ("execute the corresponding assistive action exclusively", Sec. 3.2 and
3.2.1.1); ``"blend"`` follows eq. (3.2) with ``beta`` the MAP posterior (3.11), as Sec.
3.2.1.2 also reads. Choices where the thesis is silent: docs/decisions.md.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from scipy.special import ndtr

from autonomy._reactive_kernels import mark_scan
from autonomy.arbitration import blend
from autonomy.dwa import DWASettings, dwa
from autonomy.modes import register, settings_from
from autonomy.safety import safe_command, translation_distance
from autonomy.types import EMPTY_PATH, Assist, RobotModel

SITUATIONS = ("FT", "OA", "GOA")
FREE, OCCUPIED, UNKNOWN = 0, 1, 2
_WINDINGS = (2 * math.pi * np.array([-1.0, 0.0, 1.0]))[:, None]  # shifts of the circle
ARBITRATIONS = ("exclusive", "blend")  # values of ReactiveSettings.arbitration


@dataclass(frozen=True, slots=True)
class ReactiveSettings:
    """Settings of the reactive mode (choices: docs/decisions.md)."""

    sector_deg: float = 5.0  # [deg] angular width of a sector (thesis: 5)
    zone_radius: float = 1.0  # [m] security zone around the robot's centre
    grid_resolution: float = 0.05  # [m] cell size of the local occupancy grid
    sigma_deg: float = 10.0  # [deg] std. dev. of the input direction (3.15)
    d_safe: float = 0.15  # [m] safe distance of Object Approach (3.7)
    min_translation: float = 0.02  # [m/s] below this the input is a pure rotation
    # "exclusive": v = g of the MAP situation (Sec. 3.2.1.1); "blend": eq. (3.2), beta (3.11)
    arbitration: str = "exclusive"
    dwa: DWASettings = field(default_factory=DWASettings)

    def __post_init__(self) -> None:
        n = 360.0 / self.sector_deg if self.sector_deg > 0 else 0.0
        if not (n >= 1 and abs(n - round(n)) < 1e-9):
            raise ValueError(
                f"reactive_bn setting sector_deg: must divide 360 into whole sectors, "
                f"got {self.sector_deg!r}"
            )
        for name in ("zone_radius", "grid_resolution"):
            if not getattr(self, name) > 0:
                raise ValueError(
                    f"reactive_bn setting {name}: must be positive, got {getattr(self, name)!r}"
                )
        if not 0 < self.sigma_deg <= 90:
            raise ValueError(
                f"reactive_bn setting sigma_deg: must be in (0, 90], got {self.sigma_deg!r}"
            )
        for name in ("d_safe", "min_translation"):
            if not getattr(self, name) >= 0:
                raise ValueError(
                    f"reactive_bn setting {name}: must be >= 0, got {getattr(self, name)!r}"
                )
        if self.arbitration not in ARBITRATIONS:
            raise ValueError(
                f"reactive_bn setting arbitration: must be one of {', '.join(ARBITRATIONS)}, "
                f"got {self.arbitration!r}"
            )


@dataclass(frozen=True, slots=True, eq=False)
class SectorGrid:
    """The security zone as cells of a robot-centred grid, with their sectors."""

    cells: np.ndarray  # (n, 2) [m] cell centres in the robot frame
    sector: np.ndarray  # (n,) sector index of each cell
    counts: np.ndarray  # (N,) cells per sector
    edges: np.ndarray  # (N + 1,) [rad] sector boundaries, -pi .. pi
    resolution: float  # [m]
    half: int  # the grid spans cells -half .. half on each axis
    lookup: np.ndarray  # ((2 half + 1)^2,) zone cell of each grid cell, -1 outside the zone
    # per-scanner geometry derived from the grid (see :func:`_scan_geometry`), keyed by the
    # scanner's origin and beam angles: a mounted scanner's beams are the same every tick
    cache: dict = field(default_factory=dict, repr=False)


_CACHE_SIZE = 16  # scanner geometries kept per grid (a robot has a few scanners)


def sector_grid(
    robot: RobotModel, *, zone_radius: float, resolution: float, sector_deg: float
) -> SectorGrid:
    """Cells of the security zone (within ``zone_radius`` [m] of the centre, outside
    the footprint) and their 5-degree sectors; geometry only, built once per robot.

    A cell belongs to sector ``j`` when the bearing of its centre lies in
    ``[-pi + j w, -pi + (j + 1) w)``, ``w = sector_deg`` (Sec. 3.2, Eqs. 3.12-3.14).

    Raises
    ------
    ValueError
        If some sector would contain no cell (zone too small for the footprint).
    """
    half = int(math.ceil(zone_radius / resolution))
    ticks = resolution * np.arange(-half, half + 1)
    gx, gy = np.meshgrid(ticks, ticks, indexing="ij")
    centres = np.column_stack((gx.ravel(), gy.ravel()))
    outside = np.max(centres @ robot.edge_normals.T - robot.edge_offsets, axis=1) > 0
    in_zone = outside & (np.hypot(centres[:, 0], centres[:, 1]) <= zone_radius)
    cells = centres[in_zone]
    n_sectors = int(round(360.0 / sector_deg))
    width = 2 * math.pi / n_sectors
    sector = np.floor((np.arctan2(cells[:, 1], cells[:, 0]) + math.pi) / width).astype(int)
    sector %= n_sectors
    counts = np.bincount(sector, minlength=n_sectors)
    if np.any(counts == 0):
        raise ValueError(
            f"reactive_bn setting zone_radius: {zone_radius} m leaves sectors without grid cells "
            f"beyond the footprint at grid_resolution {resolution} m; use a larger zone"
        )
    lookup = np.full(len(centres), -1)
    lookup[np.flatnonzero(in_zone)] = np.arange(len(cells))
    edges = -math.pi + width * np.arange(n_sectors + 1)
    return SectorGrid(cells, sector, counts, edges, resolution, half, lookup)


def _nearest_beam(bearing: np.ndarray, angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Index of the beam nearest each bearing, and whether the bearing is inside the
    scanner's field of view (within half an increment of that beam). Beams are
    taken to be evenly spaced and in order, as a laser scanner delivers them."""
    unwrapped = np.unwrap(angles)
    order = np.argsort(unwrapped)
    offsets = unwrapped[order] - unwrapped[order[0]]
    increment = offsets[-1] / (len(offsets) - 1)
    rel = np.mod(bearing - angles[order[0]], 2 * math.pi)  # [0, 2 pi) from the first beam
    right = np.clip(np.searchsorted(offsets, rel), 1, len(offsets) - 1)
    left = right - 1
    take_left = rel - offsets[left] <= offsets[right] - rel
    nearest = np.where(take_left, left, right)
    error = np.abs(rel - offsets[nearest])
    wrap = 2 * math.pi - rel < error  # closer to the first beam across +-pi
    nearest = np.where(wrap, 0, nearest)
    error = np.where(wrap, 2 * math.pi - rel, error)
    return order[nearest], error <= increment / 2 + 1e-9


def _scan_geometry(
    grid: SectorGrid, angles: np.ndarray, origin: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """What :func:`cell_states` needs of one scanner's geometry, cached on the grid.

    Returns
    -------
    seen : (v,) indices of the zone cells inside the scanner's field of view.
    beam : (v,) index of the beam nearest each of them in bearing.
    far : (v,) [m] their distance from the scanner plus half a cell: a cell is Free when
        its beam's range exceeds this.
    cos, sin : (n,) of the beam angles.
    """
    key = (origin.tobytes(), angles.tobytes())
    found = grid.cache.get(key)
    if found is not None:
        return found
    rel = grid.cells - origin
    distance = np.hypot(rel[:, 0], rel[:, 1])
    beam, visible = _nearest_beam(np.arctan2(rel[:, 1], rel[:, 0]), angles)
    seen = np.flatnonzero(visible)
    found = (seen, beam[seen], distance[seen] + grid.resolution / 2, np.cos(angles), np.sin(angles))
    for array in found:
        array.setflags(write=False)
    if len(grid.cache) >= _CACHE_SIZE:
        grid.cache.clear()
    grid.cache[key] = found
    return found


def cell_states(scans: Any, grid: SectorGrid) -> np.ndarray:
    """State of every zone cell from the current scans (inverse range-sensor model of
    occupancy-grid mapping: Thrun, Burgard and Fox, *Probabilistic Robotics*, Table 9.2).

    For each scanner a cell is Free when the beam nearest to it in bearing passes beyond
    it (its range exceeds the cell's distance by half a cell), Occupied when a laser hit
    falls in it, and Unknown otherwise (shadowed, or outside every scanner's field of
    view). The grid is rebuilt from the current scans every tick (Eq. 3.12).

    Parameters
    ----------
    scans : iterable of scans with ``angles`` (n,) [rad], ``ranges`` (n,) [m] (``==
        max_range`` where nothing was hit), ``origin`` (2,) [m] and ``max_range`` [m],
        all in the robot frame (``sim.types.LaserScan``).
    grid : the zone, from :func:`sector_grid`.

    Returns
    -------
    (n,) int: ``FREE`` (0), ``OCCUPIED`` (1) or ``UNKNOWN`` (2) per zone cell.
    """
    free = np.zeros(len(grid.cells), dtype=bool)
    occupied = np.zeros(len(grid.cells), dtype=bool)
    for scan in scans:
        angles = np.asarray(scan.angles, dtype=float)
        ranges = np.ascontiguousarray(scan.ranges, dtype=float)
        origin = np.asarray(scan.origin, dtype=float)
        if len(angles) < 2:
            continue
        seen, beam, far, cos, sin = _scan_geometry(grid, angles, origin)
        mark_scan(
            free, occupied, seen, beam, far, ranges, cos, sin, float(origin[0]),
            float(origin[1]), float(scan.max_range), float(grid.resolution), int(grid.half),
            grid.lookup,
        )  # fmt: skip
    return np.where(occupied, OCCUPIED, np.where(free, FREE, UNKNOWN))


def sector_occupancy(scans: Any, grid: SectorGrid) -> np.ndarray:
    """``p(s_j = Occ)`` for every sector (3.12, 3.13): the share of its cells that are
    occupied or unknown.

    Returns
    -------
    (N,) probabilities in [0, 1].
    """
    cost = (cell_states(scans, grid) != FREE).astype(float)  # Eq. (3.12)
    not_free = np.bincount(grid.sector, weights=cost, minlength=len(grid.counts))
    return not_free / grid.counts  # Eq. (3.13)


def input_sector_probabilities(theta_u: float, sigma: float, edges: np.ndarray) -> np.ndarray:
    """``p(u in s_j)``: mass of the wrapped normal ``N(theta_u, sigma^2)`` over each sector
    (Eqs. 3.15, 3.16; ``theta_u = atan2(v_y, v_x)``, three windings, renormalised: the
    factor epsilon of 3.15).

    Parameters
    ----------
    theta_u : [rad] input direction.
    sigma : [rad] standard deviation, at most pi / 2.
    edges : (N + 1,) [rad] sector boundaries from -pi to pi.

    Returns
    -------
    (N,) probabilities summing to one.
    """
    cdf = ndtr((edges - theta_u + _WINDINGS) / sigma)  # (3, N + 1), three windings
    mass = (cdf[:, 1:] - cdf[:, :-1]).sum(axis=0)  # Eq. (3.16)
    return mass / mass.sum()  # epsilon of Eq. (3.15)


def situation_posteriors(p_input: np.ndarray, p_sector: np.ndarray) -> np.ndarray:
    """Posteriors of (FT, OA, GOA) given the input and environment models.

    Parameters
    ----------
    p_input : (N,) ``p(u in s_j)``.
    p_sector : (N,) ``p(s_j = Occ)``.

    Returns
    -------
    (3,) posteriors in the order of :data:`SITUATIONS`, summing to one.
    """
    p_occ = float(np.max(p_sector))  # Eq. (3.14)
    occupied = np.max(p_input * p_sector)  # max_j of Eq. (3.17)
    free = np.max(p_input * (1.0 - p_sector))  # max_j of Eq. (3.18)
    joint = np.array(
        [
            free * (1.0 - p_occ),  # Eq. (3.19)
            occupied * p_occ,  # Eq. (3.20)
            free * p_occ,  # Eq. (3.21)
        ]
    )
    total = joint.sum()
    if not total > 0:  # only if every sector's input mass underflowed
        return np.array([1.0, 0.0, 0.0])
    return joint / total  # eta


def oa_attenuation(d: np.ndarray | float, d_safe: float) -> np.ndarray:
    """Attenuation of Object Approach, ``exp(-1 / (d - d_safe))`` above ``d_safe``, else 0.

    Parameters
    ----------
    d : [m] distance to the facing obstacle (``inf`` gives 1).
    d_safe : [m] safe distance.

    Returns
    -------
    alpha in [0, 1), same shape as ``d`` (Eq. 3.7).
    """
    d = np.asarray(d, dtype=float)
    gap = np.where(d > d_safe, d - d_safe, 1.0)
    with np.errstate(over="ignore"):  # a vanishing gap gives exp(-inf) = 0, as it should
        return np.where(d > d_safe, np.exp(-1.0 / gap), 0.0)  # Eq. (3.7)


def arbitrate_exclusive(
    u: np.ndarray, g: np.ndarray, label: str, confidence: float
) -> tuple[np.ndarray, float]:
    """The MAP situation's action alone, ``v = g`` (Sec. 3.2 and 3.2.1.1: "execute the
    corresponding assistive action exclusively"; 3.5-3.8).

    ``beta`` reports whose command is executed, so that ``v = blend(u, g, beta)`` (3.2)
    still holds: 0 in FT (``g = u``, the user's command runs as given), 1 in OA and GOA
    (the robot's command replaces ``u``) and for a pure rotation whose residual
    translation :func:`hold_creep` dropped. ``confidence`` (the MAP posterior, 3.11) is
    not used; the posteriors are in the Assist's scores.

    Returns
    -------
    v : (3,) the command sent (v_x [m/s], v_y [m/s], omega [rad/s]).
    beta : 0.0 or 1.0.
    """
    return g.copy(), 0.0 if label == "FT" and np.array_equal(g, u) else 1.0


def arbitrate_blend(
    u: np.ndarray, g: np.ndarray, label: str, confidence: float
) -> tuple[np.ndarray, float]:
    """Eq. (3.2) with ``beta`` the MAP posterior (3.11): ``v = (1 - beta) u + beta g``.

    Returns
    -------
    v : (3,) the command sent (v_x [m/s], v_y [m/s], omega [rad/s]).
    beta : ``confidence``, in [0, 1].
    """
    return blend(u, g, confidence), confidence  # Eq. (3.2)


# ReactiveSettings.arbitration -> (u, g, MAP label, MAP posterior) -> (v, beta)
ARBITRATE = {"exclusive": arbitrate_exclusive, "blend": arbitrate_blend}


class ReactiveBNMode:
    """The reactive Bayesian-network mode; stateless between ticks."""

    name = "reactive_bn"

    def __init__(self, settings: ReactiveSettings | None = None) -> None:
        self.settings = settings if settings is not None else ReactiveSettings()
        self.robot_: RobotModel | None = None
        self.grid_: SectorGrid | None = None

    def settings_dict(self) -> dict[str, Any]:
        """The effective :class:`ReactiveSettings` (``arbitration`` among them), DWA's nested."""
        return dataclasses.asdict(self.settings)

    def reset(self, robot: RobotModel) -> None:
        s = self.settings
        self.robot_ = robot
        self.grid_ = sector_grid(
            robot, zone_radius=s.zone_radius, resolution=s.grid_resolution, sector_deg=s.sector_deg
        )

    def step(self, obs: Any, u: np.ndarray) -> Assist:
        """One tick: recognise the situation from ``obs.scans`` and ``u``, act, arbitrate
        (``settings.arbitration``).

        Parameters
        ----------
        obs : observation with ``scans``, ``points`` (m, 2) [m] and ``velocity`` (3,).
        u : (3,) joystick command (v_x [m/s], v_y [m/s], omega [rad/s]).
        """
        if self.robot_ is None or self.grid_ is None:
            raise RuntimeError("reactive_bn: call reset(robot) before step()")
        start = time.perf_counter()
        s, robot, grid = self.settings, self.robot_, self.grid_
        u = np.array(u, dtype=float).reshape(3)
        p_sector = sector_occupancy(obs.scans, grid)
        p_occ = float(p_sector.max())
        t_env = time.perf_counter()

        rotation = math.hypot(u[0], u[1]) < s.min_translation
        if rotation:  # pure rotation: pass through
            posterior, situation, beta = np.array([1.0, 0.0, 0.0]), 0, 0.0
            d, alpha = math.nan, 1.0
        else:
            p_input = input_sector_probabilities(
                math.atan2(u[1], u[0]), math.radians(s.sigma_deg), grid.edges
            )
            posterior = situation_posteriors(p_input, p_sector)
            situation = int(np.argmax(posterior))  # Eq. (3.10)
            beta = float(posterior[situation])  # Eq. (3.11)
            max_range = max((float(scan.max_range) for scan in obs.scans), default=math.inf)
            d = float(np.min(translation_distance(obs.points, u[:2], robot), initial=max_range))
            alpha = float(oa_attenuation(d, s.d_safe))
        t_inf = time.perf_counter()

        label = SITUATIONS[situation]
        g, path = self._act(label, u, obs, alpha, rotation=rotation)
        v, beta = ARBITRATE[s.arbitration](u, g, label, beta)
        end = time.perf_counter()
        scores = dict(zip(SITUATIONS, map(float, posterior), strict=True))
        scores.update(p_occ=p_occ, d=d, alpha=alpha)
        return Assist(
            v=v,
            g=g,
            beta=beta,
            label=label,
            target="",
            scores=scores,
            predicted_path=path,
            timings_ms={
                "environment": (t_env - start) * 1e3,
                "inference": (t_inf - t_env) * 1e3,
                "action": (end - t_inf) * 1e3,
                "total": (end - start) * 1e3,
            },
        )

    def _act(
        self, label: str, u: np.ndarray, obs: Any, alpha: float, *, rotation: bool
    ) -> tuple[np.ndarray, np.ndarray]:
        """The MAP situation's action ``g`` (3,) and the DWA's predicted path (k, 3);
        ``rotation``: the input was taken for a pure rotation (FT, passed through)."""
        s, robot = self.settings, self.robot_
        if label == "OA":  # Eq. (3.6): zero within d_safe
            if s.arbitration == "exclusive":
                return oa_turning(u, alpha, obs.points, robot), EMPTY_PATH
            return alpha * u, EMPTY_PATH
        if label == "GOA":
            # Eq. (3.8); zero when no sampled twist is admissible
            result = dwa(u, obs.points, obs.velocity, robot, settings=s.dwa)
            return result.v, result.path
        if rotation and s.arbitration == "exclusive":
            return hold_creep(u, obs.points, robot, s.d_safe), EMPTY_PATH
        return u.copy(), EMPTY_PATH  # Eq. (3.5)


ROTATION_HORIZON_S = 0.25  # [s] a rotation kept in OA must stay clear this long


def oa_turning(u: np.ndarray, alpha: float, points: np.ndarray, robot: RobotModel) -> np.ndarray:
    """Object Approach's action under exclusive arbitration: the translation attenuated,
    ``alpha u_xy`` (Eq. 3.6, 3.7), the rotation kept -- slowed by the safety layer
    (:func:`autonomy.safety.safe_command`, :data:`ROTATION_HORIZON_S`) only as far as
    the footprint's corners would sweep into the protective field. OA is about driving
    *towards* an obstacle; with ``alpha u`` taken literally the rotation stopped as
    well, so an operator within about 0.5 m of a wall (alpha < 0.14) could not turn
    away while the stick also pushed towards it (a pure rotation already passes, FT).

    Parameters
    ----------
    u : (3,) command (v_x [m/s], v_y [m/s], omega [rad/s]).
    alpha : attenuation in [0, 1) (Eq. 3.7).
    points : (m, 2) [m] laser points in the robot frame.
    robot : footprint, protective margin, limits, control tick.

    Returns
    -------
    (3,) ``(alpha v_x, alpha v_y, omega')`` with ``|omega'| <= |omega|``.
    """
    turn, _ = safe_command(np.array([0.0, 0.0, u[2]]), points, robot, horizon_s=ROTATION_HORIZON_S)
    return np.array([alpha * u[0], alpha * u[1], turn[2]])


def hold_creep(u: np.ndarray, points: np.ndarray, robot: RobotModel, d_safe: float) -> np.ndarray:
    """A pure rotation's command with its residual translation (below ``min_translation``)
    dropped when, held for one tick, it would bring the footprint within ``d_safe`` [m]
    of a laser point along its direction (OA's ``alpha = 0`` there, Eq. 3.7); the
    rotation passes through. Without it a gentle push at a wall would creep into it.

    Parameters
    ----------
    u : (3,) command (v_x [m/s], v_y [m/s], omega [rad/s]).
    points : (m, 2) [m] laser points in the robot frame.
    robot : footprint and control tick ``dt`` [s].
    d_safe : [m] safe distance.

    Returns
    -------
    (3,) ``u``, or ``(0, 0, omega)``.
    """
    speed = math.hypot(u[0], u[1])
    if speed == 0.0:
        return u.copy()
    d = float(np.min(translation_distance(points, u[:2] / speed, robot), initial=math.inf))
    if d - speed * robot.dt >= d_safe:
        return u.copy()
    return np.array([0.0, 0.0, u[2]])


@register("reactive_bn")
def make_reactive_bn(**settings: Any) -> ReactiveBNMode:
    """Registry factory: keyword settings are the fields of :class:`ReactiveSettings`."""
    return ReactiveBNMode(settings_from(ReactiveSettings, settings, where="mode 'reactive_bn'"))
