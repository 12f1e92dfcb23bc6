"""The optimised contextual mode (autonomy.contextual) gives the outputs of its plain
formulation: the reference below is the implementation before the per-tick optimisations
(batched recogniser, scalar GMR prediction, the rollout's folded Mahalanobis map, one call
for all target points), kept here verbatim in its arithmetic; its local GMR follows the
faithful Alg. 3: ``u*`` at every step from the local GMM of
:func:`autonomy.local_gmr.local_gmm` (EM to convergence; checked against a plain EM in
tests/test_local_gmr.py), so the fits agree to rounding. Both run on the same model
file (a copy of the shipped model, so retraining it meanwhile changes nothing here) and on
the same observations: the robot driven through ``cluttered_room`` by ``sim.world``, and
synthetic scenes with plain tuples of components.
"""

from __future__ import annotations

import dataclasses
import math
import shutil
import sys
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from scipy.spatial import cKDTree
from scipy.special import ndtr

from autonomy.arbitration import blend
from autonomy.contextual import ContextualSettings, ContextualTaskMode, Recogniser
from autonomy.features import encode, task_features
from autonomy.gmr import data_scale
from autonomy.local_gmr import local_gmm
from autonomy.model import DEFAULT_MODEL, GMR_INPUT, load_model
from autonomy.safety import safe_command
from autonomy.sogp_classifier import argmax_finite
from autonomy.task_types import contextual_task, primitive_motions
from autonomy.tracking import track
from autonomy.types import RobotModel
from sim.types import SemanticComponent

sys.path.insert(0, str(Path(__file__).parent))
from contextual_reference import (  # noqa: E402
    assert_recognitions_match,
    recognition_tolerances,
)
from fp import PIPELINE_RTOL, assert_close, assert_pipeline_close, near_best  # noqa: E402

# the reference keeps the yield rule before issue 19 (below half the safety scale, the
# scales compared); the mode's settings select it, as the golden rows pin old DWA scoring
OLD_YIELD = {"yield_below_scale": 0.5, "yield_by_progress": False, "yield_planner": False}
OLD_YIELD["recogniser"] = "thesis"  # the reference is the thesis's Ch. 6 recogniser

# --------------------------------------------------------------------------- reference


class _RefRecogniser:
    def __init__(self, sogp: dict[str, Any]) -> None:
        self.twin_ = Recogniser(sogp)  # its arrays give the tolerances (tests/fp.py)
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

    def __call__(self, Z):
        Z = np.atleast_2d(np.asarray(Z, dtype=float))
        m, c = Z.shape[0], len(self.gps_)
        mean = np.empty((m, c))
        kernels = []
        for j, (xs, xs2, alpha, _, sf2, _, ls) in enumerate(self.gps_):
            a = Z / ls
            sq = xs2[:, None] + (a * a).sum(axis=1)[None, :] - 2.0 * (xs @ a.T)
            K = sf2 * np.exp(-0.5 * np.maximum(sq, 0.0))
            mean[:, j] = alpha @ K
            kernels.append(K)
        i, j = argmax_finite(mean)
        if i < 0:
            return -1, -1, 0.0, mean
        _, _, _, C, sf2, noise, _ = self.gps_[j]
        k = kernels[j][:, i]
        var = max(sf2 + float(k @ (C @ k)), 0.0) + noise
        beta = float(ndtr(mean[i, j] / math.sqrt(var)))
        if not math.isfinite(beta):
            beta = 0.0
        return i, int(self.classes_[j]), beta, mean


