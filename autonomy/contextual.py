"""Contextual-task aware shared autonomy (thesis Ch. 5-6, Sec. 7.6.1.2; spec sections 3-4;
issue 3), registered as the mode ``"contextual_task"``.

Per control tick, with the user's command ``u`` and the semantic components of the scene
in the robot frame (``obs.components``, duck-typed: ``.id``, ``.kind``, ``.points``,
``.target_point()``):

1. candidates: the ``candidates`` components whose target points ``s`` are nearest the
   robot (Sec. 5.1, 6.1);
2. per candidate the task feature ``q* = (s, theta, u)`` with ``u`` normalised by the
   robot's limits (Sec. 5.1), encoded (cos, sin) and standardised by the model's scaler;
3. recognition (Eqs. 5.6, 5.8, 5.10): the largest SOGP posterior mean over clusters x
   candidates picks the target (the candidate) and the motion primitive (the cluster);
   ``beta = Phi(mu / sqrt(var))`` of that winner (Sec. 6.2.3);
4. rollout (Alg. 3): from the robot's pose (the origin of the robot frame) repeat: ``s*``
   = the target seen from the rolled-out pose (for objects and walls the surface point
   nearest that pose); ``u*`` = the fast online GMR of the primitive (Alg. 2; input ``s*``,
   output ``u*``); ``q_est = (s*, theta*, u*)``; stop when its Mahalanobis distance to
   the primitive's mean and covariance exceeds ``mahalanobis_stop`` (Eq. 6.3) or after
   ``rollout_steps`` steps; otherwise integrate the holonomic kinematics for ``dt`` and
   append the pose. The loop is bounded, so the rollout always terminates;
5. ``g`` = the holonomic pure-pursuit controller following the predicted path
   (:mod:`autonomy.tracking`; the thesis used ROS navigation);
6. ``v = blend(u, g, beta)`` (Eq. 3.2), then the safety layer
   (:func:`autonomy.safety.safe_command`, thesis footnote 31) scales ``v`` until it is
   collision-free over ``safety_horizon_s`` against the current laser points;
7. the :class:`~autonomy.types.Assist` carries ``v``, ``g``, ``beta``, the primitive's name
   as ``label``, the component id as ``target``, per-candidate best posterior mean as
   ``scores``, the predicted path (k, 3) and the timings.

Without a model (``model_path=""``) or without candidates (no semantic components) the
mode behaves as manual control: ``g = u``, ``beta = 0``, empty label, target and path; the
safety layer still checks the command (it belongs to this condition, Sec. 7.6.1.2). A
``model_path`` that does not exist is an error (``ValueError`` naming the file) when the
mode is built, not a silent fallback.

Decisions where the spec is silent:

- Speed. The tick budget (p95 < 5 ms with 10 candidates on one core) rules out calling
  :class:`autonomy.gmr.FastOnlineGMR` at every rollout step: its EM (``em_diagonal``, with
  random k-means++ seeding) costs about 1 ms for 10 points, i.e. 60 ms for a 60-step
  rollout. The rollout therefore runs the same Alg. 2 pipeline in a lean form here
  (:class:`LocalGMR`): the k nearest points by ``cKDTree``, EM for 2 diagonal components
  with a fixed number of iterations and *deterministic* seeds (the point of the local set
  nearest its mean and the point farthest from that one), and Gaussian mixture regression
  (Eqs. 4.5-4.8; with diagonal covariances each component predicts its own output mean).
  With deterministic seeding the local fit is a function of the neighbour set alone, so it
  is cached per neighbour set (exact, bounded). The tests check the regression against
  :func:`autonomy.gmr.gmr`.
- Recognition uses the SOGPs' arrays directly: the posterior means of all candidates and
  clusters (one kernel matrix per cluster, Eq. 5.6), and the variance (Eq. 5.9) only for
  the winner, which is all Eq. 5.10 needs; the tests check it against
  :func:`autonomy.sogp_classifier.recognise`.
- ``u*`` is re-evaluated every ``gmr_every`` = 4 rollout steps (every 0.2 s, the 5 Hz
  way-point rate of the thesis's demonstrations, Sec. 7.3 footnote 11) and held in
  between; ``s*``, ``q_est`` and the Mahalanobis stop are evaluated at every step. With 5
  EM iterations this keeps a 60-step rollout within the tick budget even when no local fit
  is cached (measured: see ``asa bench --only autonomy``).
- Yielding. Blending by the confidence alone can deadlock: near an obstacle the predicted
  path may lead into it, the safety layer stops the robot, and with ``beta`` near 1 the
  user's command (say, a turn away) has no effect, tick after tick (seen with scripted
  drivers at a gap of ``practice_course``). When the safety layer scales the blended
  command below ``yield_below_scale`` and the user's own command is freer, the mode
  yields for that tick: ``v`` = the user's safe command, ``beta`` = 0 (stored as such).
- ``u*`` from the GMR is clipped to the normalised range [-1, 1] before it is integrated.
  The kinematics are integrated with the mid-step heading (second order).
- If the rollout stops at its first step (the first ``q_est`` is already an outlier of the
  primitive), the path is empty and ``g = u``: nothing was predicted to assist with.
- The Mahalanobis statistics live in the model's standardised encoded feature space
  (7 dims; :mod:`autonomy.training`).
- No assistance without translational input: when ``|u_xy|`` in the normalised units is
  below ``min_input`` (0.05, i.e. 5 % of full stick deflection; 0.025 m/s on the default
  robot), the mode behaves as manual control (``beta = 0``, ``v = u`` through the safety
  layer). There is then no input direction, so the task feature carries no intention
  (the demonstrations keep only moving ticks, so the model never saw such inputs), and a
  driver who lets go of the stick must not be moved by the assistance.
- A recognition with no finite score (:func:`autonomy.sogp_classifier.argmax_finite`)
  also falls back to manual control.
- The local GMM's variance floor is relative to the primitive's data scale
  (``1e-3 *`` the column variance of its GMR points, as :mod:`autonomy.gmr`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
from scipy.spatial import cKDTree
from scipy.special import ndtr

from autonomy.arbitration import blend
from autonomy.features import encode, task_features
from autonomy.gmr import data_scale
from autonomy.model import DEFAULT_MODEL, GMR_INPUT, ContextualModel, load_model
from autonomy.modes import register, settings_from
from autonomy.safety import safe_command
from autonomy.sogp_classifier import argmax_finite
from autonomy.tracking import TrackingSettings, track
from autonomy.types import EMPTY_PATH, Assist, RobotModel


@dataclass(frozen=True, slots=True)
class ContextualSettings:
    """Settings of the contextual-task mode (values: see the module docstring)."""

    model_path: str = str(DEFAULT_MODEL)  # "" = no model: manual behaviour
    candidates: int = 10  # nearest semantic components considered
    rollout_steps: int = 60  # cap of Alg. 3's loop (3 s at dt = 0.05 s)
    gmr_k: int = 10  # neighbours of the fast online GMR (thesis Sec. 7.4.4)
    em_iters: int = 5  # EM iterations of the local 2-component GMM
    gmr_every: int = 4  # rollout steps per GMR evaluation (u* held in between; 5 Hz)
    mahalanobis_stop: float = 3.0  # Eq. (6.3) threshold (thesis Sec. 7.4.4)
    min_input: float = 0.05  # |u_xy| (normalised) below which the mode does not assist
    dt: float = 0.05  # [s] rollout step (thesis Sec. 7.4.4)
    tracking: TrackingSettings = field(default_factory=TrackingSettings)
    safety_horizon_s: float = 1.0  # [s] the safety layer's horizon
    # the assistance yields (beta = 0, v = the user's safe command) when the safety layer
    # must scale the blended command below this and the user's own command is freer
    yield_below_scale: float = 0.5

    def __post_init__(self) -> None:
        ybs = self.yield_below_scale
        if not (isinstance(ybs, int | float) and 0.0 <= ybs <= 1.0):
            raise ValueError(
                "contextual_task setting yield_below_scale: must be a number in [0, 1], got "
                f"{self.yield_below_scale!r}"
            )
        for name in ("candidates", "rollout_steps", "gmr_k", "em_iters", "gmr_every"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(
                    f"contextual_task setting {name}: must be an integer >= 1, got {value!r}"
                )
        for name in ("mahalanobis_stop", "dt", "safety_horizon_s", "min_input"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and math.isfinite(value) and value > 0):
                raise ValueError(
                    f"contextual_task setting {name}: must be a positive number, got {value!r}"
                )
        if not isinstance(self.model_path, str | Path):
            raise ValueError(
                f"contextual_task setting model_path: must be a file path or '', got "
                f"{self.model_path!r}"
            )


# --------------------------------------------------------------------------- recognition


class Recogniser:
    """Eqs. (5.6), (5.8), (5.10) over candidates x clusters from the arrays of a fitted SOGP
    classifier (``SOGPClassifier.to_dict()``; the GPs' ``Q`` is not needed).

    Equivalent to :func:`autonomy.sogp_classifier.recognise`, but computes the predictive
    variance only for the winning candidate and cluster.
    """

    def __init__(self, sogp: dict[str, Any]) -> None:
        self.classes_ = np.asarray(sogp["classes"]).copy()
        self.gps_ = []
        for gp in sogp["models"]:
            ls = np.asarray(gp["length_scales"], dtype=float)
            xs = np.asarray(gp["basis"], dtype=float) / ls
            self.gps_.append(
                (
                    xs,
                    (xs * xs).sum(axis=1),
                    np.asarray(gp["alpha"], dtype=float),
                    np.asarray(gp["C"], dtype=float),
                    float(gp["signal_var"]),
                    float(gp["noise_var"]),
                    ls,
                )
            )

    def __call__(self, Z: np.ndarray) -> tuple[int, int, float, np.ndarray]:
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
        Z = np.atleast_2d(np.asarray(Z, dtype=float))
        m, c = Z.shape[0], len(self.gps_)
        mean = np.empty((m, c))
        kernels = []
        for j, (xs, xs2, alpha, _, sf2, _, ls) in enumerate(self.gps_):
            a = Z / ls
            sq = xs2[:, None] + (a * a).sum(axis=1)[None, :] - 2.0 * (xs @ a.T)
            K = sf2 * np.exp(-0.5 * np.maximum(sq, 0.0))  # (b, m), Eq. (5.7)
            mean[:, j] = alpha @ K  # Eq. (5.6)
            kernels.append(K)
        i, j = argmax_finite(mean)  # Eq. (5.8), never a non-finite score
        if i < 0:
            return -1, -1, 0.0, mean
        _, _, _, C, sf2, noise, _ = self.gps_[j]
        k = kernels[j][:, i]
        var = max(sf2 + float(k @ (C @ k)), 0.0) + noise  # Eq. (5.9), clamped
        beta = float(ndtr(mean[i, j] / math.sqrt(var)))  # Eq. (5.10)
        if not math.isfinite(beta):
            beta = 0.0
        return i, int(self.classes_[j]), beta, mean


# --------------------------------------------------------------------------- local GMR


def local_gmm(local: np.ndarray, *, iters: int, reg: float = 1e-3, scale: np.ndarray | None = None):
    """EM for 2 diagonal Gaussian components on a small local set, deterministic seeds.

    Parameters
    ----------
    local : numpy.ndarray
        (k, D) points.
    iters : int
        EM iterations.
    reg : float
        Variance floor relative to ``scale``: ``reg * scale`` is added to every variance.
    scale : numpy.ndarray, optional
        (D,) per-column scale; default :func:`autonomy.gmr.data_scale` of ``local``.

    Returns
    -------
    weights : (K,), means : (K, D), variances : (K, D) with K = 2, or 1 when all points
    coincide.
    """
    k = local.shape[0]
    floor = reg * (data_scale(local) if scale is None else scale)
    centre = local.mean(axis=0)
    first = int(np.argmin(((local - centre) ** 2).sum(axis=1)))
    d2 = ((local - local[first]) ** 2).sum(axis=1)
    second = int(np.argmax(d2))
    if not d2[second] > 0:
        return np.ones(1), centre[None, :], (local.var(axis=0) + floor)[None, :]
    mu = local[[first, second]].copy()
    var = np.tile(local.var(axis=0) + floor, (2, 1))
    log_w = np.full(2, -math.log(2.0))
    sq = local * local
    for _ in range(iters):
        prec = 1.0 / var
        # E step: log pi_c + log N(x; mu_c, diag var_c) up to a constant, (k, 2)
        logp = (local @ (mu * prec).T - 0.5 * (sq @ prec.T)) + (
            log_w - 0.5 * ((mu * mu * prec).sum(axis=1) + np.log(var).sum(axis=1))
        )
        r = np.exp(logp - logp.max(axis=1, keepdims=True))
        r /= r.sum(axis=1, keepdims=True)
        nk = r.sum(axis=0) + 1e-12  # M step
        log_w = np.log(nk / k)
        mu = (r.T @ local) / nk[:, None]
        var = np.maximum((r.T @ sq) / nk[:, None] - mu * mu, 0.0) + floor
    w = np.exp(log_w)
    return w, mu, var


class LocalGMR:
    """Fast online GMR of one primitive (Alg. 2) with a per-neighbour-set cache.

    Parameters
    ----------
    points : numpy.ndarray
        (N, 5) demonstration points ``(s_x, s_y [m], v_x, v_y, omega)`` of the primitive.
    k : int
        Neighbours per query.
    iters : int
        EM iterations of :func:`local_gmm`.
    cache_size : int
        Local fits kept (cleared when full).
    """

    def __init__(self, points: np.ndarray, *, k: int, iters: int, cache_size: int = 50000):
        self.points_ = np.asarray(points, dtype=float)
        self.scale_ = data_scale(self.points_)  # for the relative variance floor
        self.tree_ = cKDTree(self.points_[:, list(GMR_INPUT)])
        self.k = min(int(k), len(self.points_))
        self.iters = int(iters)
        self.cache_size = int(cache_size)
        self.cache_: dict[bytes, tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = {}

    def fit_local(self, x: np.ndarray):
        """The local mixture for query ``x`` (2,): (weights, means, variances)."""
        _, idx = self.tree_.query(x, k=self.k)  # Alg. 2: nearest neighbours
        idx = np.sort(np.atleast_1d(idx))
        key = idx.tobytes()
        fit = self.cache_.get(key)
        if fit is None:
            w, mu, var = local_gmm(self.points_[idx], iters=self.iters, scale=self.scale_)
            fit = (np.log(w), mu[:, :2], var[:, :2], mu[:, 2:])
            if len(self.cache_) >= self.cache_size:
                self.cache_.clear()
            self.cache_[key] = fit
        return fit

    def predict(self, x: np.ndarray) -> np.ndarray:
        """Predicted output ``u*`` (3,) for the input ``s*`` (2,) [m] (Eqs. 4.5-4.8)."""
        log_w, mu_x, var_x, mu_y = self.fit_local(x)
        diff = x - mu_x
        logp = log_w - 0.5 * ((diff * diff / var_x).sum(axis=1) + np.log(var_x).sum(axis=1))
        h = np.exp(logp - logp.max())  # Eqs. (4.6), (4.7)
        return (h @ mu_y) / h.sum()  # Eq. (4.8), diagonal: mu_y|x = mu_y


# --------------------------------------------------------------------------- rollout


@dataclass(frozen=True, slots=True, eq=False)
class Runtime:
    """What the mode derives from a model once: recogniser, GMRs, Mahalanobis factors."""

    model: ContextualModel
    recogniser: Recogniser
    gmrs: tuple[LocalGMR, ...]
    whiten: np.ndarray  # (c, 7, 7) L^-1 with L L^T the primitive's covariance
    row: dict[int, int]  # cluster id -> row of the per-cluster arrays
    names: tuple[str, ...]


def build_runtime(model: ContextualModel, settings: ContextualSettings) -> Runtime:
    """Derive the run-time structures of ``model`` for ``settings``."""
    L = np.linalg.cholesky(model.cluster_covariances)
    eye = np.broadcast_to(np.eye(L.shape[1]), L.shape)
    whiten = np.linalg.solve(L, eye)
    gmrs = tuple(
        LocalGMR(model.cluster_points(j), k=settings.gmr_k, iters=settings.em_iters)
        for j in range(model.n_clusters)
    )
    return Runtime(
        model=model,
        recogniser=Recogniser(model.sogp),
        gmrs=gmrs,
        whiten=whiten,
        row={int(c): j for j, c in enumerate(model.cluster_ids)},
        names=model.cluster_names(),
    )


def _target_from(
    kind: str, points: np.ndarray, s0: np.ndarray, x: float, y: float, yaw: float
) -> tuple[float, float]:
    """Target point of a component seen from the robot-frame pose (x, y, yaw)."""
    if points is not None:
        d = points - (x, y)
        i = int(np.argmin(np.einsum("ij,ij->i", d, d)))
        dx, dy = float(d[i, 0]), float(d[i, 1])
    else:
        dx, dy = float(s0[0]) - x, float(s0[1]) - y
    c, s = math.cos(yaw), math.sin(yaw)
    return c * dx + s * dy, -s * dx + c * dy


def rollout(
    runtime: Runtime,
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
    component : semantic component in the robot frame (``.kind``, ``.points``,
        ``.target_point()``).
    robot : RobotModel
        Limits that turn normalised ``u*`` into velocities.
    settings : ContextualSettings

    Returns
    -------
    path : numpy.ndarray
        (k, 3) predicted poses (x [m], y [m], yaw [rad]) in the current robot frame,
        ``k <= rollout_steps``.
    distances : numpy.ndarray
        (k + 1,) or (k,) Mahalanobis distances (6.3) of every ``q_est`` computed (the last
        one above the threshold unless the cap ended the loop).
    """
    j = runtime.row[int(cluster)]
    gmr = runtime.gmrs[j]
    W = runtime.whiten[j]
    mean = runtime.model.cluster_means[j]
    smean = runtime.model.scaler.mean_
    sscale = runtime.model.scaler.scale_
    kind = getattr(component, "kind", "")
    pts = np.asarray(getattr(component, "points", np.zeros((0, 2))), dtype=float).reshape(-1, 2)
    points = pts if kind in ("object", "wall") and len(pts) else None
    s0 = np.asarray(component.target_point(), dtype=float)
    limit = np.array([robot.max_speed, robot.max_speed, robot.max_yaw_rate])
    dt = settings.dt
    stop = settings.mahalanobis_stop
    x = y = yaw = 0.0
    path = []
    dists = []
    z = np.empty(7)
    every = settings.gmr_every
    ux = uy = uw = 0.0
    for step in range(settings.rollout_steps):
        sx, sy = _target_from(kind, points, s0, x, y, yaw)  # Alg. 3, line 9
        if step % every == 0:
            u = np.clip(gmr.predict(np.array([sx, sy])), -1.0, 1.0)  # line 10
            ux, uy, uw = float(u[0]), float(u[1]), float(u[2])
        # line 11: q_est = (s*, theta*, u*), encoded as autonomy.features.encode does:
        # |u_xy| (cos theta, sin theta), (0, 0) without translational input
        speed = math.hypot(ux, uy)
        if speed >= 1e-6 and math.hypot(sx, sy) >= 1e-9:
            theta = math.atan2(uy, ux) - math.atan2(sy, sx)
            ct, st = speed * math.cos(theta), speed * math.sin(theta)
        else:
            ct, st = speed, 0.0
        z[:] = (sx, sy, ct, st, ux, uy, uw)
        e = W @ ((z - smean) / sscale - mean)
        d = math.sqrt(float(e @ e))  # line 12, Eq. (6.3)
        dists.append(d)
        if d > stop:
            break
        vx, vy, w = ux * limit[0], uy * limit[1], uw * limit[2]
        mid = yaw + 0.5 * w * dt  # line 14: holonomic kinematics, mid-step heading
        c, s = math.cos(mid), math.sin(mid)
        x += (c * vx - s * vy) * dt
        y += (s * vx + c * vy) * dt
        yaw += w * dt
        path.append((x, y, yaw))  # line 15
    out = np.array(path, dtype=float).reshape(-1, 3)
    return out, np.array(dists)


# --------------------------------------------------------------------------- the mode

_RUNTIMES: dict[tuple, Runtime] = {}


def _runtime_for(settings: ContextualSettings) -> Runtime | None:
    if str(settings.model_path) == "":
        return None
    path = Path(settings.model_path)
    if not path.is_file():
        raise ValueError(
            f"{path}: contextual_task model file not found (setting model_path; train one "
            f"with `asa train`, see autonomy/models/README.md)"
        )
    stat = path.stat()
    key = (str(path.resolve()), stat.st_mtime_ns, stat.st_size, settings.gmr_k, settings.em_iters)
    runtime = _RUNTIMES.get(key)
    if runtime is None:
        runtime = build_runtime(load_model(path), settings)
        _RUNTIMES.clear()  # one model at a time
        _RUNTIMES[key] = runtime
    return runtime


class ContextualTaskMode:
    """The contextual-task aware mode (see the module docstring)."""

    name = "contextual_task"

    def __init__(
        self,
        settings: ContextualSettings | None = None,
        *,
        model: ContextualModel | None = None,
    ) -> None:
        self.settings = settings if settings is not None else ContextualSettings()
        if model is not None:
            self.runtime_ = build_runtime(model, self.settings)
        else:
            self.runtime_ = _runtime_for(self.settings)
        self.robot_: RobotModel | None = None

    def reset(self, robot: RobotModel) -> None:
        self.robot_ = robot

    def _manual(self, u: np.ndarray, points: np.ndarray, start: float, t_rec: float) -> Assist:
        robot = self.robot_
        v, _ = safe_command(u, points, robot, horizon_s=self.settings.safety_horizon_s)
        end = time.perf_counter()
        return Assist(
            v=v,
            g=u.copy(),
            beta=0.0,
            label="",
            target="",
            scores={},
            predicted_path=EMPTY_PATH,
            timings_ms={
                "recognition": (t_rec - start) * 1e3,
                "rollout": 0.0,
                "safety": (end - t_rec) * 1e3,
                "total": (end - start) * 1e3,
            },
        )

    def step(self, obs: Any, u: np.ndarray) -> Assist:
        """One tick (see the module docstring).

        Parameters
        ----------
        obs : observation with ``points`` (m, 2) [m] and ``components`` (robot frame).
        u : (3,) joystick command (v_x [m/s], v_y [m/s], omega [rad/s]).
        """
        if self.robot_ is None:
            raise RuntimeError("contextual_task: call reset(robot) before step()")
        start = time.perf_counter()
        s, robot, rt = self.settings, self.robot_, self.runtime_
        u = np.array(u, dtype=float).reshape(3)
        points = np.asarray(obs.points, dtype=float).reshape(-1, 2)
        components = tuple(getattr(obs, "components", ()) or ())
        limit = np.array([robot.max_speed, robot.max_speed, robot.max_yaw_rate])
        u_norm = u / limit
        if rt is None or not components or math.hypot(u_norm[0], u_norm[1]) < s.min_input:
            return self._manual(u, points, start, time.perf_counter())

        # 1. candidates: the nearest components by target point
        targets = np.array([np.asarray(c.target_point(), dtype=float) for c in components])
        order = np.argsort(np.einsum("ij,ij->i", targets, targets), kind="stable")
        chosen = order[: s.candidates]
        # 2. q* per candidate, encoded and standardised
        q = task_features(targets[chosen], u_norm)
        Z = rt.model.scaler.transform(encode(q))
        # 3. recognition, Eqs. (5.6), (5.8), (5.10)
        i, cluster, beta, mean = rt.recogniser(Z)
        t_rec = time.perf_counter()
        if i < 0:  # no finite score: nothing recognised
            return self._manual(u, points, start, t_rec)
        component = components[int(chosen[i])]
        # 4. rollout, Alg. 3
        path, _ = rollout(rt, cluster, component, robot, s)
        t_roll = time.perf_counter()
        # 5. tracking controller -> g
        if len(path):
            g = track(
                path,
                s.dt,
                max_speed=robot.max_speed,
                max_yaw_rate=robot.max_yaw_rate,
                settings=s.tracking,
            )
        else:
            g = u.copy()
        # 6. blend (3.2) and the safety layer
        v = blend(u, g, beta)  # Eq. (3.2)
        t_track = time.perf_counter()
        v, scale = safe_command(v, points, robot, horizon_s=s.safety_horizon_s)
        if beta > 0.0 and scale < s.yield_below_scale:
            # blocked assistance must not hold the robot against the user's will
            v_user, scale_user = safe_command(u, points, robot, horizon_s=s.safety_horizon_s)
            if scale_user > scale:
                v, beta = v_user, 0.0
        end = time.perf_counter()
        best = mean.max(axis=1)
        scores = {str(components[int(k)].id): float(best[n]) for n, k in enumerate(chosen)}
        return Assist(
            v=v,
            g=g,
            beta=beta,
            label=rt.names[rt.row[cluster]],
            target=str(component.id),
            scores=scores,
            predicted_path=path,
            timings_ms={
                "recognition": (t_rec - start) * 1e3,
                "rollout": (t_roll - t_rec) * 1e3,
                "tracking": (t_track - t_roll) * 1e3,
                "safety": (end - t_track) * 1e3,
                "total": (end - start) * 1e3,
            },
        )


@register("contextual_task")
def make_contextual_task(**settings: Any) -> ContextualTaskMode:
    """Registry factory: keyword settings are the fields of :class:`ContextualSettings`."""
    return ContextualTaskMode(
        settings_from(ContextualSettings, settings, where="mode 'contextual_task'")
    )
