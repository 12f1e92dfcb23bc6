"""Semantic components of a scene, derived from its exact geometry (thesis Sec. 5.1,
6.1, 7.6.1.2 and Fig. 7.49; appendix Alg. 4 and 5; spec sections 3 and 6).

The candidate targets of the contextual tasks: doorways and gaps (centre and two end
points), the dock under a table (centre), objects and wall segments (surface points).
The thesis found them in the SLAM map image with OpenCV; a scene's polygons and
circles are known exactly, so by default the same ideas apply to the geometry and a new
scenario needs no hand annotation; with ``[semantics] source = "map"`` they come from
an occupancy map image as in the thesis (:mod:`sim.semantics.map_image`,
:mod:`sim.semantics.map_passages`). :func:`derive_components` derives them once;
:func:`in_robot_frame` and :class:`RobotFrameComponents` put them into the robot
frame every tick.
"""

from sim.semantics.derive import MAX_SURFACE_POINTS, derive_components, with_semantic_source
from sim.semantics.passages import (
    CORRIDOR_PROBE_SLACK_M,
    DEPTH_STEP_M,
    MAX_PASSAGE_DEPTH_M,
    MERGE_DISTANCE_M,
    passage_extent,
)
from sim.semantics.robot_frame import (
    RobotFrameComponents,
    in_robot_frame,
    nearest_components,
    target_distances,
    target_points,
)

__all__ = [
    "CORRIDOR_PROBE_SLACK_M",
    "DEPTH_STEP_M",
    "MAX_PASSAGE_DEPTH_M",
    "MAX_SURFACE_POINTS",
    "MERGE_DISTANCE_M",
    "RobotFrameComponents",
    "derive_components",
    "in_robot_frame",
    "nearest_components",
    "passage_extent",
    "target_distances",
    "target_points",
    "with_semantic_source",
]
