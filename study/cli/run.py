"""``asa run``: one participant's session of a protocol, headless with the scripted
participant (the human and synthetic participants arrive with their own issues).

A thin shell over :func:`study.session.run_session`; prints one experimenter line per
phase and trial (participant, phase, mode, simulated time, collisions) to stdout.

Decisions: the scripted participant's generator is seeded with ``--seed`` if given, else
with a seed derived from the protocol's study seed and the participant code, and the
same number is stored as the participant's seed, so ``--resume`` continues with the same
participant. ``--headless`` is accepted for symmetry with the human interface and is the
only way the scripted participant runs.
"""

from __future__ import annotations

import hashlib
from pathlib import Path

import click
import numpy as np

INPUTS = ("scripted", "human", "synthetic")


def _default_seed(study_seed: int, code: str) -> int:
    digest = hashlib.sha256(f"{study_seed}:{code}".encode()).digest()
    return int.from_bytes(digest[:4], "little") >> 1


@click.command("run")
@click.option("--protocol", "protocol", required=True, help="Shipped protocol name or TOML file.")
@click.option("--participant", "code", required=True, help="Pseudonymous code, e.g. P01.")
@click.option(
    "--db",
    required=True,
    type=click.Path(dir_okay=False, path_type=Path),
    help="Study database (SQLite file, created if missing).",
)
@click.option(
    "--input",
    "input_kind",
    type=click.Choice(INPUTS),
    default="scripted",
    show_default=True,
    help="Who drives: only 'scripted' is built so far.",
)
@click.option(
    "--seed",
    type=click.IntRange(min=0),
    default=None,
    help="Participant seed (default: derived from the study seed and the code).",
)
@click.option("--resume", is_flag=True, help="Continue this participant's session after a crash.")
@click.option(
    "--force",
    is_flag=True,
    help="Run despite another session of this participant or another protocol "
    "in the database (recorded in the session row).",
)
@click.option("--headless", is_flag=True, help="No window (the scripted participant needs none).")
def run(
    protocol: str,
    code: str,
    db: Path,
    input_kind: str,
    seed: int | None,
    resume: bool,
    force: bool,
    headless: bool,
) -> None:
    """Run one participant through every phase of a protocol and store it in --db.

    \b
    Example:
      asa run --protocol pilot --participant P01 --db pilot.db --input scripted --headless
      asa run --protocol pilot --participant P01 --db pilot.db --resume   # after a crash
    """
    if input_kind != "scripted":
        raise ValueError(
            f"--input: '{input_kind}' participants are not built yet; use --input scripted"
        )
    from study.participants import ScriptedParticipant
    from study.protocol import load_protocol
    from study.session import check_code, run_session

    check_code(code)
    p = load_protocol(protocol)
    seed = seed if seed is not None else _default_seed(p.study.seed, code)
    participant = ScriptedParticipant(np.random.default_rng(seed))
    summary = run_session(
        p,
        code,
        db,
        participant=participant,
        seed=seed,
        resume=resume,
        force=force,
        progress=lambda line: click.echo(line),
    )
    click.echo(
        f"{summary.participant}: session {summary.session_id} {summary.status}, "
        f"{len(summary.trials)} trials run"
    )
