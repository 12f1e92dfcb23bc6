"""Benchmark group ``autonomy``: timings of the assistance layer (DESIGN.md budgets).

The reactive and contextual-task modes, the DWA, the safety layer and the SOGP, timed
on observations of the shipped ``cluttered_room`` along a scripted drive (a synthetic
cluttered room when the scene is not available), BLAS limited to one thread. The
figures are listed in :func:`run`.
"""

from __future__ import annotations

import math
import time

import numpy as np
from threadpoolctl import threadpool_limits

from autonomy.dwa import dwa
from autonomy.reactive_bn import ReactiveBNMode
from autonomy.safety import safe_command, translation_distance
from autonomy.types import RobotModel
from sim.testing import cluttered_segments, synthetic_observation


def _percentiles(samples_ms: list[float], qs: tuple[int, ...]) -> dict[str, float]:
    values = np.percentile(np.asarray(samples_ms), qs)
    return {f"p{q}": round(float(v), 4) for q, v in zip(qs, values, strict=True)}


def _joystick(k: int) -> np.ndarray:
    """A scripted joystick: mostly forward, weaving sideways, turning now and then."""
    t = 0.05 * k
    return np.array(
        [0.6 + 0.3 * math.sin(0.3 * t), 0.4 * math.sin(0.7 * t), 0.5 * math.sin(0.2 * t)]
    )


_WANDER_DIRECTIONS = np.radians(np.arange(-90.0, 91.0, 15.0))


def _wander(obs, robot: RobotModel, k: int) -> np.ndarray:
    """A driver that wanders through the room: towards the most open of the forward
    directions (the longest free translation of the footprint), turning that way,
    weaving a little sideways."""
    free = np.array(
        [
            np.min(translation_distance(obs.points, (math.cos(a), math.sin(a)), robot), initial=8.0)
            for a in _WANDER_DIRECTIONS
        ]
    )
    best = _WANDER_DIRECTIONS[np.argmax(np.minimum(free, 3.0) - 0.1 * np.abs(_WANDER_DIRECTIONS))]
    heading = best + 0.3 * math.sin(0.35 * k * robot.dt)
    return np.array([0.6 * math.cos(heading), 0.6 * math.sin(heading), 0.8 * best])


def _world_observations(n: int) -> tuple[list, RobotModel] | None:
    """Observations of the shipped cluttered room along a drive with the reactive mode."""
    try:
        from sim.scenario import load_scenario
        from sim.world import World
    except ImportError:
        return None
    try:
        scenario = load_scenario("cluttered_room")
    except ValueError:
        return None
    robot = RobotModel.from_spec(scenario.robot)
    mode = ReactiveBNMode()
    mode.reset(robot)
    observations = []
    with World(scenario, seed=0) as world:
        obs = world.reset()
        for k in range(n):
            u = _wander(obs, robot, k)
            observations.append((obs, u))
            world.apply(mode.step(obs, u).v)
            world.step()
            obs = world.sense()
    return observations, robot


def _synthetic_observations(n: int) -> tuple[list, RobotModel]:
    rng = np.random.default_rng(0)
    robot = RobotModel.rectangle()
    observations = []
    for _ in range(n):
        segments = cluttered_segments(rng, robot, n_boxes=int(rng.integers(6, 16)))
        velocity = np.array(
            [rng.uniform(-0.3, 0.8), rng.uniform(-0.4, 0.4), rng.uniform(-0.5, 0.5)]
        )
        obs = synthetic_observation(segments, velocity=velocity, rng=rng)
        observations.append((obs, _joystick(len(observations))))
    return observations, robot


def _sogp_rate(quick: bool) -> float:
    from autonomy.sogp import SparseOnlineGP

    rng = np.random.default_rng(1)
    gp = SparseOnlineGP(capacity=500, length_scales=np.full(7, 0.8), signal_var=1.0, noise_var=0.05)
    while gp.n_basis_ < 500:
        x = rng.normal(size=7)
        gp.update(x, float(np.sign(x[0])))
    n = 300 if quick else 3000
    xs = rng.normal(size=(n, 7))
    ys = np.sign(xs[:, 0])
    start = time.perf_counter()
    for x, y in zip(xs, ys, strict=True):
        gp.update(x, float(y))
        gp.predict(x[None, :])
    return n / (time.perf_counter() - start)


def run(quick: bool) -> dict:
    """Measure the assistance layer (wall time, BLAS limited to one thread).

    Returns
    -------
    dict
        - ``reactive_tick_ms`` {p50, p95, p99}: one ``reactive_bn`` tick (environment
          model, posteriors, the situation's action including the DWA, blending);
        - ``dwa_ms``, ``safety_ms`` {p50, p95}: :func:`autonomy.dwa.dwa` and
          :func:`autonomy.safety.safe_command` alone on the same observations;
        - ``sogp_updates_per_s``: ``SparseOnlineGP(capacity=500)`` update plus a
          one-point prediction per second, at capacity, 7-D inputs;
        - ``autonomy_observations`` (where the observations came from) and
          ``autonomy_laser_points`` (their mean number of laser points);
        - ``contextual_tick_ms`` {p50, p95, p99, candidates}: one ``contextual_task``
          tick (candidates, recognition, the Alg. 3 rollout, tracking, blending, the
          safety layer) with ``candidates`` = 10 semantic components per tick;
          ``rollout_ms`` {p50, p95, p99}: the rollout alone; ``rollout_steps_mean``: the
          mean number of predicted poses over the ticks with a rollout; ``rollout_em``
          {fits, iterations_mean, iterations_max}: the local EM fits the rollouts made
          (neighbour sets not yet cached) and their EM iterations;
          ``contextual_stage_ms``: the mean of each stage of ``Assist.timings_ms``;
          ``contextual_recognised_share``;
          ``contextual_model``: "shipped", or "synthetic" when the shipped model is
          missing.
    """
    with threadpool_limits(limits=1):
        return _run(quick)


