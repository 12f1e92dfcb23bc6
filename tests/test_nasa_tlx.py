"""NASA-TLX: items, pairwise comparisons, weights and scoring (questionnaires.nasa_tlx)."""

from __future__ import annotations

import itertools
import math
from collections import Counter

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from questionnaires import nasa_tlx as tlx

RATINGS = st.fixed_dictionaries(
    {sid: st.sampled_from(tlx.RATING_VALUES) for sid in tlx.SUBSCALE_IDS}
)
CHOICES = st.lists(st.booleans(), min_size=15, max_size=15).map(
    lambda first: {
        pair: pair[0] if f else pair[1] for pair, f in zip(tlx.PAIRS, first, strict=True)
    }
)
GOOD = {
    "mental": 70,
    "physical": 20,
    "temporal": 55,
    "performance": 30,
    "effort": 60,
    "frustration": 40,
}


def test_subscales_and_instrument_follow_the_manual() -> None:
    assert tlx.SUBSCALE_IDS == (
        "mental",
        "physical",
        "temporal",
        "performance",
        "effort",
        "frustration",
    )
    assert tlx.RATING_VALUES == tuple(range(0, 101, 5)) and len(tlx.RATING_VALUES) == 21
    assert tlx.INSTRUMENT.ids == tlx.SUBSCALE_IDS
    for item, sub in zip(tlx.INSTRUMENT.items, tlx.SUBSCALES, strict=True):
        assert item.kind == "slider" and item.values == tlx.RATING_VALUES
        assert item.text and item.description and item.title == sub.title
        expected = ("Perfect", "Failure") if sub.id == "performance" else ("Very Low", "Very High")
        assert item.anchors == expected


def test_pairs_are_all_fifteen_distinct_pairs() -> None:
    assert len(tlx.PAIRS) == 15
    assert {frozenset(p) for p in tlx.PAIRS} == {
        frozenset(p) for p in itertools.combinations(tlx.SUBSCALE_IDS, 2)
    }


def test_presentation_order_covers_each_pair_once_and_is_seeded(seed: int) -> None:
    orders = [tlx.presentation_order(np.random.default_rng(seed + i)) for i in range(200)]
    for order in orders:
        assert len(order) == 15
        assert Counter(frozenset(p) for p in order) == Counter(frozenset(p) for p in tlx.PAIRS)
    assert tlx.presentation_order(np.random.default_rng(seed)) == orders[0]
    # Random placement: every pair is shown both ways round, and the order is shuffled.
    shown = {pair for order in orders for pair in order}
    assert all((a, b) in shown and (b, a) in shown for a, b in tlx.PAIRS)
    assert len({tuple(frozenset(p) for p in order) for order in orders}) > 150


def test_comparison_instrument_round_trips_into_weights(rng: np.random.Generator) -> None:
    instrument = tlx.comparison_instrument(rng)
    assert len(instrument.items) == 15
    answers = {item.id: item.values[int(rng.integers(2))] for item in instrument.items}
    assert instrument.validate(answers) == answers
    weights = tlx.weights_from_choices(answers)
    assert sum(weights.values()) == 15
    for item in instrument.items:
        assert item.kind == "choice" and len(item.values) == 2
        assert item.id == tlx.pair_id(*item.values)
        assert [label for _, label in item.choices] == [
            tlx.SUBSCALES[tlx.SUBSCALE_IDS.index(v)].title for v in item.values
        ]


def test_pair_id_is_symmetric() -> None:
    for a, b in tlx.PAIRS:
        assert tlx.pair_id(a, b) == tlx.pair_id(b, a) == f"{a}_vs_{b}"


@settings(max_examples=60, deadline=None)
@given(ratings=RATINGS, choices=CHOICES)
def test_raw_is_the_mean_and_weighted_the_weighted_sum(ratings: dict, choices: dict) -> None:
    weights = tlx.weights_from_choices(choices)
    result = tlx.score(ratings, weights)
    r = np.array([ratings[s] for s in tlx.SUBSCALE_IDS], dtype=float)
    w = np.array([weights[s] for s in tlx.SUBSCALE_IDS], dtype=float)
    assert math.isclose(result.raw, r.mean())
    assert math.isclose(result.weighted, float(r @ w) / 15.0)
    assert result.adjusted == {s: ratings[s] * weights[s] for s in tlx.SUBSCALE_IDS}
    assert result.ratings == ratings and result.weights == weights
    assert 0.0 <= result.weighted <= 100.0
    unweighted = tlx.score(ratings)
    assert unweighted.weighted is None and unweighted.weights is None
    assert unweighted.raw == result.raw


@settings(max_examples=40, deadline=None)
@given(rating=st.sampled_from(tlx.RATING_VALUES), choices=CHOICES)
def test_equal_ratings_give_that_rating_for_any_weights(rating: int, choices: dict) -> None:
    result = tlx.score(dict.fromkeys(tlx.SUBSCALE_IDS, rating), tlx.weights_from_choices(choices))
    assert math.isclose(result.raw, rating) and math.isclose(result.weighted, rating)


