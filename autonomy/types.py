"""Plain value types of the assistance layer: what a mode knows about the robot
(:class:`RobotModel`), what it returns every tick (:class:`Assist`), the semantic
components it may take as the operator's target (:class:`Component`,
:class:`Candidates`), and the interface every mode implements (:class:`Mode`).

A mode sees observations by duck typing (``obs.t``, ``obs.pose``,
``obs.velocity``, ``obs.points``, ``obs.scans``, ``obs.components``; see
``sim.types.Observation``) and never imports the simulation, so the same code
could drive a real robot (DESIGN.md, "Layout and layers").

Commands ``u`` (joystick), ``g`` (the robot's own command) and ``v`` (sent to
the robot) are robot-frame velocities in physical units, ``(v_x [m/s],
v_y [m/s], omega [rad/s])``, shape (3,); eq. (3.2) of the thesis blends them.

Decisions where the spec is silent: the footprint may be any convex
counter-clockwise polygon (the scenario gives a rectangle); its half-plane
form (outward edge normals and offsets), used by every collision check of the
assistance layer, is derived once here so that the 20 Hz tick does not redo it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any, Protocol, runtime_checkable

import numpy as np

EMPTY_PATH = np.zeros((0, 3))
EMPTY_PATH.setflags(write=False)


@dataclass(frozen=True, slots=True, eq=False)
class RobotModel:
    """What a mode knows about the robot; the study layer builds it from the scenario.

    The footprint's half-plane form is derived on construction: a robot-frame
    point ``q`` lies inside the footprint inflated by ``c`` (square corners) iff
    ``max(edge_normals @ q - edge_offsets) <= c``.
    """

    footprint: np.ndarray  # (k, 2) [m] robot-frame polygon, convex, counter-clockwise
    max_speed: float = 1.0  # [m/s] translational limit (thesis 7.6.1.1)
    max_yaw_rate: float = 1.2  # [rad/s]
    max_accel: float = 2.0  # [m/s^2]
    max_yaw_accel: float = 4.0  # [rad/s^2]
    protective_margin: float = 0.05  # [m] laser protective field beyond the footprint
    dt: float = 0.05  # [s] control tick
    edge_normals: np.ndarray = field(init=False, repr=False)  # (k, 2) outward unit normals
    edge_offsets: np.ndarray = field(init=False, repr=False)  # (k,) [m] n_e . vertex_e
    # the same edges as lines |n . q - mid| - half, opposite parallel edges merged into
    # one line (half = nan: a one-sided line n . q - mid)
    line_normals: np.ndarray = field(init=False, repr=False)  # (l, 2)
    line_mid: np.ndarray = field(init=False, repr=False)  # (l,) [m]
    line_half: np.ndarray = field(init=False, repr=False)  # (l,) [m]

    def __post_init__(self) -> None:
        fp = np.array(self.footprint, dtype=float)
        if fp.ndim != 2 or fp.shape[1] != 2 or fp.shape[0] < 3 or not np.all(np.isfinite(fp)):
            raise ValueError(
                f"robot footprint: must be a (k, 2) array of finite corners with k >= 3, "
                f"got shape {fp.shape}"
            )
        edges = np.roll(fp, -1, axis=0) - fp
        cross = edges[:, 0] * np.roll(edges[:, 1], -1) - edges[:, 1] * np.roll(edges[:, 0], -1)
        if np.any(cross <= 0.0):
            raise ValueError(
                "robot footprint: must be a convex polygon with its corners in "
                "counter-clockwise order"
            )
        for name in ("max_speed", "max_yaw_rate", "max_accel", "max_yaw_accel", "dt"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"robot {name}: must be a positive number, got {value!r}")
        if not (math.isfinite(self.protective_margin) and self.protective_margin >= 0):
            raise ValueError(
                f"robot protective_margin: must be zero or positive, got {self.protective_margin!r}"
            )
        normals = np.column_stack((edges[:, 1], -edges[:, 0]))
        normals /= np.linalg.norm(normals, axis=1)[:, None]
        offsets = np.einsum("ij,ij->i", normals, fp)
        k = len(normals)
        if k % 2 == 0 and np.allclose(normals[: k // 2], -normals[k // 2 :], atol=1e-12):
            # opposite edges parallel (a rectangle): one two-sided line per pair
            c1, c2 = offsets[: k // 2], offsets[k // 2 :]
            lines = (normals[: k // 2], (c1 - c2) / 2, (c1 + c2) / 2)
        else:
            lines = (normals, offsets, np.full(k, np.nan))
        derived = {
            "footprint": fp,
            "edge_normals": normals,
            "edge_offsets": offsets,
            "line_normals": lines[0],
            "line_mid": lines[1],
            "line_half": lines[2],
        }
        for name, value in derived.items():
            value.setflags(write=False)
            object.__setattr__(self, name, value)

    @classmethod
    def rectangle(cls, length: float = 0.6, width: float = 0.5, **limits: Any) -> RobotModel:
        """A robot with a centred rectangular footprint ``length`` x ``width`` [m]."""
        hx, hy = length / 2, width / 2
        return cls(np.array([[-hx, -hy], [hx, -hy], [hx, hy], [-hx, hy]]), **limits)

    @classmethod
    def from_spec(cls, spec: Any, *, dt: float = 0.05) -> RobotModel:
        """From a scenario's robot description, duck-typed like ``sim.scenario.RobotSpec``
        (``footprint()``, the limits and ``protective_margin``), and the control tick ``dt``."""
        return cls(
            spec.footprint(),
            max_speed=spec.max_speed,
            max_yaw_rate=spec.max_yaw_rate,
            max_accel=spec.max_accel,
            max_yaw_accel=spec.max_yaw_accel,
            protective_margin=spec.protective_margin,
            dt=dt,
        )

    def inflated_radius(self, margin: float) -> float:
        """Largest distance [m] from the robot's origin to the footprint inflated by
        ``margin`` with square corners (the set ``h(q) <= margin``)."""
        n_prev = np.roll(self.edge_normals, 1, axis=0)
        # corner i moves along the miter w, with n_prev . w = n_i . w = 1
        dots = np.einsum("ij,ij->i", n_prev, self.edge_normals)
        miter = (n_prev + self.edge_normals) / (1.0 + dots)[:, None]
        corners = self.footprint + margin * miter
        return float(np.max(np.hypot(corners[:, 0], corners[:, 1])))


@dataclass(frozen=True, slots=True, eq=False)
class Assist:
    """One mode's output for one control tick, diagnostics included (the caller logs them)."""

    v: np.ndarray  # (3,) command sent to the robot (v_x [m/s], v_y [m/s], omega [rad/s])
    g: np.ndarray  # (3,) the robot's own command, same units
    beta: float  # arbitration factor in [0, 1], eq. (3.2)
    label: str  # situation ("FT", "OA", "GOA") or recognised task/cluster; "" for manual
    target: str  # recognised component id, "" if none
    scores: dict[str, float]  # situation posteriors and diagnostics, or per-candidate scores
    predicted_path: np.ndarray  # (k, 3) robot-frame poses (x [m], y [m], yaw [rad]); (0, 3)
    timings_ms: dict[str, float]  # [ms] per stage, "total" included