def _run(quick: bool) -> dict:
    n = 150 if quick else 1200
    found = _world_observations(n)
    source = "sim.world cluttered_room" if found is not None else "synthetic cluttered room"
    observations, robot = found if found is not None else _synthetic_observations(n // 4)

    mode = ReactiveBNMode()
    mode.reset(robot)
    tick, dwa_ms, safety_ms = [], [], []
    repeats = max(1, n // len(observations))
    for k in range(repeats * len(observations)):
        obs, u = observations[k % len(observations)]
        start = time.perf_counter()
        mode.step(obs, u)
        tick.append((time.perf_counter() - start) * 1e3)
        start = time.perf_counter()
        dwa(u, obs.points, obs.velocity, robot)
        dwa_ms.append((time.perf_counter() - start) * 1e3)
        start = time.perf_counter()
        safe_command(u, obs.points, robot)
        safety_ms.append((time.perf_counter() - start) * 1e3)

    figures = {
        "reactive_tick_ms": _percentiles(tick, (50, 95, 99)),
        "dwa_ms": _percentiles(dwa_ms, (50, 95)),
        "safety_ms": _percentiles(safety_ms, (50, 95)),
        "sogp_updates_per_s": round(_sogp_rate(quick), 1),
        "autonomy_observations": source,
        "autonomy_laser_points": round(float(np.mean([len(o.points) for o, _ in observations])), 1),
    }
    figures.update(_contextual_figures(observations, robot, n))
    return figures


CONTEXTUAL_CANDIDATES = 10


def _synthetic_components(rng: np.random.Generator, n: int) -> tuple:
    """``n`` doorways, objects and walls scattered around the robot (robot frame)."""
    from sim.types import SemanticComponent

    out = []
    for k in range(n):
        kind = ("doorway", "object", "wall")[k % 3]
        c = rng.uniform(-4.0, 4.0, 2)
        if kind == "doorway":
            pts = np.array([c + (0.0, -0.45), c + (0.0, 0.45)])
        elif kind == "object":
            a = np.linspace(0, 2 * math.pi, 24, endpoint=False)
            pts = c + 0.3 * np.column_stack((np.cos(a), np.sin(a)))
        else:
            pts = np.column_stack((np.linspace(c[0] - 2, c[0] + 2, 41), np.full(41, c[1])))
        out.append(SemanticComponent(id=f"bench_{kind}_{k}", kind=kind, centre=c, points=pts))
    return tuple(out)


def _em_iterations(mode) -> np.ndarray:
    """(max_iter + 1,) local fits so far of the mode's rollout GMRs, per EM iteration
    count (zeros without a model)."""
    runtime = mode.runtime_
    if runtime is None:
        return np.zeros(1, dtype=int)
    return np.sum([gmr.n_iter_counts_ for gmr in runtime.gmrs], axis=0)


def _contextual_figures(observations: list, robot: RobotModel, n: int) -> dict:
    import dataclasses

    from autonomy.contextual import ContextualSettings, ContextualTaskMode
    from autonomy.model import DEFAULT_MODEL

    if DEFAULT_MODEL.is_file():
        mode, which = ContextualTaskMode(ContextualSettings()), "shipped"
    else:
        from autonomy.training import TrainSettings, synthetic_demonstrations, train

        q, _, run = synthetic_demonstrations(np.random.default_rng(0), runs=6, steps=60)
        model = train(q, seed=0, run=run, settings=TrainSettings(capacity=200, restarts=2))
        mode = ContextualTaskMode(ContextualSettings(model_path=""), model=model)
        which = "synthetic"
    mode.reset(robot)
    rng = np.random.default_rng(2)
    prepared = []
    for obs, u in observations:
        comps = tuple(obs.components or ())
        if len(comps) < CONTEXTUAL_CANDIDATES:
            extra = _synthetic_components(rng, CONTEXTUAL_CANDIDATES - len(comps))
            obs = dataclasses.replace(obs, components=comps + extra)
        prepared.append((obs, u))
    tick, roll, steps, assisted = [], [], [], 0
    stages: dict[str, list[float]] = {}
    before = _em_iterations(mode)
    repeats = max(1, n // len(prepared))
    for k in range(repeats * len(prepared)):
        obs, u = prepared[k % len(prepared)]
        start = time.perf_counter()
        assist = mode.step(obs, u)
        tick.append((time.perf_counter() - start) * 1e3)
        roll.append(assist.timings_ms["rollout"])
        for stage, ms in assist.timings_ms.items():
            stages.setdefault(stage, []).append(ms)
        assisted += assist.target != ""  # below min_input the mode does not recognise
        if assist.target != "":
            steps.append(len(assist.predicted_path))
    iters = _em_iterations(mode) - before
    fits = int(iters.sum())
    return {
        "contextual_tick_ms": {
            **_percentiles(tick, (50, 95, 99)),
            "candidates": CONTEXTUAL_CANDIDATES,
        },
        "rollout_ms": _percentiles(roll, (50, 95, 99)),
        "rollout_steps_mean": round(float(np.mean(steps)), 2) if steps else 0.0,
        "rollout_em": {
            "fits": fits,
            "iterations_mean": round(float(iters @ np.arange(len(iters))) / max(fits, 1), 3),
            "iterations_max": int(np.flatnonzero(iters).max()) if fits else 0,
        },
        "contextual_stage_ms": {k: round(float(np.mean(v)), 4) for k, v in stages.items()},
        "contextual_recognised_share": round(assisted / max(len(tick), 1), 3),
        "contextual_model": which,
    }
