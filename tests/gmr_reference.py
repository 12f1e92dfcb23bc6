"""Plain reference implementations of the local GMR (Alg. 2) and the rollout (Alg. 3)
for tests/test_local_gmr.py and tests/test_contextual.py: written for reading, with no
caching, pooling or rearranged arithmetic, to check autonomy.local_gmr and
autonomy.contextual.rollout against."""

from __future__ import annotations

import math

import numpy as np
from scipy.special import logsumexp

from autonomy.gmr import data_scale, gmr


def ref_local_gmm(local, *, tol, max_iter, reg=1e-3, scale=None):
    """EM for 2 diagonal Gaussians written plainly: seeds (the point nearest the mean,
    the point farthest from it), the partition by the nearer seed as the first
    responsibilities, then M step, E step and the relative log-likelihood test."""
    k, dim = local.shape
    floor = reg * (data_scale(local) if scale is None else scale)
    first = int(np.argmin(((local - local.mean(axis=0)) ** 2).sum(axis=1)))
    d0 = ((local - local[first]) ** 2).sum(axis=1)
    second = int(np.argmax(d0))
    if d0[second] == 0:
        return np.ones(1), local.mean(axis=0)[None], (local.var(axis=0) + floor)[None], 0
    near = ((local - local[second]) ** 2).sum(axis=1) < d0
    resp = np.column_stack((~near, near)).astype(float)
    previous = math.nan
    for it in range(1, max_iter + 1):
        nk = resp.sum(axis=0) + 1e-12
        w = nk / k
        mu = resp.T @ local / nk[:, None]
        var = np.stack([resp[:, c] @ (local - mu[c]) ** 2 / nk[c] for c in (0, 1)]) + floor
        logp = np.log(w) + np.stack(
            [
                (-0.5 * ((local - mu[c]) ** 2 / var[c] + np.log(2 * np.pi * var[c]))).sum(axis=1)
                for c in (0, 1)
            ],
            axis=1,
        )
        lse = logsumexp(logp, axis=1)
        current = lse.mean()
        if abs(current - previous) < tol * abs(current):
            return w, mu, var, it
        resp = np.exp(logp - lse[:, None])
        previous = current
    return w, mu, var, max_iter


def ref_predict(points, x, *, k, tol, max_iter):
    """Fast online GMR (Alg. 2) from scratch: brute-force kNN, EM, GMR (Eqs. 4.5-4.8)."""
    d2 = ((points[:, :2] - x) ** 2).sum(axis=1)
    idx = np.sort(np.argsort(d2, kind="stable")[: min(k, len(points))])
    w, mu, var, _ = ref_local_gmm(points[idx], tol=tol, max_iter=max_iter, scale=data_scale(points))
    mean, _ = gmr(w, mu, var, np.asarray(x)[None, :], [0, 1], [2, 3, 4])
    return mean[0]


def ref_rollout(model, cluster, component, robot, s):
    """Alg. 3 written plainly: at every step s* at the rolled-out pose, u* from a fresh
    local fit, q_est, its Mahalanobis distance (Eq. 6.3) and the holonomic step."""
    j = list(model.cluster_ids).index(cluster)
    pts = model.cluster_points(j)
    mean, cov = model.cluster_means[j], model.cluster_covariances[j]
    kind = component.kind
    surface = np.asarray(component.points, dtype=float).reshape(-1, 2)
    x = y = yaw = 0.0
    path, dists = [], []
    for _ in range(s.rollout_steps):
        if kind in ("object", "wall") and len(surface):
            target = surface[np.argmin(((surface - (x, y)) ** 2).sum(axis=1))]
        else:
            target = np.asarray(component.target_point(), dtype=float)
        dx, dy = target - (x, y)
        sx = math.cos(yaw) * dx + math.sin(yaw) * dy
        sy = -math.sin(yaw) * dx + math.cos(yaw) * dy
        u = np.clip(
            ref_predict(pts, (sx, sy), k=s.gmr_k, tol=s.em_tol, max_iter=s.em_max_iter), -1, 1
        )
        speed = math.hypot(u[0], u[1])
        if speed >= 1e-6 and math.hypot(sx, sy) >= 1e-9:
            theta = math.atan2(u[1], u[0]) - math.atan2(sy, sx)
            enc = (speed * math.cos(theta), speed * math.sin(theta))
        else:
            enc = (speed, 0.0)
        q = (np.array([sx, sy, *enc, *u]) - model.scaler.mean_) / model.scaler.scale_
        e = q - mean
        dists.append(math.sqrt(e @ np.linalg.solve(cov, e)))
        if dists[-1] > s.mahalanobis_stop:
            break
        v = u * (robot.max_speed, robot.max_speed, robot.max_yaw_rate)
        mid = yaw + 0.5 * v[2] * s.dt
        x += (math.cos(mid) * v[0] - math.sin(mid) * v[1]) * s.dt
        y += (math.sin(mid) * v[0] + math.cos(mid) * v[1]) * s.dt
        yaw += v[2] * s.dt
        path.append((x, y, yaw))
    return np.array(path).reshape(-1, 3), np.array(dists)
