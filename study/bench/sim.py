"""Benchmark group ``sim``: how fast the world runs a control tick, and renders the camera.

One full tick as the trial loop runs it (``apply`` + ``step`` + ``sense``, camera off),
headless, in the cluttered room (a built-in room if that is not shipped), steered by a
scripted driver (:func:`_wander`). The figures are listed in :func:`run`.
"""

from __future__ import annotations

import math
import time

import numpy as np

from sim.scenario import Scenario, load_scenario, parse_scenario
from sim.types import Observation
from sim.world import World, WorldSettings

# used when the cluttered room is not shipped: walls, crates, cylinders and a table
_FALLBACK_SCENE = {
    "name": "bench_room",
    "bounds": [[0.0, 0.0], [10.0, 8.0]],
    "start": {"x": 1.5, "y": 1.5, "yaw_deg": 0.0},
    "walls": [
        {"name": "south", "from": [0, 0], "to": [10, 0]},
        {"name": "east", "from": [10, 0], "to": [10, 8]},
        {"name": "north", "from": [10, 8], "to": [0, 8]},
        {"name": "west", "from": [0, 8], "to": [0, 0]},
        {"name": "inner", "from": [5, 0], "to": [5, 3.5]},
    ],
    "boxes": [
        {"name": f"crate{i}", "centre": [2.0 + 1.3 * i, 5.5 - 0.4 * (i % 3)], "size": [0.6, 0.4]}
        for i in range(6)
    ],
    "cylinders": [
        {"name": "red_cylinder", "centre": [7.5, 2.0], "radius": 0.25, "colour": [0.9, 0.1, 0.1]},
        {"name": "bin", "centre": [3.0, 3.0], "radius": 0.2},
    ],
    "tables": [{"name": "table", "centre": [8.5, 6.5], "size": [1.2, 0.9]}],
}


def _scene() -> Scenario:
    try:
        return load_scenario("cluttered_room")
    except ValueError:  # not shipped
        return parse_scenario(_FALLBACK_SCENE, "bench:fallback")


def _wander(obs: Observation) -> np.ndarray:
    """A scripted driver [robot-frame command]: forward while the way ahead is clear,
    turning towards the more open side when it is not, with a sideways sway, so the
    robot roams the room, turns and strafes, and only now and then touches something."""
    pts = obs.points
    ahead = pts[(pts[:, 0] > 0.0) & (np.abs(pts[:, 1]) < 0.45)]
    clear = float(ahead[:, 0].min()) if len(ahead) else 8.0
    left = np.count_nonzero((pts[:, 1] > 0.3) & (np.hypot(pts[:, 0], pts[:, 1]) < 1.5))
    right = np.count_nonzero((pts[:, 1] < -0.3) & (np.hypot(pts[:, 0], pts[:, 1]) < 1.5))
    forward = min(max((clear - 0.6) / 1.0, 0.0), 1.0)
    turn = 1.0 if left <= right else -1.0
    omega = turn * (1.0 - forward) + 0.4 * math.sin(0.45 * obs.t)
    return np.array([0.9 * forward, 0.25 * math.sin(1.3 * obs.t), omega])


def _ticks_per_s(world: World, n: int) -> dict:
    """Ticks per second (wall and CPU time of apply + step + sense, the driver left out),
    median ms of ``step`` and ``sense``, and the fraction of ticks in contact."""
    obs = world.reset()
    step_s, sense_s, cpu_s, touching = [], [], 0.0, 0
    for _ in range(n):
        v = _wander(obs)
        c0, t0 = time.process_time(), time.perf_counter()
        world.apply(v)
        world.step()
        t1 = time.perf_counter()
        obs = world.sense()
        t2, c2 = time.perf_counter(), time.process_time()
        step_s.append(t1 - t0)
        sense_s.append(t2 - t1)
        cpu_s += c2 - c0
        touching += world.touching
    return {
        "ticks_per_s": n / (sum(step_s) + sum(sense_s)),
        "ticks_per_cpu_s": n / cpu_s,
        "step_ms": 1e3 * float(np.median(step_s)),
        "sense_ms": 1e3 * float(np.median(sense_s)),
        "touching": touching / n,
    }


def run(quick: bool) -> dict:
    """Measure the world; ``quick`` runs fewer ticks and frames.

    Returns
    -------
    dict
        ``sim_ticks_per_s``: control ticks per wall second (both laser scans, the pose
        estimate and the IMU; the semantic components are put into the robot frame only
        when a mode reads them, which this driver does not); ``sim_ticks_per_cpu_s`` the
        same per CPU second of this process (less disturbed by other processes);
        ``sim_step_ms``, ``sim_sense_ms``: median times; ``sim_real_time_factor`` at the
        20 Hz tick; ``sim_touching_fraction``: ticks in contact (a robot pressed against a
        wall makes the physics step dearer); ``sim_ticks_per_s_pybullet_rays`` and
        ``sim_sense_ms_pybullet_rays`` with pybullet's ``rayTestBatch`` as the laser
        backend, for comparison; ``sim_camera_frames_per_s`` at the scenario's camera
        size (``sim_camera_size``, default 320 x 240); ``sim_scene``,
        ``sim_rays_per_tick``, ``sim_components``.
    """
    scenario = _scene()
    n_ticks, n_frames = (300, 5) if quick else (3000, 40)
    figures: dict = {"sim_scene": scenario.name}
    with World(scenario, seed=0) as world:
        world.sense()  # derive the semantic components outside the timing
        m = _ticks_per_s(world, n_ticks)
        figures.update(
            sim_ticks_per_s=round(m["ticks_per_s"], 1),
            sim_ticks_per_cpu_s=round(m["ticks_per_cpu_s"], 1),
            sim_step_ms=round(m["step_ms"], 4),
            sim_sense_ms=round(m["sense_ms"], 4),
            sim_real_time_factor=round(m["ticks_per_s"] * world.settings.dt, 1),
            sim_touching_fraction=round(m["touching"], 3),
            sim_rays_per_tick=sum(las.n_beams for las in scenario.robot.lasers),
            sim_components=len(world.sense().components),
        )
        obs = world.reset()
        world.camera_image()
        render_s = 0.0
        for _ in range(n_frames):  # a frame from a new pose each time
            for _ in range(5):
                world.apply(_wander(obs))
                world.step()
                obs = world.sense()
            start = time.perf_counter()
            world.camera_image()
            render_s += time.perf_counter() - start
        figures["sim_camera_frames_per_s"] = round(n_frames / render_s, 1)
        cam = scenario.robot.camera
        figures["sim_camera_size"] = f"{cam.width}x{cam.height_px}"
    pybullet_rays = WorldSettings(laser_backend="pybullet")
    with World(scenario, seed=0, settings=pybullet_rays) as world:
        world.sense()
        m = _ticks_per_s(world, max(n_ticks // 5, 100))
        figures["sim_ticks_per_s_pybullet_rays"] = round(m["ticks_per_s"], 1)
        figures["sim_sense_ms_pybullet_rays"] = round(m["sense_ms"], 4)
    return figures
