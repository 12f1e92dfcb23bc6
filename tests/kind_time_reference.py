"""The kind-and-time recogniser's likelihood in numpy (autonomy.kind_time before its
kernel, autonomy._intent_kernels), the oracle of tests/test_kind_time.py."""

from __future__ import annotations

import math

import numpy as np

from autonomy.intent_prior import KIND_CLASS, RANKS


def ref_likelihood(rec, mean, kinds, targets, normals, u):
    """``(log L (n,), best primitive (n,), log L(c, j) (n, J))`` of
    :class:`autonomy.kind_time.KindTimeRecogniser` ``rec`` for one tick's candidates."""
    s, p = rec.settings, rec.prior
    n = len(kinds)
    k = np.array([KIND_CLASS.get(kind, 0) for kind in kinds])
    d = np.hypot(targets[:, 0], targets[:, 1])
    x = np.log(np.maximum(d, 0.05))[:, None]
    z_exec = (x - p.exec_mean[None, :]) / p.exec_sd[None, :]
    z_app = (x - p.approach[0]) / p.approach[1]
    log_exec = -0.5 * z_exec * z_exec - np.log(p.exec_sd)[None, :]
    log_app = -0.5 * z_app * z_app - math.log(p.approach[1])
    lj = s.evidence_scale * np.nan_to_num(mean, nan=-1e3, neginf=-1e3, posinf=1e3)
    lj = lj + p.log_kind[:, k].T + s.distance_weight * (log_exec - log_app)
    best = np.argmax(lj, axis=1)
    top = lj.max(axis=1)
    log_l = top + np.log(np.exp(lj - top[:, None]).sum(axis=1))
    log_l += s.rank_weight * p.log_rank[np.minimum(np.arange(n), RANKS - 1)]
    speed = math.hypot(float(u[0]), float(u[1]))
    if speed > 1e-9:
        ux, uy = float(u[0]) / speed, float(u[1]) / speed
        norm = np.hypot(normals[:, 0], normals[:, 1])
        axis = np.abs(normals[:, 0] * ux + normals[:, 1] * uy) / np.where(norm > 0, norm, 1.0)
        toward = (targets[:, 0] * ux + targets[:, 1] * uy) / np.where(d > 1e-9, d, 1.0)
        docks = np.array([kind == "dock" for kind in kinds])
        along = np.abs(normals[:, 0] * targets[:, 0] + normals[:, 1] * targets[:, 1])
        along = along / np.where((norm > 0) & (d > 1e-9), norm * d, 1.0)
        leaving = (toward < 0.0) & ~docks & (d <= s.exit_radius) & (norm > 0)
        toward = np.where(leaving, along * axis, toward)
        passage = k == 0
        log_l[passage] += s.axis_weight * axis[passage] + s.toward_weight * toward[passage]
        log_l[docks & (toward < 0.0)] -= s.dock_departure
    return log_l, best, lj
