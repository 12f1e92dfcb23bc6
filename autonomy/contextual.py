"""Contextual-task aware shared autonomy (thesis Ch. 5-6, Sec. 7.6.1.2; spec sections 3-4;
issue 3), registered as the mode ``"contextual_task"``.

Per tick: the nearest semantic components are the candidates (Sec. 5.1, 6.1); the SOGP
classifier recognises the target and the motion primitive (Eqs. 5.6, 5.8, 5.10); the
rollout predicts the primitive's path (Alg. 3); a pure-pursuit controller follows it,
the command is blended by the confidence (Eq. 3.2) and checked by the safety layer.
Without a model, candidates or input the mode is manual control through the safety
layer. Choices where the thesis is silent: docs/decisions.md.
"""

from __future__ import annotations

import dataclasses
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from autonomy import _kernels, _tick_kernels
from autonomy.arbitration import blend
from autonomy.dwa import DWASettings, dwa
from autonomy.intent_prior import IntentPrior
from autonomy.kind_time import KindTimeRecogniser, KindTimeSettings
from autonomy.local_gmr import EM_MAX_ITER, EM_TOL, LocalGMR
from autonomy.model import DEFAULT_MODEL, ContextualModel, load_model
from autonomy.modes import register, settings_from
from autonomy.safety import safe_command
from autonomy.sogp_recogniser import Recogniser
from autonomy.task_types import TASK_TYPES, contextual_task, primitive_motions
from autonomy.tracking import TrackingSettings, track
from autonomy.types import EMPTY_PATH, Assist, RobotModel, as_candidates

RECOGNISERS = ("kind_time", "thesis", "oracle", "none")


