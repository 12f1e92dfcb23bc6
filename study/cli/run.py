"""``asa run``: one participant's session of a protocol, by a person at the pygame screen,
or by a scripted or synthetic participant, with or without the screen.

A thin shell over :func:`study.engine.launch.run_participant` and the experimenter's
terminal (:mod:`study.cli.terminal`): one line per phase and trial (participant, phase,
mode, how it ended: completed, timed out or aborted, simulated time, collisions), and while
a trial runs one live status line (trial time, collisions, screen and camera frame rates),
rewritten in place on a terminal and printed every 30 s into a log. Ctrl-C stops the
session cleanly (the trial that runs is stored as aborted), also when started from a script
with ``&``; then, or after any interruption, the terminal names the trial cut short and
prints the ``--resume`` command that continues the session. The participant's window never
shows the mode.

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

from study.cli import SEED, db_option

INPUTS = ("scripted", "human", "synthetic")  # study.engine.launch.INPUTS
# the library's errors name run_session's parameters; the experimenter types flags
_FLAGS = (
    ("run with resume=False", "run without --resume"),
    ("resume=True", "--resume"),
    ("force=True", "--force"),
)
SCREEN_STATUS_EVERY_S = 1.0  # [s] wall time between the screen's status lines


@click.command("run")
@click.option("--protocol", "protocol", required=True, help="Shipped protocol name or TOML file.")
@click.option("--participant", "code", required=True, help="Pseudonymous code, e.g. P01.")
@db_option("Study database: a SQLite file (created if missing) or a SQLAlchemy URL.")
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
    type=SEED,
    default=None,
    help="Participant seed (default: derived from the study seed and the code).",
)
@click.option(
    "--resume", is_flag=True, help="Continue this participant's session after a crash or Ctrl-C."
)
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
@click.option(
    "--site",
    default=None,
    help="The site this session runs at, one of the protocol's [study] sites (required in a "
    "multi-site study) [default: $ASA_SITE].",
)
@click.option(
    "--lsl",
    "lsl",
    is_flag=True,
    help="Lab Streaming Layer on, also for a protocol without [lsl]: the event and state "
    "outlets, and the lab's streams the protocol's [[lsl.record]] names. Needs pylsl: "
    "pip install -e '.[lsl]'.",
)
@click.option(
    "--recordings",
    type=click.Path(file_okay=False, path_type=Path),
    default=None,
    help="Folder of the trials' recordings [default: <database name>_recordings beside the "
    "database].",
)
@click.option(
    "--machine",
    default=None,
    help="The machine's name recorded with the session [default: $ASA_MACHINE, else the host "
    "name].",
)
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
    site: str | None,
    machine: str | None,
    lsl: bool,
    recordings: Path | None,
) -> None:
    """Run one participant through every phase of a protocol and store it in --db.

    One line per trial (completed, timed out or aborted) and one live status line.
    Ctrl-C stops the session cleanly (the running trial is stored as aborted) and
    prints the --resume command that continues it.

    \b
    Example:
      asa run --protocol pilot --participant P01 --db pilot.db --input human
      asa run --protocol pilot --participant P01 --db pilot.db --input scripted
      asa run --protocol pilot --participant P01 --db pilot.db --input scripted \\
          --headless --snapshots shots/
      asa run --protocol pilot --participant P01 --db pilot.db --resume   # after a crash
      asa run --protocol multisite.toml --participant LYON-07 --site lyon \\
          --db postgresql://asa@db.example.org/study --input human
      asa run --protocol pilot --participant P01 --db pilot.db --input human --lsl
    """
    from study.cli.terminal import ExperimenterTerminal
    from study.engine.launch import run_participant
    from study.engine.sites import Place

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
    terminal = ExperimenterTerminal(code, screen=screen)
    params = click.get_current_context().params
    try:
        summary = run_participant(
            protocol, code, db, input_kind=input_kind, seed=seed, resume=resume, force=force,
            headless=headless, snapshots=snapshots, fast=fast, progress=terminal.line,
            status=terminal.status, on_tick=terminal.on_tick,
            status_every_s=SCREEN_STATUS_EVERY_S, place=Place.given(site, machine),
            lsl=True if lsl else None, recordings=recordings,
        )  # fmt: skip
    except BaseException as error:
        terminal.close()
        if terminal.opened:  # the session exists: say what was cut short, how to go on
            _interrupted(code, db, params)
        if isinstance(error, ValueError) and _with_flags(str(error)) != str(error):
            raise ValueError(_with_flags(str(error))) from error
        raise
    terminal.close()
    click.echo(
        f"{summary.participant}: session {summary.session_id} {summary.status}, "
        f"{len(summary.trials)} trials run"
    )
    if summary.status == "aborted" and _interrupted(code, db, params):
        raise SystemExit(130)  # as the shell reports a process stopped by Ctrl-C


def _interrupted(code: str, db: str, params: dict[str, Any]) -> bool:
    """Print the trial cut short and the resume command; True when one was cut short
    by Ctrl-C or an error (not, e.g., a participant excluded after practice)."""
    from study.cli.terminal import interruption_lines, resume_command
    from study.engine.resume import last_session

    state = last_session(db, code)
    if state is not None and state.status == "aborted" and not state.again:
        return False  # ended by the protocol (exclusion), not cut short
    for line in interruption_lines(code, state, resume_command(params)):
        click.echo(line)
    return True


def _with_flags(message: str) -> str:
    """``message`` with run_session's parameter names as the flags that set them."""
    for name, flag in _FLAGS:
        message = message.replace(name, flag)
    return message
