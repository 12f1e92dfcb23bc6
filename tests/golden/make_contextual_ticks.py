"""Make contextual_ticks.npz: inputs of the contextual mode's step recorded from a short
synthetic trial (study.bench.synth._trial, 60 s simulated; issue 25), every 8th tick the
mode assisted: the normalised command, every component's target point and the chosen
component's geometry (the recognition is recomputed from them).
tests/test_contextual_kernels.py runs the kernels and the pre-kernel code
(tests/contextual_reference.py) on them.

Run from the repository root: ``python tests/golden/make_contextual_ticks.py``.
"""

from __future__ import annotations

import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
import autonomy.contextual as ctx  # noqa: E402
from study.bench.synth import _trial  # noqa: E402

rows: list[tuple] = []
_step = ctx.ContextualTaskMode.step


def _recording_step(self, obs, u):
    a = _step(self, obs, u)
    if a.label:
        comps = ctx.as_candidates(obs.components)
        robot = self.robot_
        limit = np.array([robot.max_speed, robot.max_speed, robot.max_yaw_rate])
        target = next(comps[i] for i in range(len(comps)) if str(comps[i].id) == a.target)
        points, s0x, s0y = ctx._target_geometry(target)
        rows.append(
            (
                np.asarray(u, dtype=float) / limit,
                np.asarray(comps.target_points(), dtype=float).reshape(-1, 2),
                np.zeros((0, 2)) if points is None else points,
                (s0x, s0y),
            )
        )
    return a


def main() -> None:
    ctx.ContextualTaskMode.step = _recording_step
    with tempfile.TemporaryDirectory() as folder:
        _trial(Path(folder), 60.0)
    ctx.ContextualTaskMode.step = _step
    keep = rows[::8]
    out = Path(__file__).with_name("contextual_ticks.npz")
    np.savez_compressed(
        out,
        u=np.array([r[0] for r in keep]),
        targets=np.concatenate([r[1] for r in keep]),
        target_counts=np.array([len(r[1]) for r in keep]),
        surface=np.concatenate([r[2] for r in keep]),
        surface_counts=np.array([len(r[2]) for r in keep]),
        s0=np.array([r[3] for r in keep]),
    )
    print(f"{out}: {len(keep)} ticks")


if __name__ == "__main__":
    main()
