"""The passage normals of recorded demonstrations' candidates (issue 40): the recorder
stores every candidate's target point, id and kind, not the crossing normal the
kind-and-time recogniser reads (:mod:`autonomy.kind_time`), so the evaluation takes it
from the run's scene, in the robot frame of the estimated pose as the mode sees it."""

from __future__ import annotations

import numpy as np

from sim.types import Pose2D

PASSAGE_KINDS = ("doorway", "gap", "dock")  # components with a normal (target: the centre)
MATCH_TOL_M = 1e-6  # a passage's centre seen from the stored pose against its stored point


def candidate_normals(demos) -> tuple[np.ndarray, list[str]]:
    """Every candidate's passage normal (robot frame) from its run's shipped scene.

    A run's components are derived from the shipped scenario its manifest entry names
    (``scene``), as the recording world derived them; each candidate's map-frame normal is
    turned into the robot frame of the tick's estimated pose (``pose_est``), as
    ``SemanticComponent.transformed`` does. A run whose scene is not a shipped scenario,
    lacks one of its candidates, or whose passages' centres, seen from the stored poses,
    miss the stored target points by more than :data:`MATCH_TOL_M` (another scene of
    that name) keeps zero normals.

    Parameters
    ----------
    demos : study.jobs.demonstrations.Demonstrations

    Returns
    -------
    normals : numpy.ndarray
        (m, 2) in ``demos``' candidate order; zeros for objects and walls.
    missing : list of str
        The scenes of the runs left with zero normals, one entry per run.
    """
    off = np.asarray(demos.cand_offsets, dtype=np.int64)
    normals = np.zeros((len(demos.cand_ids), 2))
    tick_of = np.repeat(np.arange(len(off) - 1), np.diff(off))
    scenes: dict[str, dict | None] = {}
    missing: list[str] = []
    for r, entry in enumerate(demos.runs):
        ticks = np.flatnonzero(np.asarray(demos.run) == r)
        if not len(ticks):
            continue
        name = str(entry.get("scene", ""))
        if name not in scenes:
            scenes[name] = _scene_components(name)
        rows = np.arange(off[ticks[0]], off[ticks[-1] + 1])
        found = _run_normals(demos, rows, tick_of[rows], scenes[name])
        if found is None:
            missing.append(name)
        else:
            normals[rows] = found
    return normals, missing


def _scene_components(name: str) -> dict | None:
    """Component id -> (kind, centre (2,), normal (2,)) [m, map frame] of the shipped
    scenario ``name``; None if there is none."""
    from sim.scenario import available_scenarios
    from sim.semantics import derive_components
    from study.jobs.scenes import load

    if name not in available_scenarios():
        return None
    return {
        c.id: (str(c.kind), np.asarray(c.centre, dtype=float), np.asarray(c.normal, dtype=float))
        for c in derive_components(load(name))
    }


def _run_normals(
    demos, rows: np.ndarray, ticks: np.ndarray, components: dict | None
) -> np.ndarray | None:
    """(k, 2) normals of candidate ``rows`` (of ``ticks``) in the robot frame, or None
    when ``components`` cannot be the run's (see :func:`candidate_normals`)."""
    ids = np.asarray(demos.cand_ids)[rows]
    if components is None or any(str(i) not in components for i in ids):
        return None
    pose = np.asarray(demos.pose_est, dtype=float)[ticks]
    yaw = pose[:, 2]
    c, s = np.cos(yaw), np.sin(yaw)
    normal_map = np.array([components[str(i)][2] for i in ids]).reshape(-1, 2)
    out = np.column_stack(
        (c * normal_map[:, 0] + s * normal_map[:, 1], -s * normal_map[:, 0] + c * normal_map[:, 1])
    )  # the rotation of SemanticComponent.transformed
    points = np.asarray(demos.cand_points, dtype=float)[rows]
    for k, i in enumerate(ids):
        kind, centre, _ = components[str(i)]
        if kind in PASSAGE_KINDS:
            seen = Pose2D(*pose[k]).to_robot_frame(centre)[0]
            if np.max(np.abs(seen - points[k])) > MATCH_TOL_M:
                return None
    return out
