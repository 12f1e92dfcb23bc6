"""Make ``mode_equivalence.json``: the reactive mode, DWA and safety layer on 24 rooms.

The rows are the outputs of :class:`autonomy.reactive_bn.ReactiveBNMode`,
:func:`autonomy.dwa.dwa` and :func:`autonomy.safety.safe_command` on 24 fixed synthetic
cluttered rooms (:func:`sim.testing.cluttered_segments` and
:func:`~sim.testing.synthetic_observation`, drawn from one generator seeded with
:data:`SEED`). ``tests/test_mode_equivalence.py`` recomputes them and compares to
``rtol = atol = 1e-12``.

The rows were first made with the code before the per-tick optimisations (cached scanner
geometry, one CDF pass, edge-wise translation distance, inlined ``sinc``, cached inflated
radius) and stored in the test as a literal table. This script reproduces them with the
current code: the JSON it writes agrees with that table to the test's tolerance (when the
table moved here, 383 of its 384 numbers were bit-identical and one differed in the last
bit). The reactive mode's rows record ``arbitration = "blend"`` (eq. 3.2 with ``beta`` the
MAP posterior), the only behaviour before the setting existed; :func:`golden_mode` pins
it, so the default ``"exclusive"`` left the JSON unchanged; likewise :data:`GOLDEN_DWA`
pins the DWA's scoring as it was before ``clearance_by_progress``. If the generators' draws
change, rerun it from the repository root (so that the checkout's code is imported)::

    python -m tests.golden.make_mode_equivalence
"""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np

from autonomy.dwa import DWASettings, dwa
from autonomy.reactive_bn import ReactiveBNMode, ReactiveSettings
from autonomy.safety import safe_command
from autonomy.types import RobotModel
from sim.testing import cluttered_segments, synthetic_observation
from sim.types import Observation

SEED = 20261123
N_CASES = 24
PATH = Path(__file__).with_name("mode_equivalence.json")
# one row per case: the floats in this order, then the reactive mode's label
COLUMNS = (
    "reactive_vx", "reactive_vy", "reactive_wz", "beta", "p_occ", "d",
    "dwa_vx", "dwa_vy", "dwa_wz", "dwa_clearance", "dwa_n_checked",
    "safe_vx", "safe_vy", "safe_wz", "safe_scale", "safe_scale_fast_dwa",
)  # fmt: skip


#: The DWA the rows were made with: the clearance term counted in full whatever the
#: twist's progress (``clearance_by_progress`` came later and is off here).
GOLDEN_DWA = DWASettings(clearance_by_progress=False)


def golden_mode() -> ReactiveBNMode:
    """The reactive mode the rows were made with: ``arbitration = "blend"`` and
    :data:`GOLDEN_DWA`."""
    return ReactiveBNMode(ReactiveSettings(arbitration="blend", dwa=GOLDEN_DWA))


def cases(n: int = N_CASES) -> Iterator[tuple[RobotModel, Observation, np.ndarray]]:
    """The ``n`` fixed situations: robot, observation, operator input (3,) [m/s, m/s, rad/s].

    Every sixth input is a pure rotation (speed 0.01 m/s).
    """
    rng = np.random.default_rng(SEED)
    robot = RobotModel.rectangle()
    for k in range(n):
        segments = cluttered_segments(rng, robot, n_boxes=int(rng.integers(6, 16)))
        velocity = np.array(
            [rng.uniform(-0.3, 0.8), rng.uniform(-0.4, 0.4), rng.uniform(-0.5, 0.5)]
        )
        obs = synthetic_observation(segments, velocity=velocity, rng=rng)
        heading = rng.uniform(-math.pi, math.pi)
        speed = rng.uniform(0.0, 1.0) if k % 6 else 0.01
        u = np.array([speed * math.cos(heading), speed * math.sin(heading), rng.uniform(-1.2, 1.2)])
        yield robot, obs, u


def outputs(
    mode: ReactiveBNMode, robot: RobotModel, obs: Observation, u: np.ndarray
) -> tuple[list[float], str]:
    """One case's floats (in :data:`COLUMNS` order) and the reactive mode's label.

    ``mode`` is stepped (it keeps its state from case to case, as in a trial); the safety
    layer is also asked for 1.5 times the DWA command over a 1 s horizon.
    """
    if mode.robot_ is None:
        mode.reset(robot)
    a = mode.step(obs, u)
    r = dwa(u, obs.points, obs.velocity, robot, settings=GOLDEN_DWA)
    v_safe, scale = safe_command(u, obs.points, robot)
    _, scale_fast = safe_command(r.v * 1.5, obs.points, robot, horizon_s=1.0)
    got = [*a.v, a.beta, a.scores["p_occ"], a.scores["d"], *r.v, r.clearance, r.n_checked]
    got += [*v_safe, scale, scale_fast]
    return [float(x) for x in got], a.label


def _encode(x: float) -> float | str:
    # strict JSON has no NaN or infinity: those are written as "nan", "inf", "-inf"
    return x if math.isfinite(x) else repr(x)


def load(path: Path = PATH) -> list[tuple[list[float], str]]:
    """The stored rows: (floats in :data:`COLUMNS` order, label) per case."""
    data = json.loads(path.read_text())
    if data["columns"] != [*COLUMNS, "label"]:
        raise ValueError(f"{path}: columns {data['columns']} are not {[*COLUMNS, 'label']}")
    return [([float(x) for x in row[:-1]], row[-1]) for row in data["rows"]]


def main() -> None:
    mode = golden_mode()
    rows = []
    for robot, obs, u in cases():
        floats, label = outputs(mode, robot, obs, u)
        rows.append([*map(_encode, floats), label])
    head = {"seed": SEED, "columns": [*COLUMNS, "label"]}
    lines = [f' "{key}": {json.dumps(value)},' for key, value in head.items()]
    body = ",\n".join("  " + json.dumps(row, allow_nan=False) for row in rows)
    PATH.write_text("{\n" + "\n".join(lines) + '\n "rows": [\n' + body + "\n ]\n}\n")
    print(f"wrote {len(rows)} rows to {PATH}")


if __name__ == "__main__":
    main()
