"""Contextual task types: what a driver does with a semantic component (thesis Sec. 6.1,
7.4.1-7.4.2; spec section 3).

Six task types, each about one kind of semantic component (``sim.types.COMPONENT_KINDS``):

===================  ===========  ==========================================
task type            targets      direction
===================  ===========  ==========================================
``doorway_crossing``  doorway     ``""`` (the side the robot starts on decides)
``gap_crossing``      gap         ``""`` (likewise)
``object_inspection`` object      ``"cw"`` or ``"ccw"`` around the object
``object_bypass``     object      ``"left"``/``"right"``: the side of the robot
                                  the object is passed on
``wall_following``    wall        ``"left"``/``"right"``: the side of the robot
                                  the wall is on
``robot_docking``     dock        ``""``
===================  ===========  ==========================================

The thesis demonstrated four of them (:data:`DEMONSTRATED`, Sec. 7.4.2) and tested
whether the learnt model generalises to the other two.

Decisions where the spec is silent:

- Default demonstration scene per type (:data:`DEFAULT_SCENES`): the ``demo_*`` scene of
  that name; docking uses ``demo_docking``; gap crossing uses ``cluttered_room``, the
  only shipped scene with gaps (the bypass scene's objects stand too far apart to form
  passages), so gap crossings are demonstrated where the study is run.
- ``"cw"``/``"ccw"`` are seen from above (map frame, z up): counter-clockwise is the
  robot's position angle about the object increasing.
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

# task type -> default demonstration scene (a shipped scenario name)
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
