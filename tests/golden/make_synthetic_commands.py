"""Make ``synthetic_commands.json``: what one synthetic participant does, tick by tick,
in a closed-loop thesis main trial (manual mode, the inspection and the secondary
questions on, the first :data:`TIMEOUT_S` simulated seconds).

Each row is one call of :meth:`SyntheticParticipant.act`: the command ``u`` (3 floats,
stored as ``float.hex`` so the comparison is bit for bit), the answer and the intention
label. The last entry holds the participant's random streams' states at the end (the
same draws in the same order). The rows were made with the code before issue 25's
restructuring of the participant's act (commit 5b8a1d4); ``tests/test_participant_kernels.py``
runs the same trial and compares. Rerun it from the repository root only when the
behaviour is meant to change::

    python -m tests.golden.make_synthetic_commands
"""

from __future__ import annotations

import hashlib
import json
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

from study.engine.protocol import load_protocol
from study.engine.standalone import standalone_trial
from study.participants.synthetic import Population, SyntheticParticipant

SEED = 7061
TIMEOUT_S = 45.0
PATH = Path(__file__).with_name("synthetic_commands.json")


class Recording(SyntheticParticipant):
    """A synthetic participant that keeps every tick's output."""

    rows: list[list[Any]]

    def act(self, obs, screen):  # type: ignore[no-untyped-def]
        out = super().act(obs, screen)
        self.rows.append([[float(v).hex() for v in out.u], out.answer, list(self.intention())])
        return out


def streams(person: SyntheticParticipant) -> str:
    """A digest of the participant's three random streams' states."""
    states = [
        person._rng.bit_generator.state,
        person._driver._rng.bit_generator.state,
        person._stick._rng.bit_generator.state,
    ]
    return hashlib.sha256(repr(states).encode()).hexdigest()


def run(timeout_s: float = TIMEOUT_S) -> dict[str, Any]:
    """The trial's rows and the streams' digest."""
    protocol = load_protocol("thesis-7-6")
    rng = np.random.default_rng(SEED)
    person = Recording(Population().sample(rng), rng)
    person.rows = []
    with tempfile.TemporaryDirectory(prefix="asa-golden-") as tmp:
        _, engine = standalone_trial(
            Path(tmp),
            person,
            mode="manual",
            scenario=protocol.main.scenario,
            inspection=True,
            timeout_s=timeout_s,
            secondary=protocol.secondary_settings,
            seed=SEED,
        )
        engine.dispose()
    return {"rows": person.rows, "streams": streams(person), "mismatch": person._mismatch}


if __name__ == "__main__":
    PATH.write_text(json.dumps(run()) + "\n")
    print(f"wrote {PATH}")
