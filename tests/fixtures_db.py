"""A generator of realistic synthetic study databases for the analysis and report tests.

:func:`make_study_db` writes, through the storage models only, what the session engine
would leave after a complete study of the thesis protocol (``protocols/thesis-7-6.toml``,
stored as the study's protocol text): N participants x the three modes, counterbalanced
over the six permutations, each with an experience questionnaire, a baseline block of 40
questions, one main trial per mode with a few hundred samples, collision, question and
trial events, the secondary questions and a NASA-TLX (six ratings and the 15 pairwise
choices) after each main trial.

The mode effects are chosen (:class:`FixtureSettings`) so that tests can assert their
direction: completion time, collisions and TLX fall from manual to reactive to contextual,
the assistance share rises, answering is faster in the baseline than while driving.
Samples are spread evenly over the trial's duration (not one per 50 ms tick: a few hundred
per trial keep the files small); tick numbers are contiguous. The outcome columns of each
trial are computed from its own samples, as the primary task would.

Everything random comes from the passed-in generator: the same seed gives the same file.
"""

from __future__ import annotations

import hashlib
import importlib.resources
import itertools
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from sqlalchemy.orm import Session

from questionnaires import nasa_tlx
from study.data.storage import (
    Event,
    Participant,
    Question,
    Response,
    Sample,
    SessionRow,
    Study,
    Trial,
    open_database,
)

MODES: tuple[str, ...] = ("manual", "reactive_bn", "contextual_task")
TASKS: tuple[str, ...] = ("doorway", "inspection", "docking")
TARGETS: dict[str, str] = {"doorway": "door_1", "inspection": "red_cylinder", "docking": "table"}
# the contextual mode labels ticks with motion primitives and stores what each stands for
PRIMITIVES: dict[str, str] = {"doorway": "primitive_0", "inspection": "primitive_1",
                              "docking": "primitive_2"}  # fmt: skip
LABEL_TASKS: dict[str, str] = {v: k for k, v in PRIMITIVES.items()}
START = np.array([1.0, 1.0])
DOCK = np.array([8.0, 6.0])


@dataclass(frozen=True, slots=True)
class FixtureSettings:
    """What to generate. Per-mode tuples follow :data:`MODES`.

    Attributes
    ----------
    n_participants : complete participants (all three main trials).
    time_s : mean completion time per mode [s].
    collisions : mean collisions per mode (Poisson).
    tlx : mean NASA-TLX rating per mode (0..100).
    beta_share : share of ticks with assistance per mode.
    answer_time_s : mean answer time while driving, and ``baseline_answer_time_s`` without [s].
    p_wrong : chance of a wrong answer while driving, ``baseline_p_wrong`` in the baseline.
    recognition : share of ticks the contextual mode recognises the true task and target.
    samples : samples per main trial.
    questions : questions per main trial; the baseline has ``baseline_questions``.
    aborted_retry : the first participant's first main trial is aborted once, then rerun.
    incomplete : one more participant whose session stopped after the first main trial
        (the second is aborted), so listwise deletion drops them.
    kind : participant kind ("synthetic" carries true intentions in the samples).
    """

    n_participants: int = 6
    time_s: tuple[float, float, float] = (260.0, 205.0, 160.0)
    collisions: tuple[float, float, float] = (3.0, 1.2, 0.5)
    tlx: tuple[float, float, float] = (65.0, 50.0, 35.0)
    beta_share: tuple[float, float, float] = (0.0, 0.35, 0.7)
    answer_time_s: float = 2.4
    baseline_answer_time_s: float = 1.6
    p_wrong: float = 0.15
    baseline_p_wrong: float = 0.04
    recognition: float = 0.8
    samples: int = 240
    questions: int = 20
    baseline_questions: int = 40
    aborted_retry: bool = True
    incomplete: bool = True
    kind: str = "synthetic"


def protocol_text() -> str:
    """The shipped thesis protocol's exact text."""
    return (importlib.resources.files("protocols") / "thesis-7-6.toml").read_text("utf-8")


