"""Drive the human interface with any participant's decisions, as pygame events.

Issue 5 ("Headless path"): ``asa run --input scripted|synthetic --headless`` runs exactly the
human path (:class:`study.participants.human.HumanParticipant` on the pygame screen, with
SDL's dummy video driver) while a scripted or synthetic participant decides; its decisions
reach the interface only as the events a person would cause:

- driving: a virtual gamepad (announced with a ``JOYDEVICEADDED`` event carrying
  ``virtual=True``) whose axes are set by ``JOYAXISMOTION`` events, computed through the
  protocol's mapping with the deadzone undone (:meth:`GamepadMapping.stick_to_raw`), so the
  command the interface derives equals the participant's up to float rounding and the robot's
  limits (a translation faster than ``max_speed`` is clipped to the unit stick disc);
- answers and the pause button: ``JOYBUTTONDOWN`` / ``JOYBUTTONUP`` of the mapped buttons;
- text pages (and the "time's up" page): the Enter key; questionnaires: the digits of a
  number, arrow keys and Enter, exactly the presses the form needs to reach each answer
  (:class:`study.ui.forms.FormState`); pairwise comparisons: left or right and Enter.

:class:`EventDriver` is generic over any object with the participant interface
(``study.participants.base.Participant``); ``intention`` and ``end_trial`` are passed on.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
import pygame

from questionnaires.base import DECLINE, Instrument
from sim.types import Observation
from study.participants.base import Participant
from study.types import ScreenState, TrialInfo
from study.ui.forms import FormState
from study.ui.input import GamepadMapping

VIRTUAL_ID = 9001  # instance id of the virtual gamepad
VIRTUAL_NAME = "asa virtual gamepad"


def post_key(key: int) -> None:
    """Post a key press and release."""
    pygame.event.post(pygame.event.Event(pygame.KEYDOWN, key=key, mod=0, unicode="", scancode=0))
    pygame.event.post(pygame.event.Event(pygame.KEYUP, key=key, mod=0, unicode="", scancode=0))


def post_button(button: int, instance: int = VIRTUAL_ID) -> None:
    """Post a gamepad button press and release."""
    pygame.event.post(pygame.event.Event(pygame.JOYBUTTONDOWN, instance_id=instance, button=button))
    pygame.event.post(pygame.event.Event(pygame.JOYBUTTONUP, instance_id=instance, button=button))


def post_device(added: bool, instance: int = VIRTUAL_ID, name: str = VIRTUAL_NAME) -> None:
    """Post the virtual gamepad's arrival or removal."""
    if added:
        event = pygame.event.Event(
            pygame.JOYDEVICEADDED, device_index=-1, instance_id=instance, virtual=True, name=name
        )
    else:
        event = pygame.event.Event(pygame.JOYDEVICEREMOVED, instance_id=instance)
    pygame.event.post(event)


def form_keys(state: FormState, answers: Mapping[str, object]) -> list[int]:
    """The key presses that fill ``state`` (fresh) with ``answers`` and finish it: a
    number's digits typed (left from empty declines it), an option reached with the arrows."""
    keys: list[int] = []
    for row, item in enumerate(state.instrument.items):
        value = answers.get(item.id)
        if value is not None and item.kind == "number":
            digits = [getattr(pygame, f"K_{d}") for d in str(value)]
            keys.extend([pygame.K_LEFT] if value == DECLINE else digits)
        elif value is not None:
            values = [v for v, _ in state.options[row]]
            target = values.index(value)
            start = state.start_index(row)
            keys.append(pygame.K_RIGHT)  # puts the mark at the start
            step = pygame.K_RIGHT if target > start else pygame.K_LEFT
            keys.extend([step] * abs(target - start))
        keys.append(pygame.K_DOWN)
    keys.append(pygame.K_RETURN)
    return keys


class EventDriver:
    """Turns a participant's decisions into pygame events for the human interface.

    Parameters
    ----------
    inner : Participant
        Who decides (scripted, synthetic, ...).
    mapping : GamepadMapping
        The protocol's gamepad mapping (the interface reads the axes through it).
    max_speed, max_yaw_rate : float
        Not needed up front: taken from each trial's scenario.
    """

    def __init__(self, inner: Participant, mapping: GamepadMapping) -> None:
        self.inner = inner
        self.mapping = mapping
        self.kind: str = inner.kind
        self.parameters: dict[str, Any] = dict(inner.parameters)
        self._limits = (1.0, 1.0)
        self._plugged = False
        self._answers: dict[tuple[str, str], str] = {}
        self._pair_index = 0

    # -------------------------------------------------------------- pages

    def on_text(self, text: str) -> None:
        self.inner.read(text)
        post_key(pygame.K_RETURN)

    def on_ready(self, info: TrialInfo) -> None:
        post_key(pygame.K_RETURN)

    def on_page(self) -> None:
        """A page that needs no decision (time's up): go on."""
        post_key(pygame.K_RETURN)

    def on_form(
        self, instrument: Instrument, context: Mapping[str, Any], state: FormState
    ) -> dict[str, object]:
        answers = instrument.validate(self.inner.fill(instrument, context=context))
        for key in form_keys(state, answers):
            post_key(key)
        return answers

    def on_choose(self, pairs: Sequence[tuple[str, str]]) -> None:
        self._answers = dict(self.inner.choose(pairs))
        self._pair_index = 0

    def on_pair(self, pair: tuple[str, str]) -> None:
        chosen = self._answers[pair]
        post_key(pygame.K_LEFT if chosen == pair[0] else pygame.K_RIGHT)
        post_key(pygame.K_RETURN)

    # -------------------------------------------------------------- trials

    def begin_trial(self, info: TrialInfo) -> None:
        robot = info.scenario.robot
        self._limits = (float(robot.max_speed), float(robot.max_yaw_rate))
        if not self._plugged:
            post_device(True)
            self._plugged = True
        self.inner.begin_trial(info)

    def on_act(self, obs: Observation, screen: ScreenState) -> None:
        inp = self.inner.act(obs, screen)
        speed, yaw_rate = self._limits
        u = np.asarray(inp.u, dtype=float)
        stick = np.array([u[0] / speed, u[1] / speed, u[2] / yaw_rate])
        for axis, value in self.mapping.stick_to_raw(stick).items():
            pygame.event.post(
                pygame.event.Event(
                    pygame.JOYAXISMOTION, instance_id=VIRTUAL_ID, axis=axis, value=value
                )
            )
        if inp.answer is not None:
            post_button(int(self.mapping.buttons["yes" if inp.answer else "no"]))
        if inp.pause:
            post_button(int(self.mapping.buttons["pause"]))

    def intention(self) -> tuple[str, str]:
        return self.inner.intention()

    def end_trial(self, outcome: dict[str, Any]) -> None:
        self.inner.end_trial(outcome)
