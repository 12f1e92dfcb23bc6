"""``asa run``: one participant's session of a protocol, by a person at the pygame screen,
or by a scripted or synthetic participant, with or without the screen.

A thin shell over :func:`study.engine.launch.run_participant`; prints one experimenter line per
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
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any

import click

INPUTS = ("scripted", "human", "synthetic")  # study.engine.launch.INPUTS
# the library's errors name run_session's parameters; the experimenter types flags
_FLAGS = (
    ("run with resume=False", "run without --resume"),
    ("resume=True", "--resume"),
    ("force=True", "--force"),
)


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
    from study.engine.launch import run_participant

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
    terminal = _Terminal(code)
    try:
        summary = run_participant(
            protocol, code, db, input_kind=input_kind, seed=seed, resume=resume, force=force,
            headless=headless, snapshots=snapshots, fast=fast,
            progress=lambda line: click.echo(line), status=terminal.status,
            on_tick=terminal.on_tick,
        )  # fmt: skip
    except ValueError as error:
        text = _with_flags(str(error))
        if text == str(error):
            raise
        raise ValueError(text) from error
    click.echo(
        f"{summary.participant}: session {summary.session_id} {summary.status}, "
        f"{len(summary.trials)} trials run"
    )


def _with_flags(message: str) -> str:
    """``message`` with run_session's parameter names as the flags that set them."""
    for name, flag in _FLAGS:
        message = message.replace(name, flag)
    return message
