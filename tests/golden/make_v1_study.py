"""Make tests/golden/v1_study.db: a study database of schema version 1, the schema
before Alembic (``meta.schema_version = 1``, no ``alembic_version``), for
tests/test_migrations.py.

It must be run with the platform as it was before the migrations (commit 3a79bc3):

    git archive 3a79bc3 | tar -x -C /tmp/v1
    PYTHONPATH=/tmp/v1 python tests/golden/make_v1_study.py tests/golden

One scripted participant's whole session of a small protocol (a baseline block with
questions, two main trials with samples, events and NASA-TLX responses), no recordings.
"""

from __future__ import annotations

import shutil
import sys
import tempfile
from pathlib import Path

import numpy as np

from study.engine.protocol import load_protocol
from study.engine.session import run_session
from study.participants import ScriptedParticipant

PROTOCOL = """
[study]
name = "v1-golden"
participants = 2
seed = 5

[modes]
names = ["manual", "reactive_bn"]
counterbalancing = "full_permutation"

[[phases]]
kind = "baseline"
questions = 3

[[phases]]
kind = "main"
scenario = "practice_course"
route = ["A", "B"]
inspection = false
secondary = false
timeout_s = 60.0

[phases.after_trial]
instrument = "nasa_tlx"
weights = "raw"
"""


def main(out: Path) -> None:
    target = out / "v1_study.db"
    if target.exists():
        raise SystemExit(f"{target}: exists; remove it first")
    with tempfile.TemporaryDirectory() as tmp:  # its lock and maps folders stay there
        proto = Path(tmp) / "v1-golden.toml"
        proto.write_text(PROTOCOL, encoding="utf-8")
        summary = run_session(
            load_protocol(proto),
            "P01",
            Path(tmp) / "v1_study.db",
            participant=ScriptedParticipant(np.random.default_rng(3)),
            seed=3,
            record=False,
        )
        if summary.status != "completed":
            raise SystemExit(f"the session ended {summary.status}")
        shutil.copyfile(Path(tmp) / "v1_study.db", target)


if __name__ == "__main__":
    main(Path(sys.argv[1]))
