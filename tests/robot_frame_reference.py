"""The robot-frame semantic components' per-tick arithmetic as numpy computed it before
issue 25's kernels (sim/semantics/robot_frame.py at 5b8a1d4): the readable reference the
tests compare the kernels with, bit for bit."""

from __future__ import annotations

import math

import numpy as np


def transform_stacked(x: np.ndarray, y: np.ndarray, n: int, pose) -> np.ndarray:  # type: ignore[no-untyped-def]
    """Stacked coordinates (columns ``x``, ``y``) seen from ``pose``; rows from ``n`` on
    are positions (shifted), rows before are normals (rotated only): (rows, 2) [m]."""
    c, s = math.cos(pose.yaw), math.sin(pose.yaw)
    out = np.empty((len(x), 2))
    ox, oy = out[:, 0], out[:, 1]
    np.multiply(x, c, out=ox)  # the rotation of Pose2D.to_robot_frame
    ox += s * y
    np.multiply(y, c, out=oy)
    oy -= s * x
    ox[n:] -= c * pose.x + s * pose.y  # positions are shifted, normals (rows < n) are not
    oy[n:] -= -s * pose.x + c * pose.y
    return out


def packed_target_points(
    stacked: np.ndarray, target_rows: np.ndarray, target_starts: np.ndarray
) -> np.ndarray:
    """Per run of ``target_rows`` the row of ``stacked`` nearest the origin (the first on
    ties): (n, 2) [m]."""
    candidates = stacked[target_rows]  # (m, 2)
    sq = np.einsum("ij,ij->i", candidates, candidates)
    lowest = np.minimum.reduceat(sq, target_starts)
    counts = np.diff(np.append(target_starts, len(sq)))
    at_min = np.flatnonzero(sq == np.repeat(lowest, counts))
    first = at_min[np.searchsorted(at_min, target_starts)]  # first minimum per run
    return candidates[first]
