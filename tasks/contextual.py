"""Contextual task types: what a driver does with a semantic component (thesis Sec. 6.1,
7.4.1-7.4.2; spec section 3).

Six task types, each about one kind of semantic component
(``sim.types.COMPONENT_KINDS``): ``doorway_crossing`` and ``gap_crossing`` (direction
``""``: the side the robot starts on decides), ``object_inspection`` (``"cw"`` or
``"ccw"`` around the object, seen from above: ccw is the robot's position angle about
the object increasing), ``object_bypass`` and ``wall_following`` (``"left"``/``"right"``:
the side of the robot the object is passed on, or the wall is on) and
``robot_docking`` (``""``). The thesis demonstrated four of them (:data:`DEMONSTRATED`,
Sec. 7.4.2) and tested whether the learnt model generalises to the other two.
"""

from __future__ import annotations

from dataclasses import dataclass

TASK_TYPES: tuple[str, ...] = (
    "doorway_crossing",
    "gap_crossing",
    "object_inspection",
    "object_bypass",
    "wall_following",
    "robot_docking",
)

# task type -> the component kind it targets (sim.types.COMPONENT_KINDS)
TARGET_KIND: dict[str, str] = {
    "doorway_crossing": "doorway",
    "gap_crossing": "gap",
    "object_inspection": "object",
    "object_bypass": "object",
    "wall_following": "wall",
    "robot_docking": "dock",
}

# the four types of the thesis's demonstrations (Sec. 7.4.2); the model must generalise to
# gap crossing and docking
DEMONSTRATED: tuple[str, ...] = (
    "doorway_crossing",
    "object_inspection",
    "wall_following",
    "object_bypass",
)

# task type -> allowed values of ContextualTask.direction
DIRECTIONS: dict[str, tuple[str, ...]] = {
    "doorway_crossing": ("",),
    "gap_crossing": ("",),
    "object_inspection": ("cw", "ccw"),
    "object_bypass": ("left", "right"),
    "wall_following": ("left", "right"),
    "robot_docking": ("",),
}

# task type -> default demonstration scene (a shipped scenario name; gap crossing: the
# only shipped scene with gaps)
DEFAULT_SCENES: dict[str, str] = {
    "doorway_crossing": "demo_doorway_crossing",
    "gap_crossing": "cluttered_room",
    "object_inspection": "demo_object_inspection",
    "object_bypass": "demo_object_bypass",
    "wall_following": "demo_wall_following",
    "robot_docking": "demo_docking",
}


def check_task_type(task_type: str, *, field: str = "task") -> str:
    """Return ``task_type`` if it is known, else ValueError naming ``field`` and the choices."""
    if task_type not in TASK_TYPES:
        raise ValueError(
            f"{field}: unknown task type {task_type!r}; allowed: {', '.join(TASK_TYPES)}"
        )
    return task_type


@dataclass(frozen=True, slots=True)
class ContextualTask:
    """One contextual task: a type, the id of its target component and a direction.

    Parameters
    ----------
    type : str
        One of :data:`TASK_TYPES`.
    target_id : str
        Id of the semantic component the task is about (its kind must be
        ``TARGET_KIND[type]``; checked by the skill against the observation).
    direction : str
        One of ``DIRECTIONS[type]``.
    """

    type: str
    target_id: str
    direction: str = ""

    def __post_init__(self) -> None:
        check_task_type(self.type, field="ContextualTask.type")
        if not self.target_id:
            raise ValueError("ContextualTask.target_id: must name a semantic component")
        allowed = DIRECTIONS[self.type]
        if self.direction not in allowed:
            shown = ", ".join(repr(d) for d in allowed)
            raise ValueError(
                f"ContextualTask.direction: {self.direction!r} not allowed for {self.type}; "
                f"allowed: {shown}"
            )

    @property
    def target_kind(self) -> str:
        """The component kind this task targets."""
        return TARGET_KIND[self.type]
