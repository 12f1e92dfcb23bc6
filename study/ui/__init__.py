"""The participant's pygame interface (issue 5): the screen (:mod:`study.ui.screen`, its map
:mod:`study.ui.map_view` and key legends :mod:`study.ui.legend`), gamepad and keyboard input
(:mod:`study.ui.input`), questionnaire forms (:mod:`study.ui.forms`, drawn by
:mod:`study.ui.form_view`), the camera rendered off the control path (:mod:`study.ui.camera`),
the clock that draws between ticks (:mod:`study.ui.clock`) and the event injector of the
headless path (:mod:`study.ui.inject`). Together with :mod:`study.participants.human` the
only modules that import pygame (DESIGN.md, layering); nothing is imported here so that
``import study.ui.camera`` in the camera's worker process does not load pygame.
"""

from __future__ import annotations
