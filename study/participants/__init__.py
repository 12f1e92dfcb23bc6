"""Participants of a session: the interface (:mod:`study.participants.base`) and the
scripted test driver (:mod:`study.participants.scripted`) and the synthetic participants
(:mod:`study.participants.synthetic`). Human participants implement the same interface in
their own module."""

from __future__ import annotations

from study.participants.base import Participant
from study.participants.scripted import ScriptedParticipant, ScriptedSettings
from study.participants.synthetic import (
    ParticipantParams,
    Population,
    SyntheticParticipant,
    TrialLoad,
    synthetic_participant,
    tlx_ratings,
)

__all__ = [
    "Participant",
    "ParticipantParams",
    "Population",
    "ScriptedParticipant",
    "ScriptedSettings",
    "SyntheticParticipant",
    "TrialLoad",
    "synthetic_participant",
    "tlx_ratings",
]
