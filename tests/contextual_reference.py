"""The contextual mode's step as it was before its kernels (issue 25), kept verbatim as
the oracle of tests/test_contextual_kernels.py: the fast online GMR with its pooled kNN and
fit cache (autonomy.local_gmr.LocalGMR), the rollout (Alg. 3), the recogniser's call
(a function of an autonomy.sogp_recogniser.Recogniser) and the tracking controller."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import ndtr

from autonomy.contextual import ContextualSettings, Recogniser, _target_geometry
from autonomy.features import wrap_angle
from autonomy.gmr import data_scale
from autonomy.local_gmr import (
    EM_MAX_ITER,
    EM_TOL,
    POOL_FACTOR,
    POOLS,
    _features,
    _fit,
    check_em_settings,
)
from autonomy.model import GMR_INPUT
from autonomy.sogp_classifier import argmax_finite
from autonomy.tracking import TrackingSettings
from autonomy.types import Candidates, RobotModel


class RefLocalGMR:
    """Fast online GMR of one primitive (Alg. 2) with a per-neighbour-set cache.

    Parameters
    ----------
    points : numpy.ndarray
        (N, 5) demonstration points ``(s_x, s_y [m], v_x, v_y, omega)`` of the primitive.
    k : int
        Neighbours per query.
    tol, max_iter :
        EM's stopping rule (:func:`local_gmm`).
    cache_size : int
        Local fits kept (cleared when full).

    Attributes
    ----------
    n_iter_counts_ : list of int
        (max_iter + 1,) number of local fits made with each EM iteration count.
    """

    def __init__(
        self,
        points: np.ndarray,
        *,
        k: int,
        tol: float = EM_TOL,
        max_iter: int = EM_MAX_ITER,
        cache_size: int = 50000,
    ):
        check_em_settings(tol, max_iter)
        self.points_ = np.asarray(points, dtype=float)
        if self.points_.ndim != 2 or self.points_.shape[1] != 5 or len(self.points_) < 1:
            raise ValueError(f"points: must be a non-empty (N, 5) array, got {self.points_.shape}")
        if isinstance(k, bool) or not (isinstance(k, int | np.integer) and k >= 1):
            raise ValueError(f"k: must be an integer >= 1, got {k!r}")
        self.scale_ = data_scale(self.points_)  # for the relative variance floor
        self.floor_ = (1e-3 * self.scale_).tolist()  # as local_gmm's default reg
        self.inputs_ = np.ascontiguousarray(self.points_[:, list(GMR_INPUT)])  # (N, 2) [m]
        self.tree_ = cKDTree(self.inputs_)
        self.k = min(int(k), len(self.points_))
        self.tol = tol
        self.max_iter = max_iter
        self.cache_size = int(cache_size)
        self.cache_: dict[bytes, tuple[tuple[float, ...], ...]] = {}
        self.n_iter_counts_ = [0] * (max_iter + 1)
        self.pool_size = min(POOL_FACTOR * self.k, len(self.points_))
        self.origin_ = self.points_.mean(axis=0)  # (5,) origin of the local fits' sums
        self.features_ = _features(self.points_ - self.origin_)  # (N, 11), see _fit
        self._query = np.ones(3)  # work arrays of the kNN search
        self._centre = np.empty(2)
        self._pools: list[tuple] = []  # (centre x, y [m], radius [m], indices, see _key)

    def _key(self, sx: float, sy: float) -> bytes:
        """The sorted indices of the ``k`` points nearest ``(sx, sy)`` (Alg. 2), as bytes.

        Searched by brute force among a pool, the ``pool_size`` points nearest an earlier
        query ``c`` (every point within ``radius`` of it), when that is exact: when the
        k-th nearest pool point lies closer than ``radius - |q - c|``, every point outside
        the pool is farther. The last ``POOLS`` pools are kept (a rollout starts near
        where the previous one started); without one that answers, a pool is fetched
        around ``q`` from the tree.
        """
        k, pools = self.k, self._pools
        for n, (cx, cy, radius, idx, rel) in enumerate(pools):
            dx, dy = sx - cx, sy - cy
            margin = radius - math.hypot(dx, dy)
            if margin > 0.0:
                q = self._query  # |p - q|^2 = |p - c|^2 - 2 (p - c).(q - c) + |q - c|^2
                q[0], q[1] = -2.0 * dx, -2.0 * dy
                d2 = rel.dot(q)  # (P,), up to |q - c|^2
                order = d2.argsort(kind="stable")
                if d2.item(order.item(k - 1)) + (dx * dx + dy * dy) < margin * margin:
                    if n:
                        pools.insert(0, pools.pop(n))
                    near = idx.take(order[:k])
                    near.sort()
                    return near.tobytes()
        c = self._centre
        c[0], c[1] = sx, sy
        dist, idx = self.tree_.query(c, k=self.pool_size)
        if self.pool_size == 1:
            dist, idx = np.atleast_1d(dist), np.atleast_1d(idx)
        radius = math.inf if self.pool_size == len(self.inputs_) else dist.item(-1)
        rel = np.empty((len(idx), 3))  # (p - c, |p - c|^2)
        np.subtract(self.inputs_.take(idx, axis=0), c, out=rel[:, :2])
        np.einsum("ij,ij->i", rel[:, :2], rel[:, :2], out=rel[:, 2])
        pools.insert(0, (sx, sy, radius, idx, rel))
        del pools[POOLS:]
        return np.sort(idx[:k]).tobytes()

    def _terms(self, key: bytes) -> tuple[tuple[float, ...], ...]:
        """The local fit of the neighbour set ``key`` as per-component constants of
        Eqs. (4.6)-(4.8): (log w, the input means (2) and variances (2) [m, m^2], the
        log determinant of the input covariance, the output means ``u*`` (3))."""
        terms = self.cache_.get(key)
        if terms is None:
            phi = self.features_.take(np.frombuffer(key, dtype=np.intp), axis=0)
            params, n_iter, _ = _fit(phi, self.floor_, self.tol, self.max_iter)
            self.n_iter_counts_[n_iter] += 1
            cx, cy, c0, c1, c2 = self.origin_.tolist()
            terms = tuple(
                (
                    lw,
                    mu[0] + cx,
                    mu[1] + cy,
                    var[0],
                    var[1],
                    math.log(var[0] * var[1]),
                    mu[2] + c0,
                    mu[3] + c1,
                    mu[4] + c2,
                )
                for lw, mu, var, _ in params
            )
            if len(self.cache_) >= self.cache_size:
                self.cache_.clear()
            self.cache_[key] = terms
        return terms

    def fit_local(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """The local mixture for query ``x`` (2,) [m]: log weights (K,), input means and
        variances (K, 2), output means (K, 3)."""
        t = np.array(self._terms(self._key(float(x[0]), float(x[1]))))
        return t[:, 0], t[:, 1:3], t[:, 3:5], t[:, 6:]

    def predict(self, x: np.ndarray) -> np.ndarray:
        """Predicted output ``u*`` (3,) for the input ``s*`` (2,) [m] (Eqs. 4.5-4.8)."""
        log_w, mu_x, var_x, mu_y = self.fit_local(x)
        diff = np.asarray(x, dtype=float) - mu_x
        logp = log_w - 0.5 * ((diff * diff / var_x).sum(axis=1) + np.log(var_x).sum(axis=1))
        h = np.exp(logp - logp.max())  # Eqs. (4.6), (4.7)
        return (h @ mu_y) / h.sum()  # Eq. (4.8), diagonal: mu_y|x = mu_y

    def predict_xy(self, sx: float, sy: float) -> tuple[float, float, float]:
        """:meth:`predict` for the input ``(sx, sy)`` [m] in scalar arithmetic (the
        rollout's inner loop): the same Eqs. (4.5)-(4.8)."""
        key = self._key(sx, sy)
        terms = self.cache_.get(key) or self._terms(key)
        if len(terms) == 1:
            return terms[0][6:]
        (lw0, mx0, my0, vx0, vy0, ld0, a0, b0, c0), (lw1, mx1, my1, vx1, vy1, ld1, a1, b1, c1) = (
            terms
        )
        dx0, dy0, dx1, dy1 = sx - mx0, sy - my0, sx - mx1, sy - my1
        l0 = lw0 - 0.5 * ((dx0 * dx0 / vx0 + dy0 * dy0 / vy0) + ld0)  # Eqs. (4.6), (4.7)
        l1 = lw1 - 0.5 * ((dx1 * dx1 / vx1 + dy1 * dy1 / vy1) + ld1)
        if l0 >= l1:
            h0, h1 = 1.0, math.exp(l1 - l0)
        else:
            h0, h1 = math.exp(l0 - l1), 1.0
        h = h0 + h1
        return (h0 * a0 + h1 * a1) / h, (h0 * b0 + h1 * b1) / h, (h0 * c0 + h1 * c1) / h


def _clip1(value: float) -> float:
    """``value`` clipped to [-1, 1] (NaN stays NaN, as with ``numpy.clip``)."""
    return -1.0 if value < -1.0 else (1.0 if value > 1.0 else value)


def ref_rollout(
    runtime: Any,
    cluster: int,
    component: Any,
    robot: RobotModel,
    settings: ContextualSettings,
) -> tuple[np.ndarray, np.ndarray]:
    """Algorithm 3: the local trajectory predicted for a recognised primitive and target.

    Parameters
    ----------
    runtime : Runtime
    cluster : int
        The recognised cluster id.
    component : semantic component (``.kind``, ``.points``, ``.target_point()``), robot frame
    robot : RobotModel
        Limits that turn normalised ``u*`` into velocities.
    settings : ContextualSettings

    Returns
    -------
    path : numpy.ndarray
        (k, 3) predicted poses (x, y [m], yaw [rad]), robot frame, ``k <= rollout_steps``.
    distances : numpy.ndarray
        (k + 1,) or (k,) Mahalanobis distances (6.3) of every ``q_est`` computed (the last
        one above the threshold unless the cap ended the loop).
    """
    j = runtime.row[int(cluster)]
    gmr = runtime.gmrs[j]
    # e = W ((z - mean_) / scale_ - mu) = A (z, 1), row by row in scalar arithmetic
    rows = runtime.mahalanobis[j].tolist()
    points, s0x, s0y = _target_geometry(component)
    if points is not None:  # |p - h|^2 - |h|^2 = (p, |p|^2) . (-2 h, 1): one product
        surface = points.tolist()
        lifted = np.column_stack((points, np.einsum("ij,ij->i", points, points)))
        here = np.ones(3)
    lim_v, lim_w = float(robot.max_speed), float(robot.max_yaw_rate)
    dt, stop = settings.dt, settings.mahalanobis_stop
    cos, sin, atan2, hypot, sqrt = math.cos, math.sin, math.atan2, math.hypot, math.sqrt
    x = y = yaw = 0.0
    path, dists = [], []
    for _ in range(settings.rollout_steps):
        # Alg. 3, line 9: s* seen from the rolled-out pose
        if points is not None:
            here[0], here[1] = -2.0 * x, -2.0 * y
            px, py = surface[lifted.dot(here).argmin()]
            dx, dy = px - x, py - y
        else:
            dx, dy = s0x - x, s0y - y
        c, s = cos(yaw), sin(yaw)
        sx, sy = c * dx + s * dy, -s * dx + c * dy
        ux, uy, uw = gmr.predict_xy(sx, sy)  # line 10: the fast online GMR, Alg. 2
        ux, uy, uw = _clip1(ux), _clip1(uy), _clip1(uw)
        speed = hypot(ux, uy)
        # line 11: q_est = (s*, theta*, u*), encoded as autonomy.features.encode does:
        # |u_xy| (cos theta, sin theta), (0, 0) without translational input
        if speed >= 1e-6 and hypot(sx, sy) >= 1e-9:
            theta = atan2(uy, ux) - atan2(sy, sx)
            ct, st = speed * cos(theta), speed * sin(theta)
        else:
            ct, st = speed, 0.0
        dist2 = 0.0
        for a0, a1, a2, a3, a4, a5, a6, a7 in rows:
            e = a0 * sx + a1 * sy + a2 * ct + a3 * st + a4 * ux + a5 * uy + a6 * uw + a7
            dist2 += e * e
        dist = sqrt(dist2)  # line 12, Eq. (6.3)
        dists.append(dist)
        if dist > stop:
            break
        vx, vy, w = ux * lim_v, uy * lim_v, uw * lim_w
        mid = yaw + 0.5 * w * dt  # line 14: holonomic kinematics, mid-step heading
        c, s = cos(mid), sin(mid)
        x += (c * vx - s * vy) * dt
        y += (s * vx + c * vy) * dt
        yaw += w * dt
        path.append((x, y, yaw))  # line 15
    out = np.array(path, dtype=float).reshape(-1, 3)
    return out, np.array(dists)


def _ref_kernels(self: Recogniser, Z: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The SOGP kernel values ``K`` (c, b, m) of Eq. (5.7) as numpy computed them, and
    the magnitude of the squared distances' terms (c, b, m) (the scale of their rounding:
    ``|xs|^2 + |a|^2 + 2 |xs| . |a|``)."""
    Z = np.atleast_2d(np.asarray(Z, dtype=float))
    a = Z / self.ls_  # (c, m, d)
    sq = self.xs2_ + (a * a).sum(axis=2)[:, None, :]
    terms = sq + 2.0 * (np.abs(self.xs_) @ np.abs(a).transpose(0, 2, 1))
    sq -= 2.0 * (self.xs_ @ a.transpose(0, 2, 1))  # (c, b, m)
    np.maximum(sq, 0.0, out=sq)
    sq *= -0.5
    K = np.exp(sq, out=sq)
    K *= self.sf2_  # Eq. (5.7)
    return K, terms


def ref_recognise(self: Recogniser, Z: np.ndarray) -> tuple[int, int, float, np.ndarray]:
    """Recognise over the rows of ``Z`` (m, d), standardised encoded features.

    Returns
    -------
    best_candidate : int
        Row of ``Z`` with the largest finite posterior mean over all clusters (5.8);
        -1 if no mean is finite.
    best_cluster : int
        Its cluster id (-1 if none).
    beta : float
        ``Phi(mu / sqrt(var))`` of the winner (5.10); 0 if none.
    mean : numpy.ndarray
        (m, c) posterior means (5.6).
    """
    K, _ = _ref_kernels(self, Z)
    mean = (self.alpha_ @ K)[:, 0, :].T  # (m, c), Eq. (5.6)
    i, j = argmax_finite(mean)  # Eq. (5.8), never a non-finite score
    if i < 0:
        return -1, -1, 0.0, mean
    k = K[j, : self.n_basis_[j], i]
    sf2 = float(self.sf2_[j, 0, 0])
    var = max(sf2 + float(k @ (self.C_[j] @ k)), 0.0) + float(self.noise_[j])  # Eq. (5.9)
    beta = float(ndtr(mean[i, j] / math.sqrt(var)))  # Eq. (5.10)
    if not math.isfinite(beta):
        beta = 0.0
    return i, int(self.classes_[j]), beta, mean


def recognition_tolerances(self: Recogniser, Z: np.ndarray) -> tuple[np.ndarray, float]:
    """How far another summation order may move :func:`ref_recognise`'s means (m, c) and
    blend weight (tests/fp.py). The kernel values carry the rounding of their squared
    distances (relative to the terms' magnitude, amplified by ``exp``), the means that of
    ``|alpha| . K``; the variance that of ``sf2 + |k|^T |C| |k| + noise`` (the SOGP's
    variance cancels: ``k^T C k`` is close to ``-sf2`` near the basis); the blend weight
    ``Phi(t)``, ``t = mean / sqrt(var)``, moves by ``phi(t) (d mean / sd + |t| d var /
    (2 var))`` to first order. Each relative part is :data:`fp.PIPELINE_RTOL`."""
    from fp import PIPELINE_RTOL, U

    K, terms = _ref_kernels(self, Z)
    with np.errstate(invalid="ignore", over="ignore"):
        dK = K * (1.0 + terms)
        mean_tol = PIPELINE_RTOL * (np.abs(self.alpha_) @ dK)[:, 0, :].T  # (m, c)
    mean = (self.alpha_ @ K)[:, 0, :].T
    i, j = argmax_finite(mean)
    if i < 0:
        return mean_tol, 0.0
    k = np.abs(K[j, : self.n_basis_[j], i])
    sf2, noise = float(self.sf2_[j, 0, 0]), float(self.noise_[j])
    var_k = sf2 + float(k @ (self.C_[j] @ K[j, : self.n_basis_[j], i]))
    var = max(var_k, 0.0) + noise
    var_tol = PIPELINE_RTOL * (sf2 + float(k @ (np.abs(self.C_[j]) @ k)) + noise)
    sd = math.sqrt(var)
    t = mean[i, j] / sd
    density = math.exp(-0.5 * t * t) / math.sqrt(2.0 * math.pi)
    beta_tol = density * (mean_tol[i, j] / sd + abs(t) * var_tol / (2.0 * var)) + 8 * U
    return mean_tol, beta_tol


def assert_recognition_close(self: Recogniser, Z: np.ndarray, got, *, name: str) -> bool:
    """``got`` (the recogniser's ``(i, cluster, beta, mean)`` on ``Z``) equals
    :func:`ref_recognise` within :func:`recognition_tolerances`
    (:func:`assert_recognitions_match`). Returns False at a near-tie."""
    mean_tol, beta_tol = recognition_tolerances(self, Z)
    return assert_recognitions_match(
        got, ref_recognise(self, Z), mean_tol, beta_tol, self.classes_, name=name
    )


def assert_recognitions_match(got, ref, mean_tol, beta_tol, classes, *, name: str) -> bool:
    """Two recognitions ``(i, cluster, beta, mean)`` agree: the means (m, c) within
    ``mean_tol``, the winner the same unless another mean is tied with the reference's
    within the tolerances (then any of the tied), the blend weight within ``beta_tol``.
    Returns False at such a tie (the rest of a tick is then not comparable)."""
    from fp import assert_close, near_best

    assert_close(got[3], ref[3], mean_tol, name=f"{name}.mean")
    if ref[0] < 0:
        assert tuple(got[:3]) == tuple(ref[:3])
        return True
    tied = near_best(ref[3], mean_tol)
    if tied.sum() > 1:
        rows, cols = np.nonzero(tied)
        allowed = {(int(r), int(classes[c])) for r, c in zip(rows, cols, strict=True)}
        assert (got[0], got[1]) in allowed, f"{name}: winner {got[:2]} not among {allowed}"
        return False
    assert tuple(got[:2]) == tuple(ref[:2]), f"{name}: winner {got[:2]} != {ref[:2]}"
    assert_close(got[2], ref[2], beta_tol, name=f"{name}.beta")
    return True


def ref_track(
    path: np.ndarray,
    dt: float,
    *,
    max_speed: float,
    max_yaw_rate: float,
    settings: TrackingSettings | None = None,
) -> np.ndarray:
    """Pure-pursuit command following a predicted robot-frame path.

    Parameters
    ----------
    path : numpy.ndarray
        (k, 3) predicted poses (x [m], y [m], yaw [rad]) at times dt, 2 dt, ..., k dt,
        in the current robot frame (the robot is at the origin, yaw 0).
    dt : float
        [s] time between way points.
    max_speed : float
        [m/s] translational limit.
    max_yaw_rate : float
        [rad/s] rotational limit.
    settings : TrackingSettings, optional

    Returns
    -------
    numpy.ndarray
        (3,) command (v_x [m/s], v_y [m/s], omega [rad/s]); zeros for an empty path.
    """
    settings = TrackingSettings() if settings is None else settings
    path = np.asarray(path, dtype=float).reshape(-1, 3)
    if len(path) == 0:
        return np.zeros(3)
    xy = np.vstack((np.zeros((1, 2)), path[:, :2]))
    yaw = np.concatenate(([0.0], np.unwrap(path[:, 2])))
    arc = np.concatenate(([0.0], np.cumsum(np.hypot(*np.diff(xy, axis=0).T))))
    total = float(arc[-1])
    if total < 1e-9:  # a predicted pure rotation
        t_end = max(len(path) * dt, settings.min_time_s)
        omega = float(np.clip(wrap_angle(yaw[-1]) / t_end, -max_yaw_rate, max_yaw_rate))
        return np.array([0.0, 0.0, omega])
    target = min(settings.lookahead_m, total)
    # index i with arc[i] <= target <= arc[i + 1], then interpolate
    i = int(min(np.searchsorted(arc, target, side="right") - 1, len(arc) - 2))
    span = arc[i + 1] - arc[i]
    f = (target - arc[i]) / span if span > 0 else 1.0
    point = xy[i] + f * (xy[i + 1] - xy[i])
    yaw_l = yaw[i] + f * (yaw[i + 1] - yaw[i])
    t_l = max((i + f) * dt, settings.min_time_s)
    speed = target / t_l  # the path's speed up to the look-ahead point
    dist = math.hypot(point[0], point[1])
    direction = point / dist if dist > 1e-12 else np.zeros(2)
    v_xy = min(speed, max_speed) * direction
    omega = float(np.clip(yaw_l / t_l, -max_yaw_rate, max_yaw_rate))
    return np.array([v_xy[0], v_xy[1], omega])


def _nearest_candidates(candidates: Candidates, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The ``n`` candidates whose target points are nearest the robot (Sec. 5.1, 6.1):
    (all target points (p, 2) [m]; the chosen indices, nearest first, ties by order)."""
    targets = np.asarray(candidates.target_points(), dtype=float).reshape(-1, 2)
    order = np.argsort(np.einsum("ij,ij->i", targets, targets), kind="stable")
    return targets, order[:n]
