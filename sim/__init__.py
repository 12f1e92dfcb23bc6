"""The world: a pybullet scene of a cluttered room, a holonomic robot, its sensors.

Depends on pybullet and numpy only; knows nothing of the study, the modes or the
screen (DESIGN.md, "Layout and layers").
"""