class Component(Protocol):
    """A semantic component as a mode sees it, in the robot frame (thesis Sec. 5.1, 6.1).

    ``sim.types.SemanticComponent`` is one; a real robot's map may supply its own.
    """

    id: str
    kind: str  # "doorway", "gap", "dock", "object" or "wall"
    points: np.ndarray  # (k, 2) [m] surface points (objects, walls); a passage's ends

    def target_point(self) -> np.ndarray:
        """The intentional target point ``s`` (2,) [m]: a passage's or the dock's centre,
        the surface point of an object or wall nearest the robot."""
        ...


@runtime_checkable
class Candidates(Protocol):
    """The components a contextual mode chooses its target from (robot frame): indexable,
    with every target point in one call. ``sim.semantics.RobotFrameComponents`` (what
    ``World.sense`` hands out) is one; :func:`as_candidates` makes one of any sequence."""

    def __len__(self) -> int: ...

    def __getitem__(self, index: int) -> Component: ...

    def target_points(self) -> np.ndarray:
        """Every component's target point ``s`` (n, 2) [m], in index order."""
        ...

    # optional: ``ids()``, ``kinds()`` (str) and ``normals()`` ((n, 2), robot frame) in
    # index order, read without building the components (autonomy.contextual)


@dataclass(frozen=True, slots=True, eq=False)
class ComponentList:
    """:class:`Candidates` made of a plain sequence of components."""

    items: tuple[Component, ...]
    targets: np.ndarray  # (n, 2) [m] the items' target points

    def __len__(self) -> int:
        return len(self.items)

    def __getitem__(self, index: int) -> Component:
        return self.items[index]

    def target_points(self) -> np.ndarray:
        return self.targets

    def ids(self) -> tuple[str, ...]:
        """The items' ids in index order."""
        return tuple(str(c.id) for c in self.items)

    def kinds(self) -> tuple[str, ...]:
        """The items' kinds in index order."""
        return tuple(str(c.kind) for c in self.items)

    def normals(self) -> np.ndarray:
        """The items' passage normals (n, 2) (zeros where a component has none)."""
        rows = [np.asarray(getattr(c, "normal", (0.0, 0.0)), dtype=float) for c in self.items]
        return np.array(rows, dtype=float).reshape(-1, 2)


