"""The contextual task a recognised motion primitive performs on a recognised semantic
component (thesis Sec. 4.2.4, 5.1, 7.4.2): a task is an action primitive in the context
of one component, so the component's kind names the task and, where a kind admits two
tasks (an object is inspected or bypassed), the primitive's motion decides."""

from __future__ import annotations

from collections.abc import Mapping

# component kind -> the task type performed on it (the vocabulary of tasks.contextual)
KIND_TASK: dict[str, str] = {
    "doorway": "doorway_crossing",
    "gap": "gap_crossing",
    "dock": "robot_docking",
    "wall": "wall_following",
    "object": "object_bypass",
}
# (component kind, motion of the primitive) -> task type, where it differs from KIND_TASK
MOTION_TASK: dict[tuple[str, str], str] = {("object", "object_inspection"): "object_inspection"}
TASK_TYPES: tuple[str, ...] = tuple(dict.fromkeys([*KIND_TASK.values(), *MOTION_TASK.values()]))


def contextual_task(kind: str, motion: str) -> str:
    """The task type of a primitive whose demonstrations were mostly ``motion`` (a task
    type, "" if unknown) performed on a component of ``kind``; "" for an unknown kind."""
    return MOTION_TASK.get((kind, motion), KIND_TASK.get(kind, ""))


def primitive_motions(clusters: list[Mapping]) -> dict[int, str]:
    """Cluster id -> the task type most of its demonstration points came from, from a
    model's metadata ``clusters`` (entries with ``id`` and ``task_share``); clusters
    without shares are left out."""
    out: dict[int, str] = {}
    for cluster in clusters:
        shares = cluster.get("task_share") or {}
        if shares:
            out[int(cluster["id"])] = max(shares, key=shares.get)
    return out
