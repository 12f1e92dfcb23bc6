"""The participant interface: every participant, human, synthetic or scripted, is an object
behind these few methods (issue 4, "A participant interface").

The session engine calls :meth:`Participant.read` for texts (briefing, instructions,
debrief), :meth:`Participant.fill` for a questionnaire, :meth:`Participant.choose` for the
NASA-TLX pairwise comparisons, :meth:`Participant.begin_trial` before a trial, and
:meth:`Participant.act` once per control tick. ``kind`` and ``parameters`` are stored with
the participant row. A participant may also expose ``intention() -> (task, target)``
(ground truth stored in every sample) and ``end_trial(outcome)`` (called with the trial's
stored outcome dict once it is committed, before any questionnaire); both are optional and
looked up with ``getattr``. So is ``learns`` (default True; False skips the training
phase, see :mod:`study.engine.session`), and ``attach(world, event)``, called before ``begin_trial``
with the trial's ``sim.world.World`` (to be read, never stepped: the human screen renders
the camera from it) and ``event(t, kind, **detail)`` to store an event row of the trial
(:mod:`study.participants.human` stores a lost and a returned input device with it).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, Protocol, runtime_checkable

from sim.types import Observation
from study.types import ParticipantInput, ScreenState, TrialInfo


@runtime_checkable
class Participant(Protocol):
    """A participant of a session."""

    kind: str  # "human", "synthetic" or "scripted" (storage.PARTICIPANT_KINDS)
    parameters: dict[str, Any]  # stored with the participant row

    def read(self, text: str) -> None:
        """Show ``text``; return when the participant has acknowledged it."""
        ...

    def fill(self, instrument: Any, *, context: Mapping[str, Any]) -> dict[str, Any]:
        """Answer a questionnaire (``questionnaires.base.Instrument``): item id -> value.

        ``context`` says when it is asked (``{"phase": "main", "ordinal": 0}``).
        """
        ...

    def choose(self, pairs: Sequence[tuple[str, str]]) -> dict[tuple[str, str], str]:
        """NASA-TLX pairwise comparisons: each pair (as presented) -> the chosen subscale."""
        ...

    def begin_trial(self, info: TrialInfo) -> None:
        """A trial is about to start (the instructions, as a value)."""
        ...

    def act(self, obs: Observation, screen: ScreenState) -> ParticipantInput:
        """One control tick: what the participant does given what they see."""
        ...
