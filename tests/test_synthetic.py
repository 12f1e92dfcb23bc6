"""Synthetic participants (study/participants/synthetic.py): the population, the NASA-TLX
model, the questionnaires and driving a short trial in every mode."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from sqlalchemy import select
from sqlalchemy.orm import Session

from autonomy.modes import available_modes
from questionnaires import experience as experience_q
from questionnaires import nasa_tlx
from sim.scenario import load_scenario
from sim.semantics import derive_components
from sim.world import World
from study.data.storage import Sample
from study.engine.standalone import standalone_trial
from study.participants import (
    Participant,
    ParticipantParams,
    Population,
    SyntheticParticipant,
    TrialLoad,
    tlx_ratings,
)
from study.participants.synthetic import DISTRACTIONS, TLX_ORDER
from study.types import ScreenState, TrialInfo
from tasks.contextual import TASK_TYPES

SEEDS = st.integers(min_value=0, max_value=2**32 - 1)


def _params(seed: int) -> ParticipantParams:
    return Population().sample(np.random.default_rng(seed))


# ---------------------------------------------------------------- population


def test_population_is_seeded(seed):
    assert _params(seed) == _params(seed)
    people = Population().sample_many(5, np.random.default_rng(seed))
    assert len({p.as_dict()["preferred_speed"] for p in people}) > 1


@settings(max_examples=40, deadline=None)
@given(SEEDS)
def test_population_ranges(s):
    pop = Population()
    p = _params(s)
    assert pop.speed_range[0] <= p.preferred_speed <= pop.speed_range[1]
    assert pop.noise_range[0] - 1e-9 <= p.steering_noise <= pop.noise_range[1] + 1e-9
    assert pop.delay_range_s[0] <= p.reaction_delay_s <= pop.delay_range_s[1]
    assert 0.0 <= p.caution <= 1.0
    assert pop.disturbance_range[0] <= p.question_disturbance <= pop.disturbance_range[1]
    assert p.distraction in DISTRACTIONS
    assert 1.4 <= p.answer_time_s <= 3.2
    assert pop.error_range[0] <= p.error_rate <= pop.error_range[1]
    assert p.dual_task_slowdown >= 1.0 and p.dual_task_error_factor >= 1.0
    assert len(p.tlx_importance) == 6 and math.isclose(sum(p.tlx_importance), 1.0, abs_tol=1e-3)
    assert p.tlx_noise > 0 and p.tlx_gain > 0
    assert 18 <= p.age <= 45
    for item in ("driving", "games", "gamepad", "robots"):
        assert getattr(p, item) in (1, 2, 3, 4, 5)


def test_parameters_are_stored_as_json_and_round_trip(seed):
    rng = np.random.default_rng(seed)
    person = SyntheticParticipant(_params(seed), rng)
    assert isinstance(person, Participant)
    assert person.kind == "synthetic"
    text = json.dumps(person.parameters)
    assert ParticipantParams.from_dict(json.loads(text)) == person.params


def test_population_mean_speed_is_the_thesis_figure(seed):
    """Thesis Sec. 7.2.3: about 0.3 m/s on average."""
    people = Population().sample_many(400, np.random.default_rng(seed))
    assert 0.27 < np.mean([p.preferred_speed for p in people]) < 0.33


# ---------------------------------------------------------------- NASA-TLX model

LOADS = st.builds(
    TrialLoad,
    time_ratio=st.floats(0.0, 5.0),
    collisions=st.integers(0, 20),
    completed=st.booleans(),
    corrections=st.floats(0.0, 1.0),
    question_load=st.floats(0.0, 1.0),
    answer_errors=st.floats(0.0, 1.0),
)


@settings(max_examples=60, deadline=None)
@given(LOADS, SEEDS, st.floats(-60.0, 60.0))
def test_tlx_ratings_are_on_the_scale(load, s, bias):
    params = replace(_params(s), tlx_bias=bias)
    z = np.random.default_rng(s).standard_normal(6) * 3
    ratings = tlx_ratings(load, params, z)
    assert tuple(ratings) == TLX_ORDER
    for value in ratings.values():
        assert 0 <= value <= 100 and value % 5 == 0
    nasa_tlx.validate_ratings(ratings)


@settings(max_examples=40, deadline=None)
@given(LOADS, SEEDS)
def test_tlx_more_collisions_and_longer_trials_rate_higher(load, s):
    params = _params(s)
    z = np.random.default_rng(s).standard_normal(6)
    base = tlx_ratings(replace(load, collisions=0, time_ratio=1.0), params, z)
    hit = tlx_ratings(replace(load, collisions=4, time_ratio=1.0), params, z)
    late = tlx_ratings(replace(load, collisions=0, time_ratio=2.0), params, z)
    for k in ("performance", "frustration", "mental", "effort"):
        assert hit[k] >= base[k]
    for k in ("temporal", "performance", "effort"):
        assert late[k] >= base[k]
    busy = tlx_ratings(replace(load, question_load=1.0), params, z)
    idle = tlx_ratings(replace(load, question_load=0.0), params, z)
    assert busy["mental"] >= idle["mental"] and busy["temporal"] >= idle["temporal"]


def test_tlx_collisions_raise_the_mean_rating(seed):
    """Not only monotone with frozen noise: clearly higher on average."""
    rng = np.random.default_rng(seed)
    people = Population().sample_many(60, rng)
    calm = TrialLoad(1.0, 0, True, 0.1, 0.3, 0.05)
    rough = replace(calm, collisions=3, time_ratio=1.6)
    diff = [
        tlx_ratings(rough, p, rng.standard_normal(6))["frustration"]
        - tlx_ratings(calm, p, rng.standard_normal(6))["frustration"]
        for p in people
    ]
    assert np.mean(diff) > 20


# ---------------------------------------------------------------- questionnaires


def test_experience_answers_follow_the_parameters(seed):
    person = SyntheticParticipant(_params(seed), np.random.default_rng(seed))
    answers = person.fill(experience_q.INSTRUMENT, context={"phase": "experience"})
    answers = experience_q.validate(answers)
    p = person.params
    assert answers["age"] == p.age and answers["handedness"] == p.handedness
    assert (answers["gamepad"], answers["games"]) == (p.gamepad, p.games)


def test_pairwise_choices_follow_importance(seed):
    person = SyntheticParticipant(_params(seed), np.random.default_rng(seed))
    pairs = nasa_tlx.presentation_order(np.random.default_rng(seed))
    weights = nasa_tlx.weights_from_choices(person.choose(pairs))
    assert sum(weights.values()) == 15
    only = replace(person.params, tlx_importance=(0.0, 0.0, 1.0, 0.0, 0.0, 0.0))
    person = SyntheticParticipant(only, np.random.default_rng(seed))
    weights = nasa_tlx.weights_from_choices(person.choose(pairs))
    assert weights["temporal"] == 5


def test_answers_take_time_and_are_slower_while_driving(seed):
    """A question is answered after a modelled delay, never at once; with the same draws
    the answer comes later while driving (dual_task_slowdown > 1)."""
    scenario = load_scenario("practice_course")
    times = {}
    for drive in (False, True):
        params = replace(_params(seed), dual_task_slowdown=1.5, question_disturbance=0.0)
        person = SyntheticParticipant(params, np.random.default_rng(seed))
        info = TrialInfo("main", scenario, ("dock",), False, True, 60.0, drive=drive)
        person.begin_trial(info)
        with World(scenario, seed=0) as world:
            obs = world.reset(seed=0)
            screen = ScreenState(phase="main", question="12 + 30 = 42 ?")
            t = 0.0
            while True:
                t += 0.05
                inp = person.act(replace(obs, t=t), replace(screen, t=t))
                if inp.answer is not None:
                    break
                assert t < 30
        times[drive] = t
    assert times[False] > 0.3
    assert times[True] > times[False]


def test_a_trial_does_not_depend_on_how_many_draws_earlier_trials_took(seed):
    """Each trial has its own random stream (phase, position, attempt): a person who drew
    much more in an earlier trial answers the same main trial's question at the same
    moment (before, one stream ran through the session, and a change to one mode's
    training trial moved the manual main trial after it)."""
    scenario = load_scenario("practice_course")
    pairs = [(a, b) for a in TLX_ORDER for b in TLX_ORDER if a < b]
    times = []
    with World(scenario, seed=0) as world:
        for earlier in (1, 40):
            person = SyntheticParticipant(_params(seed), np.random.default_rng(seed))
            person.begin_trial(TrialInfo("training", scenario, ("dock",), False, True, 60.0))
            for _ in range(earlier):
                person.choose(pairs)  # the earlier trial's draws
            person.begin_trial(
                TrialInfo("main", scenario, ("dock",), False, True, 60.0, drive=False, ordinal=1)
            )
            obs = world.reset(seed=0)
            screen = ScreenState(phase="main", question="12 + 30 = 42 ?")
            t = 0.0
            while True:
                t += 0.05
                inp = person.act(replace(obs, t=t), replace(screen, t=t))
                if inp.answer is not None:
                    break
                assert t < 30
            times.append((round(t / 0.05), inp.answer))
    assert times[0] == times[1]


# ---------------------------------------------------------------- driving


def _short_trial(tmp_path, mode_name: str, seed: int):
    rng = np.random.default_rng(seed)
    person = SyntheticParticipant(Population().sample(rng), rng)
    result, engine = standalone_trial(
        tmp_path,
        person,
        mode=mode_name,
        scenario="practice_course",
        phase="practice",
        route=("dock",),
        timeout_s=120.0,
        seed=seed,
        database=f"{mode_name}.db",
    )
    with Session(engine) as s:
        truth = s.execute(select(Sample.true_task, Sample.true_target)).all()
    engine.dispose()
    return result, truth, derive_components(load_scenario("practice_course"))


@pytest.mark.parametrize("mode_name", available_modes())
def test_completes_a_short_trial_in_every_mode(tmp_path, seed, mode_name):
    result, truth, components = _short_trial(tmp_path, mode_name, seed)
    assert result.status == "completed"
    # what the mode's labels mean is stored with the trial (only task-recognising modes)
    assert ("label_tasks" in result.outcome) == mode_name.startswith("contextual_")
    assert result.outcome["completed"], result.outcome
    ids = {c.id for c in components}
    tasks = {task for task, _ in truth}
    assert tasks - {""} and tasks <= set(TASK_TYPES) | {""}
    assert all(target in ids for task, target in truth if task)
    if any(c.kind == "dock" for c in components):
        assert any(task == "robot_docking" for task, _ in truth)