class _RefLocalGMR:
    def __init__(self, points, *, k, tol, max_iter):
        self.points_ = np.asarray(points, dtype=float)
        self.scale_ = data_scale(self.points_)
        self.tree_ = cKDTree(self.points_[:, list(GMR_INPUT)])
        self.k = min(int(k), len(self.points_))
        self.tol, self.max_iter = tol, max_iter
        self.cache_ = {}

    def predict(self, x):
        _, idx = self.tree_.query(x, k=self.k)
        idx = np.sort(np.atleast_1d(idx))
        key = idx.tobytes()
        fit = self.cache_.get(key)
        if fit is None:
            w, mu, var, *_ = local_gmm(
                self.points_[idx],
                tol=self.tol,
                max_iter=self.max_iter,
                scale=self.scale_,
                origin=self.points_.mean(axis=0),  # the sums' origin LocalGMR uses
            )
            fit = self.cache_[key] = (np.log(w), mu[:, :2], var[:, :2], mu[:, 2:])
        log_w, mu_x, var_x, mu_y = fit
        diff = x - mu_x
        logp = log_w - 0.5 * ((diff * diff / var_x).sum(axis=1) + np.log(var_x).sum(axis=1))
        h = np.exp(logp - logp.max())
        return (h @ mu_y) / h.sum()


def _ref_target_from(kind, points, s0, x, y, yaw):
    if points is not None:
        d = points - (x, y)
        i = int(np.argmin(np.einsum("ij,ij->i", d, d)))
        dx, dy = float(d[i, 0]), float(d[i, 1])
    else:
        dx, dy = float(s0[0]) - x, float(s0[1]) - y
    c, s = math.cos(yaw), math.sin(yaw)
    return c * dx + s * dy, -s * dx + c * dy


class _Reference:
    """The contextual mode's step before the optimisations."""

    def __init__(self, model, settings: ContextualSettings, robot: RobotModel) -> None:
        self.model, self.s, self.robot = model, settings, robot
        self.recogniser = _RefRecogniser(model.sogp)
        self.gmrs = [
            _RefLocalGMR(
                model.cluster_points(j),
                k=settings.gmr_k,
                tol=settings.em_tol,
                max_iter=settings.em_max_iter,
            )
            for j in range(model.n_clusters)
        ]
        L = np.linalg.cholesky(model.cluster_covariances)
        self.whiten = np.linalg.solve(L, np.broadcast_to(np.eye(L.shape[1]), L.shape))
        self.row = {int(c): j for j, c in enumerate(model.cluster_ids)}

    def rollout(self, cluster, component):
        j, s, robot = self.row[int(cluster)], self.s, self.robot
        gmr, W, mean = self.gmrs[j], self.whiten[j], self.model.cluster_means[j]
        smean, sscale = self.model.scaler.mean_, self.model.scaler.scale_
        kind = getattr(component, "kind", "")
        pts = np.asarray(getattr(component, "points", np.zeros((0, 2))), dtype=float)
        pts = pts.reshape(-1, 2)
        points = pts if kind in ("object", "wall") and len(pts) else None
        s0 = np.asarray(component.target_point(), dtype=float)
        limit = np.array([robot.max_speed, robot.max_speed, robot.max_yaw_rate])
        x = y = yaw = 0.0
        path, z = [], np.empty(7)
        for _ in range(s.rollout_steps):
            sx, sy = _ref_target_from(kind, points, s0, x, y, yaw)
            u = np.clip(gmr.predict(np.array([sx, sy])), -1.0, 1.0)
            ux, uy, uw = float(u[0]), float(u[1]), float(u[2])
            speed = math.hypot(ux, uy)
            if speed >= 1e-6 and math.hypot(sx, sy) >= 1e-9:
                theta = math.atan2(uy, ux) - math.atan2(sy, sx)
                ct, st = speed * math.cos(theta), speed * math.sin(theta)
            else:
                ct, st = speed, 0.0
            z[:] = (sx, sy, ct, st, ux, uy, uw)
            e = W @ ((z - smean) / sscale - mean)
            if math.sqrt(float(e @ e)) > s.mahalanobis_stop:
                break
            vx, vy, w = ux * limit[0], uy * limit[1], uw * limit[2]
            mid = yaw + 0.5 * w * s.dt
            c, sn = math.cos(mid), math.sin(mid)
            x += (c * vx - sn * vy) * s.dt
            y += (sn * vx + c * vy) * s.dt
            yaw += w * s.dt
            path.append((x, y, yaw))
        return np.array(path, dtype=float).reshape(-1, 3)

    def step(self, obs, u):
        s, robot = self.s, self.robot
        u = np.array(u, dtype=float).reshape(3)
        points = np.asarray(obs.points, dtype=float).reshape(-1, 2)
        components = tuple(getattr(obs, "components", ()) or ())
        limit = np.array([robot.max_speed, robot.max_speed, robot.max_yaw_rate])
        u_norm = u / limit
        horizon = s.safety_horizon_s
        manual = (safe_command(u, points, robot, horizon_s=horizon)[0], u.copy(), 0.0, "", "")
        manual_tol = {"tied": False, "beta": 0.0, "scores": {}, "v": 0.0}
        if not components or math.hypot(u_norm[0], u_norm[1]) < s.min_input:
            return (*manual, {}, np.zeros((0, 3)), manual_tol)
        targets = np.array([np.asarray(c.target_point(), dtype=float) for c in components])
        order = np.argsort(np.einsum("ij,ij->i", targets, targets), kind="stable")
        chosen = order[: s.candidates]
        Z = self.model.scaler.transform(encode(task_features(targets[chosen], u_norm)))
        i, cluster, beta, mean = self.recogniser(Z)
        mean_tol, beta_tol = recognition_tolerances(self.recogniser.twin_, Z)
        if i < 0:
            return (*manual, {}, np.zeros((0, 3)), manual_tol)
        tied = bool(near_best(mean, mean_tol).sum() > 1)
        component = components[int(chosen[i])]
        path = self.rollout(cluster, component)
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
        v, scale = safe_command(blend(u, g, beta), points, robot, horizon_s=horizon)
        if beta > 0.0 and scale < s.yield_below_scale:
            v_user, scale_user = safe_command(u, points, robot, horizon_s=horizon)
            if scale_user > scale:
                v, beta = v_user, 0.0
        best, best_tol = mean.max(axis=1), mean_tol.max(axis=1)
        scores = {str(components[int(k)].id): float(best[n]) for n, k in enumerate(chosen)}
        # the label names the contextual task (autonomy.task_types), not the primitive
        motion = primitive_motions(self.model.metadata.get("clusters", [])).get(cluster, "")
        label = contextual_task(str(component.kind), motion)
        tol = {
            "tied": tied,
            "beta": beta_tol,
            "scores": {str(components[int(k)].id): best_tol[n] for n, k in enumerate(chosen)},
            "v": PIPELINE_RTOL * max(float(np.abs(v).max()), 1.0)
            + float(np.abs(g - u).max()) * beta_tol,
        }
        return v, g, beta, label, str(component.id), scores, path, tol


