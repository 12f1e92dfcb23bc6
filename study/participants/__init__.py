"""Participants of a session: the interface (:mod:`study.participants.base`) and the
scripted test driver (:mod:`study.participants.scripted`). Human and synthetic
participants implement the same interface in their own modules."""

from __future__ import annotations

from study.participants.base import Participant
from study.participants.scripted import ScriptedParticipant, ScriptedSettings

__all__ = ["Participant", "ScriptedParticipant", "ScriptedSettings"]
