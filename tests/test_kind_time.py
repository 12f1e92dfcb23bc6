"""The kind-and-time recogniser (autonomy.kind_time, autonomy.intent_prior; issue 40):
its prior learnt from demonstrations, its filter over time, its decisive blend weight,
and the contextual mode's recogniser setting."""

from __future__ import annotations

import math

import numpy as np
import pytest

from autonomy.contextual import ContextualSettings, ContextualTaskMode
from autonomy.intent_prior import (
    EXECUTION_SD,
    KIND_CLASS,
    RANKS,
    IntentPrior,
    fit_intent_prior,
)
from autonomy.kind_time import KindTimeRecogniser, KindTimeSettings
from autonomy.modes import make_mode

# two primitives: 0 demonstrated at passages (executed close), 1 along walls (at 0.6 m)
CLASSES = np.array([0, 1])


def _prior(rng, n=600):
    labels = rng.integers(0, 2, n)
    kind = np.where(labels == 0, "doorway", "wall")
    executing = rng.random(n) < 0.6
    distance = np.where(
        executing,
        np.where(labels == 0, rng.lognormal(math.log(0.3), 0.5, n), rng.lognormal(-0.5, 0.1, n)),
        rng.lognormal(0.4, 0.4, n),
    )
    rank = np.minimum(rng.geometric(0.6, n) - 1, 12)
    return fit_intent_prior(labels, distance, executing, kind, rank)


def test_the_prior_is_learnt_from_kinds_distances_and_ranks(rng):
    prior = _prior(rng)
    for shares in prior["kind_share"].values():
        assert math.isclose(sum(shares), 1.0, abs_tol=1e-5) and min(shares) > 0
    assert prior["kind_share"]["0"][KIND_CLASS["doorway"]] > 0.9
    assert prior["kind_share"]["1"][KIND_CLASS["wall"]] > 0.9
    mean_wall = prior["execution_log_distance"]["1"][0]
    assert abs(mean_wall - (-0.5)) < 0.05  # the executed wall distances' log mean
    assert math.isclose(sum(prior["rank"]), 1.0, abs_tol=1e-5) and len(prior["rank"]) == RANKS
    assert prior["rank"][0] > prior["rank"][1] > prior["rank"][2]
    # one standoff demonstrated: the spread is the least a driver's is taken to have
    one = fit_intent_prior(
        np.zeros(50, int),
        np.full(50, 0.9),
        np.ones(50, bool),
        np.full(50, "object"),
        np.zeros(50, int),
    )
    assert one["execution_log_distance"]["0"] == [round(math.log(0.9), 6), EXECUTION_SD]
    arrays = IntentPrior.from_metadata({"intent_prior": prior}, CLASSES[::-1])
    assert arrays.learnt and arrays.log_kind.shape == (2, 3)
    assert arrays.exec_mean[0] == pytest.approx(mean_wall)  # aligned with the classes
    neutral = IntentPrior.from_metadata({}, CLASSES)
    assert not neutral.learnt and np.allclose(np.exp(neutral.log_kind).sum(axis=1), 1.0)


def _recogniser(rng, **settings):
    prior = IntentPrior.from_metadata({"intent_prior": _prior(rng)}, CLASSES)
    return KindTimeRecogniser(prior, KindTimeSettings(**settings))


def _tick(rec, favour, u=(0.6, 0.0, 0.0)):
    """A doorway 'd' 0.4 m ahead and a wall 'w' 0.6 m beside (where each task is executed
    in the prior); the SOGP favours ``favour`` (its passage primitive for 'd', its wall
    primitive for 'w')."""
    mean = (
        np.array([[1.0, -1.0], [-1.0, -1.0]])
        if favour == "d"
        else np.array([[-1.0, -1.0], [-1.0, 1.0]])
    )
    targets = np.array([[0.4, 0.0], [0.0, 0.6]])
    normals = np.array([[1.0, 0.0], [0.0, 0.0]])
    return rec(mean, ["d", "w"], ["doorway", "wall"], targets, normals, np.array(u))


