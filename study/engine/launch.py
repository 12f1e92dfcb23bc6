"""One participant's session as ``asa run`` starts it: a scripted or synthetic participant
without a screen, or the pygame screen (:class:`study.participants.human.HumanParticipant`)
driven by a person or, headless, by a scripted or synthetic participant's decisions
(:class:`study.ui.inject.EventDriver`); Ctrl-C aborts it cleanly
(:func:`study.engine.clocks.sigint_aborts`)."""

from __future__ import annotations

import os
from collections.abc import Callable
from pathlib import Path

import numpy as np

from study.engine.clocks import ExperimenterControl, sigint_aborts
from study.engine.protocol import Protocol, load_protocol
from study.engine.session import SessionSummary, check_code, default_seed, run_session
from study.engine.sites import Place
from study.engine.trial import TrialWriter
from study.participants.base import Participant

INPUTS = ("scripted", "human", "synthetic")


def decider(input_kind: str, seed: int) -> Participant:
    """The scripted or synthetic participant that decides, its generator seeded with
    ``seed`` (the same seed draws the same synthetic person, so a resumed session
    continues with them)."""
    from study.participants import ScriptedParticipant, synthetic_participant

    if input_kind == "synthetic":
        return synthetic_participant(np.random.default_rng(seed))
    return ScriptedParticipant(np.random.default_rng(seed))


def run_participant(
    protocol: str,
    code: str,
    db: Path,
    *,
    input_kind: str = "scripted",
    seed: int | None = None,
    resume: bool = False,
    force: bool = False,
    headless: bool = False,
    snapshots: Path | None = None,
    fast: bool = False,
    progress: Callable[[str], None] | None = None,
    status: Callable[[str], None] | None = None,
    on_tick: Callable[[int, TrialWriter], None] | None = None,
    status_every_s: float = 5.0,
    place: Place | None = None,
    lsl: bool | None = None,
    recordings: Path | None = None,
) -> SessionSummary:
    """Run (or resume) participant ``code``'s session of ``protocol`` in ``db``.

    Parameters
    ----------
    protocol : str
        Shipped protocol name or TOML file.
    code : str
        Pseudonymous participant code.
    db : Path
        Study database.
    input_kind : str
        One of :data:`INPUTS`: who decides.
    seed : int, optional
        The participant's seed (and its generator's); default derived from the
        protocol's study seed and ``code``.
    resume, force : bool
        As :func:`study.engine.session.run_session`.
    headless : bool
        A scripted or synthetic participant through the screen, SDL's dummy video driver.
    snapshots : Path, optional
        Folder for the screen's PNG snapshots.
    fast : bool
        Headless: free-running instead of the wall clock.
    progress, status, on_tick : callable, optional
        One line per phase and trial; the screen's status line, every
        ``status_every_s`` of wall time during a trial (screen only); after every tick.
    status_every_s : float
        [s] of wall time between the screen's status lines.
    place : Place, optional
        The site and machine (:class:`study.engine.sites.Place`); default no site, this
        host.
    lsl : bool, optional
        True: the LSL outlets even without the protocol's ``[lsl]`` (``--lsl``); None: as
        the protocol says (:func:`study.engine.session.run_session`).
    recordings : Path, optional
        Folder of the recordings (``--recordings``); default beside the database.

    Returns
    -------
    SessionSummary
        ``status`` "aborted" when Ctrl-C stopped a trial (its row ``aborted`` with the
        reason :data:`study.engine.clocks.INTERRUPTED`); Ctrl-C outside a trial raises
        ``KeyboardInterrupt`` (the session stays resumable).
    """
    check_code(code)
    p = load_protocol(protocol)
    seed = seed if seed is not None else default_seed(p.study.seed, code)
    with sigint_aborts(ExperimenterControl()) as control:
        if input_kind != "human" and not headless:
            participant = decider(input_kind, seed)
            return run_session(
                p, code, db, participant=participant, seed=seed, resume=resume, force=force,
                progress=progress, control=control, on_tick=on_tick, place=place, lsl=lsl,
                recordings=recordings,
            )  # fmt: skip
        return _on_screen(
            p, code, db, input_kind, seed, resume=resume, force=force, headless=headless,
            snapshots=snapshots, fast=fast, progress=progress, status=status, on_tick=on_tick,
            control=control, status_every_s=status_every_s, place=place, lsl=lsl,
            recordings=recordings,
        )  # fmt: skip


def _on_screen(
    p: Protocol,
    code: str,
    db: Path,
    input_kind: str,
    seed: int,
    *,
    resume: bool,
    force: bool,
    headless: bool,
    snapshots: Path | None,
    fast: bool,
    progress: Callable[[str], None] | None,
    status: Callable[[str], None] | None,
    on_tick: Callable[[int, TrialWriter], None] | None,
    control: ExperimenterControl,
    status_every_s: float,
    place: Place | None,
    lsl: bool | None,
    recordings: Path | None,
) -> SessionSummary:
    """The session on the participant's screen (the camera image it shows is recorded)."""
    if headless:
        os.environ["SDL_VIDEODRIVER"] = "dummy"
        os.environ.setdefault("SDL_AUDIODRIVER", "dummy")
    from study.engine.trial import FreeClock
    from study.participants.human import HumanParticipant
    from study.ui.inject import EventDriver
    from study.ui.input import GamepadMapping

    driver = None
    if input_kind != "human":
        driver = EventDriver(decider(input_kind, seed), GamepadMapping.from_settings(p.input))
    person = HumanParticipant(
        p.ui, p.input, driver=driver, snapshots=snapshots, status=status,
        status_every_s=status_every_s,
    )  # fmt: skip
    try:
        return run_session(
            p,
            code,
            db,
            participant=person,
            seed=seed,
            resume=resume,
            force=force,
            progress=progress,
            control=control,
            clock=FreeClock() if fast else person.clock(),
            on_tick=on_tick,
            place=place,
            lsl=lsl,
            recordings=recordings,
        )
    finally:
        person.close()