@settings(max_examples=60, deadline=None)
@given(choices=CHOICES, flip=st.lists(st.booleans(), min_size=15, max_size=15))
def test_weights_from_choices_tally_to_fifteen(choices: dict, flip: list[bool]) -> None:
    weights = tlx.weights_from_choices(choices)
    assert list(weights) == list(tlx.SUBSCALE_IDS)
    assert sum(weights.values()) == 15 and all(0 <= w <= 5 for w in weights.values())
    assert weights == {s: sum(c == s for c in choices.values()) for s in tlx.SUBSCALE_IDS}
    assert tlx.validate_weights(weights) == weights
    # Keys in either orientation, or as pair ids, give the same tally.
    turned = {(p[::-1] if f else p): c for (p, c), f in zip(choices.items(), flip, strict=True)}
    assert tlx.weights_from_choices(turned) == weights
    assert tlx.weights_from_choices({tlx.pair_id(*p): c for p, c in choices.items()}) == weights


def test_weights_accepted_exactly_when_some_choices_give_them() -> None:
    # Independent check of the Landau condition: enumerate all 2**15 sets of choices.
    first = (np.arange(2**15)[:, None] >> np.arange(15)) & 1
    tally = np.zeros((2**15, 6), dtype=int)
    for k, (a, b) in enumerate(tlx.PAIRS):
        i, j = tlx.SUBSCALE_IDS.index(a), tlx.SUBSCALE_IDS.index(b)
        tally[:, i] += first[:, k]
        tally[:, j] += 1 - first[:, k]
    achievable = {tuple(row) for row in tally}
    for w in itertools.product(range(6), repeat=6):
        if sum(w) != 15:
            continue
        weights = dict(zip(tlx.SUBSCALE_IDS, w, strict=True))
        if w in achievable:
            assert tlx.validate_weights(weights) == weights
        else:
            with pytest.raises(ValueError, match="no set of pairwise choices"):
                tlx.validate_weights(weights)


@pytest.mark.parametrize(
    ("change", "named", "allowed"),
    [
        ({"physical": 37}, "'physical'", "multiple of 5 from 0 to 100"),
        ({"effort": 105}, "'effort'", "multiple of 5 from 0 to 100"),
        ({"mental": -5}, "'mental'", "multiple of 5 from 0 to 100"),
        ({"temporal": 52.5}, "'temporal'", "multiple of 5"),
        ({"frustration": True}, "'frustration'", "multiple of 5"),
        ({"performance": "50"}, "'performance'", "multiple of 5"),
        ({"performance": float("nan")}, "'performance'", "required"),
        ({"menta": 50}, "'menta'", "mental, physical"),
        ({"effort": None}, "'effort'", "required"),
    ],
)
def test_invalid_ratings_name_the_subscale(change: dict, named: str, allowed: str) -> None:
    with pytest.raises(ValueError, match="subscale") as info:
        tlx.score({**GOOD, **change})
    assert named in str(info.value) and allowed in str(info.value)


def test_missing_subscale_is_named() -> None:
    ratings = {k: v for k, v in GOOD.items() if k != "effort"}
    with pytest.raises(ValueError, match="missing subscale 'effort'"):
        tlx.score(ratings)
    weights = dict.fromkeys(tlx.SUBSCALE_IDS[:5], 3)
    with pytest.raises(ValueError, match="missing subscale 'frustration'"):
        tlx.score(GOOD, weights)


def test_whole_float_ratings_are_accepted_as_ints() -> None:
    result = tlx.score({k: float(v) for k, v in GOOD.items()})
    assert result.ratings == GOOD and all(type(v) is int for v in result.ratings.values())


@pytest.mark.parametrize(
    ("weights", "message"),
    [
        (
            {
                "mental": 4,
                "physical": 2,
                "temporal": 3,
                "performance": 2,
                "effort": 2,
                "frustration": 3,
            },
            "must sum to 15",
        ),
        (
            {
                "mental": 6,
                "physical": 2,
                "temporal": 2,
                "performance": 2,
                "effort": 2,
                "frustration": 1,
            },
            "subscale 'mental'.*from 0 to 5",
        ),
        (
            {
                "mental": 2.5,
                "physical": 2.5,
                "temporal": 3,
                "performance": 2,
                "effort": 2,
                "frustration": 3,
            },
            "subscale 'mental'",
        ),
        (
            {
                "mental": 5,
                "physical": 5,
                "temporal": 5,
                "performance": 0,
                "effort": 0,
                "frustration": 0,
            },
            "no set of pairwise choices",
        ),
    ],
)
def test_invalid_weights_raise(weights: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        tlx.score(GOOD, weights)


def test_invalid_choices_raise() -> None:
    good = {p: p[0] for p in tlx.PAIRS}
    with pytest.raises(ValueError, match="'mental_vs_physical'.*'mental' or 'physical'"):
        tlx.weights_from_choices({**good, ("mental", "physical"): "effort"})
    with pytest.raises(ValueError, match="2 of the 15 pairs missing: mental_vs_effort, "):
        tlx.weights_from_choices(
            {
                p: c
                for p, c in good.items()
                if p not in {("mental", "effort"), ("temporal", "effort")}
            }
        )
    with pytest.raises(ValueError, match="more than once"):
        tlx.weights_from_choices({**good, ("physical", "mental"): "mental"})
    with pytest.raises(ValueError, match="not a pair of two different subscales"):
        tlx.weights_from_choices({**good, ("mental", "mental"): "mental"})
    with pytest.raises(ValueError, match="not a pair of two different subscales"):
        tlx.weights_from_choices({**good, ("mental", "boredom"): "mental"})