# --------------------------------------------------------------------------- fixtures


@pytest.fixture(scope="module")
def model_file(tmp_path_factory) -> str:
    if not DEFAULT_MODEL.is_file():
        pytest.skip("no shipped model file")
    path = tmp_path_factory.mktemp("model") / "model.npz"
    shutil.copyfile(DEFAULT_MODEL, path)
    return str(path)


def _assert_same(assist, ref) -> bool:
    """The mode's output equals the reference's within its tolerances (tests/fp.py):
    values to rounding, the recognised task and target exactly unless the reference's
    winner was tied within the tolerances (then the rest is not comparable: False)."""
    v, g, beta, label, target, scores, path, tol = ref
    if tol["tied"]:
        return False
    assert (assist.label, assist.target) == (label, target)
    assert assist.scores.keys() == scores.keys()
    for key, value in scores.items():
        assert_close(assist.scores[key], value, tol["scores"][key], name="step.score")
    assert_close(assist.beta, beta, tol["beta"], name="step.beta")
    assert_close(assist.v, v, tol["v"], name="step.v")
    assert_close(assist.g, g, PIPELINE_RTOL * max(float(np.abs(g).max()), 1.0), name="step.g")
    assert assist.predicted_path.shape == path.shape
    assert_pipeline_close(assist.predicted_path, path, name="step.path")
    return True


def _weave(k: int, phase: float) -> np.ndarray:
    t = 0.05 * k + phase
    return np.array(
        [0.25 + 0.2 * math.sin(0.3 * t), 0.2 * math.sin(0.7 * t), 0.5 * math.sin(0.25 * t)]
    )


# --------------------------------------------------------------------------- tests


