"""The participant interface: human, synthetic and scripted participants are objects behind
these methods (issue 4, "A participant interface"); :class:`ParticipantBase` gives the
optional hooks their defaults.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np

from sim.types import Observation
from study.types import ParticipantInput, ScreenState, TrialInfo


@runtime_checkable
class Participant(Protocol):
    """A participant of a session: every hook the session engine and the trial loop call."""

    kind: str  # "human", "synthetic" or "scripted" (storage.PARTICIPANT_KINDS)
    parameters: dict[str, Any]  # stored with the participant row
    learns: bool  # False: the session skips the training phase (study.engine.session)
    shows_camera: bool  # True: the recording logs camera_image() instead of rendering

    def read(self, text: str) -> None:
        """Show ``text`` (briefing, instructions, feedback, debrief); return when acknowledged."""
        ...

    def fill(self, instrument: Any, *, context: Mapping[str, Any]) -> dict[str, Any]:
        """Answer a questionnaire (``questionnaires.base.Instrument``): item id -> value.

        ``context`` says when it is asked (``{"phase": "main", "ordinal": 0}``).
        """
        ...

    def choose(self, pairs: Sequence[tuple[str, str]]) -> dict[tuple[str, str], str]:
        """NASA-TLX pairwise comparisons: each pair (as presented) -> the chosen subscale."""
        ...

    def attach_session(self, event: Callable[..., None]) -> None:
        """Before the session's first phase: ``event(kind, **detail)``, which stores an event
        row of the session outside any trial, with the phase it happened in."""
        ...

    def attach(self, world: Any, event: Callable[..., None]) -> None:
        """Before :meth:`begin_trial`: the trial's ``sim.world.World`` (read, never stepped)
        and ``event(t, kind, **detail)``, which stores an event row of the trial."""
        ...

    def begin_trial(self, info: TrialInfo) -> None:
        """A trial is about to start (the instructions, as a value)."""
        ...

    def act(self, obs: Observation, screen: ScreenState) -> ParticipantInput:
        """One control tick: what the participant does given what they see."""
        ...

    def intention(self) -> tuple[str, str]:
        """Ground truth stored in every sample: (task type, component id), ``("", "")``
        while driving freely or when unknown."""
        ...

    def camera_image(self, which: str = "front") -> np.ndarray | None:
        """The image of camera ``which`` ("front" or "tail") shown now (read only when
        ``shows_camera``), None before any or when not shown."""
        ...

    def end_trial(self, outcome: dict[str, Any]) -> None:
        """The trial's stored outcome, once committed and before any questionnaire."""
        ...


class ParticipantBase:
    """Defaults of the optional hooks of :class:`Participant`; participants inherit them
    and implement ``read``, ``fill``, ``choose``, ``begin_trial`` and ``act``."""

    kind: str = ""
    parameters: dict[str, Any] = {}  # noqa: RUF012 (read only; instances set their own)
    learns: bool = True
    shows_camera: bool = False

    def attach_session(self, event: Callable[..., None]) -> None:
        """Nothing to store outside trials."""

    def attach(self, world: Any, event: Callable[..., None]) -> None:
        """Nothing to attach."""

    def intention(self) -> tuple[str, str]:
        """Unknown: ``("", "")``."""
        return ("", "")

    def camera_image(self, which: str = "front") -> np.ndarray | None:
        """No image shown."""
        return None

    def end_trial(self, outcome: dict[str, Any]) -> None:
        """Nothing to remember."""