def test_a_decisive_recognition_engages_and_persists_but_recovers(rng):
    rec = _recogniser(rng)
    first = _tick(rec, "d")
    found = [_tick(rec, "d") for _ in range(20)]
    assert all(f.candidate == 0 and f.primitive == 0 for f in found)
    assert found[-1].beta >= rec.settings.engage and found[-1].posterior < 1.0
    assert found[-1].posterior >= first.posterior  # evidence accumulates
    flipped = [_tick(rec, "w") for _ in range(40)]
    assert flipped[0].candidate == 0  # one tick of other evidence does not flip it
    assert flipped[-1].candidate == 1  # sustained evidence does: never certain
    for f in flipped:
        assert 0.0 <= f.posterior <= 1.0
        assert f.beta == 0.0 or f.beta >= rec.settings.engage


def test_idling_decays_towards_uniform_and_contradiction_lowers_belief(rng):
    rec = _recogniser(rng)
    for _ in range(20):
        _tick(rec, "d")
    before = dict(rec.belief_)
    rec.contradict("d")
    assert rec.belief_["d"] < before["d"]
    assert math.isclose(sum(rec.belief_.values()), 1.0)
    for _ in range(400):
        rec.idle()
    values = np.array(list(rec.belief_.values()))
    assert np.allclose(values, 1.0 / len(values), atol=1e-6)
    rec.reset()
    assert rec.belief_ == {}


def test_nothing_near_means_no_assistance(rng):
    rec = _recogniser(rng)
    far = np.array([[6.0, 0.5], [0.3, 7.0]])
    for _ in range(30):
        found = rec(
            np.array([[-0.5, -1.0], [-1.0, -0.5]]),
            ["d", "w"],
            ["doorway", "wall"],
            far,
            np.zeros((2, 2)),
            np.array([0.5, 0.0, 0.0]),
        )
        assert found.beta == 0.0
    assert rec(np.zeros((0, 2)), [], [], np.zeros((0, 2)), np.zeros((0, 2)), np.zeros(3)) == (
        found.__class__(-1, -1, 0.0, 0.0, 0.0)
    )


def test_the_recogniser_setting(tmp_path):
    with pytest.raises(
        ValueError, match="recogniser: must be one of kind_time, thesis, oracle, none"
    ):
        ContextualSettings(recogniser="oracle-ish")
    with pytest.raises(ValueError, match=r"kind_time\.stay: must be a number in \[0, 1\]"):
        KindTimeSettings(stay=1.5)
    mode = make_mode("contextual_task", recogniser="thesis", kind_time={"engage": 0.9})
    assert mode.settings.recogniser == "thesis" and mode.intent_ is None
    assert mode.settings_dict()["kind_time"]["engage"] == 0.9
    assert ContextualTaskMode().settings.recogniser == "kind_time"


@pytest.mark.parametrize("recogniser", ["oracle", "none"])
def test_the_ablations_in_a_trial(tmp_path, rng, recogniser):
    """The oracle assists on the true target only (so every assisted tick is right); no
    recognition never assists."""
    from study.engine.standalone import standalone_trial
    from study.participants.synthetic import synthetic_participant

    result, engine = standalone_trial(
        tmp_path,
        synthetic_participant(rng),
        mode="contextual_task",
        mode_settings={"recogniser": recogniser},
        scenario="demo_docking",
        timeout_s=30.0,
    )
    engine.dispose()
    rec = result.outcome["recognition"]
    assert result.outcome["mode_settings"]["recogniser"] == recogniser
    if recogniser == "none":
        assert rec["assist"]["assist_all_ticks"] == 0
    else:
        assert rec["assist"]["assist_all_ticks"] > 0 and rec["assist_precision"] == 1.0
        assert rec["confident_wrong_s"] == 0.0


def test_the_oracle_is_refused_for_other_participants(tmp_path, rng):
    from study.engine.standalone import standalone_trial
    from study.participants.scripted import ScriptedParticipant

    with pytest.raises(ValueError, match="only synthetic participants have"):
        standalone_trial(
            tmp_path,
            ScriptedParticipant(rng),
            mode="contextual_task",
            mode_settings={"recogniser": "oracle"},
            timeout_s=2.0,
        )