def test_equal_outputs_on_a_drive_through_the_cluttered_room(model_file, rng):
    from sim.scenario import load_scenario
    from sim.semantics import derive_components
    from sim.world import World

    scenario = load_scenario("cluttered_room")
    robot = RobotModel.from_spec(scenario.robot)
    settings = ContextualSettings(model_path=model_file, **OLD_YIELD)
    mode = ContextualTaskMode(settings)
    mode.reset(robot)
    ref = _Reference(load_model(model_file), settings, robot)
    phase = float(rng.uniform(0.0, 100.0))
    recognised = compared = 0
    with World(scenario, seed=int(rng.integers(1000)), components=derive_components(scenario)) as w:
        obs = w.reset()
        for k in range(120):
            u = _weave(k, phase)
            expected = ref.step(obs, u)  # reads obs.components: materialised for both
            assist = mode.step(obs, u)
            compared += _assert_same(assist, expected)
            recognised += assist.target != ""
            w.apply(assist.v)
            w.step()
            obs = w.sense()
    assert recognised > 60  # the comparison covered the rollout, not only manual ticks
    assert compared > 100  # near-ties (not compared) are rare


def _scene(rng: np.random.Generator, n: int) -> tuple[SemanticComponent, ...]:
    out = []
    for k in range(n):
        kind = ("doorway", "object", "wall", "dock")[k % 4]
        c = rng.uniform(-4.0, 4.0, 2)
        if kind in ("doorway", "dock"):
            ends = np.array([c + (0.0, -0.45), c + (0.0, 0.45)])
            comp = SemanticComponent(f"{kind}_{k}", kind, c, ends, ends, 0.9)
        elif kind == "object":
            a = np.linspace(0, 2 * math.pi, 24, endpoint=False)
            pts = c + 0.3 * np.column_stack((np.cos(a), np.sin(a)))
            comp = SemanticComponent(f"object_{k}", kind, c, pts)
        else:
            pts = np.column_stack((np.linspace(c[0] - 2, c[0] + 2, 41), np.full(41, c[1])))
            comp = SemanticComponent(f"wall_{k}", kind, c, pts)
        out.append(comp)
    return tuple(out)


def test_equal_outputs_on_synthetic_scenes_with_plain_tuples(model_file, rng):
    from sim.testing import cluttered_segments, synthetic_observation

    robot = RobotModel.rectangle()
    settings = ContextualSettings(
        model_path=model_file, candidates=int(rng.integers(1, 12)), **OLD_YIELD
    )
    mode = ContextualTaskMode(settings)
    mode.reset(robot)
    ref = _Reference(load_model(model_file), settings, robot)
    for k in range(40):
        segments = cluttered_segments(rng, robot, n_boxes=int(rng.integers(4, 10)))
        obs = synthetic_observation(segments, velocity=np.zeros(3), rng=rng)
        obs = dataclasses.replace(obs, components=_scene(rng, int(rng.integers(0, 16))))
        u = rng.uniform(-1.0, 1.0, 3) * (robot.max_speed, robot.max_speed, robot.max_yaw_rate)
        if k % 5 == 0:
            u[:2] *= 0.01  # below min_input: manual
        _assert_same(mode.step(obs, u), ref.step(obs, u))


def test_recogniser_with_unequal_basis_sizes_equals_the_reference(model_file, rng):
    import copy

    sogp = copy.deepcopy(load_model(model_file).sogp)
    for j, gp in enumerate(sogp["models"]):  # a different basis size per cluster
        keep = max(1, len(gp["alpha"]) - 7 * j - 1)
        gp["basis"] = np.asarray(gp["basis"])[:keep]
        gp["alpha"] = np.asarray(gp["alpha"])[:keep]
        gp["C"] = np.asarray(gp["C"])[:keep, :keep]
    fast, ref = Recogniser(sogp), _RefRecogniser(sogp)
    assert len(set(fast.n_basis_)) > 1
    for _ in range(20):
        Z = rng.normal(size=(int(rng.integers(1, 12)), 7)) * rng.uniform(0.2, 2.0)
        mean_tol, beta_tol = recognition_tolerances(fast, Z)
        assert_recognitions_match(
            fast(Z), ref(Z), mean_tol, beta_tol, fast.classes_, name="unequal_basis"
        )
