"""The participant's side of a protocol: ``[ui]`` (the window, the texts), ``[input]``
(the gamepad's indices and names, the keyboard's keys) and the participant's texts with
their placeholders (:mod:`study.engine.texts`; issue 19: the protocol's text stays in the
protocol file, validated here with the file and field named)."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import replace

from sim.fields import FieldReader
from sim.scenario import Scenario
from study.engine import texts
from study.engine.protocol.readers import boolean, string_list, text
from study.engine.protocol.types import (
    AXES,
    BUTTONS,
    DEFAULT_AXES,
    DEFAULT_BUTTONS,
    DEFAULT_INVERT,
    DEFAULT_KEYS,
    KEY_ACTIONS,
    PAD_CONTROLS,
    PHASE_KINDS,
    UI_LAYOUTS,
    Baseline,
    Briefing,
    Debrief,
    InputSettings,
    MainTrials,
    Phase,
    Practice,
    Training,
    UiSettings,
)


def template(r: FieldReader, key: str, default: str | None, field: str) -> str:
    """A participant's text that may hold the placeholders allowed for ``field``
    (:func:`study.engine.texts.allowed_placeholders`)."""
    value = text(r, key, default)
    allowed = texts.allowed_placeholders(field)
    bad = texts.unknown_placeholder(value, allowed)
    if bad is not None:
        names = ", ".join("{" + a + "}" for a in allowed)
        raise r.fail(key, f"unknown placeholder {{{bad}}}; this text may use {names}")
    return value


def ui_settings(r: FieldReader) -> UiSettings:
    window = r.vector("window", 2, [1280, 720], positive=True)
    if not all(v == int(v) and v >= 320 for v in window):
        raise r.fail("window", f"must be two whole numbers of pixels >= 320, got {list(window)}")
    ir = r.sub("instructions")
    instructions = {
        kind: template(ir, kind, None, f"instructions.{kind}")
        for kind in PHASE_KINDS
        if kind in ir.data
    }
    ir.finish()
    tr = r.sub("texts")
    shown = {
        key: template(tr, key, default, f"texts.{key}")
        for key, default in texts.DEFAULT_TEXTS.items()
    }
    tr.finish()
    layout = r.string("layout", "map", allowed=UI_LAYOUTS)
    show_map = boolean(r, "show_map", layout == "map")
    if layout == "laser" and show_map:
        raise r.fail("show_map", 'must be false with layout = "laser" (that screen has no map)')
    show_object = boolean(r, "show_object", False)
    if show_object and not show_map:
        raise r.fail("show_object", "needs show_map = true (the object is marked on the map)")
    u = UiSettings(
        window=(int(window[0]), int(window[1])),
        fullscreen=boolean(r, "fullscreen", False),
        show_map=show_map,
        instructions=instructions,
        layout=layout,
        show_object=show_object,
        texts=shown,
    )
    r.finish()
    return u


def _default_instructions(phases: tuple[Phase, ...], has_object: bool) -> dict[str, str]:
    """The "get ready" texts of the trial phases, as :func:`texts.default_instruction`
    words them for what each phase asks."""
    out = {}
    for p in phases:
        if isinstance(p, Training):
            out["training"] = texts.default_instruction(
                "training", secondary=p.secondary, rehearsal=p.rehearsal_questions > 0
            )
        elif isinstance(p, Practice):
            out["practice"] = texts.default_instruction("practice", secondary=p.secondary)
        elif isinstance(p, Baseline):
            out["baseline"] = texts.default_instruction("baseline", secondary=True)
        elif isinstance(p, MainTrials):
            out["main"] = texts.default_instruction(
                "main", secondary=p.secondary, inspection=p.inspection and has_object
            )
    return out


def protocol_words(
    r: FieldReader, phases: tuple[Phase, ...], ui: UiSettings, main_scene: Scenario
) -> tuple[tuple[Phase, ...], UiSettings]:
    """The texts with ``{object}`` (the main scene's inspection object, as coloured there)
    and ``{laser_colour}`` filled in; ``{object}`` without such an object is refused."""
    main = next(p for p in phases if isinstance(p, MainTrials))
    thing = texts.object_words(main_scene)
    values = {"object": thing, "laser_colour": texts.LASER_COLOUR_NAME}
    ui = replace(ui, instructions={**_default_instructions(phases, bool(thing)), **ui.instructions})
    if not thing:
        del values["object"]
        fields = [(f"phases[{i}].text", getattr(p, "text", "")) for i, p in enumerate(phases)]
        fields += [(f"ui.instructions.{k}", v) for k, v in ui.instructions.items()]
        fields += [(f"ui.texts.{k}", v) for k, v in ui.texts.items()]
        for name, text in fields:
            if "object" in texts.placeholders(text):
                raise FieldReader(r.path, {}).fail(
                    name,
                    f"uses {{object}}, but scenario {main.scenario!r} has no inspection_object",
                )
    filled = tuple(
        replace(p, text=texts.fill(p.text, values)) if isinstance(p, Briefing | Debrief) else p
        for p in phases
    )
    ui = replace(
        ui,
        instructions={k: texts.fill(v, values) for k, v in ui.instructions.items()},
        texts={k: texts.fill(v, values) for k, v in ui.texts.items()},
    )
    return filled, ui


def _indices(
    r: FieldReader, names: tuple[str, ...], defaults: Mapping[str, int]
) -> Mapping[str, int]:
    out = {name: r.integer(name, defaults[name], minimum=0) for name in names}
    r.finish()
    values = list(out.values())
    duplicates = sorted({v for v in values if values.count(v) > 1})
    if duplicates:
        clash = [n for n, v in out.items() if v == duplicates[0]]
        raise r.fail(clash[1], f"uses index {duplicates[0]} as {clash[0]!r} does")
    return out


def input_settings(r: FieldReader) -> InputSettings:
    deadzone = r.number("deadzone", 0.1, non_negative=True)
    if deadzone >= 1:
        raise r.fail("deadzone", f"must lie in [0, 1), got {deadzone!r}")
    s = InputSettings(
        axes=_indices(r.sub("axes"), AXES, DEFAULT_AXES),
        buttons=_indices(r.sub("buttons"), BUTTONS, DEFAULT_BUTTONS),
        invert=string_list(r, "invert", list(DEFAULT_INVERT), allowed=AXES),
        deadzone=deadzone,
        keys=_keys(r.sub("keys")),
        names=_names(r.sub("names")),
    )
    r.finish()
    return s


def _keys(r: FieldReader) -> dict[str, str]:
    """The keyboard's keys: one letter each, no letter twice."""
    out: dict[str, str] = {}
    for action in KEY_ACTIONS:
        letter = r.string(action, DEFAULT_KEYS[action])
        if len(letter) != 1 or not ("A" <= letter.upper() <= "Z"):
            raise r.fail(action, f"must be one letter A-Z, got {letter!r}")
        letter = letter.upper()
        clash = next((a for a, k in out.items() if k == letter), None)
        if clash is not None:
            raise r.fail(action, f"uses the key {letter} as {clash!r} does")
        out[action] = letter
    r.finish()
    return out


def _names(r: FieldReader) -> dict[str, str]:
    """What the legends call the gamepad's controls (only those the protocol names)."""
    out = {key: text(r, key) for key in PAD_CONTROLS if key in r.data}
    r.finish()
    return out