def test_a_dock_is_approached_never_departed(rng):
    """Docking is doorway-like motion at a dock (Sec. 4.2.4), but a dock is a goal: moving
    away from it is no docking."""
    found = {}
    for direction in (1.0, -1.0):
        rec = _recogniser(rng)
        for _ in range(30):
            f = rec(
                np.array([[1.0, -1.0]]),
                ["dock"],
                ["dock"],
                np.array([[0.4, 0.0]]),
                np.array([[1.0, 0.0]]),
                np.array([0.5 * direction, 0.0, 0.0]),
            )
        found[direction] = f
    assert found[1.0].beta >= 0.8 and found[1.0].posterior > found[-1.0].posterior
    assert found[-1.0].beta == 0.0


def test_a_crossing_goes_on_past_the_passage_centre(rng):
    """Leaving a doorway within ``exit_radius`` of its centre scores as its mirror image
    approaching it (head-on on the axis, less beside it); beyond the radius it does not."""
    prior = IntentPrior.from_metadata({"intent_prior": _prior(rng)}, CLASSES)
    rec = KindTimeRecogniser(prior, KindTimeSettings())
    plain = KindTimeRecogniser(prior, KindTimeSettings(exit_radius=0.0))
    mean, normal, u = np.array([[1.0, -1.0]]), np.array([[1.0, 0.0]]), np.array([0.6, 0, 0])

    def log_l(r, target):
        return r._likelihood(mean, ["doorway"], np.array([target]), normal, u)[0][0]

    assert log_l(rec, [-0.4, 0.0]) == pytest.approx(log_l(rec, [0.4, 0.0]), rel=1e-12)
    w = rec.settings.toward_weight
    assert log_l(rec, [-0.4, 0.0]) == pytest.approx(log_l(plain, [-0.4, 0.0]) + 2 * w)
    beyond = [-(rec.settings.exit_radius + 0.2), 0.0]
    assert log_l(rec, beyond) == log_l(plain, beyond)
    # beside the axis (45 degrees off it): as its mirror image approaching, less than on it
    aside = [-0.3, 0.3]
    assert log_l(rec, aside) == pytest.approx(log_l(rec, [0.3, 0.3]), rel=1e-12)
    assert log_l(plain, aside) < log_l(rec, aside) < log_l(rec, [-0.3 * 2**0.5, 0.0])
    # a dock is never crossed: leaving it is departure, whatever the radius
    dock = rec._likelihood(mean, ["dock"], np.array([[-0.4, 0.0]]), normal, u)[0][0]
    assert dock < log_l(plain, [-0.4, 0.0])


def test_the_compiled_likelihood_equals_its_numpy_formulation(rng):
    """Within PIPELINE_RTOL (tests/fp.py: exp, log and sums in another order), the best
    primitive exactly unless two are tied within it."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).parent))
    from fp import PIPELINE_RTOL, assert_pipeline_close
    from kind_time_reference import ref_likelihood

    rec = _recogniser(rng)
    kinds_all = list(KIND_CLASS)
    for t in range(300):
        n = int(rng.integers(1, 12))
        mean = rng.normal(size=(n, 2)) * rng.uniform(0.1, 3.0)
        if t % 10 == 0:
            mean[int(rng.integers(n)), int(rng.integers(2))] = rng.choice([np.nan, np.inf, -np.inf])
        kinds = [kinds_all[int(i)] for i in rng.integers(0, len(kinds_all), n)]
        targets = rng.normal(size=(n, 2)) * rng.uniform(0.05, 4.0)
        normals = rng.normal(size=(n, 2)) * (rng.random((n, 1)) < 0.5)
        u = rng.uniform(-1, 1, 3) * (t % 7 != 0)
        got, got_best = rec._likelihood(mean, kinds, targets, normals, u)
        ref, ref_best, lj = ref_likelihood(rec, mean, kinds, targets, normals, u)
        assert_pipeline_close(got, ref, name="kind_time.likelihood")
        for c in range(n):  # another primitive only where the two tie within the tolerance
            gap = lj[c, ref_best[c]] - lj[c, got_best[c]]
            assert gap <= PIPELINE_RTOL * max(abs(lj[c, ref_best[c]]), 1.0)
