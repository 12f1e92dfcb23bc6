"""Regenerate the example ROS map: the shipped ``cluttered_room`` rendered at 0.05 m
with SLAM-like noise (``sim.map_noise``), seed 23.

    python examples/maps/make_map.py

writes ``cluttered_room_noisy.pgm`` and ``cluttered_room_noisy.yaml`` beside this file;
the same seed gives the same bytes. ``cluttered_room_noisy.additions.toml`` places A,
B, the table and the object to inspect, for ``asa scenario from-map``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from sim.map_files import save_ros_map
from sim.map_noise import noisy_scene_map
from sim.scenario import load_scenario

SEED = 23
HERE = Path(__file__).resolve().parent


def main() -> None:
    grid = noisy_scene_map(load_scenario("cluttered_room"), np.random.default_rng(SEED))
    for path in save_ros_map(grid, HERE, "cluttered_room_noisy"):
        print(f"wrote {path}")


if __name__ == "__main__":
    main()
