"""Demonstrations of the contextual tasks: recording, start poses, files and loading
(thesis Sec. 7.2.3, 7.3, 7.4.1-7.4.2; spec section 3; issue 3).

A scripted skill (:mod:`tasks.skills`) behind a simulated human stick drives the world in
manual mode, one run per demonstration (:mod:`.record`), from a random start
(:mod:`.starts`); every tick is stored in one ``.npz`` per run with a manifest and loaded
back checked (:mod:`.files`); the candidates' passage normals come from the runs' scenes
(:mod:`.normals`). The choices where the spec is silent are in
docs/decisions.md.
"""

from __future__ import annotations

from study.jobs.demonstrations.files import (
    FORMAT_VERSION,
    MANIFEST,
    Demonstrations,
    load_demonstrations,
    summarise,
)
from study.jobs.demonstrations.normals import candidate_normals
from study.jobs.demonstrations.record import (
    MOVING_SPEED,
    RecordSettings,
    RunRecord,
    candidates_of,
    plan_recording,
    record_demonstrations,
    record_run,
    resolve_plan,
    run_seed,
)
from study.jobs.demonstrations.starts import (
    BYPASS_HEADING_NOISE_DEG,
    CONNECT_CLEARANCE_M,
    MAX_START_TRIES,
    PATH_CLEARANCE_M,
    START_CLEARANCE_M,
    START_DISTANCE_M,
    FreeSpace,
    sample_start,
)

__all__ = [
    "BYPASS_HEADING_NOISE_DEG",
    "CONNECT_CLEARANCE_M",
    "FORMAT_VERSION",
    "MANIFEST",
    "MAX_START_TRIES",
    "MOVING_SPEED",
    "PATH_CLEARANCE_M",
    "START_CLEARANCE_M",
    "START_DISTANCE_M",
    "Demonstrations",
    "FreeSpace",
    "RecordSettings",
    "RunRecord",
    "candidate_normals",
    "candidates_of",
    "load_demonstrations",
    "plan_recording",
    "record_demonstrations",
    "record_run",
    "resolve_plan",
    "run_seed",
    "sample_start",
    "summarise",
]
