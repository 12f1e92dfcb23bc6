"""The contextual-task mode with another recogniser under a name of its own (issue 40), so
that one protocol can compare them (protocols/ablation.toml): the thesis's Ch. 6
recogniser, the synthetic participant's true intention (an oracle) and no recognition
(the safety layer alone). Choices: docs/decisions.md."""

from __future__ import annotations

from typing import Any

from autonomy.contextual import ContextualSettings, ContextualTaskMode
from autonomy.modes import register, settings_from

# the contextual mode with another recogniser under its own name, so that one protocol can
# compare them (protocols/ablation.toml): registry name -> recogniser
VARIANTS: dict[str, str] = {
    "contextual_thesis": "thesis",
    "contextual_oracle": "oracle",
    "contextual_safety": "none",
}


def _variant(name: str, recogniser: str) -> None:
    @register(name)
    def make(**settings: Any) -> ContextualTaskMode:
        where = f"mode {name!r}"
        if "recogniser" in settings:
            raise ValueError(f"{where}: setting 'recogniser' is fixed ({recogniser!r})")
        values = {**settings, "recogniser": recogniser}
        mode = ContextualTaskMode(settings_from(ContextualSettings, values, where=where))
        mode.name = name
        return mode

    make.__doc__ = f"The contextual mode with ``recogniser = {recogniser!r}`` (an ablation)."


for _name, _recogniser in VARIANTS.items():
    _variant(_name, _recogniser)