def as_candidates(components: Candidates | Sequence[Component]) -> Candidates:
    """``components`` as :class:`Candidates`: a tuple or list of components becomes a
    :class:`ComponentList` of its items with their target points (n, 2) [m]; anything
    else is taken as :class:`Candidates` already (a per-tick call: the Protocol's own
    ``isinstance`` check would cost about 10 us)."""
    if not isinstance(components, tuple | list):
        return components
    items = tuple(components)
    targets = np.array([np.asarray(c.target_point(), dtype=float) for c in items])
    return ComponentList(items, targets.reshape(-1, 2))


@runtime_checkable
class Mode(Protocol):
    """A control mode: found by name in :mod:`autonomy.modes`, driven once per tick.

    A mode class may subclass it to inherit the default of :meth:`label_tasks`.
    """

    name: str

    def reset(self, robot: RobotModel) -> None:
        """Prepare for a new trial with this robot (settings-derived geometry only)."""
        ...

    def step(self, obs: Any, u: np.ndarray) -> Assist:
        """One control tick: observation and joystick command ``u`` (3,) -> :class:`Assist`."""
        ...

    def label_tasks(self) -> dict[str, str] | None:
        """What the mode's labels stand for: label -> contextual task type (stored with each
        trial so the analysis scores recognition from the data alone); None (the default,
        for a class that subclasses :class:`Mode`): the labels are no task types."""
        return None

    def settings_dict(self) -> dict[str, Any]:
        """The mode's effective settings, stored with each trial: a mode with a settings
        dataclass returns ``dataclasses.asdict`` of it (plain values; the trial loop makes
        them JSON-ready); {} (the default) for a mode without settings."""
        return {}

    def needs_intention(self) -> bool:
        """Whether the mode is to be told the participant's true intention before every
        step (:meth:`observe_intention`): an oracle, for ablations with synthetic
        participants only. False (the default)."""
        return False

    def observe_intention(self, task: str, target: str) -> None:
        """The participant's true contextual task type and target component id this tick
        (``""`` while it does no task); called before :meth:`step` when
        :meth:`needs_intention`. The default ignores it."""
        return None
