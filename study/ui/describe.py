"""The participant's screens, each described once (DESIGN.md, "Participants in a browser"):
what a page, a questionnaire, a pairwise comparison and the driving screen show, as
frozen values built from the protocol's texts and the engine's state. Two renderers draw
them: the pygame window (:mod:`study.ui.screen`, :mod:`study.ui.form_view`) and the
browser's canvas (:mod:`study.web`, which sends them as JSON, :func:`to_json`). Pure: no
pygame.

Every text a participant reads is made here or in :mod:`study.engine.texts`; the renderers
place it. The driving screen's description is static for a trial (layout, title, legend,
goals); what changes every tick travels separately (the pose, the laser hits, the stick,
the question strip).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from questionnaires import nasa_tlx
from questionnaires.base import DECLINE, Item
from sim.occupancy import OccupancyGrid
from sim.scenario import Scenario
from study.engine.protocol import UiSettings
from study.engine.texts import fill, first_sentence, trial_title, trial_values
from study.types import TrialInfo
from study.ui.controls import (
    Controls,
    Legend,
    drive_legend,
    form_legend,
    page_legend,
    pairs_legend,
    prompt_text,
    resume_text,
)
from study.ui.forms import FormState

DEVICE_LOST = (
    "The gamepad was disconnected. The trial is paused. Please plug it in again: the trial "
    "continues as soon as it is back."
)
NUMBER_HINT = "type the number, or step it with left / right"


@dataclass(frozen=True, slots=True)
class PageScreen:
    """A page of text (briefing, get ready, time's up, a practice result, debrief)."""

    tag: str  # what it is, for snapshots ("page", "main_ready", "practice_result")
    title: str
    body: str  # paragraphs separated by "\n"
    prompt: str  # how to go on, in words
    legend: Legend


@dataclass(frozen=True, slots=True)
class FormRow:
    """One item of a questionnaire page as shown."""

    label: str  # "Mental Demand: How mentally demanding was the task?"
    kind: str  # "slider", "likert", "choice" or "number" (questionnaires.base.Item)
    options: tuple[str, ...]  # labels in display order (a number: "Prefer not to say", if any)
    chosen: int | None  # index into options; None: unanswered (a number: see typed)
    typed: str  # a number item's digits
    declined: bool  # a number item's "Prefer not to say"
    unit: str  # a number item's unit ("years")
    anchors: tuple[str, ...]  # a slider's end labels (low, high)
    scale: int  # points on a slider's scale (its options without the decline option)
    problem: str  # why a typed number is refused ("" if it is not)


@dataclass(frozen=True, slots=True)
class FormScreen:
    """A questionnaire page: one row per item, "Done" below them."""

    tag: str  # "form_<instrument>"
    title: str
    instructions: str
    rows: tuple[FormRow, ...]
    row: int  # the selected row; len(rows) is "Done"
    description: str  # the selected item's description ("" on "Done")
    reminder: str  # what still blocks "Done" ("" when nothing does)
    hint: str  # under a selected number row: its problem or how to type it
    legend: Legend


@dataclass(frozen=True, slots=True)
class PairScreen:
    """One NASA-TLX pairwise comparison."""

    question: str
    progress: str  # "Pair 3 of 15"
    titles: tuple[str, str]
    texts: tuple[str, str]
    highlight: int | None  # 0 or 1, None: neither yet
    legend: Legend


@dataclass(frozen=True, slots=True)
class Goal:
    """A goal of the trial as drawn: a circle of the position tolerance, and for a pose
    with a heading (B) an arrow and a wedge of the heading tolerance."""

    label: str  # "A" or "B"
    x: float  # [m] map frame
    y: float
    tolerance_m: float
    yaw: float | None = None  # [rad] the heading to stop in, None: any
    tolerance_rad: float = 0.0


@dataclass(frozen=True, slots=True)
class DriveScreen:
    """The driving screen of one trial, what stays the same from its first tick to its last
    (never the mode)."""

    layout: str  # "map" (camera and map) or "laser" (scan, front and tail cameras)
    show_map: bool
    show_object: bool  # the inspection object on the map in its colour
    questions: bool  # the question strip (the trial asks questions)
    drive: bool  # the stick moves the robot (False: the baseline)
    title: str  # "Trial 1 of 3"
    reminder: str  # the task in one line
    legend: Legend
    yes_label: str  # "Yes  (A / Y)"
    no_label: str
    goals: tuple[Goal, ...]
    marks: tuple[tuple[str, float, float], ...]  # (label, x, y) [m] of A and B
    footprint: tuple[tuple[float, float], ...]  # (4, 2) [m] robot frame


@dataclass(frozen=True, slots=True)
class DriveStrip:
    """What changes now and then on the driving screen: the question, the confirmation of
    an answer, a message over everything (paused, connection or gamepad lost), feedback."""

    question: str | None = None
    confirmation: str = ""
    overlay: str = ""
    feedback: str = ""


Screen = PageScreen | FormScreen | PairScreen | DriveScreen


# ---------------------------------------------------------------------- pages


def text_page(
    body: str, controls: Controls, *, title: str = "", tag: str = "page", verb: str = ""
) -> PageScreen:
    """A page that the Yes button or Enter ends (``verb``: "continue" or "start")."""
    verb = verb or "continue"
    return PageScreen(
        tag=tag,
        title=title,
        body=body,
        prompt=prompt_text(controls, verb),
        legend=page_legend(controls, verb),
    )


def ready_page(info: TrialInfo, ui: UiSettings, controls: Controls) -> tuple[PageScreen, str]:
    """The "get ready" page of a trial (its title the trial's place, its body the protocol's
    instruction for the phase) and the one-line reminder the driving screen repeats."""
    texts, values = ui.texts, trial_values(info)
    body = fill(ui.instructions.get(info.phase, ""), values)
    reminder = first_sentence(body)
    if info.phase == "main":
        body += "\n\n" + fill(texts["break"], values)
    title = trial_title(info, texts)
    return text_page(body, controls, title=title, tag=f"{info.phase}_ready", verb="start"), reminder


def ended_page(
    info: TrialInfo, outcome: Mapping[str, Any], ui: UiSettings, controls: Controls
) -> PageScreen | None:
    """After a training or main trial that its time limit ended, "time's up"; after one a
    collision ended (``end_on_collision``), a page saying so; otherwise none."""
    key = "crashed" if outcome.get("crashed") else "times_up"
    ended = outcome.get("crashed") or outcome.get("timed_out")
    if not ended or info.phase not in ("training", "main"):
        return None
    text = fill(ui.texts[key], trial_values(info))
    title = trial_title(info, ui.texts)
    return text_page(text, controls, title=title, tag=f"{info.phase}_{key}")


def paused_text(ui: UiSettings, controls: Controls) -> str:
    """The box over a paused trial."""
    return f"{ui.texts['paused']} {resume_text(controls)}"


# ---------------------------------------------------------------------- forms


def form_screen(state: FormState, controls: Controls | None) -> FormScreen:
    """What a questionnaire page shows now (no legend without ``controls``)."""
    items = state.items
    rows = tuple(_form_row(state, k, item) for k, item in enumerate(items))
    current = items[state.row] if state.row < state.done_row else None
    hint = ""
    if current is not None and current.kind == "number":
        hint = state.problem(state.row) or NUMBER_HINT
    numbers = any(item.kind == "number" for item in items)
    return FormScreen(
        tag=f"form_{state.instrument.id}",
        title=state.instrument.title,
        instructions=state.instrument.instructions,
        rows=rows,
        row=state.row,
        description=current.description if current is not None else "",
        reminder=state.reminder,
        hint=hint,
        legend=form_legend(controls, numbers=numbers) if controls is not None else (),
    )


def _form_row(state: FormState, k: int, item: Item) -> FormRow:
    options = state.options[k]
    return FormRow(
        label=f"{item.title}: {item.text}" if item.title else item.text,
        kind=item.kind,
        options=tuple(label for _, label in options),
        chosen=state.index[k],
        typed=state.typed[k],
        declined=state.declined[k],
        unit=item.unit,
        anchors=tuple(item.anchors or ()),
        scale=sum(1 for value, _ in options if value != DECLINE),
        problem=state.problem(k),
    )


def pair_screen(
    pair: tuple[str, str], k: int, n: int, highlight: int | None, controls: Controls | None
) -> PairScreen:
    """Pairwise comparison ``k`` (from 0) of ``n``: two NASA-TLX subscales."""
    titles = {s.id: s.title for s in nasa_tlx.SUBSCALES}
    texts = {s.id: s.description for s in nasa_tlx.SUBSCALES}
    return PairScreen(
        question=nasa_tlx.PAIR_QUESTION,
        progress=f"Pair {k + 1} of {n}",
        titles=(titles[pair[0]], titles[pair[1]]),
        texts=(texts[pair[0]], texts[pair[1]]),
        highlight=highlight,
        legend=pairs_legend(controls) if controls is not None else (),
    )


# ---------------------------------------------------------------------- driving


def goals(info: TrialInfo) -> tuple[Goal, ...]:
    """The goals of the trial's route, with their tolerances."""
    scenario, out = info.scenario, []
    if "start" in info.route:
        a = scenario.start
        tol = info.primary.goal_tolerance_m if info.primary is not None else 0.3
        out.append(Goal("A", a.x, a.y, tol))
    if "dock" in info.route and scenario.dock is not None:
        d = scenario.dock
        out.append(Goal("B", d.pose.x, d.pose.y, d.tolerance_m, d.pose.yaw, d.tolerance_rad))
    return tuple(out)


def scenario_marks(info: TrialInfo) -> tuple[tuple[str, float, float], ...]:
    """The labels A and B at the scene's start and dock."""
    scenario = info.scenario
    marks = [("A", scenario.start.x, scenario.start.y)]
    if scenario.dock is not None:
        marks.append(("B", scenario.dock.pose.x, scenario.dock.pose.y))
    return tuple(marks)


def drive_screen(
    info: TrialInfo, ui: UiSettings, controls: Controls, *, title: str, reminder: str
) -> DriveScreen:
    """The driving screen of the trial ``info`` under the protocol's ``[ui]``."""
    c = controls
    footprint = info.scenario.robot.footprint()
    return DriveScreen(
        layout=ui.layout,
        show_map=ui.show_map and ui.layout == "map",
        show_object=ui.show_object,
        questions=info.secondary,
        drive=info.drive,
        title=title,
        reminder=reminder,
        legend=drive_legend(c, drive=info.drive, questions=info.secondary),
        yes_label=f"Yes  ({c.pad['yes']} / {c.keys['yes']})",
        no_label=f"No  ({c.pad['no']} / {c.keys['no']})",
        goals=goals(info),
        marks=scenario_marks(info),
        footprint=tuple((float(x), float(y)) for x, y in footprint),
    )


def map_cells(scenario: Scenario, grid: OccupancyGrid) -> np.ndarray:
    """The map as drawn: per grid cell (rows, cols) uint8, 0 free, 1 in the question region
    (pale yellow), 2 occupied (dark grey); row 0 at the grid's origin."""
    occ = np.asarray(grid.occupied)
    out = np.zeros(occ.shape, dtype=np.uint8)
    rows, cols = occ.shape
    if len(scenario.question_region):
        cells = np.stack(np.meshgrid(np.arange(rows), np.arange(cols), indexing="ij"), -1)
        centres = grid.cell_to_world(cells.reshape(-1, 2))
        inside = in_polygon(centres, np.asarray(scenario.question_region))
        out[inside.reshape(rows, cols)] = 1
    out[occ] = 2
    return out


def in_polygon(points: np.ndarray, polygon: np.ndarray) -> np.ndarray:
    """Even-odd rule: which of ``points`` (k, 2) lie inside ``polygon`` (m, 2)."""
    x, y = points[:, 0], points[:, 1]
    inside = np.zeros(len(points), dtype=bool)
    px, py = polygon[:, 0], polygon[:, 1]
    j = len(polygon) - 1
    for i in range(len(polygon)):
        crosses = (py[i] > y) != (py[j] > y)
        with np.errstate(divide="ignore", invalid="ignore"):
            xs = (px[j] - px[i]) * (y - py[i]) / (py[j] - py[i]) + px[i]
        inside ^= crosses & (x < xs)
        j = i
    return inside


def to_json(screen: Screen) -> dict[str, Any]:
    """``screen`` as a JSON-ready dict with its ``kind`` ("page", "form", "pair", "drive")."""
    kinds = {PageScreen: "page", FormScreen: "form", PairScreen: "pair", DriveScreen: "drive"}
    return {"kind": kinds[type(screen)], **dataclasses.asdict(screen)}
