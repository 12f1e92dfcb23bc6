"""``asa run``: one participant's session of a protocol, by a person at the pygame screen,
or by a scripted or synthetic participant, with or without the screen.

A thin shell over :func:`study.engine.session.run_session`; prints one experimenter line per
phase and trial (participant, phase, mode, simulated time, collisions) to stdout, and while
a trial runs on the screen a status line every few seconds (participant, phase, mode,
trial time, collisions, frame rates). The participant's window never shows the mode.

- ``--input human``: the window of :mod:`study.ui` (size and fullscreen from the protocol's
  ``[ui]``), gamepad or keyboard, paced by the wall clock.
- ``--input scripted|synthetic``: no screen at all, free-running (fast; CI and studies).
- ``--input scripted|synthetic --headless``: exactly the human path with SDL's dummy video
  driver, the participant's decisions injected as pygame events
  (:class:`study.ui.inject.EventDriver`), paced by the wall clock unless ``--fast``;
  ``--snapshots DIR`` saves PNG screenshots at every page and trial start and every few
  seconds of trial time.

Decisions: the participant's generator is seeded with ``--seed`` if given, else with a
seed derived from the protocol's study seed and the participant code, and the same number
is stored as the participant's seed, so ``--resume`` continues with the same participant.
A person cannot run ``--headless`` (nobody would see the screen), and ``--snapshots`` needs
the screen. On the screen path the recordings get the camera image the participant saw
(2 Hz, the session engine's default for a human; for scripted and synthetic participants
driving through the screen too), taken from the screen's camera process, never rendered
on the control path.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import click
import numpy as np

INPUTS = ("scripted", "human", "synthetic")


def _decider(input_kind: str, seed: int) -> Any:
    """The scripted or synthetic participant that decides."""
    from study.participants import ScriptedParticipant

    if input_kind == "synthetic":
        from study.participants import synthetic_participant

        # the same seed draws the same person, so --resume continues with them
        return synthetic_participant(np.random.default_rng(seed))
    return ScriptedParticipant(np.random.default_rng(seed))


class _Terminal:
    """The experimenter's status lines: the trial's mode looked up once per trial."""

    def __init__(self, code: str) -> None:
        self.code = code
        self.trial_id = -1
        self.mode = ""

    def on_tick(self, tick: int, writer: Any) -> None:
        if writer.trial_id == self.trial_id:
            return
        from sqlalchemy.orm import Session

        from study.data.storage import Trial

        with Session(writer.engine) as s:
            row = s.get(Trial, writer.trial_id)
            self.mode = row.mode if row is not None else ""
        self.trial_id = writer.trial_id

    def status(self, line: str) -> None:
        click.echo(f"  {self.code} [mode {self.mode or '-'}] {line}")


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
    help="Who drives: a person at the screen, or a scripted or synthetic participant.",
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
@click.option(
    "--headless",
    is_flag=True,
    help="Scripted/synthetic input through the participant's screen, without a window "
    "(SDL dummy video driver).",
)
@click.option(
    "--snapshots",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Folder for PNG screenshots of the screen (with --headless or --input human).",
)
@click.option("--fast", is_flag=True, help="With --headless: do not pace ticks by the wall clock.")
def run(
    protocol: str,
    code: str,
    db: Path,
    input_kind: str,
    seed: int | None,
    resume: bool,
    force: bool,
    headless: bool,
    snapshots: Path | None,
    fast: bool,
) -> None:
    """Run one participant through every phase of a protocol and store it in --db.

    \b
    Example:
      asa run --protocol pilot --participant P01 --db pilot.db --input human
      asa run --protocol pilot --participant P01 --db pilot.db --input scripted
      asa run --protocol pilot --participant P01 --db pilot.db --input scripted \\
          --headless --snapshots shots/
      asa run --protocol pilot --participant P01 --db pilot.db --resume   # after a crash
    """
    from study.engine.protocol import load_protocol
    from study.engine.session import check_code, default_seed, run_session

    if input_kind == "human" and headless:
        raise ValueError("--headless: a person needs the window; drop --headless")
    screen = input_kind == "human" or headless
    if snapshots is not None and not screen:
        raise ValueError("--snapshots: needs the screen; add --headless (or use --input human)")
    if fast and not headless:
        raise ValueError("--fast: only with --headless")
    if input_kind == "human" and os.environ.get("SDL_VIDEODRIVER") == "dummy":
        raise ValueError(
            "--input human: SDL_VIDEODRIVER is 'dummy', so no window can open; unset it"
        )
    check_code(code)
    p = load_protocol(protocol)
    seed = seed if seed is not None else default_seed(p.study.seed, code)
    if not screen:
        participant = _decider(input_kind, seed)
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
    else:
        if headless:
            os.environ["SDL_VIDEODRIVER"] = "dummy"
            os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
        from study.participants.human import HumanParticipant
        from study.engine.trial import FreeClock
        from study.ui.inject import EventDriver
        from study.ui.input import GamepadMapping

        driver = None
        if input_kind != "human":
            driver = EventDriver(_decider(input_kind, seed), GamepadMapping.from_settings(p.input))
        terminal = _Terminal(code)
        person = HumanParticipant(
            p.ui, p.input, driver=driver, snapshots=snapshots, status=terminal.status
        )
        try:
            summary = run_session(
                p,
                code,
                db,
                participant=person,
                seed=seed,
                resume=resume,
                force=force,
                progress=lambda line: click.echo(line),
                clock=FreeClock() if fast else person.clock(),
                camera_hz=2.0,  # the image on the screen (HumanParticipant.camera_image)
                on_tick=terminal.on_tick,
            )
        finally:
            person.close()
    click.echo(
        f"{summary.participant}: session {summary.session_id} {summary.status}, "
        f"{len(summary.trials)} trials run"
    )