@dataclass(frozen=True, slots=True)
class ContextualSettings:
    """Settings of the contextual-task mode (choices: docs/decisions.md)."""

    model_path: str = str(DEFAULT_MODEL)  # "" = no model: manual behaviour
    candidates: int = 10  # nearest semantic components considered
    rollout_steps: int = 60  # cap of Alg. 3's loop (3 s at dt = 0.05 s)
    gmr_k: int = 10  # neighbours of the fast online GMR (thesis Sec. 7.4.4)
    em_tol: float = EM_TOL  # local EM: stop below this relative change of the log-likelihood
    em_max_iter: int = EM_MAX_ITER  # local EM iterations at most
    mahalanobis_stop: float = 3.0  # Eq. (6.3) threshold (thesis Sec. 7.4.4)
    min_input: float = 0.05  # |u_xy| (normalised) below which the mode does not assist
    dt: float = 0.05  # [s] rollout step (thesis Sec. 7.4.4)
    tracking: TrackingSettings = field(default_factory=TrackingSettings)
    safety_horizon_s: float = 1.0  # [s] the safety layer's horizon
    # the assistance yields (beta = 0, v = the user's safe command) when the safety layer
    # must scale the blended command below this (1: whenever it slows it at all) and the
    # user's own command is freer
    yield_below_scale: float = 1.0
    # freer: the user's safe command gets further along the user's translational input
    # than the safe blend; False: its safety scale is larger (the rule before issue 19)
    yield_by_progress: bool = True
    # where the safety layer would slow the user's command, the command yielded to is the
    # dynamic window's admissible twist nearest it (the reactive mode's obstacle avoidance,
    # Eq. 3.8) if that gets further; False: always the user's command, scaled
    yield_planner: bool = True
    planner: DWASettings = field(default_factory=DWASettings)
    # which recogniser drives the assistance: "kind_time" (issue 40: the component's kind
    # and time, autonomy.kind_time), "thesis" (Ch. 6: Eq. 5.8 per tick, beta of Eq. 5.10),
    # "oracle" (the synthetic participant's true task and target, blend weight 1: an
    # ablation), "none" (recognition shown, never assisting: the safety layer alone)
    recogniser: str = "kind_time"
    kind_time: KindTimeSettings = field(default_factory=KindTimeSettings)

    def __post_init__(self) -> None:
        if self.recogniser not in RECOGNISERS:
            raise ValueError(
                f"contextual_task setting recogniser: must be one of "
                f"{', '.join(RECOGNISERS)}, got {self.recogniser!r}"
            )
        if not isinstance(self.yield_planner, bool):
            raise ValueError(
                "contextual_task setting yield_planner: must be true or false, got "
                f"{self.yield_planner!r}"
            )
        ybs = self.yield_below_scale
        if not (isinstance(ybs, int | float) and 0.0 <= ybs <= 1.0):
            raise ValueError(
                "contextual_task setting yield_below_scale: must be a number in [0, 1], got "
                f"{self.yield_below_scale!r}"
            )
        if not isinstance(self.yield_by_progress, bool):
            raise ValueError(
                "contextual_task setting yield_by_progress: must be true or false, got "
                f"{self.yield_by_progress!r}"
            )
        for name in ("candidates", "rollout_steps", "gmr_k"):
            value = getattr(self, name)
            if not (isinstance(value, int) and value >= 1):
                raise ValueError(
                    f"contextual_task setting {name}: must be an integer >= 1, got {value!r}"
                )
        tol, cap = self.em_tol, self.em_max_iter
        if isinstance(tol, bool) or not (isinstance(tol, int | float) and 0 <= tol < math.inf):
            raise ValueError(
                f"contextual_task setting em_tol: must be a finite number >= 0, got {tol!r}"
            )
        if isinstance(cap, bool) or not (isinstance(cap, int) and cap >= 1):
            raise ValueError(
                f"contextual_task setting em_max_iter: must be an integer >= 1, got {cap!r}"
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


# --------------------------------------------------------------------------- rollout


@dataclass(frozen=True, slots=True, eq=False)
class Runtime:
    """What the mode derives from a model once: recogniser, GMRs, Mahalanobis factors."""

    model: ContextualModel
    recogniser: Recogniser
    gmrs: tuple[LocalGMR, ...]
    whiten: np.ndarray  # (c, 7, 7) L^-1 with L L^T the primitive's covariance
    row: dict[int, int]  # cluster id -> row of the per-cluster arrays
    # the Mahalanobis map of raw encoded features: e = whiten_scaled[j] @ z - whiten_offset[j]
    whiten_scaled: np.ndarray  # (c, 7, 7) whiten / the scaler's scale_
    whiten_offset: np.ndarray  # (c, 7) whiten @ (mean_ / scale_ + cluster mean)
    # e = [whiten_scaled[j], -whiten_offset[j]] @ (z, 1): one product a rollout step
    mahalanobis: np.ndarray  # (c, 7, 8)


def build_runtime(model: ContextualModel, settings: ContextualSettings) -> Runtime:
    """Derive the run-time structures of ``model`` for ``settings``."""
    L = np.linalg.cholesky(model.cluster_covariances)
    eye = np.broadcast_to(np.eye(L.shape[1]), L.shape)
    whiten = np.linalg.solve(L, eye)
    gmrs = tuple(
        LocalGMR(
            model.cluster_points(j),
            k=settings.gmr_k,
            tol=settings.em_tol,
            max_iter=settings.em_max_iter,
        )
        for j in range(model.n_clusters)
    )
    scaler = model.scaler
    whiten_scaled = whiten / scaler.scale_[None, None, :]
    whiten_offset = np.einsum(
        "cij,cj->ci", whiten, scaler.mean_ / scaler.scale_ + model.cluster_means
    )
    return Runtime(
        model=model,
        recogniser=Recogniser(model.sogp),
        gmrs=gmrs,
        whiten=whiten,
        row={int(c): j for j, c in enumerate(model.cluster_ids)},
        whiten_scaled=whiten_scaled,
        whiten_offset=whiten_offset,
        mahalanobis=np.concatenate((whiten_scaled, -whiten_offset[:, :, None]), axis=2),
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


def _target_geometry(component: Any) -> tuple[np.ndarray | None, float, float]:
    """How the rollout sees ``component``'s target: an object's or wall's surface points
    (p, 2) [m], robot frame, whose nearest to the rolled-out pose is the target, else
    None and the fixed target point ``(s0x, s0y)`` [m]."""
    pts = np.asarray(component.points, dtype=float).reshape(-1, 2)
    points = pts if component.kind in ("object", "wall") and len(pts) else None
    if points is None:
        s0 = np.asarray(component.target_point(), dtype=float)
        return None, float(s0[0]), float(s0[1])
    return points, 0.0, 0.0


def rollout(
    runtime: Runtime,
    cluster: int,
    component: Any,
    robot: RobotModel,
    settings: ContextualSettings,
) -> tuple[np.ndarray, np.ndarray]:
    """Algorithm 3: the local trajectory predicted for a recognised primitive and target.

    Computed by :func:`autonomy._kernels.rollout_kernel` (the loop written out in
    scalar arithmetic, bit-identical to the Python loop it replaced, kept in
    tests/contextual_reference.py): per step the target point ``s*`` seen from the
    rolled-out pose (line 9), the fast online GMR ``u*`` (line 10, Alg. 2), ``q_est``
    encoded as :func:`autonomy.features.encode` does (line 11), its Mahalanobis distance
    (6.3) to the primitive (line 12; stop above ``mahalanobis_stop``) and a holonomic
    step with the mid-step heading (line 14).

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
    points, s0x, s0y = _target_geometry(component)
    if points is not None:  # |p - h|^2 - |h|^2 = (p, |p|^2) . (-2 h, 1): one product
        lifted = _tick_kernels.lift_points(np.ascontiguousarray(points))
    else:
        lifted = _NO_POINTS
    cap = settings.rollout_steps
    fs = np.array(
        (0.0, 0.0, 0.0, s0x, s0y, float(robot.max_speed), float(robot.max_yaw_rate))
        + (float(settings.dt), float(settings.mahalanobis_stop))
    )
    it = np.array((cap, 0, 0), dtype=np.int64)  # steps cap, path rows, distances
    path, dists = np.empty((cap, 3)), np.empty(cap)
    gmr.cache_.reserve(cap)
    _kernels.rollout_kernel(gmr.kernel_state(), lifted, runtime.mahalanobis[j], fs, it, path, dists)
    return path[: it[1]].copy(), dists[: it[2]].copy()


_NO_POINTS = np.empty((0, 3))


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
    key = (
        str(path.resolve()),
        stat.st_mtime_ns,
        stat.st_size,
        settings.gmr_k,
        settings.em_tol,
        settings.em_max_iter,
    )
    runtime = _RUNTIMES.get(key)
    if runtime is None:
        runtime = build_runtime(load_model(path), settings)
        _RUNTIMES.clear()  # one model at a time
        _RUNTIMES[key] = runtime
    return runtime


def _ids(components: Any, chosen: np.ndarray) -> list[str]:
    """The ids (str) of the ``chosen`` candidates (indices), read from the candidates'
    ``ids()`` where they have it (no component built), else from each component."""
    ids = getattr(components, "ids", None)
    if ids is not None:
        every = ids()
        return [every[k] for k in chosen.tolist()]
    return [str(components[int(k)].id) for k in chosen.tolist()]


def _progress(v: np.ndarray, u: np.ndarray) -> float:
    """Speed [m/s] of the command ``v`` (3,) along the translational input of ``u`` (3,),
    which is not zero (the mode assists only above ``min_input``)."""
    return (v[0] * u[0] + v[1] * u[1]) / math.hypot(u[0], u[1])


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
        self.motions_ = (
            primitive_motions(self.runtime_.model.metadata.get("clusters", []))
            if self.runtime_ is not None
            else {}
        )
        self.intent_ = None
        self.intention_ = ("", "")  # the oracle's: the participant's true (task, target)
        if self.runtime_ is not None and self.settings.recogniser == "kind_time":
            prior = IntentPrior.from_metadata(
                self.runtime_.model.metadata, self.runtime_.recogniser.classes_
            )
            self.intent_ = KindTimeRecogniser(prior, self.settings.kind_time)

    def reset(self, robot: RobotModel) -> None:
        self.robot_ = robot
        if self.intent_ is not None:
            self.intent_.reset()
        # (3,) the limits that normalise a command (max speed twice, max yaw rate)
        self.limit_ = np.array([robot.max_speed, robot.max_speed, robot.max_yaw_rate])

    def settings_dict(self) -> dict[str, Any]:
        """The effective :class:`ContextualSettings`, tracking's nested."""
        return dataclasses.asdict(self.settings)

    def needs_intention(self) -> bool:
        """The oracle (``recogniser = "oracle"``) is driven by the true intention."""
        return self.settings.recogniser == "oracle"

    def observe_intention(self, task: str, target: str) -> None:
        self.intention_ = (str(task), str(target))

    def label_tasks(self) -> dict[str, str]:
        """The mode's labels are contextual task types (:mod:`autonomy.task_types`): each
        means itself; empty without a model. The trial loop stores it so that the
        recognition can be scored against a synthetic participant's true intention."""
        if self.runtime_ is None:
            return {}
        return {t: t for t in TASK_TYPES}

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

    def _safe(
        self, v: np.ndarray, u: np.ndarray, beta: float, points: np.ndarray, velocity: np.ndarray
    ) -> tuple[np.ndarray, float]:
        """The safety layer on the blended command ``v`` (3,); the mode yields (``v`` the
        user's safe command, ``beta`` 0) when ``v`` is scaled below ``yield_below_scale``
        and the user's own command ``u`` (3,) is freer. With ``yield_planner`` the user's
        safe command is, where the safety layer would slow ``u``, the dynamic window's
        admissible twist nearest ``u`` (Eq. 3.8; the window centred on ``velocity`` (3,))
        when that gets further along ``u``.
        ``points`` (m, 2) [m]."""
        s, robot = self.settings, self.robot_
        v, scale = safe_command(v, points, robot, horizon_s=s.safety_horizon_s)
        if scale < s.yield_below_scale and (beta > 0.0 or s.yield_planner):
            # an assistance the safety layer must slow may not hold the robot back where
            # the user's own command, checked alike, gets further (docs/decisions.md)
            v_user, scale_user = safe_command(u, points, robot, horizon_s=s.safety_horizon_s)
            if s.yield_planner and scale_user < 1.0:
                planned = dwa(u, points, velocity, robot, settings=s.planner).v
                if _progress(planned, u) > _progress(v_user, u):
                    v_user = planned
            if s.yield_by_progress:
                freer = _progress(v_user, u) > _progress(v, u)
            else:
                freer = scale_user > scale
            if freer:
                v, beta = v_user, 0.0
        return v, beta

    def step(self, obs: Any, u: np.ndarray) -> Assist:
        """One tick (see the module docstring).

        Parameters
        ----------
        obs : observation with ``points`` (m, 2) [m] and ``components`` (robot frame,
            :class:`autonomy.types.Candidates` or a sequence of components).
        u : (3,) joystick command (v_x [m/s], v_y [m/s], omega [rad/s]).
        """
        if self.robot_ is None:
            raise RuntimeError("contextual_task: call reset(robot) before step()")
        start = time.perf_counter()
        s, robot, rt = self.settings, self.robot_, self.runtime_
        u = np.array(u, dtype=float).reshape(3)
        points = np.asarray(obs.points, dtype=float).reshape(-1, 2)
        components = obs.components
        u_norm = u / self.limit_
        nx, ny, _ = u_norm.tolist()
        if rt is None or not len(components) or math.hypot(nx, ny) < s.min_input:
            if self.intent_ is not None:
                self.intent_.idle()
            return self._manual(u, points, start, time.perf_counter())

        # 1. candidates: the nearest components by target point
        components = as_candidates(components)
        # 2. q* per candidate, encoded and standardised (features.task_features, encode)
        targets = np.ascontiguousarray(components.target_points(), dtype=float).reshape(-1, 2)
        n = min(s.candidates, len(targets))
        chosen, Z = np.empty(n, dtype=np.int64), np.empty((n, 7))
        scaler = rt.model.scaler
        _tick_kernels.candidate_features(targets, n, u_norm, scaler.mean_, scaler.scale_, Z, chosen)
        # 3. recognition, Eqs. (5.6), (5.8), (5.10); with kind and time (autonomy.kind_time)
        ids = _ids(components, chosen)
        i, cluster, beta, mean = self._recognise(components, chosen, ids, targets, Z, u_norm)
        t_rec = time.perf_counter()
        if i < 0:  # no finite score: nothing recognised
            return self._manual(u, points, start, t_rec)
        component = components[int(chosen[i])]
        # 4. rollout, Alg. 3 (not while the kind-and-time recogniser withholds assistance)
        if beta > 0.0 or s.recogniser in ("thesis", "none"):
            path, _ = rollout(rt, cluster, component, robot, s)
        else:
            path = EMPTY_PATH
        t_roll = time.perf_counter()
        # 5. tracking controller -> g
        g, beta = self._guide(path, u, beta, ids[i])
        # 6. blend (3.2) and the safety layer
        v = blend(u, g, beta)  # Eq. (3.2)
        t_track = time.perf_counter()
        v, beta = self._safe(v, u, beta, points, obs.velocity)
        end = time.perf_counter()
        best = mean.max(axis=1)
        scores = dict(zip(ids, best.tolist(), strict=True))
        return Assist(
            v=v,
            g=g,
            beta=beta,
            label=contextual_task(str(component.kind), self.motions_.get(int(cluster), "")),
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

    def _recognise(
        self,
        components: Any,
        chosen: np.ndarray,
        ids: list[str],
        targets: np.ndarray,
        Z: np.ndarray,
        u_norm: np.ndarray,
    ) -> tuple[int, int, float, np.ndarray]:
        """The settings' recogniser on the ``chosen`` candidates' features ``Z`` (n, 7):
        (candidate row, cluster id, blend weight, the SOGP means (n, c))."""
        recogniser = self.settings.recogniser
        if self.intent_ is not None:  # the means alone (Eq. 5.6): no Ch. 6 winner needed
            mean = self.runtime_.recogniser.means(Z)
            if not np.isfinite(mean).any():
                return -1, -1, 0.0, mean
            i, cluster, beta = self._kind_time(components, chosen, ids, targets, mean, u_norm)
            return i, cluster, beta, mean
        i, cluster, beta, mean = self.runtime_.recogniser(Z)  # Eqs. (5.6), (5.8), (5.10)
        if recogniser == "oracle":
            i, cluster, beta = self._oracle(components, chosen, ids, mean)
        elif recogniser == "none":
            beta = 0.0
        return i, cluster, beta, mean

    def _guide(
        self, path: np.ndarray, u: np.ndarray, beta: float, target: str
    ) -> tuple[np.ndarray, float]:
        """The tracking controller's command ``g`` (3,) along ``path`` (``u`` without one)
        and the blend weight: 0 when the driver's command ``u`` points against ``g`` with
        the kind-and-time or oracle recogniser (which then believes less in ``target``)."""
        s, robot = self.settings, self.robot_
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
        pushing = g[0] * u[0] + g[1] * u[1] < 0.0
        if s.recogniser in ("kind_time", "oracle") and beta > 0.0 and pushing:
            if self.intent_ is not None:
                self.intent_.contradict(target)
            beta = 0.0
        return g, beta

    def _kind_time(
        self,
        components: Any,
        chosen: np.ndarray,
        ids: list[str],
        targets: np.ndarray,
        mean: np.ndarray,
        u_norm: np.ndarray,
    ) -> tuple[int, int, float]:
        """The kind-and-time recogniser's candidate (row of ``chosen``), cluster id and
        blend weight; ``mean`` (n, c) the SOGP means of the ``chosen`` candidates."""
        every_kind = getattr(components, "kinds", None)  # as _ids: without building them
        if every_kind is not None:
            kinds_all = every_kind()
            kinds = [kinds_all[k] for k in chosen.tolist()]
            normals = np.asarray(components.normals(), dtype=float)[chosen]
        else:
            picked = [components[int(k)] for k in chosen.tolist()]
            kinds = [str(c.kind) for c in picked]
            normals = np.array([np.asarray(c.normal, dtype=float).reshape(2) for c in picked])
        near = targets[chosen]
        found = self.intent_(mean, ids, kinds, near, normals, u_norm)
        classes = self.runtime_.recogniser.classes_
        return found.candidate, int(classes[found.primitive]), found.beta

    def _oracle(
        self, components: Any, chosen: np.ndarray, ids: list[str], mean: np.ndarray
    ) -> tuple[int, int, float]:
        """The true target among the candidates (row of ``chosen``; -1 when the driver
        does no task or the target is not among them), the best-scoring primitive whose
        motion makes the true task on it (any primitive if none does), blend weight 1."""
        task, target = self.intention_
        if not task or target not in ids:
            return -1, -1, 0.0
        i = ids.index(target)
        kind = str(components[int(chosen[i])].kind)
        classes = self.runtime_.recogniser.classes_
        fits = [contextual_task(kind, self.motions_.get(int(c), "")) == task for c in classes]
        scores = np.where(fits, mean[i], -np.inf) if any(fits) else mean[i]
        return i, int(classes[int(np.argmax(scores))]), 1.0


@register("contextual_task")
def make_contextual_task(**settings: Any) -> ContextualTaskMode:
    """Registry factory: keyword settings are the fields of :class:`ContextualSettings`."""
    return ContextualTaskMode(
        settings_from(ContextualSettings, settings, where="mode 'contextual_task'")
    )


# the mode's variants with other recognisers register themselves once the mode exists
from autonomy import contextual_variants  # noqa: E402, F401, I001