def _path(rng: np.random.Generator, n: int) -> np.ndarray:
    """(n, 2) a noisy A -> B -> A route [m]."""
    s = np.linspace(0.0, 1.0, n)
    leg = np.where(s < 0.5, s * 2.0, 2.0 - s * 2.0)[:, None]
    xy = START + leg * (DOCK - START)
    bend = np.sin(np.pi * 2.0 * s)[:, None] * np.array([-1.0, 1.0]) * 0.8
    wobble = np.cumsum(rng.normal(0.0, 0.02, (n, 2)), axis=0)
    wobble -= np.linspace(0.0, 1.0, n)[:, None] * wobble[-1]  # back at A
    return xy + bend + wobble


def _intentions(n: int) -> tuple[list[str], list[str]]:
    """True task and target per sample: a third each of doorway, inspection, docking."""
    tasks = [TASKS[min(3 * i // n, 2)] for i in range(n)]
    return tasks, [TARGETS[t] for t in tasks]


def _tlx_rows(rng, mean, person_id, trial_id) -> list[Response]:
    rows = []
    for sid in nasa_tlx.SUBSCALE_IDS:
        value = int(np.clip(np.round(rng.normal(mean, 8.0) / 5.0) * 5.0, 0, 100))
        rows.append(
            Response(
                participant_id=person_id,
                trial_id=trial_id,
                instrument="nasa_tlx",
                item=sid,
                value=float(value),
                text="",
            )
        )
    for a, b in nasa_tlx.PAIRS:
        chosen = a if rng.random() < 0.5 else b
        rows.append(
            Response(
                participant_id=person_id,
                trial_id=trial_id,
                instrument="nasa_tlx",
                item=f"pair:{a}|{b}",
                value=None,
                text=chosen,
            )
        )
    return rows


def _questions(rng, trial_id, n, *, mean_time, p_wrong, start_t) -> list[Question]:
    rows = []
    t = start_t
    for i in range(n):
        shown_is_correct = bool(rng.random() < 0.5)
        timeout = rng.random() < 0.03
        answer = float(rng.lognormal(np.log(mean_time), 0.25))
        if timeout or answer >= 8.0:
            rows.append(
                Question(
                    trial_id=trial_id,
                    block=0,
                    index=i,
                    text=f"{10 + i} + 11 = {21 + i}",
                    shown_is_correct=shown_is_correct,
                    shown_t=t,
                    answered_t=None,
                    response=None,
                    correct=False,
                    answer_time_s=None,
                )
            )
            t += 8.5
            continue
        wrong = rng.random() < p_wrong
        response = shown_is_correct != wrong
        rows.append(
            Question(
                trial_id=trial_id,
                block=0,
                index=i,
                text=f"{10 + i} + 11 = {21 + i}",
                shown_is_correct=shown_is_correct,
                shown_t=t,
                answered_t=t + answer,
                response=response,
                correct=not wrong,
                answer_time_s=answer,
            )
        )
        t += answer + 0.5
    return rows


def _experience(rng, person_id) -> list[Response]:
    answers = {
        "age": float(rng.integers(22, 35)),
        "handedness": "right" if rng.random() < 0.85 else "left",
        "driving": float(rng.integers(1, 6)),
        "games": float(rng.integers(1, 6)),
        "gamepad": float(rng.integers(1, 6)),
        "robots": float(rng.integers(1, 6)),
    }
    return [
        Response(
            participant_id=person_id,
            trial_id=None,
            instrument="experience",
            item=item,
            value=value if isinstance(value, float) else None,
            text=value if isinstance(value, str) else "",
        )
        for item, value in answers.items()
    ]


def _main_trial(s, rng, cfg, person, session, ordinal, mode, *, attempt, aborted) -> Trial:
    m = MODES.index(mode)
    n = cfg.samples if not aborted else cfg.samples // 3
    duration = float(max(rng.normal(cfg.time_s[m], 0.08 * cfg.time_s[m]), 30.0))
    if aborted:
        duration /= 3.0
    trial = Trial(
        participant_id=person.id,
        session_id=session.id,
        phase="main",
        mode=mode,
        ordinal=ordinal,
        attempt=attempt,
        scenario="cluttered_room",
        seed=int(rng.integers(0, 2**31 - 1)),
        status="aborted" if aborted else "completed",
    )
    s.add(trial)
    s.flush()
    xy = _path(rng, n)
    t = np.linspace(0.0, duration, n)
    yaw = np.arctan2(np.gradient(xy[:, 1]), np.gradient(xy[:, 0]))
    clear_scale = 0.35 + 0.15 * m  # assistance keeps the robot further from obstacles
    clearance = 0.05 + rng.gamma(2.0, clear_scale, n)
    assisted = rng.random(n) < cfg.beta_share[m]
    beta = np.where(assisted, rng.uniform(0.1, 0.9, n), 0.0)
    true_task, true_target = _intentions(n)
    if mode == "contextual_task":
        hit = rng.random(n) < cfg.recognition
        tasks = [
            tt if h else ("doorway" if tt != "doorway" else "docking")
            for tt, h in zip(true_task, hit, strict=True)
        ]
        label = [PRIMITIVES[tk] for tk in tasks]
        target = [TARGETS[tk] for tk in tasks]
    elif mode == "reactive_bn":
        label = ["narrow" if c < 0.3 else "open" for c in clearance]
        target = [""] * n
    else:
        label, target = [""] * n, [""] * n
    synthetic = cfg.kind == "synthetic"
    u = rng.normal(0.0, 0.3, (n, 3))
    s.add_all(
        Sample(
            trial_id=trial.id,
            tick=i,
            t=float(t[i]),
            x=float(xy[i, 0]),
            y=float(xy[i, 1]),
            yaw=float(yaw[i]),
            u_x=float(u[i, 0]),
            u_y=float(u[i, 1]),
            u_w=float(u[i, 2]),
            v_x=float(u[i, 0] * (1 - beta[i])),
            v_y=float(u[i, 1] * (1 - beta[i])),
            v_w=float(u[i, 2]),
            beta=float(beta[i]),
            label=label[i],
            target=target[i],
            min_clearance_m=float(clearance[i]),
            in_region=bool(0.2 < i / n < 0.45),
            true_task=true_task[i] if synthetic else "",
            true_target=true_target[i] if synthetic else "",
        )
        for i in range(n)
    )
    s.add(Event(session_id=session.id, trial_id=trial.id, t=0.0, kind="trial_started"))
    if aborted:
        trial.outcome = {"ticks": n, "duration_s": duration, "aborted_reason": "input lost"}
        s.add(Event(session_id=session.id, trial_id=trial.id, t=duration, kind="abort"))
        s.add(Event(session_id=session.id, trial_id=trial.id, t=duration, kind="trial_ended"))
        return trial
    collisions = int(rng.poisson(cfg.collisions[m]))
    for c in range(collisions):
        ct = float(duration * (c + 1) / (collisions + 1))
        s.add(Event(session_id=session.id, trial_id=trial.id, t=ct, kind="collision"))
    hist, _ = np.histogram(np.minimum(clearance, 2.05), bins=np.append(np.arange(21) * 0.1, 9.0))
    path_length = float(np.sum(np.hypot(*np.diff(xy, axis=0).T)))
    trial.completed_task = True
    trial.completion_time_s = duration
    trial.collisions = collisions
    trial.score = duration + 60.0 * collisions
    trial.path_length_m = path_length
    trial.clearance_mean_m = float(clearance.mean())
    trial.clearance_min_m = float(clearance.min())
    trial.tick_jitter_ms = 0.0
    trial.outcome = {
        "ticks": n,
        "duration_s": duration,
        "completed": True,
        "clearance_histogram": [int(h) for h in hist],
        "clearance_samples": n,
        "inspection_required": True,
        "inspection_done": True,
    }
    if mode == "contextual_task":
        trial.outcome["label_tasks"] = dict(LABEL_TASKS)
    qs = _questions(
        rng,
        trial.id,
        cfg.questions,
        mean_time=cfg.answer_time_s,
        p_wrong=cfg.p_wrong,
        start_t=0.25 * duration,
    )
    s.add_all(qs)
    s.add(Event(session_id=session.id, trial_id=trial.id, t=duration, kind="trial_ended"))
    s.add_all(_tlx_rows(rng, cfg.tlx[m], person.id, trial.id))
    return trial


# the study of test_report.py and test_report_presentation.py (tests/conftest.py's
# generated_report, whose report of every metric they share)
REPORT_STUDY = FixtureSettings(n_participants=6, samples=100, questions=12, baseline_questions=20)


def make_study_db(
    path: str | Path,
    rng: np.random.Generator,
    *,
    settings: FixtureSettings | None = None,
) -> Path:
    """Write a synthetic study database to ``path`` (a new SQLite file) and return its path.

    Parameters
    ----------
    path : where to write; must not exist yet.
    rng : the only source of randomness.
    settings : what to generate; defaults to :class:`FixtureSettings`.
    """
    cfg = settings or FixtureSettings()
    path = Path(path)
    if path.exists():
        raise ValueError(f"{path}: already exists; make_study_db writes a new database")
    text = protocol_text()
    engine = open_database(path)
    orders = list(itertools.permutations(MODES))
    try:
        with Session(engine) as s, s.begin():
            study = Study(
                name="thesis-7-6",
                protocol_text=text,
                protocol_sha256=hashlib.sha256(text.encode("utf-8")).hexdigest(),
                platform_version="0.1.0",
                seed=7061,
            )
            s.add(study)
            s.flush()
            n_total = cfg.n_participants + (1 if cfg.incomplete else 0)
            for p in range(n_total):
                incomplete = cfg.incomplete and p == cfg.n_participants
                index = p % len(orders)
                person = Participant(
                    study_id=study.id,
                    code=f"P{p + 1:02d}",
                    kind=cfg.kind,
                    parameters={"skill": float(rng.uniform(0.5, 1.5))}
                    if cfg.kind == "synthetic"
                    else {},
                    order_index=index,
                    mode_order=list(orders[index]),
                    seed=int(rng.integers(0, 2**31 - 1)),
                )
                s.add(person)
                s.flush()
                session = SessionRow(
                    participant_id=person.id, status="aborted" if incomplete else "completed"
                )
                s.add(session)
                s.flush()
                s.add_all(_experience(rng, person.id))
                baseline = Trial(
                    participant_id=person.id,
                    session_id=session.id,
                    phase="baseline",
                    mode="",
                    ordinal=0,
                    scenario="cluttered_room",
                    seed=int(rng.integers(0, 2**31 - 1)),
                    status="completed",
                    outcome={"ticks": 0, "duration_s": 100.0},
                )
                s.add(baseline)
                s.flush()
                s.add_all(
                    _questions(
                        rng,
                        baseline.id,
                        cfg.baseline_questions,
                        mean_time=cfg.baseline_answer_time_s,
                        p_wrong=cfg.baseline_p_wrong,
                        start_t=0.0,
                    )
                )
                for ordinal, mode in enumerate(orders[index]):
                    if incomplete and ordinal == 2:
                        break
                    attempt = 0
                    if (cfg.aborted_retry and p == 0 and ordinal == 0) or (
                        incomplete and ordinal == 1
                    ):
                        _main_trial(
                            s, rng, cfg, person, session, ordinal, mode, attempt=0, aborted=True
                        )
                        attempt = 1
                        if incomplete:
                            break
                    _main_trial(
                        s, rng, cfg, person, session, ordinal, mode, attempt=attempt, aborted=False
                    )
    finally:
        engine.dispose()
    return path
